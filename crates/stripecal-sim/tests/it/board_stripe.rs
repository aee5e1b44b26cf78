//! The stripe's bias on the calibration board (`stripecal::pipeline::board_stripe`): on
//! the twin's noise-free images the board's stripe points lie a fraction of a micrometre
//! off the sheet's centre plane, all on the same side, and the one-stage adjustment turns
//! that into a hand-eye translation error of several of its own sigmas. With the
//! correction the error is gone and the reported sigma covers what is left; the sheet's
//! thickness estimated from the widths is the twin's.
//!
//! Studied on the rigid model with the noise model's own covariance (`wave_two()`): the
//! bias is the same in every view of a noise-free render, a micrometre-level effect
//! against the detector noise's sigma. The defaults of issue 38 (the robot-pose noise,
//! the covariance widened to the views' own scatter) count a bias every view shares as
//! scatter of the views (the hand-eye sigma 2.2 um instead of about 0.3 um here), which
//! covers it: honest, but no longer the premise these tests measure the correction by.

use std::ops::ControlFlow;

use stripecal::pipeline::emitter_carry::EmitterResponse;
use stripecal::pipeline::measure::{
    measure_scan_sphere, scan_readings, scan_uncertainty_model, MeasureOptions,
};
use stripecal::pipeline::{calibrate_dataset, CalibrateOptions};
use stripecal::reconstruct::uncertainty::perturbed_calibration;
use stripecal::reconstruct::{load_scan, reconstruct_scan, ReconstructOptions, UncertaintyOptions};
use stripecal_sim::{SimConfig, Twin};

#[test]
fn the_board_stripe_correction_removes_the_hand_eye_bias() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({
            "seed": 1, "poses": {"count": 5}, "scan": {"max_frames": 1},
            "imaging": {"noise_gray": 0.0, "psf_sigma_px": 0.7}
        }))
        .unwrap();
    let sheet_true = cfg.imaging.laser_sigma_mm;
    let twin = Twin::new(cfg).unwrap();
    twin.write(dir.path(), &mut |_, _, _| {}).unwrap();
    let truth = twin.hand_cam.translation.vector;
    let run = |on: bool| {
        let opts = CalibrateOptions {
            board_stripe_bias: on,
            ..wave_two()
        };
        let rep = calibrate_dataset(dir.path().join("calib"), &opts).unwrap();
        let c = rep.calibration;
        let err = c.hand_cam.translation.vector - truth;
        let sd = rep.adjustment.sigma.hand_cam.translation_mm;
        (err, sd, c.extra.get("board_stripe_bias").cloned())
    };
    let (e0, s0, x0) = run(false);
    let (e1, s1, x1) = run(true);
    eprintln!("hand-eye t error (um): uncorrected {:.3?} (sigma {:.3?}); corrected {:.3?} (sigma {:.3?}); {x1:?}",
        e0 * 1e3, s0 * 1e3, e1 * 1e3, s1 * 1e3);
    assert!(x0.is_none());
    // The premise: the uncorrected x error is several of its sigmas (about -1.3 um).
    assert!(
        e0.x.abs() > 3.0 * s0.x && e0.x.abs() > 0.8e-3,
        "{e0:?} {s0:?}"
    );
    // Corrected: within 3 sigma on every axis and a third of the uncorrected error.
    for k in 0..3 {
        assert!(
            e1[k].abs() < 3.0 * s1[k],
            "axis {k}: {} vs sigma {}",
            e1[k],
            s1[k]
        );
    }
    assert!(e1.x.abs() < e0.x.abs() / 3.0);
    let x1 = x1.expect("the correction's record");
    let sheet = x1["sheet_sigma_mm"].as_f64().unwrap();
    assert!(
        (sheet / sheet_true - 1.0).abs() < 0.05,
        "sheet sigma {sheet} vs {sheet_true}"
    );
    assert_eq!(x1["points_left_out"].as_u64(), Some(0));
}

