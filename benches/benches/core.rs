//! Criterion benchmarks of the foundation: projection, forward kinematics, rendering.
//! Run: `cargo bench -p stripecal-benches --bench core`; figures go to BENCHMARKS.md.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use nalgebra::Vector3;
use std::hint::black_box;

use stripecal::{Camera, DistortionModel, Intrinsics, Robot};
use stripecal_sim::{SimConfig, Twin};

fn camera() -> Camera {
    Camera::new(
        768,
        576,
        Intrinsics {
            fu: 1271.65,
            fv: 1322.52,
            u0: 346.14,
            v0: 262.60,
        },
        DistortionModel::OpenCv5,
        [-0.3, 0.1, 1e-3, 1e-3, 0.0],
    )
    .unwrap()
}

fn projection(c: &mut Criterion) {
    let cam = camera();
    let pts: Vec<Vector3<f64>> = (0..1000)
        .map(|i| {
            Vector3::new(
                -20.0 + 0.04 * i as f64,
                15.0 - 0.03 * i as f64,
                100.0 + 0.01 * i as f64,
            )
        })
        .collect();
    let mut g = c.benchmark_group("camera");
    g.throughput(Throughput::Elements(pts.len() as u64));
    g.bench_function("project_1000", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for p in &pts {
                acc += cam.project(black_box(p)).map(|uv| uv.x).unwrap_or(0.0);
            }
            acc
        })
    });
    g.bench_function("project_with_jacobians_1000", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for p in &pts {
                if let Ok((uv, jp, jc)) = cam.project_with_jacobians(black_box(p)) {
                    acc += uv.x + jp[(0, 0)] + jc[(0, 0)];
                }
            }
            acc
        })
    });
    let pix: Vec<nalgebra::Vector2<f64>> = pts.iter().filter_map(|p| cam.project(p).ok()).collect();
    g.bench_function("unproject_1000", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for uv in &pix {
                acc += cam.unproject(black_box(uv)).map(|r| r.x).unwrap_or(0.0);
            }
            acc
        })
    });
    g.finish();
}

fn kinematics(c: &mut Criterion) {
    let robot = Robot::hp3();
    let q = [3.0, -10.0, 12.0, 20.0, -80.0, 30.0];
    c.bench_function("kinematics/hp3_forward", |b| {
        b.iter(|| robot.forward(black_box(&q)))
    });
}

fn rendering(c: &mut Criterion) {
    let twin = Twin::new(SimConfig::hp3_paper()).unwrap();
    let poses = twin.calibration_poses().unwrap();
    let q = poses[0].q_deg.clone();
    // warm the ray table
    let _ = twin.render_linear(&q, false).unwrap();
    let mut g = c.benchmark_group("twin");
    g.sample_size(10);
    g.bench_function("render_linear_768x576", |b| {
        b.iter(|| twin.render_linear(black_box(&q), false).unwrap())
    });
    g.bench_function("render_view_board_and_laser_768x576", |b| {
        b.iter(|| twin.render_view(black_box(&q), 0).unwrap())
    });
    let qs = twin.scan_poses().unwrap();
    let mid = qs[qs.len() / 2].clone();
    g.bench_function("render_scan_frame_768x576", |b| {
        b.iter(|| twin.render_scan_frame(black_box(&mid), 0).unwrap())
    });
    g.finish();
}

criterion_group!(benches, projection, kinematics, rendering);
criterion_main!(benches);
