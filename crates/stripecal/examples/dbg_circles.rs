// scratch: not committed
use stripecal::io::{load_gray, read_rig};
use stripecal::vision::target::{detect_target, TargetOptions};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let rig = read_rig(&args[1]).unwrap();
    for p in &args[2..] {
        let img = load_gray(p).unwrap();
        let t0 = std::time::Instant::now();
        let r = detect_target(img.view().unwrap(), &rig.board, &TargetOptions::default());
        let dt = t0.elapsed().as_secs_f64() * 1e3;
        match r {
            Ok(d) => println!(
                "{p}: {} points, {} dropped, alt {:?}, H rms {:.3} markers {} ({dt:.2} ms)",
                d.points.len(),
                d.dropped.len(),
                d.alternatives,
                d.homography_rms_px,
                d.circles.as_ref().map(|c| c.markers_seen).unwrap_or(0)
            ),
            Err(e) => println!("{p}: ERR {e} ({dt:.2} ms)"),
        }
    }
}