/// The emitter is in no calibration file: the correction assumes it at the plane's point
/// nearest the camera centre and widens the covariance by the calibration's change for
/// the emitter at either end of +-30 mm along the plane's two axes. With the twin's
/// emitter moved 25 mm within the plane (noise-free images), the correction made with
/// the wrong emitter leaves an error (hand-eye x: -0.64 um, where the emitter at `n d`
/// leaves -0.06 um) that the widened sigmas cover within 2 sigma on every number of the
/// hand-eye translation and the plane's offset.
///
/// A sphere scan then locates the emitter from the stripe's brightness (0.56 mm off);
/// carried into the calibration (`pipeline::emitter_carry`), the response moves the
/// calibration's numbers to the estimate: hand-eye x -0.64 -> -0.14 um, the hand-eye
/// translation 0.74 -> 0.29 um from the nominal twin's.
#[test]
fn the_emitter_part_covers_a_moved_emitter() {
    let cfg_of = |emitter: Option<[f64; 3]>| {
        let mut over = serde_json::json!({
            "seed": 1, "poses": {"count": 5}, "scan": {"max_frames": 1},
            "imaging": {"noise_gray": 0.0, "psf_sigma_px": 0.7}
        });
        if let Some(e) = emitter {
            over["imaging"]["laser_emitter_mm"] = serde_json::json!(e);
            // The whole ball scan, for the emitter's estimate.
            over["scan"] = serde_json::json!({});
        }
        SimConfig::hp3_paper().with_overrides(&over).unwrap()
    };
    let nominal = Twin::new(cfg_of(None)).unwrap();
    let n = nominal.laser_plane.normal;
    let w = n.cross(&(nalgebra::Vector3::y() - n * n.y).normalize());
    let e = nominal.emitter + w * 25.0;
    let dir = tempfile::tempdir().unwrap();
    let run = |twin: &Twin, root: &std::path::Path| {
        twin.write(root, &mut |_, _, _| {}).unwrap();
        let rep = calibrate_dataset(root.join("calib"), &wave_two()).unwrap();
        let c = rep.calibration;
        let s = rep.adjustment.sigma;
        let (err_t, err_d) = errors(&c, twin);
        (err_t, err_d, s.hand_cam.translation_mm, s.plane_d_mm, c)
    };
    let (et0, ed0, s0, sd0, _) = run(&nominal, &dir.path().join("nominal"));
    eprintln!(
        "nominal twin: hand-eye t error {:.3?} um, plane d {:.3} um",
        et0 * 1e3,
        ed0 * 1e3
    );
    let moved = Twin::new(cfg_of(Some([e.x, e.y, e.z]))).unwrap();
    let root = dir.path().join("moved");
    let (et, ed, st, sd, cal) = run(&moved, &root);
    eprintln!(
        "emitter moved 25 mm: hand-eye t error {:.3?} um (sigma {:.3?}, at n d {:.3?}); plane d error {:.3} um (sigma {:.3}, at n d {:.3})",
        et * 1e3, st * 1e3, s0 * 1e3, ed * 1e3, sd * 1e3, sd0 * 1e3
    );
    within_two_sigma((et, ed), (st, sd));

    // The ball scan's emitter estimate, carried into the calibration.
    let scan = load_scan(root.join("scan"), &cal).unwrap();
    let points = reconstruct_scan(
        &cal,
        &scan,
        &ReconstructOptions::default(),
        &mut |_, _, _| ControlFlow::Continue(()),
    )
    .unwrap();
    let model = scan_uncertainty_model(&cal, &scan, &UncertaintyOptions::default()).unwrap();
    let m = measure_scan_sphere(
        &model,
        &scan_readings(&scan),
        &points,
        &MeasureOptions::default(),
    )
    .unwrap();
    let carried = m.calibration_emitter.expect("an estimate carried");
    assert!(carried.reason.is_none(), "{carried:?}");
    let response = EmitterResponse::of(&cal)
        .unwrap()
        .expect("the response kept");
    let at = response.origin_cam_mm
        + response.axes_cam[0] * carried.offset_mm[0]
        + response.axes_cam[1] * carried.offset_mm[1];
    let off = (at - moved.emitter).norm();
    // The calibration's numbers at the estimate.
    let named = cal.covariance.as_ref().unwrap();
    let c = response
        .carry(
            &cal,
            &named.parameters,
            &named.matrix,
            carried.offset_mm,
            carried.sd_mm,
        )
        .unwrap();
    let fixed = perturbed_calibration(&cal, &named.parameters, c.shift.as_slice()).unwrap();
    let (ft, fd) = errors(&fixed, &moved);
    eprintln!(
        "carried: estimate {off:.2} mm from the emitter ({:?}); hand-eye t error {:.3?} um, plane d {:.3} um",
        carried.offset_mm, ft * 1e3, fd * 1e3
    );
    assert!(off < 3.0, "emitter estimate {off} mm off");
    // Most of the wrong emitter's error goes: hand-eye x (-0.64 um; -0.06 with the
    // emitter where the correction assumed it, on the nominal twin), and the hand-eye
    // translation comes closer to the nominal twin's by more than half (the two twins'
    // images differ in brightness, so not all the way).
    assert!(
        ft.x.abs() < 0.4 * et.x.abs(),
        "hand-eye x {} -> {}",
        et.x,
        ft.x
    );
    let (before, after) = ((et - et0).norm(), (ft - et0).norm());
    assert!(
        after < 0.5 * before,
        "from the nominal: {before} -> {after}"
    );
    within_two_sigma((ft, fd), (st, sd));
}

/// Every hand-eye translation error and the plane offset's within 2 of their sigmas.
fn within_two_sigma(err: (nalgebra::Vector3<f64>, f64), sigma: (nalgebra::Vector3<f64>, f64)) {
    for k in 0..3 {
        assert!(
            err.0[k].abs() < 2.0 * sigma.0[k],
            "axis {k}: {} vs sigma {}",
            err.0[k],
            sigma.0[k]
        );
    }
    assert!(
        err.1.abs() < 2.0 * sigma.1,
        "plane d: {} vs sigma {}",
        err.1,
        sigma.1
    );
}

/// The hand-eye translation's and the plane offset's errors of a calibration, mm.
fn errors(c: &stripecal::model::Calibration, twin: &Twin) -> (nalgebra::Vector3<f64>, f64) {
    let plane = c.laser_plane.unwrap();
    (
        c.hand_cam.translation.vector - twin.hand_cam.translation.vector,
        plane.d - twin.laser_plane.d,
    )
}

/// The rigid model with the noise model's own covariance (module docs).
fn wave_two() -> CalibrateOptions {
    CalibrateOptions {
        robot_pose_noise: false,
        clustered_covariance: false,
        ..CalibrateOptions::default()
    }
}
