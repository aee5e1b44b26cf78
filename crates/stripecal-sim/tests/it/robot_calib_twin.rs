//! The twin for robot kinematic calibration (issue 14): random robot errors from the
//! seed, wide-excursion pose sets, the bare-table scan and surface errors against truth.
//! No image is rendered here except the two frames of the written table scan.

use serde_json::json;
use stripecal_sim::{surface_errors, SimConfig, Twin};

fn cfg(over: serde_json::Value) -> SimConfig {
    SimConfig::hp3_paper().with_overrides(&over).unwrap()
}

const SIGMAS: [f64; 5] = [0.05, 0.02, 0.3, 0.3, 0.02];

fn errs() -> serde_json::Value {
    json!({"theta0_deg": 0.05, "alpha_deg": 0.02, "a_mm": 0.3, "d_mm": 0.3, "beta_deg": 0.02})
}

#[test]
fn robot_error_draws_are_reproducible_bounded_and_beta_only_on_row_2() {
    let a = Twin::new(cfg(json!({"seed": 7, "robot_error": errs()}))).unwrap();
    let b = Twin::new(cfg(json!({"seed": 7, "robot_error": errs()}))).unwrap();
    let c = Twin::new(cfg(json!({"seed": 8, "robot_error": errs()}))).unwrap();
    let plain = Twin::new(cfg(json!({"seed": 7}))).unwrap();
    assert_eq!(a.robot_true, b.robot_true);
    assert_ne!(a.robot_true, c.robot_true);
    assert_eq!(a.robot_nominal, plain.robot_nominal);
    assert_eq!(plain.robot_true, plain.robot_nominal);
    let mut moved = 0;
    for (i, (t, n)) in a
        .robot_true
        .joints
        .iter()
        .zip(&a.robot_nominal.joints)
        .enumerate()
    {
        let d = [
            t.theta0_deg - n.theta0_deg,
            t.alpha_deg - n.alpha_deg,
            t.a_mm - n.a_mm,
            t.d_mm - n.d_mm,
            t.beta_deg - n.beta_deg,
        ];
        for (k, (e, s)) in d.iter().zip(SIGMAS).enumerate() {
            assert!(
                e.abs() <= 5.0 * s,
                "row {} quantity {k}: {e} vs sigma {s}",
                i + 1
            );
            if *e != 0.0 {
                moved += 1;
            }
        }
        // beta only on row 2 (alpha 180; row 6 is the last)
        assert_eq!(d[4] != 0.0, i == 1, "row {} beta {}", i + 1, d[4]);
    }
    assert_eq!(moved, 6 * 4 + 1);
    // the knob does not change the other draws: the same poses (the board placement
    // follows the true robot, so the readings move by a little only)
    let (pa, pp) = (
        a.calibration_poses().unwrap(),
        plain.calibration_poses().unwrap(),
    );
    for (x, y) in pa.iter().zip(&pp) {
        let d = x
            .q_deg
            .iter()
            .zip(&y.q_deg)
            .map(|(u, v)| (u - v).abs())
            .fold(0.0, f64::max);
        assert!(d < 2.0, "{d}");
    }
    // dh_errors add on top
    let mut dh = vec![[0.0; 4]; 6];
    dh[0][0] = 0.1;
    let both = Twin::new(cfg(
        json!({"seed": 7, "robot_error": errs(), "dh_errors": dh}),
    ))
    .unwrap();
    let d0 = both.robot_true.joints[0].theta0_deg - a.robot_true.joints[0].theta0_deg;
    assert!((d0 - 0.1).abs() < 1e-12);
}

#[test]
fn robot_error_knob_is_validated() {
    for bad in [json!({"a_mm": -0.1}), json!({"beta_deg": -1.0})] {
        let e = SimConfig::hp3_paper()
            .with_overrides(&json!({ "robot_error": bad }))
            .unwrap_err()
            .to_string();
        assert!(e.contains("robot_error."), "{e}");
    }
    let e = SimConfig::hp3_paper()
        .with_overrides(&json!({"robot_error": {"theta": 1.0}}))
        .unwrap_err()
        .to_string();
    assert!(e.contains("theta"), "{e}");
    let e = SimConfig::hp3_paper()
        .with_overrides(&json!({"poses": {"spread": "far"}}))
        .unwrap_err()
        .to_string();
    assert!(e.contains("poses.spread"), "{e}");
}

