//! Chessboard detection on real photographs (`shared/realdata`, beside the repository;
//! never copied into it). Skipped with a note when the folder is absent.
//!
//! - `visp_franka`: 8 views of a 9 x 6 board, 640 x 480: every view with all 54 corners.
//! - `etna_calib3`: 16 dark views of a 7 x 6 board, 1280 x 1024, a laser line in the
//!   same image: as many as possible; the count and the refusals are printed.

use std::path::{Path, PathBuf};
use std::time::Instant;

use stripecal::io::{load_gray, read_rig};
use stripecal::vision::chessboard::{detect_chessboard, ChessboardOptions};
use stripecal::vision::target::TargetDetection;
use stripecal::{Board, Result};

fn realdata() -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/realdata");
    if p.is_dir() {
        Some(p)
    } else {
        println!("skipped: {} does not exist", p.display());
        None
    }
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
