//! Criterion benchmark of issue 18, acceptance 5: a line profiler's calibration
//! (`calibrate_profiles`: arcs, consensus and closed-form start, the one-stage adjustment
//! with its point re-selection, the mirror test, the gates; the leave-one-out solves NOT
//! included) on ONE core (a 1-thread rayon pool), from 15 profiles of ~2,500 points of the
//! `hp3-profiler` twin in memory (as `crates/stripecal-sim/tests/it/profiler_calibration.rs`
//! builds them). The preset's 90 mm line gives 3,000 samples, ~2,940 points after its 2 %
//! dropouts; here `line_length_mm` is 75 (2,500 samples, ~2,450 points), the rest of the
//! preset unchanged (0.03 mm spacing, z noise 0.01 mm, 1 % spikes, the table beside the
//! sphere). The scipy comparison of the same problem: scripts/bench_profiler_scipy.py.
//! Run: `cargo bench -p stripecal-benches --bench profiler`; figures in BENCHMARKS.md.

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;

use stripecal::calib::joint::profile::{profile_adjustment, ProfileOptions};
use stripecal::model::ProfileRig;
use stripecal::pipeline::profile::{
    calibrate_profiles, prepare, ProfileCalibrateOptions, ProfileInput,
};
use stripecal_sim::{SimConfig, Twin};

/// The twin's 15 profiles as the calibration's inputs, and its rig.
fn inputs() -> (Vec<ProfileInput>, ProfileRig) {
    let mut cfg = SimConfig::hp3_profiler()
        .with_overrides(&serde_json::json!({"profiler": {"line_length_mm": 75.0, "views": 15}}))
        .unwrap();
    cfg.seed = 1;
    Twin::new(cfg).unwrap().profiler_inputs().unwrap()
}

fn bench_profiler(c: &mut Criterion) {
    let (inputs, rig) = inputs();
    let n: usize = inputs.iter().map(|i| i.profile.points.len()).sum();
    eprintln!(
        "profiler bench: {} profiles, {:.0} points each on average",
        inputs.len(),
        n as f64 / inputs.len() as f64
    );
    let opts = ProfileCalibrateOptions {
        leave_one_out: false,
        ..Default::default()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut g = c.benchmark_group("profiler");
    g.sample_size(30);
    g.bench_function("calibrate_profiles_15x2500_one_core_no_loo", |b| {
        b.iter(|| {
            pool.install(|| {
                let rep = calibrate_profiles(black_box(&inputs), &rig, &opts).unwrap();
                black_box(rep.calibration.sphere_diameter_mm)
            })
        })
    });
    // The adjustment alone (step 3: the solve from the closed-form start, its point
    // re-selection, the covariance), over the arcs' points: the problem scipy is given in
    // scripts/bench_profiler_scipy.py.
    let prep = prepare(&inputs, &rig).unwrap();
    let views: Vec<_> = prep
        .views
        .iter()
        .map(|v| {
            let mut v = v.clone();
            v.points = v.arc.iter().map(|&i| v.points[i]).collect();
            v.arc = (0..v.points.len()).collect();
            v
        })
        .collect();
    let popts = ProfileOptions::default();
    g.bench_function("adjustment_from_start_15x2500_one_core", |b| {
        b.iter(|| {
            pool.install(|| {
                let fit = profile_adjustment(black_box(&views), &prep.start, &popts).unwrap();
                black_box(fit.diameter)
            })
        })
    });
    g.finish();
}

criterion_group!(benches, bench_profiler);
criterion_main!(benches);