/// Per joint: the standard deviation of the readings over the set, degrees.
fn stds(poses: &[stripecal_sim::poses::PoseInfo]) -> Vec<f64> {
    let n = poses.len() as f64;
    (0..poses[0].q_deg.len())
        .map(|j| {
            let m = poses.iter().map(|p| p.q_deg[j]).sum::<f64>() / n;
            (poses.iter().map(|p| (p.q_deg[j] - m).powi(2)).sum::<f64>() / n).sqrt()
        })
        .collect()
}

fn ranges(poses: &[stripecal_sim::poses::PoseInfo]) -> Vec<f64> {
    (0..poses[0].q_deg.len())
        .map(|j| {
            let v = poses.iter().map(|p| p.q_deg[j]);
            v.clone().fold(f64::MIN, f64::max) - v.fold(f64::MAX, f64::min)
        })
        .collect()
}

#[test]
fn wide_poses_satisfy_the_constraints_and_move_every_joint_more() {
    let over = |spread: &str| {
        json!({"seed": 1, "robot_error": errs(),
               "poses": {"count": 30, "spread": spread, "max_joint_delta_deg": 90.0}})
    };
    let wide_twin = Twin::new(cfg(over("wide"))).unwrap();
    let wide = wide_twin.calibration_poses().unwrap();
    let local = Twin::new(cfg(over("local")))
        .unwrap()
        .calibration_poses()
        .unwrap();
    assert_eq!(wide.len(), 30);
    assert_eq!(
        wide,
        wide_twin.calibration_poses().unwrap(),
        "deterministic"
    );
    // every constraint of PoseProblem::check holds: explicit poses are checked by it
    let explicit: Vec<Vec<f64>> = wide.iter().map(|p| p.q_deg.clone()).collect();
    let checked = Twin::new(cfg(json!({"seed": 1, "robot_error": errs(),
        "poses": {"explicit_q_deg": explicit, "max_joint_delta_deg": 90.0}})))
    .unwrap()
    .calibration_poses()
    .unwrap();
    assert_eq!(checked.len(), 30);
    let (rw, rl) = (ranges(&wide), ranges(&local));
    let (sw, sl) = (stds(&wide), stds(&local));
    eprintln!("joint ranges over 30 poses (deg), wide: {rw:.1?}");
    eprintln!("joint ranges over 30 poses (deg), local: {rl:.1?}");
    eprintln!("joint std over 30 poses (deg), wide: {sw:.1?}");
    eprintln!("joint std over 30 poses (deg), local: {sl:.1?}");
    for j in 0..6 {
        assert!(
            rw[j] >= rl[j],
            "joint {}: wide {} local {}",
            j + 1,
            rw[j],
            rl[j]
        );
    }
    // The preset's view constraints (the board nearly fills the image, tilt <= 30 deg,
    // roll <= 10 deg) bound the excursions more than the joints do: measured with seed 1,
    // wide ranges [34.4, 34.5, 38.2, 67.4, 51.0, 52.3] deg, local [32.4, 31.9, 33.9, 62.9,
    // 46.0, 47.3]; standard deviations 9.9..19.9 against 9.1..17.5.
    assert!(sw.iter().sum::<f64>() > 1.05 * sl.iter().sum::<f64>());
}

#[test]
fn wide_poses_span_at_least_the_local_range_on_the_sheet_preset() {
    // hp3-sheet turns up to 90 deg about the optical axis: rare arm branches that the
    // local sampler finds are in the wide pool too (it starts from the local candidates)
    let c = |spread: &str| {
        SimConfig::hp3_sheet()
            .with_overrides(&json!({"poses": {"spread": spread}}))
            .unwrap()
    };
    let wide = Twin::new(c("wide")).unwrap().calibration_poses().unwrap();
    let local = Twin::new(c("local")).unwrap().calibration_poses().unwrap();
    let (rw, rl) = (ranges(&wide), ranges(&local));
    eprintln!("hp3-sheet joint ranges (deg), wide: {rw:.1?}, local: {rl:.1?}");
    for j in 0..6 {
        assert!(
            rw[j] >= rl[j],
            "joint {}: wide {} local {}",
            j + 1,
            rw[j],
            rl[j]
        );
    }
}

#[test]
fn local_spread_is_the_default_and_unchanged() {
    let c = SimConfig::hp3_paper();
    assert_eq!(c.poses.spread, "local");
    assert!(c.robot_error.is_zero() && !c.scan.table);
    let explicit = cfg(json!({"poses": {"spread": "local"}}));
    assert_eq!(
        Twin::new(c).unwrap().calibration_poses().unwrap(),
        Twin::new(explicit).unwrap().calibration_poses().unwrap()
    );
}

