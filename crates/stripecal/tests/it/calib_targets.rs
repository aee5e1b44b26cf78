//! The calibration pipeline on rendered twins of every target kind (issue 10,
//! acceptance 4): 15 poses of a chessboard, an asymmetric circle grid and a circle grid
//! without markers (whose half turn each view leaves open, resolved from the robot
//! poses) meet the circle board's targets: fu 0.01 %, u0 / v0 0.1 px, plane 0.01 mm, X
//! and Z 0.005 deg / 0.02 mm.
//!
//! `cargo test -p stripecal --test it calib_targets:: -- --nocapture` prints the table
//! quoted in docs/results/calibration.md.

use crate::common;

use common::{assert_targets, errors, iso_err, row, HEADER};
use stripecal::calib::consensus::symmetry_motion;
use stripecal::pipeline::{calibrate_dataset, CalibrateOptions};
use stripecal_sim::{SimConfig, Twin};

fn render(preset: &str, over: serde_json::Value, dir: &std::path::Path) -> Twin {
    let mut o = serde_json::json!({"poses": {"count": 15}, "seed": 1, "scan": {"enabled": false}});
    if let (Some(m), Some(extra)) = (o.as_object_mut(), over.as_object()) {
        for (k, v) in extra {
            m.insert(k.clone(), v.clone());
        }
    }
    let cfg = SimConfig::preset(preset)
        .unwrap()
        .with_overrides(&o)
        .unwrap();
    let t = Twin::new(cfg).unwrap();
    t.write(dir, &mut |_, _, _| {}).unwrap();
    t
}

fn calibrate(label: &str, preset: &str, over: serde_json::Value) {
    let dir = tempfile::tempdir().unwrap();
    let t = render(preset, over, dir.path());
    let rep = calibrate_dataset(dir.path().join("calib"), &CalibrateOptions::default())
        .unwrap_or_else(|e| panic!("{label}: {e}"));
    let mut e = errors(&t, &rep.calibration);
    // A symmetric board's frame is the first view's labelling: Z is compared with the
    // truth turned by the board's symmetries, whichever is nearest.
    let frame = rep
        .calibration
        .records
        .summary
        .as_ref()
        .and_then(|s| s.base_board_orientation.as_ref());
    if frame.is_some() {
        for s in t.board.symmetries() {
            let m = symmetry_motion(&t.board, &s);
            for z in [t.base_board * m, t.base_board * m.inverse()] {
                let ez = iso_err(&rep.calibration.base_board, &z);
                if ez.0 < e.z.0 {
                    e.z = ez;
                }
            }
        }
    }
    let used = rep.views.iter().filter(|v| v.used).count();
    println!("{HEADER}\n{}", row(label, &e));
    println!(
        "{label}: {used} views used, circle rms {:.4} px, stripe rms {:.4} px, frame {frame:?}, \
         warnings {:?}",
        rep.calibration.quality.circle_rms_px, rep.calibration.quality.stripe_rms_px, rep.warnings
    );
    assert_eq!(used, 15, "{label}: every view is used");
    assert_targets(label, &e);
}

#[test]
fn asymmetric_circle_grid_meets_the_targets() {
    calibrate(
        "asymmetric 11 x 8, 15 poses",
        "hp3-asymmetric",
        serde_json::json!({}),
    );
}

#[test]
fn circle_grid_without_markers_meets_the_targets() {
    calibrate(
        "circles 8 x 11, no markers, 15 poses",
        "hp3-paper",
        serde_json::json!({"board": {"markers": []}}),
    );
}

#[test]
fn chessboard_meets_the_targets() {
    calibrate(
        "chessboard 7 x 10, 15 poses",
        "hp3-chessboard",
        serde_json::json!({}),
    );
}

/// A grid without markers where one view's robot pose belongs to another view: its
/// labelling cannot be told from the robot poses, so it is left out with the reason;
/// the others calibrate.
#[test]
fn undecidable_view_is_left_out_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    render(
        "hp3-paper",
        serde_json::json!({"board": {"markers": []}, "poses": {"count": 7}}),
        dir.path(),
    );
    // view 2 gets view 5's joint readings
    let csv = dir.path().join("calib/views.csv");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let joints = |l: &str| l.splitn(3, ',').nth(2).unwrap().to_string();
    let head = |l: &str| l.splitn(3, ',').take(2).collect::<Vec<_>>().join(",");
    lines[3] = format!("{},{}", head(&lines[3]), joints(&lines[6]));
    std::fs::write(&csv, lines.join("\n") + "\n").unwrap();
    let rep = calibrate_dataset(dir.path().join("calib"), &CalibrateOptions::default()).unwrap();
    let v2 = rep.views.iter().find(|v| v.view == 2).unwrap();
    let note = v2.note.clone().unwrap_or_default();
    println!("view 2: {note}");
    assert!(!v2.used && note.contains("orientation"), "{note}");
    assert_eq!(rep.views.iter().filter(|v| v.used).count(), 6);
}
