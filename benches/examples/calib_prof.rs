//! Stage timings of the 15-view calibration from points (the `calib` benchmark's
//! input: the twin's exact observations plus 0.01 / 0.03 px noise), one thread: the
//! whole pipeline and each of its stages alone, median and minimum of 30 runs. Not a
//! benchmark (criterion's `calib` is): a breakdown to see where the time goes.
//!
//! Run: `cargo run --release -p stripecal-benches --example calib_prof -- [views]`.

use std::time::Instant;

use stripecal::calib::axzb::solve_axzb;
use stripecal::calib::camera::{calibrate_camera, CameraOptions};
use stripecal::calib::conic::CentreModel;
use stripecal::calib::joint::{joint_adjustment, JointOptions, JointStart};
use stripecal::calib::laser_plane::fit_laser_plane;
use stripecal::pipeline::{calibrate_observations, CalibrateOptions, Method};
use stripecal_sim::rng::Rng;
use stripecal_sim::{noisy_observations, SimConfig, Twin};

/// Median and minimum wall time of `reps` runs of `f`.
fn median_ms<T>(name: &str, reps: usize, mut f: impl FnMut() -> T) {
    let mut w = Vec::new();
    for _ in 0..reps {
        let t0 = Instant::now();
        std::hint::black_box(f());
        w.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    w.sort_by(f64::total_cmp);
    println!(
        "{name:36} median {:7.2} ms, min {:7.2} ms ({reps} runs)",
        w[reps / 2],
        w[0]
    );
}

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(15);
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"poses": {"count": n}}))
        .expect("preset");
    let t = Twin::new(cfg).expect("twin");
    let exact = t.exact_observations().expect("observations");
    let v = noisy_observations(&exact, 0.01, 0.03, &mut Rng::new(5, 1));
    let rig = t.rig().expect("rig");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    pool.install(|| {
        for method in [Method::OneStage, Method::Paper] {
            let opts = CalibrateOptions {
                method,
                ..Default::default()
            };
            median_ms(&format!("pipeline {}", method.name()), 30, || {
                calibrate_observations(&v, &rig, &opts).expect("calibration")
            });
        }
        // The stages as the one-stage pipeline runs them, from the paper method's values.
        let paper = calibrate_observations(
            &v,
            &rig,
            &CalibrateOptions {
                method: Method::Paper,
                ..Default::default()
            },
        )
        .expect("calibration");
        let mut o = CameraOptions {
            centre_model: CentreModel::Conic,
            ..Default::default()
        };
        o.lm.ftol = 1e-8;
        o.lm.xtol = 1e-8;
        median_ms("  camera (first-order model, 1e-8)", 30, || {
            calibrate_camera(
                &v,
                &rig.board,
                rig.width,
                rig.height,
                rig.distortion_model,
                &o,
            )
            .expect("camera")
        });
        let cam = paper
            .stages
            .camera
            .as_ref()
            .expect("the paper's camera stage");
        let pv: Vec<_> = cam
            .poses
            .iter()
            .map(|(i, p)| (*p, v[*i].stripe.clone()))
            .collect();
        median_ms("  laser plane", 30, || {
            fit_laser_plane(&pv, &cam.camera).expect("plane")
        });
        let (a, b): (Vec<_>, Vec<_>) = cam
            .poses
            .iter()
            .filter_map(|(i, p)| Some((v[*i].base_hand?, p.inverse())))
            .unzip();
        median_ms("  AX = ZB x (1 + views): leave-one-out", 30, || {
            for _ in 0..=a.len() {
                solve_axzb(&a, &b).expect("axzb");
            }
        });
        let start = JointStart {
            camera: cam.camera.clone(),
            plane: paper.stages.plane.as_ref().map(|p| p.plane),
            hand_cam: paper.stages.axzb.as_ref().expect("AX = ZB").x,
            base_board: paper.stages.axzb.as_ref().expect("AX = ZB").z,
        };
        median_ms("  one-stage adjustment", 30, || {
            joint_adjustment(&v, &rig.board, &start, &JointOptions::default()).expect("joint")
        });
    });
}
