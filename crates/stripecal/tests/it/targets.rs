//! The twin's target kinds (spec/DATASET.md, "Target kinds"): chessboards and
//! asymmetric circle grids rendered with exact per-image truth, their presets, the plate
//! margin, and the random board-only views of `stripecal_sim::views`.
//!
//! Truth is checked against constructions written here from the contract (point
//! positions, the camera model's formulas, the conic of a projected circle), not
//! against the twin's own code; images are checked at pixels placed by the truth.

use std::collections::HashSet;

use nalgebra::{Matrix3, Point3, Vector2, Vector3};

use stripecal::model::image::AnyGray;
use stripecal::model::Dataset;
use stripecal::{Board, BoardKind};
use stripecal_sim::scene::{SURF_INK0, SURF_NONE, SURF_PLATE, SURF_SPHERE, SURF_TABLE};
use stripecal_sim::truth::PointTruth;
use stripecal_sim::views::{board_cam, RandomViews};
use stripecal_sim::{target, SimConfig, Twin};

/// The camera of the paper's rig at half resolution (384 x 288, the same field of view).
fn half_camera() -> serde_json::Value {
    serde_json::json!({"width": 384, "height": 288, "fu": 635.825, "fv": 661.26,
                       "u0": 172.82, "v0": 131.05})
}

/// `preset` on the half-size camera, no noise, blur or vignetting, no scan, with
/// `over` merged last.
fn small_clean(preset: &str, over: serde_json::Value) -> Twin {
    let base = serde_json::json!({
        "camera": half_camera(),
        "imaging": {"noise_gray": 0.0, "psf_sigma_px": 0.0, "vignetting": 0.0},
        "scan": {"enabled": false}
    });
    let cfg = SimConfig::preset(preset)
        .unwrap()
        .with_overrides(&base)
        .unwrap()
        .with_overrides(&over)
        .unwrap();
    Twin::new(cfg).unwrap()
}

/// The contract's position of point (r, c) (spec/DATASET.md), written out here.
fn contract_point(b: &Board, r: usize, c: usize) -> Vector3<f64> {
    match b.kind {
        BoardKind::AsymmetricCircles => Vector3::new(
            (2 * c + r % 2) as f64 * b.pitch_mm / 2.0,
            r as f64 * b.pitch_mm / 2.0,
            0.0,
        ),
        _ => Vector3::new(c as f64 * b.pitch_mm, r as f64 * b.pitch_mm, 0.0),
    }
}

/// The contract's camera model (spec/DATASET.md, "Camera model"), written out here.
fn contract_project(twin: &Twin, p: &Vector3<f64>) -> Vector2<f64> {
    let c = &twin.camera;
    let [k1, k2, p1, p2, k3] = twin.cfg.camera.distortion;
    let (xn, yn) = (p.x / p.z, p.y / p.z);
    let r2 = xn * xn + yn * yn;
    let radial = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
    let xd = xn * radial + 2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn);
    let yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xn * yn;
    Vector2::new(c.fu * xd + c.u0, c.fv * yd + c.v0)
}

fn gray(img: &AnyGray, u: f64, v: f64) -> u16 {
    match img {
        AnyGray::U8(i) => i.data[v.round() as usize * i.width + u.round() as usize] as u16,
        AnyGray::U16(i) => i.data[v.round() as usize * i.width + u.round() as usize],
    }
}

/// 8-bit gray levels of the ink, the plate and the table in a clean board image.
fn levels(twin: &Twin) -> (u16, u16, u16) {
    let im = &twin.cfg.imaging;
    let g = |r: f64| (im.ambient * r * 255.0).round() as u16;
    (
        g(im.circle_reflectance),
        g(im.plate_reflectance),
        g(im.table_reflectance),
    )
}

fn find(truth: &[PointTruth], r: usize, c: usize) -> Option<&PointTruth> {
    truth.iter().find(|t| t.row == r && t.col == c)
}

