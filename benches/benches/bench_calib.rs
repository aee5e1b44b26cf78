//! Criterion benchmark of issue 17, acceptance 6: the bench calibration (a views.csv
//! without pose columns: camera, laser plane and a free board pose per view) against the
//! robot calibration of the SAME 15 views (768 x 576, the `hp3-paper` twin, noise 1 gray
//! level, PSF 0.7 px), each from the dataset folder: decoding the PNGs, detecting the
//! board and the stripe, and the whole pipeline with its leave-one-view-out, on the
//! default rayon pool. The twin is rendered once into the system's temporary folder; the
//! bench dataset is its views.csv with the pose columns removed.
//! Run: `cargo bench -p stripecal-benches --bench bench_calib`; figures in BENCHMARKS.md.

use std::path::{Path, PathBuf};

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;

use stripecal::model::Dataset;
use stripecal::pipeline::{calibrate_observations, observe_dataset, CalibrateOptions};
use stripecal_sim::{SimConfig, Twin};

/// The twin's calibration dataset (rendered once) and its bench copy.
fn datasets() -> (PathBuf, PathBuf) {
    let root = std::env::temp_dir().join("stripecal_bench_calib_15");
    let robot = root.join("calib");
    if !robot.join("views.csv").exists() {
        let cfg = SimConfig::hp3_paper()
            .with_overrides(&serde_json::json!({
                "poses": {"count": 15},
                "imaging": {"noise_gray": 1.0, "psf_sigma_px": 0.7},
                "scan": {"enabled": false}
            }))
            .unwrap();
        Twin::new(cfg)
            .unwrap()
            .write(&root, &mut |_, _, _| {})
            .unwrap();
    }
    let bench = root.join("bench");
    std::fs::create_dir_all(&bench).unwrap();
    std::fs::copy(robot.join("rig.json"), bench.join("rig.json")).unwrap();
    let text = std::fs::read_to_string(robot.join("views.csv")).unwrap();
    let mut out = String::new();
    for line in text.lines().filter(|l| !l.is_empty()) {
        let cells: Vec<&str> = line.split(',').collect();
        let name = |c: &str| {
            if c.is_empty() || c == "board_image" || c == "laser_image" {
                c.to_string()
            } else {
                format!("../calib/{c}")
            }
        };
        out.push_str(&format!("{},{}\n", name(cells[0]), name(cells[1])));
    }
    std::fs::write(bench.join("views.csv"), out).unwrap();
    (robot, bench)
}

fn run(dir: &Path, opts: &CalibrateOptions) -> f64 {
    let ds = Dataset::load(dir).unwrap();
    let (obs, _) = observe_dataset(&ds, opts).unwrap();
    let rep = calibrate_observations(&obs, &ds.rig, opts).unwrap();
    rep.calibration.camera.fu
}

fn bench_vs_robot(c: &mut Criterion) {
    let (robot, bench) = datasets();
    let opts = CalibrateOptions::default();
    assert!(Dataset::load(&bench).unwrap().is_bench());
    let mut g = c.benchmark_group("bench_calib");
    g.sample_size(10);
    g.bench_function("bench_15_views_from_images", |b| {
        b.iter(|| run(black_box(&bench), &opts))
    });
    g.bench_function("robot_15_views_from_images", |b| {
        b.iter(|| run(black_box(&robot), &opts))
    });
    g.finish();
}

criterion_group!(benches, bench_vs_robot);
criterion_main!(benches);
