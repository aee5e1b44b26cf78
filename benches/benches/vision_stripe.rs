//! Criterion benchmark of laser-stripe extraction on a 768 x 576 twin laser image
//! (`hp3-paper`, view 0, noise 1 gray level, PSF 0.7 px), single-threaded, beside a
//! plain memory read of the same image (the physical limit: every pixel read once).
//! Throughput is in images: criterion's "elem/s" is images per second. The scan-frame
//! case extracts 12 frames of the twin's ball scan per iteration.
//! Run: `cargo bench -p stripecal-benches --bench vision_stripe`; figures go to
//! BENCHMARKS.md ("Vision: stripes").

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;

use stripecal::model::image::{AnyGray, GrayImage};
use stripecal::model::StripeDirection;
use stripecal::vision::stripe::{
    extract_stripe, fit_line, flag_reflectance_edges, EdgeOptions, StripeExtractor, StripeMethod,
    StripeOptions,
};
use stripecal_sim::{SimConfig, Twin};

fn transpose(i: &GrayImage<u8>) -> GrayImage<u8> {
    let mut o = GrayImage::new(i.height, i.width);
    for y in 0..i.height {
        for x in 0..i.width {
            o.data[x * i.height + y] = i.data[y * i.width + x];
        }
    }
    o
}

fn stripes(c: &mut Criterion) {
    let twin = Twin::new(SimConfig::hp3_paper()).unwrap();
    let poses = twin.calibration_poses().unwrap();
    let view = twin.render_view(&poses[0].q_deg, 0).unwrap();
    let (Some(AnyGray::U8(laser)), Some(board)) = (view.laser_image, view.board_image) else {
        panic!("expected an 8-bit laser image and a board image");
    };
    let laser_t = AnyGray::U8(transpose(&laser));
    let laser = AnyGray::U8(laser);
    let img = laser.view().unwrap();
    let img_t = laser_t.view().unwrap();
    let bytes = match &laser {
        AnyGray::U8(i) => i.data.clone(),
        AnyGray::U16(_) => unreachable!(),
    };

    let mut g = c.benchmark_group("vision_stripe");
    g.throughput(Throughput::Elements(1));
    g.bench_function("memory_read_sum_768x576", |b| {
        b.iter(|| {
            black_box(&bytes)
                .iter()
                .fold(0u32, |a, &v| a.wrapping_add(v as u32))
        })
    });
    let cols = StripeOptions {
        direction: StripeDirection::Cols,
        ..StripeOptions::default()
    };
    let n = extract_stripe(img, &cols).unwrap().points.len();
    assert!(n > 500, "{n} points");
    g.bench_function("extract_stripe_cols_768x576", |b| {
        b.iter(|| extract_stripe(black_box(img), &cols).unwrap())
    });
    for (name, opts, view) in [
        ("extract_into_cols_reuse_768x576", cols.clone(), img),
        (
            "extract_into_auto_reuse_768x576",
            StripeOptions::default(),
            img,
        ),
        (
            "extract_into_gaussian_cols_reuse_768x576",
            StripeOptions {
                method: StripeMethod::Gaussian,
                ..cols.clone()
            },
            img,
        ),
        (
            "extract_into_rows_reuse_576x768_transposed",
            StripeOptions {
                direction: StripeDirection::Rows,
                ..StripeOptions::default()
            },
            img_t,
        ),
    ] {
        let mut ex = StripeExtractor::new(opts).unwrap();
        let mut out = Vec::new();
        ex.extract_into(view, &mut out).unwrap();
        assert_eq!(out.len(), n, "{name}");
        g.bench_function(name, |b| {
            b.iter(|| {
                ex.extract_into(black_box(view), &mut out).unwrap();
                out.len()
            })
        });
    }
    // The twin's ball-scan frames (12 spread over the scan), one extractor kept from
    // frame to frame as line software and `reconstruct_scan` use it: time per frame.
    let qs = twin.scan_poses().unwrap();
    let frames: Vec<AnyGray> = (0..12)
        .map(|i| {
            let k = (2 * i + 1) * qs.len() / 24;
            twin.render_scan_frame(&qs[k], k)
                .unwrap()
                .laser_image
                .unwrap()
        })
        .collect();
    let views: Vec<_> = frames.iter().map(|f| f.view().unwrap()).collect();
    let mut ex = StripeExtractor::new(cols.clone()).unwrap();
    let mut out = Vec::new();
    g.throughput(Throughput::Elements(views.len() as u64));
    g.bench_function("extract_into_scan_frames_768x576", |b| {
        b.iter(|| {
            let mut n = 0;
            for v in &views {
                ex.extract_into(black_box(*v), &mut out).unwrap();
                n += out.len();
            }
            n
        })
    });
    g.throughput(Throughput::Elements(1));
    let stripe = extract_stripe(img, &cols).unwrap();
    let bview = board.view().unwrap();
    g.bench_function("flag_reflectance_edges_768x576", |b| {
        b.iter(|| {
            let mut s = stripe.clone();
            flag_reflectance_edges(&mut s, black_box(bview), &EdgeOptions::default()).unwrap()
        })
    });
    let pts: Vec<[f64; 2]> = stripe.points.iter().map(|p| [p.u, p.v]).collect();
    g.bench_function("fit_line_stripe", |b| {
        b.iter(|| fit_line(black_box(&pts)).unwrap())
    });
    g.finish();
}

criterion_group!(benches, stripes);
criterion_main!(benches);
