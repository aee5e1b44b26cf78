//! Detector tests on exactly rendered synthetic chessboards (`render`).

mod render;

use super::*;
use crate::model::image::ImageView;
use render::Scene;

fn detect8(img: &[u8], w: usize, h: usize, board: &Board) -> Result<TargetDetection> {
    let v = ImageView::from_slice(img, w, h)?;
    detect_chessboard(AnyView::U8(v), board, &ChessboardOptions::default())
}

/// Position errors against the truth (labels as returned): `(rms, max, worst index)`.
fn errors(d: &TargetDetection, truth: &[[f64; 2]], board: &Board) -> (f64, f64) {
    let (mut ss, mut mx) = (0.0f64, 0.0f64);
    for p in &d.points {
        let t = truth[p.row * board.cols + p.col];
        let e = (p.u - t[0]).hypot(p.v - t[1]);
        ss += e * e;
        mx = mx.max(e);
    }
    ((ss / d.points.len().max(1) as f64).sqrt(), mx)
}

fn board69() -> Board {
    Board::chessboard(6, 9, 20.0).unwrap()
}

#[test]
fn accurate_under_tilt_and_rotation() {
    let b = board69();
    let (w, h) = (640, 480);
    let mut all = Vec::new();
    for (k, &(roll, tilt, axis)) in [
        (0.0, 0.0, 0.0),
        (17.0, 30.0, 10.0),
        (-35.0, 45.0, 70.0),
        (120.0, 40.0, 140.0),
        (200.0, 25.0, 45.0),
    ]
    .iter()
    .enumerate()
    {
        let mut s = Scene::new(&b, w, h, roll, tilt, axis, 0.6);
        s.seed = 11 + k as u64;
        let img = s.render();
        let d = detect8(&img, w, h, &b).unwrap_or_else(|e| panic!("pose {k}: {e}"));
        assert_eq!(d.points.len(), 54, "pose {k}: dropped {:?}", d.dropped);
        let (rms, mx) = errors(&d, &s.truth(), &b);
        println!("pose {k} (roll {roll}, tilt {tilt}): rms {rms:.4} px, max {mx:.4} px, homography rms {:.4}", d.homography_rms_px);
        assert!(rms <= 0.02, "pose {k}: rms {rms}");
        all.push(rms);
        assert!(d.alternatives.is_empty());
        assert!(d
            .points
            .iter()
            .all(|p| p.quality_px > 0.0 && p.quality_px < 0.05));
    }
}

#[test]
fn indices_follow_the_contract_at_any_rotation() {
    let b = board69();
    let (w, h) = (320, 240);
    for k in 0..12 {
        let roll = 30.0 * k as f64 + 7.0;
        let mut s = Scene::new(&b, w, h, roll, 20.0, 30.0 * k as f64, 0.55);
        s.seed = 100 + k;
        let img = s.render();
        let d = detect8(&img, w, h, &b).unwrap_or_else(|e| panic!("roll {roll}: {e}"));
        assert_eq!(d.points.len(), 54, "roll {roll}");
        let (rms, mx) = errors(&d, &s.truth(), &b);
        assert!(
            mx < 0.1,
            "roll {roll}: labels wrong or inaccurate (rms {rms}, max {mx})"
        );
    }
}

#[test]
fn mild_distortion_and_small_squares() {
    let b = board69();
    let (w, h) = (640, 480);
    let mut s = Scene::new(&b, w, h, 8.0, 30.0, 100.0, 0.8);
    s.k1 = -0.15;
    let img = s.render();
    let d = detect8(&img, w, h, &b).unwrap();
    assert_eq!(d.points.len(), 54);
    let (rms, mx) = errors(&d, &s.truth(), &b);
    println!(
        "distortion: rms {rms:.4} max {mx:.4} homography rms {:.3}",
        d.homography_rms_px
    );
    assert!(rms <= 0.02, "{rms}");
    // squares of about 11 px
    let s = Scene::new(&b, w, h, 12.0, 20.0, 0.0, 0.19);
    let img = s.render();
    let d = detect8(&img, w, h, &b).unwrap();
    assert_eq!(d.points.len(), 54);
    let (rms, mx) = errors(&d, &s.truth(), &b);
    println!("small squares: rms {rms:.4} max {mx:.4}");
    assert!(rms <= 0.03, "{rms}");
}

