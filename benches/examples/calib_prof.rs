//! Stage timings of the 15-view calibration from points (the `calib` benchmark's
//! input), one thread. Not a benchmark: a breakdown to see where the time goes.
//! Run: `cargo run --release -p stripecal-benches --example calib_prof`.

use std::time::Instant;

use stripecal::calib::axzb::solve_axzb;
use stripecal::calib::camera::{calibrate_camera, CameraOptions};
use stripecal::calib::conic::CentreModel;
use stripecal::calib::joint::{joint_adjustment, JointOptions, JointStart};
use stripecal::calib::laser_plane::fit_laser_plane;
use stripecal::calib::pipeline::{calibrate_observations, CalibrateOptions, Method};
use stripecal::calib::{CircleObs, ViewObs};
use stripecal_sim::rng::Rng;
use stripecal_sim::{SimConfig, Twin};

fn views(t: &Twin) -> Vec<ViewObs> {
    let mut rng = Rng::new(5, 1);
    t.exact_observations()
        .unwrap()
        .into_iter()
        .map(|v| ViewObs {
            circles: v
                .circles
                .iter()
                .map(|c| CircleObs {
                    u: c.u + 0.01 * rng.normal(),
                    v: c.v + 0.01 * rng.normal(),
                    ..*c
                })
                .collect(),
            stripe: v
                .stripe
                .iter()
                .map(|p| [p[0] + 0.03 * rng.normal(), p[1] + 0.03 * rng.normal()])
                .collect(),
            ..v
        })
        .collect()
}

/// On-CPU ns of the calling thread (time-sharing on a busy machine does not count).
fn cpu_ns() -> u64 {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").unwrap_or_default();
    s.split_whitespace()
        .next()
        .and_then(|x| x.parse().ok())
        .unwrap_or(0)
}

