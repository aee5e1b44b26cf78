//! Criterion benchmark of the reconstruction, single-threaded:
//!
//! - `triangulate_*`: pixels -> undistort -> ray -> laser plane -> `T_base_hand *
//!   T_hand_cam` -> base frame, alone (no extraction), on stripe-like pixel sequences
//!   (576 points per frame, one per row, the stripe wandering across columns) with the
//!   paper's camera (`radial1`, k1 = 0.0002), without distortion, and with the strongly
//!   distorted `hp3-wide` lens (`radial2`). Throughput in points ("elem/s").
//! - `extract_reconstruct_768x576`: stripe extraction plus reconstruction of one
//!   rendered 768 x 576 ball-scan frame of the `hp3-paper` twin (the middle of the
//!   sweep) with the reusable [`Reconstructor`]. Throughput in frames.
//!
//! - `covariance_*`: the per-point 3x3 covariance ([`UncertaintyModel`]) of the same
//!   stripe-like pixels, one frame map per 576 points included: the calibration's
//!   covariance over the camera, plane and hand-eye numbers (`_rigid`, 19 numbers) and
//!   with every DH number of a fully calibrated robot too (`_robot`, 49 numbers),
//!   stripe noise and encoder figures. Throughput in points.
//!
//! Run: `cargo bench -p stripecal-benches --bench reconstruct`; figures go to
//! BENCHMARKS.md ("Reconstruction").

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;

use nalgebra::DMatrix;
use stripecal::calib::joint::{DhKind, DhParam};
use stripecal::model::{Calibration, NamedCovariance, RobotReading};
use stripecal::reconstruct::{
    ReconstructOptions, Reconstructor, ScanPoints, Triangulator, UncertaintyModel,
    UncertaintyOptions, DEFAULT_MIN_RAY_PLANE_ANGLE_DEG,
};
use stripecal_sim::{SimConfig, Twin};

/// Stripe-like pixels: `frames` frames of one point per row, the column drifting smoothly.
fn stripe_pixels(cal: &Calibration, frames: usize) -> Vec<[f64; 2]> {
    let (w, h) = (cal.camera.width as f64, cal.camera.height as usize);
    let mut out = Vec::with_capacity(frames * h);
    for f in 0..frames {
        let c0 = 0.2 * w + 0.6 * w * (f as f64 / frames as f64);
        for r in 0..h {
            let u = c0 + 40.0 * (r as f64 * 0.01).sin() + 0.37 * (r % 3) as f64;
            out.push([u, r as f64]);
        }
    }
    out
}

fn triangulation(c: &mut Criterion) {
    let paper = Twin::new(SimConfig::hp3_paper()).unwrap();
    let wide = Twin::new(SimConfig::hp3_wide()).unwrap();
    let mut nodist = paper.true_calibration();
    nodist.camera.distortion = [0.0; 5];
    let cases = [
        ("triangulate_radial1_paper", paper.true_calibration()),
        ("triangulate_no_distortion", nodist),
        ("triangulate_radial2_wide", wide.true_calibration()),
    ];
    let q = &paper.cfg.poses.home_q_deg;
    let base_hand = paper.robot_true.forward(q).unwrap();
    let mut g = c.benchmark_group("reconstruct");
    for (name, cal) in &cases {
        let tri = Triangulator::from_calibration(cal, DEFAULT_MIN_RAY_PLANE_ANGLE_DEG).unwrap();
        let uv = stripe_pixels(cal, 200);
        let mut out = Vec::with_capacity(uv.len());
        let mut idx = Vec::with_capacity(uv.len());
        let per_frame = cal.camera.height as usize;
        // Check the workload: nearly every pixel gives a point.
        let d = tri.triangulate_into(&base_hand, &uv, &mut out, &mut idx);
        assert!(d.total() * 100 < uv.len(), "{name}: {d:?}");
        g.throughput(Throughput::Elements(uv.len() as u64));
        g.bench_function(*name, |b| {
            b.iter(|| {
                out.clear();
                idx.clear();
                // One frame pose per 576 points, as a scan has.
                for chunk in uv.chunks(per_frame) {
                    black_box(tri.triangulate_into(
                        black_box(&base_hand),
                        black_box(chunk),
                        &mut out,
                        &mut idx,
                    ));
                }
                out.len()
            })
        });
    }
    g.finish();
}