/// Chessboard corners: the truth is the contract's projection of the corner (no
/// perspective bias), for every corner inside the image and for no other, under a
/// strongly distorted lens and partial views.
#[test]
fn chessboard_corner_truth_is_the_projected_corner() {
    let twin = small_clean(
        "hp3-chessboard",
        serde_json::json!({"camera": {"distortion_model": "opencv5",
                                      "distortion": [-0.25, 0.12, 0.001, -0.0005, 0.0]}}),
    );
    let b = &twin.board;
    let views = RandomViews {
        count: 12,
        seed: 5,
        ..Default::default()
    }
    .sample(&twin)
    .unwrap();
    let mut partial = 0;
    for (k, view) in views.iter().enumerate() {
        let cam_board = view.board_cam.inverse();
        let mut want = 0;
        for (r, c) in b.indices() {
            let p = (cam_board * Point3::from(contract_point(b, r, c))).coords;
            let uv = contract_project(&twin, &p);
            let inside = p.z > 0.0
                && uv.x >= -0.5
                && uv.y >= -0.5
                && uv.x <= twin.camera.width as f64 - 0.5
                && uv.y <= twin.camera.height as f64 - 0.5;
            match find(&view.truth, r, c) {
                Some(t) => {
                    assert!(
                        (t.u - uv.x).abs() < 1e-9 && (t.v - uv.y).abs() < 1e-9,
                        "view {k} ({r}, {c}): truth ({}, {}) vs ({}, {})",
                        t.u,
                        t.v,
                        uv.x,
                        uv.y
                    );
                    assert_eq!((t.u, t.v), (t.u_center_proj, t.v_center_proj));
                    want += 1;
                }
                // corners within 1e-6 px of the border may go either way
                None => assert!(
                    !inside
                        || uv.x < 1e-6 - 0.5
                        || uv.y < 1e-6 - 0.5
                        || uv.x > twin.camera.width as f64 - 0.5 - 1e-6
                        || uv.y > twin.camera.height as f64 - 0.5 - 1e-6,
                    "view {k}: corner ({r}, {c}) at ({}, {}) is inside but not in the truth",
                    uv.x,
                    uv.y
                ),
            }
        }
        assert_eq!(want, view.truth.len());
        assert!(view.truth.len() * 10 >= b.len() * 7, "view {k}");
        if view.truth.len() < b.len() {
            partial += 1;
        }
    }
    assert!(partial > 0, "some views leave corners outside the image");
}

/// Asymmetric grids: the truth is the centre of the projected circle, computed here as
/// the centre of the image conic `H^-T C H^-1` (the image of a circle under a pinhole
/// without distortion is an ellipse, and its area centroid is its centre), at the
/// contract's circle positions; at fronto-parallel views it is the projected centre.
#[test]
fn asymmetric_truth_is_the_centre_of_the_imaged_ellipse() {
    let twin = small_clean(
        "hp3-asymmetric",
        serde_json::json!({"camera": {"distortion": [0.0, 0.0, 0.0, 0.0, 0.0]}}),
    );
    let b = twin.board.clone();
    let cam = &twin.camera;
    let k = Matrix3::new(cam.fu, 0.0, cam.u0, 0.0, cam.fv, cam.v0, 0.0, 0.0, 1.0);
    let views = RandomViews {
        count: 6,
        seed: 11,
        ..Default::default()
    }
    .sample(&twin)
    .unwrap();
    let mut worst: f64 = 0.0;
    let mut worst_bias: f64 = 0.0;
    for view in &views {
        let t = view.board_cam.inverse();
        let r = t.rotation.to_rotation_matrix().into_inner();
        let h = k * Matrix3::from_columns(&[
            r.column(0).into_owned(),
            r.column(1).into_owned(),
            t.translation.vector,
        ]);
        let hi = h.try_inverse().unwrap();
        for tr in &view.truth {
            let p = contract_point(&b, tr.row, tr.col);
            let rad = 0.5 * b.circle_diameter_mm;
            let c = Matrix3::new(
                1.0,
                0.0,
                -p.x,
                0.0,
                1.0,
                -p.y,
                -p.x,
                -p.y,
                p.x * p.x + p.y * p.y - rad * rad,
            );
            let ci = hi.transpose() * c * hi;
            let a = nalgebra::Matrix2::new(ci[(0, 0)], ci[(0, 1)], ci[(1, 0)], ci[(1, 1)]);
            let ctr = -a.try_inverse().unwrap() * Vector2::new(ci[(0, 2)], ci[(1, 2)]);
            worst = worst.max((ctr - Vector2::new(tr.u, tr.v)).norm());
            let proj = contract_project(&twin, &(t * Point3::from(p)).coords);
            assert!((proj - Vector2::new(tr.u_center_proj, tr.v_center_proj)).norm() < 1e-9);
            worst_bias = worst_bias.max((proj - Vector2::new(tr.u, tr.v)).norm());
        }
    }
    eprintln!("asymmetric: truth vs ellipse centre {worst:.2e} px; perspective bias up to {worst_bias:.4} px");
    assert!(worst < 1e-6, "{worst} px");
    assert!(worst_bias > 1e-3, "tilted views show a perspective bias");
    // fronto-parallel: the centroid is the projected centre
    let look = target::points_center(&b);
    let fronto = board_cam(look, 112.5, 0.0, 0.0, 0.1);
    let scene = twin.board_scene(&fronto);
    let truth = stripecal_sim::truth::target_truth(&scene, cam, 0.0);
    assert_eq!(truth.len(), b.len());
    for tr in &truth {
        let d = (tr.u - tr.u_center_proj).hypot(tr.v - tr.v_center_proj);
        assert!(d < 1e-7, "({}, {}): {d} px", tr.row, tr.col);
    }
}