#[test]
fn large_squares() {
    let b = Board::chessboard(2, 3, 20.0).unwrap();
    let (w, h) = (640, 480);
    let s = Scene::new(&b, w, h, 10.0, 15.0, 0.0, 0.9);
    let img = s.render();
    let d = detect8(&img, w, h, &b).unwrap();
    assert_eq!(d.points.len(), 6);
    let (rms, mx) = errors(&d, &s.truth(), &b);
    println!("large squares (~140 px): rms {rms:.4} max {mx:.4}");
    assert!(rms <= 0.02, "{rms}");
}

#[test]
fn half_turn_symmetric_board_lists_the_alternative() {
    let b = Board::chessboard(7, 9, 20.0).unwrap();
    let (w, h) = (640, 480);
    for roll in [10.0, 190.0] {
        let s = Scene::new(&b, w, h, roll, 20.0, 0.0, 0.6);
        let img = s.render();
        let d = detect8(&img, w, h, &b).unwrap();
        assert_eq!(d.points.len(), 63);
        assert_eq!(d.alternatives, b.symmetries());
        assert_eq!(d.alternatives[0].quarter_turns, 2);
        // the labelling is the truth or the truth turned
        let truth = s.truth();
        let (_, mx) = errors(&d, &truth, &b);
        let alt = d.alternatives[0];
        let mx2 = d
            .points
            .iter()
            .map(|p| {
                let (r, c) = alt.apply(&b, p.row, p.col).unwrap();
                let t = truth[r * b.cols + c];
                (p.u - t[0]).hypot(p.v - t[1])
            })
            .fold(0.0, f64::max);
        assert!(mx.min(mx2) < 0.1, "{mx} {mx2}");
    }
}

#[test]
fn mirror_images() {
    let (w, h) = (640, 480);
    let mirror = |img: &[u8]| {
        let mut m = img.to_vec();
        for y in 0..h {
            for x in 0..w {
                m[y * w + x] = img[y * w + (w - 1 - x)];
            }
        }
        m
    };
    // rows and cols both odd: no mirror symmetry, a mirror image is refused
    let b = Board::chessboard(7, 9, 20.0).unwrap();
    let img = Scene::new(&b, w, h, 15.0, 20.0, 0.0, 0.6).render();
    assert!(detect8(&img, w, h, &b).is_ok());
    let e = detect8(&mirror(&img), w, h, &b).unwrap_err();
    assert!(matches!(e, Error::Detection(_)), "{e}");
    assert!(e.to_string().contains("mirror"), "{e}");
    // 6 x 9: the pattern itself is mirror-symmetric (7 rows of squares), so its mirror
    // image is an ordinary right-handed view
    let b = board69();
    let img = Scene::new(&b, w, h, 15.0, 20.0, 0.0, 0.6).render();
    let d = detect8(&mirror(&img), w, h, &b).unwrap();
    assert_eq!(d.points.len(), 54);
}

