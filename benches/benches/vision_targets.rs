//! Criterion benchmark of target detection on 768 x 576 twin board images (view 0 of
//! each preset: noise 1 gray level, PSF 0.7 px, vignetting): the `hp3-paper` circle
//! board (88 circles, both centre methods, and the single-image view with the stripe
//! on), the `hp3-asymmetric` grid (88 circles) and the `hp3-chessboard` (70 corners).
//! One thread (a single-image call is single-threaded).
//!
//! Run: `cargo bench -p stripecal-benches --bench vision_targets`; the figures and the
//! ratio to OpenCV on the same images (tests/bench/test_bench_targets.py) go to
//! BENCHMARKS.md ("Vision: targets").

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;

use stripecal::model::image::AnyGray;
use stripecal::vision::circles::CentreMethod;
use stripecal::vision::target::{detect_target, TargetOptions};
use stripecal::Board;
use stripecal_sim::{SimConfig, Twin};

/// View 0's board image and the board of a preset, with `over` merged.
fn view(preset: &str, over: serde_json::Value) -> (AnyGray, Board) {
    let cfg = SimConfig::preset(preset)
        .unwrap()
        .with_overrides(&over)
        .unwrap();
    let twin = Twin::new(cfg).unwrap();
    let poses = twin.calibration_poses().unwrap();
    let img = twin
        .render_view(&poses[0].q_deg, 0)
        .unwrap()
        .board_image
        .unwrap();
    (img, twin.board.clone())
}

fn targets(c: &mut Criterion) {
    let none = serde_json::json!({});
    let cases = [
        (
            "circles_gravity",
            view("hp3-paper", none.clone()),
            CentreMethod::Gravity,
        ),
        (
            "circles_ellipse",
            view("hp3-paper", none.clone()),
            CentreMethod::Ellipse,
        ),
        (
            "circles_gravity_single_image",
            view(
                "hp3-paper",
                serde_json::json!({"imaging": {"single_image": true}}),
            ),
            CentreMethod::Gravity,
        ),
        (
            "asymmetric_circles",
            view("hp3-asymmetric", none.clone()),
            CentreMethod::Gravity,
        ),
        (
            "chessboard",
            view("hp3-chessboard", none),
            CentreMethod::Gravity,
        ),
    ];
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut g = c.benchmark_group("vision_targets");
    for (name, (img, board), method) in &cases {
        let mut opts = TargetOptions::default();
        opts.circles.method = *method;
        let n = detect_target(img.view().unwrap(), board, &opts)
            .unwrap()
            .points
            .len();
        assert!(n >= 60, "{name}: {n} points");
        g.bench_function(format!("{name}_768x576"), |b| {
            pool.install(|| {
                b.iter(|| detect_target(black_box(img.view().unwrap()), board, &opts).unwrap())
            })
        });
    }
    g.finish();
}

criterion_group!(benches, targets);
criterion_main!(benches);