fn median_ms<T>(name: &str, reps: usize, mut f: impl FnMut() -> T) -> T {
    let mut w = Vec::new();
    let mut out = None;
    for _ in 0..reps {
        let t0 = Instant::now();
        out = Some(f());
        w.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    w.sort_by(f64::total_cmp);
    println!(
        "{name:40} median {:8.2} ms, min {:8.2} ms ({reps} runs)",
        w[reps / 2],
        w[0]
    );
    out.unwrap()
}

fn time<T>(name: &str, reps: usize, mut f: impl FnMut() -> T) -> T {
    let mut best = f64::INFINITY;
    let mut cpu = Vec::new();
    let mut out = None;
    for _ in 0..reps {
        let t0 = Instant::now();
        let c0 = cpu_ns();
        out = Some(f());
        cpu.push((cpu_ns() - c0) as f64 * 1e-6);
        best = best.min(t0.elapsed().as_secs_f64());
    }
    cpu.sort_by(f64::total_cmp);
    println!(
        "{name:40} wall best {:8.2} ms, cpu median {:8.2} ms ({reps} runs)",
        best * 1e3,
        cpu[cpu.len() / 2]
    );
    out.unwrap()
}

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(15);
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"poses": {"count": n}}))
        .unwrap();
    let t = Twin::new(cfg).unwrap();
    let v = views(&t);
    let rig = t.rig().unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let only = std::env::args().nth(2).unwrap_or_default();
    pool.install(|| {
        if only == "one-stage" {
            let opts = CalibrateOptions::default();
            time("pipeline OneStage", 20, || {
                calibrate_observations(&v, &rig, &opts).unwrap()
            });
            return;
        }
        if only == "centre" {
            use stripecal::calib::conic::{centre_generic_n, rot_times_exp_first_order, Dual};
            let cam = [600.0, 601.0, 384.0, 288.0, -0.2, 0.0, 0.0, 0.0, 0.0];
            let r0 = nalgebra::Matrix3::identity();
            type D = Dual<15>;
            let c15: [D; 9] = std::array::from_fn(|i| {
                if i < 5 {
                    D::var(cam[i], i)
                } else {
                    D::cst(cam[i])
                }
            });
            let w: [D; 3] = std::array::from_fn(|i| D::var(0.0, 9 + i));
            let rd = rot_times_exp_first_order(&r0, &w);
            let td: [D; 3] = std::array::from_fn(|i| D::var([1.0, 2.0, 100.0][i], 12 + i));
            let rf = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
            let tf = [1.0, 2.0, 100.0];
            for (name, m) in [
                ("conic", CentreModel::Conic),
                ("exact", CentreModel::ConicExact),
            ] {
                time(&format!("1320 centres D15 {name}"), 20, || {
                    let mut acc = 0.0;
                    for i in 0..1320 {
                        let c = ((i % 11) as f64 * 5.0, (i / 11 % 8) as f64 * 5.0);
                        let uv = centre_generic_n(&c15, &rd, &td, c, 1.25, m, 12).unwrap();
                        acc += uv[0].d[3] + uv[1].d[10];
                    }
                    acc
                });
                time(&format!("1320 centres f64 {name}"), 20, || {
                    let mut acc = 0.0;
                    for i in 0..1320 {
                        let c = ((i % 11) as f64 * 5.0, (i / 11 % 8) as f64 * 5.0);
                        let uv = centre_generic_n(&cam, &rf, &tf, c, 1.25, m, 12).unwrap();
                        acc += uv[0] + uv[1];
                    }
                    acc
                });
            }
            return;
        }
        if only == "camera" {
            let mut o = CameraOptions {
                centre_model: CentreModel::Conic,
                ..Default::default()
            };
            o.lm.ftol = 1e-8;
            o.lm.xtol = 1e-8;
            time("camera Conic x50", 50, || {
                calibrate_camera(
                    &v,
                    &rig.board,
                    rig.width,
                    rig.height,
                    rig.distortion_model,
                    &o,
                )
                .unwrap()
            });
            return;
        }
        if only == "stages" {
            let opts = CalibrateOptions::default();
            median_ms("pipeline one-stage", 30, || {
                calibrate_observations(&v, &rig, &opts).unwrap()
            });
            let popts = CalibrateOptions {
                method: Method::Paper,
                ..Default::default()
            };
            let r = calibrate_observations(&v, &rig, &popts).unwrap();
            let mut o = CameraOptions {
                centre_model: CentreModel::Conic,
                ..Default::default()
            };
            o.lm.ftol = 1e-8;
            o.lm.xtol = 1e-8;
            median_ms("  camera (conic, 1e-8)", 30, || {
                calibrate_camera(
                    &v,
                    &rig.board,
                    rig.width,
                    rig.height,
                    rig.distortion_model,
                    &o,
                )
                .unwrap()
            });
            let pv: Vec<_> = r
                .stages
                .camera
                .poses
                .iter()
                .map(|(i, p)| (*p, v[*i].stripe.clone()))
                .collect();
            median_ms("  laser plane", 30, || {
                fit_laser_plane(&pv, &r.stages.camera.camera).unwrap()
            });
            let (a, b): (Vec<_>, Vec<_>) = r
                .stages
                .camera
                .poses
                .iter()
                .map(|(i, p)| (v[*i].base_hand.unwrap(), p.inverse()))
                .unzip();
            median_ms("  axzb x16 (leave-one-out)", 30, || {
                for _ in 0..16 {
                    solve_axzb(&a, &b).unwrap();
                }
            });
            let start = JointStart {
                camera: r.stages.camera.camera.clone(),
                plane: r.stages.plane.plane,
                hand_cam: r.stages.axzb.x,
                base_board: r.stages.axzb.z,
            };
            median_ms("  joint", 30, || {
                joint_adjustment(&v, &rig.board, &start, &JointOptions::default()).unwrap()
            });
            return;
        }
        if only == "joint" {
            let opts = CalibrateOptions {
                method: Method::Paper,
                ..Default::default()
            };
            let r = calibrate_observations(&v, &rig, &opts).unwrap();
            let start = JointStart {
                camera: r.stages.camera.camera.clone(),
                plane: r.stages.plane.plane,
                hand_cam: r.stages.axzb.x,
                base_board: r.stages.axzb.z,
            };
            for (vc, cm) in [
                (false, CentreModel::Conic),
                (false, CentreModel::ConicExact),
                (true, CentreModel::Conic),
                (true, CentreModel::ConicExact),
            ] {
                let jo = JointOptions {
                    centre_model: cm,
                    variance_components: vc,
                    ..Default::default()
                };
                let j = time(&format!("joint variance components {vc} {cm:?}"), 5, || {
                    joint_adjustment(&v, &rig.board, &start, &jo).unwrap()
                });
                println!("   iterations {} {:?}", j.iterations, j.stop_reason);
            }
            return;
        }
        let model = rig.distortion_model;
        for cm in [CentreModel::Conic, CentreModel::ConicExact] {
            let mut o = CameraOptions {
                centre_model: cm,
                ..Default::default()
            };
            o.lm.ftol = 1e-8;
            o.lm.xtol = 1e-8;
            let c = time(&format!("camera {cm:?} (tol 1e-8)"), 5, || {
                calibrate_camera(&v, &rig.board, rig.width, rig.height, model, &o).unwrap()
            });
            println!("   iterations {} {:?}", c.iterations, c.stop_reason);
        }
        for method in [Method::Paper, Method::OneStage] {
            let opts = CalibrateOptions {
                method,
                ..Default::default()
            };
            let r = time(&format!("pipeline {method:?}"), 5, || {
                calibrate_observations(&v, &rig, &opts).unwrap()
            });
            println!(
                "   camera iterations {}, joint iterations {} {:?}",
                r.stages.camera.iterations, r.adjustment.iterations, r.adjustment.stop_reason
            );
        }
    });
}