/// A clean chessboard image has the contract's colours where the truth says: the
/// square outside corner (0, 0) dark, every square's colour at its centre, the light
/// border, then the table; each dark square its own material, none another surface's.
#[test]
fn rendered_chessboard_has_the_contract_colours() {
    let twin = small_clean("hp3-chessboard", serde_json::json!({}));
    let b = twin.board.clone();
    let s = b.pitch_mm;
    let (ink, plate, table) = levels(&twin);
    let views = RandomViews {
        count: 3,
        seed: 3,
        max_tilt_deg: 35.0,
        ..RandomViews::whole_board()
    }
    .sample(&twin)
    .unwrap();
    for (k, view) in views.iter().enumerate() {
        let img = view.render(&twin, k as u64).unwrap();
        assert_eq!(img.size(), (384, 288));
        let tr = &view.truth;
        assert_eq!(tr.len(), b.len(), "whole-board views image every corner");
        // From the truth: the square outside corner (0, 0), opposite corner (1, 1).
        let (c00, c11) = (find(tr, 0, 0).unwrap(), find(tr, 1, 1).unwrap());
        let (u, v) = (c00.u + 0.5 * (c00.u - c11.u), c00.v + 0.5 * (c00.v - c11.v));
        assert_eq!(
            gray(&img, u, v),
            ink,
            "view {k}: the square outside (0, 0) is dark"
        );
        // Inner squares at the mean of their four corners' truth.
        for r in 0..b.rows - 1 {
            for c in 0..b.cols - 1 {
                let q = [(r, c), (r, c + 1), (r + 1, c), (r + 1, c + 1)]
                    .map(|(r, c)| find(tr, r, c).unwrap());
                let u = q.iter().map(|t| t.u).sum::<f64>() / 4.0;
                let v = q.iter().map(|t| t.v).sum::<f64>() / 4.0;
                // square (i, j) = (c, r): dark when i + j is even
                let want = if (r + c) % 2 == 0 { ink } else { plate };
                assert_eq!(gray(&img, u, v), want, "view {k}: square ({c}, {r})");
            }
        }
        // All squares, the border and the table, projected from board points.
        let scene = twin.board_scene(&view.board_cam);
        let proj = |x: f64, y: f64| {
            twin.camera
                .project(&(scene.cam_board * Point3::new(x, y, 0.0)).coords)
                .unwrap()
        };
        let mut ids = HashSet::new();
        for j in -1..b.rows as i64 {
            for i in -1..b.cols as i64 {
                let (x, y) = ((i as f64 + 0.5) * s, (j as f64 + 0.5) * s);
                let uv = proj(x, y);
                let dark = (i + j).rem_euclid(2) == 0;
                let want = if dark { ink } else { plate };
                assert_eq!(gray(&img, uv.x, uv.y), want, "view {k}: square ({i}, {j})");
                let hit = scene.shade(&twin.camera.unproject(&uv).unwrap());
                if dark {
                    assert!(hit.material >= SURF_INK0);
                    assert!(ids.insert(hit.material), "one material per square");
                } else {
                    assert_eq!(hit.material, SURF_PLATE);
                }
            }
        }
        assert!(!ids.contains(&SURF_NONE) && !ids.contains(&SURF_PLATE));
        assert!(!ids.contains(&SURF_TABLE) && !ids.contains(&SURF_SPHERE));
        let [_, x1, _, y1] = target::points_bbox(&b);
        let m = twin.cfg.board.plate_margin_mm;
        let border = 0.5 * (s + m); // between the outer squares and the plate's edge
        let uv = proj(-border, 0.5 * y1);
        assert_eq!(gray(&img, uv.x, uv.y), plate, "view {k}: light border");
        let uv = proj(x1 + border, 0.5 * y1);
        assert_eq!(gray(&img, uv.x, uv.y), plate, "view {k}: light border");
        let uv = proj(0.5 * x1, -m - 2.0);
        if twin.camera.contains(&uv, 1.0) {
            assert_eq!(gray(&img, uv.x, uv.y), table, "view {k}: the table");
        }
    }
}

