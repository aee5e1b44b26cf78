//! Chessboard detection on real photographs (`shared/realdata`, beside the repository;
//! never copied into it). Skipped with a note when the folder is absent.
//!
//! - `visp_franka`: 8 views of a 9 x 6 board, 640 x 480: every view with all 54 corners.
//! - `etna_calib3`: 16 dark views of a 7 x 6 board, 1280 x 1024, a laser line in the
//!   same image: as many as possible; the count and the refusals are printed.

use std::path::Path;
use std::time::Instant;

use crate::common::realdata;
use stripecal::io::{load_gray, read_rig};
use stripecal::model::image::AnyGray;
use stripecal::vision::chessboard::{detect_chessboard, ChessboardOptions};
use stripecal::vision::target::TargetDetection;
use stripecal::{Board, Result};

/// Checks the contract's orientation on a complete detection: the image direction of
/// increasing col crossed with that of increasing row is positive (u right, v down),
/// and the square outside corner (0, 0) is dark (darker than its two neighbours
/// outside the grid, which are light).
fn check_contract(name: &str, img: &AnyGray, board: &Board, d: &TargetDetection) {
    let at = |r: usize, c: usize| {
        let p = d
            .points
            .iter()
            .find(|p| p.row == r && p.col == c)
            .expect("corner");
        [p.u, p.v]
    };
    let (p00, p01, p10) = (at(0, 0), at(0, 1), at(1, 0));
    let dc = [p01[0] - p00[0], p01[1] - p00[1]];
    let dr = [p10[0] - p00[0], p10[1] - p00[1]];
    assert!(
        dc[0] * dr[1] - dc[1] * dr[0] > 0.0,
        "{name}: mirrored labelling"
    );
    let AnyGray::U8(g) = img else { return };
    // median of a 5 x 5 patch at p00 + a dc + b dr
    let sample = |a: f64, b: f64| {
        let (x, y) = (
            p00[0] + a * dc[0] + b * dr[0],
            p00[1] + a * dc[1] + b * dr[1],
        );
        let mut v: Vec<u8> = Vec::new();
        for dy in -2i64..=2 {
            for dx in -2i64..=2 {
                let (xx, yy) = (x.round() as i64 + dx, y.round() as i64 + dy);
                if xx >= 0 && yy >= 0 && (xx as usize) < g.width && (yy as usize) < g.height {
                    v.push(g.data[yy as usize * g.width + xx as usize]);
                }
            }
        }
        v.sort_unstable();
        v.get(v.len() / 2).copied().unwrap_or(0) as f64
    };
    let outside = sample(-0.5, -0.5);
    let (left, above) = (sample(-0.5, 0.5), sample(0.5, -0.5));
    assert!(
        outside < left.min(above),
        "{name}: the square outside corner (0, 0) is not dark ({outside} vs {left}, {above}); board {} x {}",
        board.rows,
        board.cols
    );
}

/// `(image name, detection)` for every view of the dataset in `dir`.
fn run(dir: &Path) -> (Board, Vec<(String, Result<TargetDetection>)>) {
    let rig = read_rig(dir.join("rig.json")).expect("rig.json");
    let csv = std::fs::read_to_string(dir.join("views.csv")).expect("views.csv");
    let mut out = Vec::new();
    for line in csv.lines().skip(1).filter(|l| !l.trim().is_empty()) {
        let name = line.split(',').next().unwrap_or_default().to_string();
        let img = load_gray(dir.join(&name)).expect("image");
        let t = Instant::now();
        let d = detect_chessboard(
            img.view().unwrap(),
            &rig.board,
            &ChessboardOptions::default(),
        );
        let ms = t.elapsed().as_secs_f64() * 1e3;
        match &d {
            Ok(d) => println!(
                "{name}: {} corners, {} dropped, homography rms {:.3} px, max {:.3} px, median quality {:.4} px ({ms:.1} ms)",
                d.points.len(),
                d.dropped.len(),
                d.homography_rms_px,
                d.homography_max_px,
                {
                    let mut q: Vec<f64> = d.points.iter().map(|p| p.quality_px).collect();
                    q.sort_by(f64::total_cmp);
                    q.get(q.len() / 2).copied().unwrap_or(f64::NAN)
                }
            ),
            Err(e) => println!("{name}: refused: {e} ({ms:.1} ms)"),
        }
        if let Ok(d) = &d {
            if d.points.len() == rig.board.len() {
                check_contract(&name, &img, &rig.board, d);
            }
        }
        out.push((name, d));
    }
    (rig.board, out)
}

#[test]
fn visp_franka_every_view_complete() {
    let Some(root) = realdata() else { return };
    let (board, res) = run(&root.join("visp_franka"));
    assert_eq!(res.len(), 8);
    for (name, d) in &res {
        let d = d.as_ref().unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(d.points.len(), 54, "{name}: dropped {:?}", d.dropped);
        assert!(
            d.alternatives.is_empty(),
            "{name}: 9 x 6 is fixed by its colours"
        );
        // the labelling is right-handed and row-major
        for p in &d.points {
            assert_eq!(d.points[p.row * board.cols + p.col], *p);
        }
        assert!(
            d.homography_rms_px < 1.0,
            "{name}: homography rms {}",
            d.homography_rms_px
        );
    }
}

#[test]
fn etna_calib3_dark_views_with_a_laser_line() {
    let Some(root) = realdata() else { return };
    let (board, res) = run(&root.join("etna_calib3"));
    assert_eq!(res.len(), 16);
    let ok: Vec<&TargetDetection> = res.iter().filter_map(|(_, d)| d.as_ref().ok()).collect();
    let complete = ok.iter().filter(|d| d.points.len() == board.len()).count();
    println!(
        "etna_calib3: {} of 16 views detected ({complete} with all {} corners)",
        ok.len(),
        board.len()
    );
    for (name, d) in &res {
        if let Err(e) = d {
            assert!(matches!(e, stripecal::Error::Detection(_)), "{name}: {e}");
        }
    }
    assert!(
        ok.len() >= 12,
        "only {} of 16 etna views detected",
        ok.len()
    );
}
