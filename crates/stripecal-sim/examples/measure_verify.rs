//! Measures every scan of a twin's `verify/` folder with the TRUE calibration and prints
//! the errors against truth.json: `cargo run --release -p stripecal-sim --example
//! measure_verify -- PRESET VERIFY_DIR [OVERRIDES_JSON]` (the preset and overrides the
//! folder was rendered with).

use std::ops::ControlFlow;

use nalgebra::Vector3;
use stripecal::io::read_truth;
use stripecal::reconstruct::{
    fit_plane, fit_sphere, load_scan, reconstruct_scan, FitOptions, ReconstructOptions,
};
use stripecal_sim::{SimConfig, Twin};

fn vec3(v: &serde_json::Value) -> Vector3<f64> {
    Vector3::from_iterator(v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mut cfg = SimConfig::preset(&args[1]).expect("preset");
    if let Some(o) = args.get(3) {
        cfg = cfg
            .with_overrides(&serde_json::from_str(o).expect("JSON"))
            .expect("overrides");
    }
    let twin = Twin::new(cfg).expect("twin");
    let cal = twin.true_calibration();
    let root = std::path::Path::new(&args[2]);
    let manifest = std::fs::read_to_string(root.join("verify.csv")).expect("verify.csv");
    for line in manifest.lines().skip(1) {
        let name = line.split(',').next().unwrap();
        let dir = root.join(name);
        let truth = read_truth(dir.join("truth.json")).expect("truth");
        let scan = load_scan(&dir, &cal).expect("scan");
        // STRIPECAL_DROP_BIASED=1: leave out the points the extractor flags as biased
        let opts = ReconstructOptions {
            drop_flags: if std::env::var("STRIPECAL_DROP_BIASED").is_ok() {
                stripecal::vision::stripe::FLAG_BIASED
            } else {
                0
            },
            ..Default::default()
        };
        let sp = reconstruct_scan(&cal, &scan, &opts, &mut |_, _, _| ControlFlow::Continue(()))
            .expect("reconstruct");
        if let Some(spheres) = truth.extra.get("spheres").and_then(|s| s.as_array()) {
            let mut centres = Vec::new();
            let mut line = format!("{name}: {} points;", sp.points_mm.len());
            for t in spheres {
                let c = vec3(&t["center_mm"]);
                let d = t["diameter_mm"].as_f64().unwrap();
                let near: Vec<[f64; 3]> = sp
                    .points_mm
                    .iter()
                    .filter(|p| (Vector3::from(**p) - c).norm() < 0.5 * d + 2.0)
                    .copied()
                    .collect();
                let opts = FitOptions {
                    diameter_range_mm: Some([d - 2.0, d + 2.0]),
                    ..Default::default()
                };
                let f = fit_sphere(&near, &opts).expect("sphere fit");
                let all = FitOptions {
                    trim_sigma: 0.0,
                    ..opts
                };
                let g = fit_sphere(&near, &all).expect("sphere fit");
                let r: Vec<f64> = near
                    .iter()
                    .map(|p| (Vector3::from(*p) - g.center_mm).norm() - 0.5 * g.diameter_mm)
                    .collect();
                let form = range_kept(&r, 1.0);
                line += &format!(
                    " {} centre {:.4} diameter {:+.4} (all points: {:+.4}, form {:.4}, without the 0.3% largest |r| {:.4}) mm, {} of {} inliers;",
                    t["name"].as_str().unwrap(),
                    (f.center_mm - c).norm(),
                    f.diameter_mm - d,
                    g.diameter_mm - d,
                    form,
                    range_kept(&r, 0.997),
                    f.points,
                    near.len()
                );
                centres.push(f.center_mm);
            }
            let l = (centres[1] - centres[0]).norm() - truth.extra["length_mm"].as_f64().unwrap();
            println!("{line} length {l:+.4} mm");
        } else if let Some(p) = truth.extra.get("plane") {
            let n = vec3(&p["normal"]);
            let d = p["d_mm"].as_f64().unwrap();
            let f = fit_plane(&sp.points_mm, &FitOptions::default()).expect("plane fit");
            let fnorm = if f.plane.normal.dot(&n) < 0.0 {
                -f.plane.normal
            } else {
                f.plane.normal
            };
            let all = fit_plane(
                &sp.points_mm,
                &FitOptions {
                    trim_sigma: 0.0,
                    ..Default::default()
                },
            )
            .expect("plane fit");
            let r: Vec<f64> = sp
                .points_mm
                .iter()
                .map(|p| all.plane.signed_distance(&Vector3::from(*p)))
                .collect();
            println!(
                "{name}: {} points, normal {:.5} deg, offset {:+.4} mm, rms {:.4} mm, flatness {:.4} mm \
                 ({} inliers; all points: flatness {:.4} mm, without the 0.3% largest |r| {:.4} mm)",
                sp.points_mm.len(),
                fnorm.angle(&n).to_degrees(),
                n.dot(&f.centroid_mm) - d,
                f.rms_mm,
                f.flatness_mm,
                f.points,
                all.flatness_mm,
                range_kept(&r, 0.997)
            );
        }
    }
}

/// Largest minus smallest residual of the fraction `keep` of residuals with the smallest
/// absolute values.
fn range_kept(r: &[f64], keep: f64) -> f64 {
    let mut v = r.to_vec();
    v.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
    v.truncate(((v.len() as f64) * keep).ceil() as usize);
    v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min)
}
