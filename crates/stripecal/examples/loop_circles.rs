// scratch: not committed
use stripecal::io::{load_gray, read_rig};
use stripecal::vision::target::{detect_target, TargetOptions};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let rig = read_rig(&args[1]).unwrap();
    let img = load_gray(&args[2]).unwrap();
    let n: usize = args[3].parse().unwrap();
    let mut best = f64::INFINITY;
    let mut tot = 0.0;
    for _ in 0..n {
        let t0 = std::time::Instant::now();
        let r = detect_target(img.view().unwrap(), &rig.board, &TargetOptions::default());
        let dt = t0.elapsed().as_secs_f64() * 1e3;
        best = best.min(dt);
        tot += dt;
        std::hint::black_box(r.ok());
    }
    println!("min {best:.3} ms mean {:.3} ms", tot / n as f64);
}