#[test]
fn stripe_across_the_board() {
    let b = board69();
    let (w, h) = (640, 480);
    for keep in [false, true] {
        let mut s = Scene::new(&b, w, h, 5.0, 25.0, 30.0, 0.6);
        s.stripe = Some(([320.0, 240.0], [0.3, 1.0], 2.5, 300.0));
        let img = s.render();
        let v = ImageView::from_slice(&img, w, h).unwrap();
        let o = ChessboardOptions {
            drop_stripe_crossed: !keep,
            ..Default::default()
        };
        let d = detect_chessboard(AnyView::U8(v), &b, &o).unwrap();
        let truth = s.truth();
        let dist =
            |p: [f64; 2]| ((p[0] - 320.0) * 1.0 - (p[1] - 240.0) * 0.3).abs() / 1.09f64.sqrt();
        let clean: Vec<&TargetPoint> = d
            .points
            .iter()
            .filter(|p| !p.flags.has(PointFlags::STRIPE_CROSSED))
            .collect();
        let (mut ss, mut mx) = (0.0f64, 0.0f64);
        for p in &clean {
            let t = truth[p.row * b.cols + p.col];
            let e = (p.u - t[0]).hypot(p.v - t[1]);
            ss += e * e;
            mx = mx.max(e);
            assert!(
                dist(t) > 4.0,
                "({}, {}) at {:.1} px from the stripe kept unflagged",
                p.row,
                p.col,
                dist(t)
            );
            if e > 0.05 {
                println!(
                    "({}, {}) off by {e:.3} px at {:.1} px from the stripe",
                    p.row,
                    p.col,
                    dist(t)
                );
            }
        }
        let rms = (ss / clean.len() as f64).sqrt();
        let crossed = d.points.len() - clean.len();
        println!(
            "stripe (keep {keep}): {} clean, {crossed} flagged, {} dropped, rms {rms:.4} max {mx:.4}",
            clean.len(),
            d.dropped.len()
        );
        assert!(rms <= 0.02, "{rms}");
        if keep {
            assert!(crossed >= 2, "{:?}", d.dropped);
        } else {
            assert!(
                d.dropped.len() >= 3 && d.dropped.iter().all(|x| x.reason.contains("stripe")),
                "{:?}",
                d.dropped
            );
            assert_eq!(crossed, 0);
        }
        assert!(clean.len() + d.dropped.len() + crossed >= 54 - 2);
        // every corner far from the stripe is measured
        for (k, t) in truth.iter().enumerate() {
            if dist(*t) > 14.0 {
                assert!(
                    clean.iter().any(|p| p.row * b.cols + p.col == k),
                    "corner {k} missing"
                );
            }
        }
    }
}

fn gradient(u: f64, v: f64, w: usize, _h: usize) -> f64 {
    0.25 + 0.75 * u / w as f64 + 0.0 * v
}

fn vignette(u: f64, v: f64, w: usize, h: usize) -> f64 {
    let (x, y) = (u / w as f64 - 0.5, v / h as f64 - 0.5);
    1.0 - 1.6 * (x * x + y * y)
}

#[test]
fn uneven_illumination() {
    let b = board69();
    let (w, h) = (640, 480);
    for (name, gain) in [
        ("gradient", gradient as fn(f64, f64, usize, usize) -> f64),
        ("vignette", vignette),
    ] {
        let mut s = Scene::new(&b, w, h, -20.0, 35.0, 60.0, 0.7);
        s.gain = gain;
        let img = s.render();
        let d = detect8(&img, w, h, &b).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(d.points.len(), 54, "{name}");
        let (rms, mx) = errors(&d, &s.truth(), &b);
        println!("{name}: rms {rms:.4} max {mx:.4}");
        assert!(rms <= 0.02, "{name}: {rms}");
    }
}

#[test]
fn dark_low_contrast_image() {
    let b = board69();
    let (w, h) = (640, 480);
    let mut s = Scene::new(&b, w, h, 25.0, 30.0, 20.0, 0.6);
    s.dark = 6.0;
    s.light = 40.0;
    s.gain = gradient;
    let img = s.render();
    let d = detect8(&img, w, h, &b).unwrap();
    assert_eq!(d.points.len(), 54);
    let (rms, mx) = errors(&d, &s.truth(), &b);
    println!("dark (whites 10-40 of 255): rms {rms:.4} max {mx:.4}");
    assert!(rms <= 0.08, "{rms}");
}

#[test]
fn sixteen_bit_uses_the_full_range() {
    let b = board69();
    let (w, h) = (320, 240);
    let s = Scene::new(&b, w, h, 40.0, 30.0, 0.0, 0.6);
    let img = s.render16();
    let v = ImageView::from_slice(&img, w, h).unwrap();
    let d = detect_chessboard(AnyView::U16(v), &b, &ChessboardOptions::default()).unwrap();
    assert_eq!(d.points.len(), 54);
    let (rms, _) = errors(&d, &s.truth(), &b);
    assert!(rms <= 0.03, "{rms}");
}

#[test]
fn wrong_board_size_says_what_was_found() {
    let b = board69();
    let (w, h) = (640, 480);
    let img = Scene::new(&b, w, h, 10.0, 20.0, 0.0, 0.6).render();
    let smaller = Board::chessboard(6, 8, 20.0).unwrap();
    let e = detect8(&img, w, h, &smaller).unwrap_err();
    assert!(matches!(e, Error::Detection(_)), "{e}");
    assert!(
        e.to_string().contains("9 x 6") || e.to_string().contains("6 x 9"),
        "{e}"
    );
    let larger = Board::chessboard(6, 10, 20.0).unwrap();
    let e = detect8(&img, w, h, &larger).unwrap_err();
    assert!(matches!(e, Error::Detection(_)), "{e}");
    println!("{e}");
}