/// A clean asymmetric-grid image is dark at every truth centroid and light between
/// neighbours of a row.
#[test]
fn rendered_asymmetric_grid_matches_its_truth() {
    let twin = small_clean("hp3-asymmetric", serde_json::json!({}));
    let b = twin.board.clone();
    let (ink, plate, _) = levels(&twin);
    let views = RandomViews {
        count: 2,
        seed: 8,
        ..Default::default()
    }
    .sample(&twin)
    .unwrap();
    for (k, view) in views.iter().enumerate() {
        let img = view.render(&twin, k as u64).unwrap();
        for t in &view.truth {
            assert_eq!(
                gray(&img, t.u, t.v),
                ink,
                "view {k}: circle ({}, {})",
                t.row,
                t.col
            );
            if let Some(n) = find(&view.truth, t.row, t.col + 1) {
                let (u, v) = (0.5 * (t.u + n.u), 0.5 * (t.v + n.v));
                assert_eq!(
                    gray(&img, u, v),
                    plate,
                    "view {k}: between ({}, {})",
                    t.row,
                    t.col
                );
            }
        }
        // the odd rows are the shifted ones: circle (1, 0) lies right of (0, 0)
        if let (Some(a), Some(c)) = (find(&view.truth, 0, 0), find(&view.truth, 1, 0)) {
            let scene = twin.board_scene(&view.board_cam);
            let p = |r, c| contract_point(&b, r, c);
            let q = |x: Vector3<f64>| {
                twin.camera
                    .project(&(scene.cam_board * Point3::from(x)).coords)
                    .unwrap()
            };
            assert!((q(p(0, 0)) - Vector2::new(a.u_center_proj, a.v_center_proj)).norm() < 1e-9);
            assert!((q(p(1, 0)) - Vector2::new(c.u_center_proj, c.v_center_proj)).norm() < 1e-9);
        }
    }
}

/// The chessboard's edges are integrated exactly: at a fronto-parallel view without
/// distortion every pixel's dark fraction is known in closed form (the squares image to
/// axis-aligned rectangles); the twin matches it to 0.5 % of the contrast on edges and
/// 1 % where corners meet, and the total dark area of a slightly rolled view to 2e-5.
#[test]
fn chessboard_edges_are_integrated_exactly() {
    let twin = small_clean(
        "hp3-chessboard",
        serde_json::json!({"camera": {"distortion": [0.0, 0.0, 0.0, 0.0, 0.0]},
                           "imaging": {"table_reflectance": 0.9}}),
    );
    let b = twin.board.clone();
    let cam = &twin.camera;
    let s = b.pitch_mm;
    let (plate, ink) = (
        twin.cfg.imaging.plate_reflectance,
        twin.cfg.imaging.circle_reflectance,
    );
    let contrast = plate - ink;
    let look = target::points_center(&b) + Vector3::new(0.0123, -0.0371, 0.0);
    let z = 112.5;
    let (lin, _) = twin
        .render_board_linear(&board_cam(look, z, 0.0, 0.0, 0.0))
        .unwrap();
    let pe = b.pattern_extent();
    let (mut worst_edge, mut worst_corner): (f64, f64) = (0.0, 0.0);
    for row in 0..lin.height {
        for col in 0..lin.width {
            let x0 = look.x + (col as f64 - 0.5 - cam.u0) * z / cam.fu;
            let x1 = look.x + (col as f64 + 0.5 - cam.u0) * z / cam.fu;
            let y0 = look.y + (row as f64 - 0.5 - cam.v0) * z / cam.fv;
            let y1 = look.y + (row as f64 + 0.5 - cam.v0) * z / cam.fv;
            if x1 < pe[0] - 1.0 || x0 > pe[1] + 1.0 || y1 < pe[2] - 1.0 || y0 > pe[3] + 1.0 {
                continue;
            }
            let mut dark = 0.0;
            for j in -1..b.rows as i64 {
                for i in -1..b.cols as i64 {
                    if (i + j).rem_euclid(2) == 0 {
                        let ox = (x1.min((i + 1) as f64 * s) - x0.max(i as f64 * s)).max(0.0);
                        let oy = (y1.min((j + 1) as f64 * s) - y0.max(j as f64 * s)).max(0.0);
                        dark += ox * oy;
                    }
                }
            }
            let exact = plate - contrast * dark / ((x1 - x0) * (y1 - y0));
            let e = (lin.ambient[row * lin.width + col] as f64 - exact).abs() / contrast;
            let xl = (x0 / s).floor() != (x1 / s).floor();
            let yl = (y0 / s).floor() != (y1 / s).floor();
            if xl && yl {
                worst_corner = worst_corner.max(e);
            } else {
                worst_edge = worst_edge.max(e);
            }
        }
    }
    // a slight roll: the total dark area (22 of the 44 dark squares' area, all of it)
    let (lin, _) = twin
        .render_board_linear(&board_cam(look, z, 0.0, 0.0, 2f64.to_radians()))
        .unwrap();
    let dark: f64 = lin
        .ambient
        .iter()
        .map(|&a| (plate - a as f64) / contrast)
        .sum();
    let n_dark = (-1..b.rows as i64)
        .flat_map(|j| (-1..b.cols as i64).map(move |i| (i + j).rem_euclid(2) == 0))
        .filter(|&d| d)
        .count();
    let want = n_dark as f64 * s * s * cam.fu * cam.fv / (z * z);
    let rel = dark / want - 1.0;
    eprintln!(
        "chessboard coverage error: edges {worst_edge:.5}, corners {worst_corner:.5} of the \
         contrast; total dark area {rel:.2e} relative"
    );
    assert!(worst_edge < 0.005, "{worst_edge}");
    assert!(worst_corner < 0.01, "{worst_corner}");
    assert!(rel.abs() < 2e-5, "{rel}");
}