fn frames(c: &mut Criterion) {
    let twin = Twin::new(SimConfig::hp3_paper()).unwrap();
    let qs = twin.scan_poses().unwrap();
    let k = qs.len() / 2;
    let img = twin
        .render_scan_frame(&qs[k], k)
        .unwrap()
        .laser_image
        .unwrap();
    let cal = twin.true_calibration();
    let mut rec = Reconstructor::new(&cal, &ReconstructOptions::default()).unwrap();
    let mut out = ScanPoints::default();
    let n = rec
        .frame_joints(img.view().unwrap(), &qs[k], 0, &mut out)
        .unwrap();
    assert!(n > 400, "{n} points");
    let mut g = c.benchmark_group("reconstruct");
    g.throughput(Throughput::Elements(1));
    g.bench_function("extract_reconstruct_768x576", |b| {
        b.iter(|| {
            out.clear();
            rec.frame_joints(black_box(img.view().unwrap()), &qs[k], 0, &mut out)
                .unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, triangulation, frames, covariance);
criterion_main!(benches);

/// A calibration with a dense covariance over `names` (a correlated matrix of
/// plausible one-sigmas: the speed does not depend on the values).
fn with_covariance(mut cal: Calibration, robot: bool) -> Calibration {
    let mut names: Vec<String> = ["fu", "fv", "u0", "v0"]
        .iter()
        .map(|n| format!("camera.{n}"))
        .collect();
    names.extend((0..5).map(|k| format!("camera.distortion[{k}]")));
    names.extend((0..3).map(|k| format!("laser_plane.normal[{k}]")));
    names.push("laser_plane.d_mm".into());
    names.extend((0..3).map(|k| format!("hand_cam.rotation_vector[{k}]")));
    names.extend((0..3).map(|k| format!("hand_cam.translation_mm[{k}]")));
    if robot {
        for joint in 0..6 {
            for kind in [
                DhKind::Theta0,
                DhKind::D,
                DhKind::A,
                DhKind::Alpha,
                DhKind::Beta,
            ] {
                names.push(DhParam { joint, kind }.name());
            }
        }
    }
    let n = names.len();
    let matrix = DMatrix::from_fn(n, n, |r, c| {
        let s = 1e-3 * (1.0 + (r % 7) as f64);
        if r == c {
            s * s
        } else {
            0.1 * s * 1e-3 * (1.0 + (c % 7) as f64) / (1.0 + (r as f64 - c as f64).abs())
        }
    });
    cal.covariance = Some(NamedCovariance {
        parameters: names,
        matrix,
    });
    cal
}

fn covariance(c: &mut Criterion) {
    let paper = Twin::new(SimConfig::hp3_paper()).unwrap();
    let q = paper.cfg.poses.home_q_deg.clone();
    let reading = RobotReading::Joints(q);
    let mut g = c.benchmark_group("reconstruct");
    for (name, robot) in [("covariance_rigid", false), ("covariance_robot", true)] {
        let cal = with_covariance(paper.true_calibration(), robot);
        let opts = UncertaintyOptions {
            stripe_sigma_px: Some(0.05),
            encoder_sigma_deg: Some(0.001),
            ..Default::default()
        };
        let model = UncertaintyModel::new(&cal, &opts).unwrap();
        let uv = stripe_pixels(&cal, 200);
        let per_frame = cal.camera.height as usize;
        let mut out = vec![[0.0; 6]; uv.len()];
        g.throughput(Throughput::Elements(uv.len() as u64));
        g.bench_function(name, |b| {
            b.iter(|| {
                for (chunk, dst) in uv.chunks(per_frame).zip(out.chunks_mut(per_frame)) {
                    let frame = model.frame(black_box(&reading)).unwrap();
                    frame.point_covariances(chunk.iter().map(|p| (p[0], p[1])), dst);
                }
                black_box(out[0][0])
            })
        });
        assert!(out.iter().all(|c| c[0].is_finite() && c[0] > 0.0));
    }
    g.finish();
}