#[test]
fn two_boards_are_refused() {
    let b = Board::chessboard(4, 5, 20.0).unwrap();
    let (w, h) = (640, 480);
    let mut s = Scene::new(&b, w, h, 10.0, 0.0, 0.0, 0.35);
    s.noise = 0.0;
    let left = s.render_f();
    let img: Vec<u8> = (0..w * h)
        .map(|k| {
            let (x, y) = (k % w, k / w);
            // left board shifted left, a copy of it on the right
            let xs = (x + 160).min(w - 1);
            let xr = x.saturating_sub(160);
            let v = if x < w / 2 {
                left[y * w + xs]
            } else {
                left[y * w + xr]
            };
            v.round() as u8
        })
        .collect();
    let e = detect8(&img, w, h, &b).unwrap_err();
    assert!(e.to_string().contains("two boards"), "{e}");
}

#[test]
fn partial_views() {
    let b = board69();
    let (w, h) = (640, 480);
    // the right columns leave the image, the left end with its plate is seen
    let mut s = Scene::new(&b, w, h, 0.0, 0.0, 0.0, 0.9);
    s.t.x += 150.0 * s.t.z / s.f;
    let img = s.render();
    let truth = s.truth();
    let visible = truth
        .iter()
        .filter(|p| p[0] > 8.0 && p[0] < w as f64 - 8.0)
        .count();
    let d = detect8(&img, w, h, &b).unwrap();
    assert!(
        d.points.len() >= visible - 6 && d.points.len() < 54,
        "{} of {visible}",
        d.points.len()
    );
    let (_, mx) = errors(&d, &truth, &b);
    assert!(mx < 0.1, "partial view mislabelled: {mx}");
    // both ends cut: nothing fixes the columns
    let mut s = Scene::new(&b, w, h, 0.0, 0.0, 0.0, 1.3);
    s.t.x += 10.0;
    let img = s.render();
    let e = detect8(&img, w, h, &b).unwrap_err();
    assert!(e.to_string().contains("nothing fixes"), "{e}");
    println!("{e}");
}

#[test]
fn bad_images_are_typed_errors() {
    let b = board69();
    let tiny = [7u8; 64];
    assert!(matches!(
        detect8(&tiny, 8, 8, &b),
        Err(Error::InvalidInput(_))
    ));
    for fill in [0u8, 128, 255] {
        let img = vec![fill; 64 * 48];
        assert!(matches!(
            detect8(&img, 64, 48, &b),
            Err(Error::Detection(_))
        ));
    }
    let mut rng = render::Rng(5);
    let noise: Vec<u8> = (0..320 * 240)
        .map(|_| (rng.uniform() * 255.0) as u8)
        .collect();
    let e = detect8(&noise, 320, 240, &b).unwrap_err();
    assert!(matches!(e, Error::Detection(_)), "{e}");
    let circles = Board::hp3_paper();
    let img = vec![0u8; 64 * 48];
    assert!(matches!(
        detect8(&img, 64, 48, &circles),
        Err(Error::InvalidInput(_))
    ));
    let v = ImageView::from_slice(&img, 64, 48).unwrap();
    for o in [
        ChessboardOptions {
            min_response: 1.5,
            ..Default::default()
        },
        ChessboardOptions {
            max_window_radius_px: f64::NAN,
            ..Default::default()
        },
        ChessboardOptions {
            pyramid_levels: 0,
            ..Default::default()
        },
    ] {
        assert!(matches!(
            detect_chessboard(AnyView::U8(v), &b, &o),
            Err(Error::InvalidInput(_))
        ));
    }
}