/// The new presets find their poses and write datasets the core reads back, rig.json
/// naming the kind, truth.json holding every point of every view.
#[test]
fn presets_write_valid_datasets() {
    for (preset, kind, n) in [
        ("hp3-chessboard", BoardKind::Chessboard, 70),
        ("hp3-asymmetric", BoardKind::AsymmetricCircles, 88),
    ] {
        // the pose sampler finds the preset's 5 poses
        let twin = Twin::new(SimConfig::preset(preset).unwrap()).unwrap();
        assert_eq!(twin.calibration_poses().unwrap().len(), 5, "{preset}");
        assert!(
            twin.board.symmetries().is_empty(),
            "{preset} fixes its orientation"
        );
        let cfg = SimConfig::preset(preset)
            .unwrap()
            .with_overrides(&serde_json::json!({"poses": {"count": 2}, "scan": {"max_frames": 2}}))
            .unwrap();
        let twin = Twin::new(cfg).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let summary = twin.write(dir.path(), &mut |_, _, _| {}).unwrap();
        assert_eq!(summary.view_circles, vec![n, n], "{preset}");
        assert!(
            summary.view_stripe_points.iter().all(|&k| k > 100),
            "{preset}"
        );
        let ds = Dataset::load(dir.path().join("calib")).unwrap();
        assert_eq!(ds.rig.board.kind, kind);
        assert_eq!(
            ds.rig.board, twin.board,
            "{preset}: rig.json round-trips the board"
        );
        let rig: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("calib/rig.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(rig["board"]["kind"], kind.name());
        let truth: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("calib/truth.json")).unwrap(),
        )
        .unwrap();
        let images = truth["images"].as_array().unwrap();
        assert_eq!(images.len(), 2);
        assert_eq!(images[1]["circles"].as_array().unwrap().len(), n);
        assert_eq!(truth["sim_config"]["board"]["kind"], kind.name());
        assert_eq!(summary.scan_frames, 2);
    }
}

