//! Criterion benchmark of the whole calibration from detected points (issue 4,
//! acceptance 6): 15 views of the `hp3-paper` twin (exact imaged-circle centres and
//! board stripe points plus Gaussian noise of 0.01 / 0.03 px), through Zhang, the camera
//! adjustment, the laser plane, AX = ZB with the outlier check and the one-stage
//! adjustment, on ONE thread (a one-thread rayon pool). Also the paper method alone, and
//! the one-stage adjustment alone with and without the robot-pose noise.
//! Run: `cargo bench -p stripecal-benches --bench calib`; figures go to BENCHMARKS.md.

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;

use stripecal::calib::joint::{joint_adjustment, JointOptions, JointStart};
use stripecal::calib::ViewObs;
use stripecal::pipeline::{calibrate_observations, CalibrateOptions, CalibrationReport, Method};
use stripecal_sim::rng::Rng;
use stripecal_sim::{noisy_observations, SimConfig, Twin};

fn views(t: &Twin) -> Vec<ViewObs> {
    noisy_observations(
        &t.exact_observations().unwrap(),
        0.01,
        0.03,
        &mut Rng::new(5, 1),
    )
}

/// The one-stage adjustment's start as the pipeline's stages gave it.
fn start_of(rep: &CalibrationReport) -> JointStart {
    let axzb = rep.stages.axzb.as_ref().unwrap();
    JointStart {
        camera: rep.stages.camera.as_ref().unwrap().camera.clone(),
        plane: rep.stages.plane.as_ref().map(|p| p.plane),
        hand_cam: axzb.x,
        base_board: axzb.z,
    }
}

fn calib(c: &mut Criterion) {
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"poses": {"count": 15}}))
        .unwrap();
    let t = Twin::new(cfg).unwrap();
    let v = views(&t);
    let rig = t.rig().unwrap();
    let n_stripe: usize = v.iter().map(|x| x.stripe.len()).sum();
    let n_circ: usize = v.iter().map(|x| x.circles.len()).sum();
    eprintln!("15 views: {n_circ} circles, {n_stripe} stripe points");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut g = c.benchmark_group("calib");
    g.sample_size(20);
    // `..._no_loo`: without the leave-one-view-out refits (the board-scale check stays).
    for (name, method, leave_one_out) in [
        ("one_stage_15_views_1_thread", Method::OneStage, true),
        (
            "one_stage_15_views_1_thread_no_loo",
            Method::OneStage,
            false,
        ),
        ("paper_15_views_1_thread", Method::Paper, true),
    ] {
        let opts = CalibrateOptions {
            method,
            leave_one_out,
            ..Default::default()
        };
        g.bench_function(name, |b| {
            b.iter(|| pool.install(|| calibrate_observations(black_box(&v), &rig, &opts).unwrap()))
        });
    }
    // The one-stage adjustment alone from the stages' values, with the robot-pose noise
    // (the default) and with the robot poses exact (the rigid model).
    let rep = pool
        .install(|| {
            calibrate_observations(
                &v,
                &rig,
                &CalibrateOptions {
                    leave_one_out: false,
                    ..Default::default()
                },
            )
        })
        .unwrap();
    let start = start_of(&rep);
    for (name, robot_noise) in [
        ("joint_adjustment_15_views_robot_noise", true),
        ("joint_adjustment_15_views_rigid", false),
    ] {
        let opts = JointOptions {
            robot_noise,
            ..Default::default()
        };
        g.bench_function(name, |b| {
            b.iter(|| {
                pool.install(|| joint_adjustment(black_box(&v), &rig.board, &start, &opts).unwrap())
            })
        });
    }
    g.finish();
}

/// Issue 14, item 7: the one-stage adjustment of 30 views with the robot's DH
/// corrections (`full`, `auto`) and without (`fixed`), on one thread, from the stages'
/// values: a twin whose TRUE robot is off (theta0 0.05 deg, alpha 0.02 deg, a and d 0.3
/// mm per row, drawn from the seed), the robot poses the NOMINAL robot's forward
/// kinematics of the readings.
fn robot(c: &mut Criterion) {
    use stripecal::calib::joint::{RobotMode, RobotOptions};
    use stripecal::model::RobotReading;
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({
            "poses": {"count": 30},
            "robot_error": {"theta0_deg": 0.05, "alpha_deg": 0.02, "a_mm": 0.3, "d_mm": 0.3}
        }))
        .unwrap();
    let t = Twin::new(cfg).unwrap();
    let mut v = views(&t);
    for o in &mut v {
        if let Some(RobotReading::Joints(q)) = &o.reading {
            o.base_hand = Some(t.robot_nominal.forward(q).unwrap());
        }
    }
    let rig = t.rig().unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let rep = pool
        .install(|| {
            calibrate_observations(
                &v,
                &rig,
                &CalibrateOptions {
                    leave_one_out: false,
                    ..Default::default()
                },
            )
        })
        .unwrap();
    let start = start_of(&rep);
    let mut g = c.benchmark_group("calib_robot");
    g.sample_size(10);
    for mode in [RobotMode::Fixed, RobotMode::Full, RobotMode::Auto] {
        let opts = JointOptions {
            robot: Some(RobotOptions {
                nominal: t.robot_nominal.clone(),
                mode,
            }),
            ..Default::default()
        };
        let name = format!("joint_adjustment_30_views_robot_{}", mode.name());
        g.bench_function(&name, |b| {
            b.iter(|| {
                pool.install(|| joint_adjustment(black_box(&v), &rig.board, &start, &opts).unwrap())
            })
        });
    }
    g.finish();
}

criterion_group!(benches, calib, robot);
criterion_main!(benches);