#[test]
fn table_scan_points_lie_on_the_true_table() {
    let twin = Twin::new(cfg(json!({"seed": 2, "robot_error": errs(),
        "scan": {"table": true, "max_frames": 9}})))
    .unwrap();
    let qs = twin.table_scan_poses().unwrap();
    assert_eq!(qs.len(), 9);
    let views = twin.calibration_poses().unwrap();
    let truth = twin.truth(true);
    let mut n = 0;
    for q in &qs {
        // elsewhere in the workspace than every calibration view
        for v in &views {
            let d = q
                .iter()
                .zip(&v.q_deg)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(d > 5.0, "{q:?} near a view {:?}", v.q_deg);
        }
        let pts = twin.exact_scan_points(q).unwrap();
        assert!(pts.len() > 100, "{}", pts.len());
        assert!(pts.iter().all(|(_, s)| *s == "table"));
        let p: Vec<_> = pts.iter().map(|(p, _)| *p).collect();
        let e = surface_errors(&truth, &p).unwrap();
        assert!(e.iter().all(|e| e.abs() < 1e-6), "{:?}", e);
        n += p.len();
    }
    assert!(n > 900);
    // the ball scan's points lie on the sphere or the table or the plate
    let scan = twin.scan_poses().unwrap();
    let mid = &scan[scan.len() / 2];
    let pts = twin.exact_scan_points(mid).unwrap();
    assert!(pts.iter().any(|(_, s)| *s == "sphere"));
    let p: Vec<_> = pts.iter().map(|(p, _)| *p).collect();
    let e = twin.surface_errors(&p).unwrap();
    assert!(e.iter().all(|e| e.abs() < 1e-6), "{:?}", e);
    // a point 2 mm above the table reads +2
    let t = twin.table_plane();
    let above = p[0] + t.normal * 2.0;
    let far = twin.surface_errors(&[above]).unwrap()[0];
    assert!(far > 0.0 && far <= 2.0 + 1e-9, "{far}");
    // truth.json's robot is the TRUE one, rig.json's the nominal one
    assert_eq!(truth.robot.as_ref(), Some(&twin.robot_true));
    assert_ne!(twin.robot_true, twin.robot_nominal);
    assert_eq!(
        twin.rig().unwrap().robot.as_ref(),
        Some(&twin.robot_nominal)
    );
}

#[test]
fn written_dataset_has_nominal_rig_true_truth_and_the_table_scan() {
    let dir = tempfile::tempdir().unwrap();
    let twin = Twin::new(cfg(json!({"seed": 3, "robot_error": errs(),
        "camera": {"width": 192, "height": 144, "fu": 318.0, "fv": 330.6, "u0": 86.5, "v0": 65.6},
        "poses": {"count": 1, "margin_px": 3.0},
        "scan": {"enabled": false, "table": true, "max_frames": 2}})))
    .unwrap();
    let s = twin.write(dir.path(), &mut |_, _, _| {}).unwrap();
    assert_eq!(s.table_frames, 2);
    let tdir = s.table_dir.unwrap();
    assert!(tdir.join("scan.csv").exists() && tdir.join("images/scan_0001.png").exists());
    let calib = dir.path().join("calib");
    let rig = stripecal::io::read_rig(calib.join("rig.json")).unwrap();
    assert_eq!(rig.robot.as_ref(), Some(&twin.robot_nominal));
    let truth = stripecal::io::read_truth(calib.join("truth.json")).unwrap();
    let tr = truth.robot.as_ref().unwrap();
    assert_eq!(tr.joints.len(), 6);
    for (a, b) in tr.joints.iter().zip(&twin.robot_true.joints) {
        assert!((a.theta0_deg - b.theta0_deg).abs() < 1e-9);
        assert!((a.a_mm - b.a_mm).abs() < 1e-9);
        assert!((a.beta_deg - b.beta_deg).abs() < 1e-12);
    }
    assert!(tr.joints[1].beta_deg != 0.0);
    let raw: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(calib.join("truth.json")).unwrap()).unwrap();
    assert!(raw["robot"].to_string().contains("beta_deg"));
    let tt = stripecal::io::read_truth(tdir.join("truth.json")).unwrap();
    assert!(tt.extra.contains_key("table") && tt.sphere.is_none());
}
