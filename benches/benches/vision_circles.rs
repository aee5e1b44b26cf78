//! Criterion benchmark of circle-grid detection on a 768 x 576 twin board image
//! (`hp3-paper`, view 0: all 88 circles, noise 1 gray level, PSF 0.7 px).
//! Run: `cargo bench -p stripecal-benches --bench vision_circles`; figures and the
//! ratio to OpenCV go to BENCHMARKS.md ("Vision: circles").

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;

use stripecal::vision::circles::{detect_circles, CentreMethod, CircleOptions};
use stripecal_sim::{SimConfig, Twin};

fn circles(c: &mut Criterion) {
    let twin = Twin::new(SimConfig::hp3_paper()).unwrap();
    let poses = twin.calibration_poses().unwrap();
    let view = twin.render_view(&poses[0].q_deg, 0).unwrap();
    let img = view.board_image.unwrap();
    let single = {
        let cfg = SimConfig::hp3_paper()
            .with_overrides(&serde_json::json!({"imaging": {"single_image": true}}))
            .unwrap();
        let t = Twin::new(cfg).unwrap();
        t.render_view(&poses[0].q_deg, 0)
            .unwrap()
            .board_image
            .unwrap()
    };
    let board = twin.board.clone();
    let mut g = c.benchmark_group("vision_circles");
    for method in [CentreMethod::Gravity, CentreMethod::Ellipse] {
        let opts = CircleOptions {
            method,
            ..Default::default()
        };
        let n = detect_circles(img.view().unwrap(), &board, &opts)
            .unwrap()
            .circles
            .len();
        assert_eq!(n, 88);
        g.bench_function(format!("detect_circles_{}_768x576", method.name()), |b| {
            b.iter(|| detect_circles(black_box(img.view().unwrap()), &board, &opts).unwrap())
        });
    }
    let opts = CircleOptions::default();
    g.bench_function("detect_circles_gravity_single_image_768x576", |b| {
        b.iter(|| detect_circles(black_box(single.view().unwrap()), &board, &opts).unwrap())
    });
    g.finish();
}

criterion_group!(benches, circles);
criterion_main!(benches);