#[test]
fn clutter_around_the_board() {
    let b = board69();
    let (w, h) = (640, 480);
    let s = Scene::new(&b, w, h, -12.0, 30.0, 80.0, 0.5);
    let mut img = s.render();
    // random dark and light rectangles and speckle away from the board
    let truth = s.truth();
    let (x0, x1) = truth
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p[0]), a.1.max(p[0])));
    let mut rng = render::Rng(3);
    for _ in 0..60 {
        let (cx, cy) = (rng.uniform() * w as f64, rng.uniform() * h as f64);
        if cx > x0 - 80.0 && cx < x1 + 80.0 {
            continue;
        }
        let (rw, rh) = (5.0 + rng.uniform() * 30.0, 5.0 + rng.uniform() * 30.0);
        let val = (rng.uniform() * 255.0) as u8;
        for y in (cy - rh).max(0.0) as usize..(cy + rh).min(h as f64) as usize {
            for x in (cx - rw).max(0.0) as usize..(cx + rw).min(w as f64) as usize {
                img[y * w + x] = val;
            }
        }
    }
    let d = detect8(&img, w, h, &b).unwrap();
    assert_eq!(d.points.len(), 54);
    let (rms, mx) = errors(&d, &truth, &b);
    assert!(rms <= 0.02 && mx < 0.1, "{rms} {mx}");
}

#[test]
fn stripe_along_a_line_of_corners() {
    // a fronto-parallel board with a stripe over the corners of column 4: the grid is
    // bridged across it, the hidden corners are dropped, the labels stay right
    let b = board69();
    let (w, h) = (640, 480);
    let s = Scene::new(&b, w, h, 0.0, 0.0, 0.0, 0.7);
    let truth = s.truth();
    let mut s = s;
    let p = truth[4];
    let q = truth[5 * b.cols + 4];
    s.stripe = Some((p, [q[0] - p[0], q[1] - p[1]], 2.5, 300.0));
    let img = s.render();
    let d = detect8(&img, w, h, &b).unwrap();
    let (rms, mx) = errors(&d, &truth, &b);
    println!(
        "stripe along column 4: {} points, {} dropped, rms {rms:.4} max {mx:.4}",
        d.points.len(),
        d.dropped.len()
    );
    assert!(mx < 0.05, "{mx}");
    assert!(d.points.iter().all(|p| p.col != 4));
    assert_eq!(d.points.len(), 48);
    assert!(
        d.dropped.iter().filter(|x| x.col == 4).count() >= 5,
        "{:?}",
        d.dropped
    );
}

#[test]
fn odd_inputs_never_panic() {
    // small images, strides, random content, a board cut into pieces: typed results only
    let mut rng = render::Rng(9);
    let boards = [
        Board::chessboard(2, 2, 10.0).unwrap(),
        board69(),
        Board::chessboard(7, 7, 5.0).unwrap(),
    ];
    for k in 0..40 {
        let w = 16 + (rng.uniform() * 60.0) as usize;
        let h = 16 + (rng.uniform() * 60.0) as usize;
        let stride = w + (rng.uniform() * 5.0) as usize;
        let sq = 3.0 + rng.uniform() * 12.0;
        let data: Vec<u8> = (0..stride * h)
            .map(|i| {
                let (x, y) = ((i % stride) as f64, (i / stride) as f64);
                let chess = ((x / sq).floor() as i64 + (y / sq).floor() as i64) % 2 == 0;
                let base = if k % 3 == 0 {
                    rng.uniform() * 255.0
                } else if chess {
                    40.0
                } else {
                    210.0
                };
                (base + 20.0 * rng.uniform()).min(255.0) as u8
            })
            .collect();
        let v = ImageView::new(&data, w, h, stride).unwrap();
        for b in &boards {
            match detect_chessboard(AnyView::U8(v), b, &ChessboardOptions::default()) {
                Ok(d) => assert!(d.points.iter().all(|p| p.row < b.rows && p.col < b.cols)),
                Err(e) => assert!(
                    matches!(e, Error::Detection(_) | Error::InvalidInput(_)),
                    "{e}"
                ),
            }
        }
    }
}

#[test]
fn detect_target_routes_chessboards_here() {
    let b = board69();
    let (w, h) = (320, 240);
    let img = Scene::new(&b, w, h, 5.0, 10.0, 0.0, 0.6).render();
    let v = ImageView::from_slice(&img, w, h).unwrap();
    let d = crate::vision::target::detect_target(AnyView::U8(v), &b, &Default::default()).unwrap();
    assert_eq!(d.kind, BoardKind::Chessboard);
    assert_eq!(d.points.len(), 54);
    assert!(d.circles.is_none());
    assert!(d.homography_rms_px < 0.05);
}