/// `board.kind` and `board.square_mm` as knobs, and the plate margin checked per kind.
#[test]
fn board_kind_knobs_and_the_plate_margin() {
    let paper = SimConfig::hp3_paper();
    let set = |c: &SimConfig, v: serde_json::Value| c.with_overrides(&v);
    // existing configurations (no kind, no square_mm) read as circle boards
    let mut old = serde_json::to_value(&paper).unwrap();
    let board = old["board"].as_object_mut().unwrap();
    board.remove("kind");
    board.remove("square_mm");
    let old: SimConfig = serde_json::from_value(old).unwrap();
    assert_eq!(old, paper);
    assert_eq!(old.board_model().unwrap(), Board::hp3_paper());
    // switching the kind of a preset
    let a = set(
        &paper,
        serde_json::json!({"board": {"kind": "asymmetric_circles"}}),
    )
    .unwrap();
    let ab = a.board_model().unwrap();
    assert_eq!(ab, Board::asymmetric_circles(8, 11, 5.0, 2.5).unwrap());
    // a chessboard's squares reach one square beyond the outer corners: the paper's 4 mm
    // plate margin does not hold 5 mm squares
    let e = set(&paper, serde_json::json!({"board": {"kind": "chessboard"}})).unwrap_err();
    let e = e.to_string();
    assert!(
        e.contains("board.plate_margin_mm") && e.contains("square_mm"),
        "{e}"
    );
    let c = set(
        &paper,
        serde_json::json!({"board": {"kind": "chessboard", "plate_margin_mm": 8.0}}),
    )
    .unwrap();
    assert_eq!(
        c.board_model().unwrap(),
        Board::chessboard(8, 11, 5.0).unwrap()
    );
    let c = set(
        &paper,
        serde_json::json!({"board": {"kind": "chessboard", "square_mm": 3.0}}),
    )
    .unwrap();
    assert_eq!(
        c.board_model().unwrap(),
        Board::chessboard(8, 11, 3.0).unwrap()
    );
    let chess = SimConfig::hp3_chessboard();
    assert!(set(
        &chess,
        serde_json::json!({"board": {"plate_margin_mm": 4.8}})
    )
    .is_err());
    set(
        &chess,
        serde_json::json!({"board": {"plate_margin_mm": 4.81}}),
    )
    .unwrap();
    // circle grids: the margin covers the largest circle (the 3.5 mm markers)
    assert!(set(
        &paper,
        serde_json::json!({"board": {"plate_margin_mm": 1.7}})
    )
    .is_err());
    set(
        &paper,
        serde_json::json!({"board": {"plate_margin_mm": 1.75}}),
    )
    .unwrap();
    let e = set(&paper, serde_json::json!({"board": {"kind": "charuco"}})).unwrap_err();
    assert!(e.to_string().contains("board.kind"), "{e}");
    // the plate is the points' bounding box grown by the margin
    let twin = Twin::new(SimConfig::hp3_chessboard()).unwrap();
    let scene = twin.board_scene(&board_cam(
        Vector3::new(20.0, 15.0, 0.0),
        110.0,
        0.0,
        0.0,
        0.0,
    ));
    assert_eq!(
        scene.plate_extent(),
        [-10.0, 9.0 * 4.8 + 10.0, -10.0, 6.0 * 4.8 + 10.0]
    );
}

/// Random views for every kind: deterministic, at least 70 % of the points imaged, and
/// the whole board with `whole_board`.
#[test]
fn random_views_for_every_kind() {
    for preset in ["hp3-paper", "hp3-asymmetric", "hp3-chessboard"] {
        let twin = small_clean(preset, serde_json::json!({}));
        let n = twin.board.len();
        let opts = RandomViews {
            count: 10,
            seed: 1,
            ..Default::default()
        };
        let views = opts.sample(&twin).unwrap();
        assert_eq!(views.len(), 10);
        for v in &views {
            assert!(v.truth.len() * 10 >= n * 7, "{preset}");
            assert!(v.tilt_deg <= 45.0 && (0.7..=1.5).contains(&v.standoff_scale));
        }
        let again = opts.sample(&twin).unwrap();
        assert!(views
            .iter()
            .zip(&again)
            .all(|(a, b)| a.board_cam == b.board_cam && a.truth == b.truth));
        let whole = RandomViews {
            count: 5,
            seed: 2,
            ..RandomViews::whole_board()
        }
        .sample(&twin)
        .unwrap();
        for v in &whole {
            assert_eq!(v.truth.len(), n, "{preset}: whole board");
            let scene = twin.board_scene(&v.board_cam);
            assert!(target::pattern_inside(&scene, &twin.camera, 2.0, 64));
        }
    }
    let twin = small_clean("hp3-paper", serde_json::json!({}));
    let e = RandomViews {
        count: 3,
        standoff_scale: [5.0, 6.0],
        max_attempts: 200,
        ..RandomViews::whole_board()
    }
    .sample(&twin);
    assert!(e.is_ok(), "far views fit: {:?}", e.err());
    let e = RandomViews {
        count: 3,
        standoff_scale: [0.2, 0.25],
        max_attempts: 200,
        ..RandomViews::whole_board()
    }
    .sample(&twin)
    .unwrap_err();
    assert!(e.to_string().contains("random views"), "{e}");
}
