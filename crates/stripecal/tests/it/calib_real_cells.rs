//! Issue 12 on the twin's exact and noisy observations: a calibration without a laser,
//! the laser plane added later with the rest held (`--laser-only --from`), the board
//! scale against the robot, and the leave-one-view-out figure against the truth.
//!
//! `cargo test -p stripecal --test it calib_real_cells:: -- --nocapture` prints the figures.

use stripecal::calib::joint::FreeBlocks;
use stripecal::calib::ViewObs;
use stripecal::model::Rig;
use stripecal::pipeline::{calibrate_observations, CalibrateOptions};
use stripecal::Iso3;
use stripecal_sim::rng::Rng;
use stripecal_sim::{noisy_observations, SimConfig, Twin};

fn twin(count: usize) -> Twin {
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"poses": {"count": count}}))
        .unwrap();
    Twin::new(cfg).unwrap()
}

fn iso_err(a: &Iso3, b: &Iso3) -> (f64, f64) {
    (
        a.rotation.angle_to(&b.rotation).to_degrees(),
        (a.translation.vector - b.translation.vector).norm(),
    )
}

fn without_laser(views: &[ViewObs]) -> Vec<ViewObs> {
    let mut v = views.to_vec();
    for x in &mut v {
        x.stripe.clear();
    }
    v
}

#[test]
fn no_laser_then_laser_only_from_it_recovers_everything() {
    let t = twin(6);
    let rig: Rig = t.rig().unwrap();
    let views = t.exact_observations().unwrap();
    // 1. Views without laser images: camera, X and Z; no plane.
    let rep =
        calibrate_observations(&without_laser(&views), &rig, &CalibrateOptions::default()).unwrap();
    let c = &rep.calibration;
    assert!(c.laser_plane.is_none());
    assert!(rep
        .warnings
        .iter()
        .any(|w| w.contains("laser plane is not estimated")));
    let (xr, xt) = iso_err(&c.hand_cam, &t.hand_cam);
    let (zr, zt) = iso_err(&c.base_board, &t.base_board);
    println!("no laser: X {xr:.1e} deg {xt:.1e} mm, Z {zr:.1e} deg {zt:.1e} mm");
    assert!(xr < 1e-6 && xt < 1e-5 && zr < 1e-6 && zt < 1e-5);
    assert!((c.camera.fu - t.camera.fu).abs() < 1e-5 * t.camera.fu);
    let cov = c.covariance.as_ref().expect("a covariance");
    assert!(cov.parameters.iter().all(|p| !p.starts_with("laser_plane")));
    assert!(cov.index("hand_cam.translation_mm[2]").is_some());
    assert!(!c.uncertainty.contains_key("laser_plane"));
    // 2. The plane from two laser views, everything else held from (1).
    let opts = CalibrateOptions {
        from: Some(c.clone()),
        free: FreeBlocks::laser_only(),
        ..CalibrateOptions::default()
    };
    let rep2 = calibrate_observations(&views[..2], &rig, &opts).unwrap();
    let c2 = &rep2.calibration;
    let p = c2.laser_plane.expect("a laser plane");
    let dn = (p.normal - t.laser_plane.normal).norm();
    let dd = (p.d - t.laser_plane.d).abs();
    println!("laser only: |dn| {dn:.1e}, dd {dd:.1e} mm");
    assert!(dn < 1e-6 && dd < 1e-4, "{dn} {dd}");
    assert_eq!(c2.camera, c.camera);
    assert_eq!(c2.hand_cam, c.hand_cam);
    assert_eq!(c2.base_board, c.base_board);
    // The held blocks' uncertainty and covariance come from (1).
    assert_eq!(c2.uncertainty.get("camera"), c.uncertainty.get("camera"));
    let cov2 = c2.covariance.as_ref().unwrap();
    assert_eq!(
        cov2.sigma("camera.fu"),
        cov.sigma("camera.fu"),
        "held camera keeps its sigma"
    );
    assert!(cov2.index("laser_plane.d_mm").is_some());
    assert_eq!(
        c2.records.held_blocks.as_deref(),
        Some(&["camera", "hand_cam", "base_board"].map(String::from)[..])
    );
    // 3. Holding blocks needs --from; --laser-only from a file without a plane is
    //    fine, holding the plane from it is not.
    let Err(e) = calibrate_observations(
        &views,
        &rig,
        &CalibrateOptions {
            free: FreeBlocks::laser_only(),
            ..CalibrateOptions::default()
        },
    ) else {
        panic!("expected an error: {}", "no --from")
    };
    assert!(e.to_string().contains("--from"), "{e}");
    let Err(e) = calibrate_observations(
        &views,
        &rig,
        &CalibrateOptions {
            from: Some(c.clone()),
            free: FreeBlocks {
                laser_plane: false,
                ..FreeBlocks::default()
            },
            ..CalibrateOptions::default()
        },
    ) else {
        panic!("expected an error: {}", "no plane to hold")
    };
    assert!(e.to_string().contains("has none"), "{e}");
}

/// rig.json's board declared 2 % too large: the check finds the true scale (1 / 1.02)
/// within 3 sigma, and (DECISIONS 5, wave three: more than 5 honest sigmas off) the
/// calibration FAILS naming the implied size and `--estimate-board-scale`; the correct
/// board passes without a warning.
#[test]
fn the_board_scale_check_finds_a_board_declared_2_percent_too_large() {
    let t = twin(8);
    let views = noisy_observations(
        &t.exact_observations().unwrap(),
        0.03,
        0.05,
        &mut Rng::new(3, 11),
    );
    let good: Rig = t.rig().unwrap();
    let rep = calibrate_observations(&views, &good, &noisy()).unwrap();
    let c = rep.board_scale.clone().expect("a board-scale check");
    println!("correct board: scale {:.6} +- {:.6}", c.scale, c.sigma);
    assert!(!c.disagrees && (c.scale - 1.0).abs() < 3.0 * c.sigma + 1e-9);
    assert!(!rep.warnings.iter().any(|w| w.contains("board scale")));
    assert!(rep.calibration.records.board_scale.is_some());
    let gate = rep
        .calibration
        .quality
        .checks
        .iter()
        .find(|c| c.name == "board_scale");
    assert!(gate.is_some_and(|g| g.passed), "{gate:?}");

    let mut wrong = good.clone();
    let k = 1.02;
    wrong.board.pitch_mm *= k;
    wrong.board.circle_diameter_mm *= k;
    wrong.board.marker_diameter_mm *= k;
    let Err(stripecal::Error::Quality(failure)) = calibrate_observations(&views, &wrong, &noisy())
    else {
        panic!("a board 2 % off must fail the calibration")
    };
    assert_eq!(failure.failed.len(), 1, "{:?}", failure.failed);
    let msg = &failure.failed[0].message;
    assert_eq!(failure.failed[0].name, "board_scale");
    assert!(
        msg.contains("implies 5.000 mm") && msg.contains("--estimate-board-scale"),
        "{msg}"
    );
    let rep = failure
        .report()
        .cloned()
        .expect("the failed calibration for inspection");
    let c = rep.board_scale.clone().unwrap();
    let truth = 1.0 / k;
    println!(
        "board declared 2 % large: scale {:.6} +- {:.6} (truth {truth:.6}), {:.2} sigma; {msg}",
        c.scale,
        c.sigma,
        (c.scale - truth) / c.sigma
    );
    assert!(c.disagrees && !c.estimated);
    assert!(
        (c.scale - truth).abs() < 3.0 * c.sigma,
        "{} {}",
        c.scale,
        c.sigma
    );
    // --estimate-board-scale frees it: the calibration then fits.
    let free = CalibrateOptions {
        free: FreeBlocks {
            board_scale: true,
            ..FreeBlocks::default()
        },
        ..CalibrateOptions::default()
    };
    let rep2 = calibrate_observations(&views, &wrong, &free).unwrap();
    let c2 = rep2.board_scale.unwrap();
    assert!(c2.estimated && (c2.scale - truth).abs() < 3.0 * c2.sigma);
    let (n1, n2) = (
        rep.adjustment.robot_noise.clone().unwrap(),
        rep2.adjustment.robot_noise.clone().unwrap(),
    );
    println!(
        "held: circles {:.4} px, robot-pose noise {:.4} mm {:.5} deg; freed: {:.4} px, {:.4} mm {:.5} deg",
        rep.calibration.quality.circle_rms_px,
        n1.sigma_translation_mm,
        n1.sigma_rotation_deg,
        rep2.calibration.quality.circle_rms_px,
        n2.sigma_translation_mm,
        n2.sigma_rotation_deg
    );
    // Held at the wrong scale the chain cannot fit the robot's translations: the
    // robot-pose corrections take up what X and Z cannot (the images still fit), and
    // the robot-pose noise says so; freed, it drops to the level of the detector noise.
    assert!(
        n2.sigma_translation_mm < 0.1 * n1.sigma_translation_mm,
        "{n1:?} {n2:?}"
    );
    let (xr, xt) = iso_err(&rep2.calibration.hand_cam, &t.hand_cam);
    println!("freed: X {xr:.4} deg {xt:.4} mm");
}

/// Issue 12, item 6: the leave-one-view-out figure against the TRUE error of predicting
/// the held-out view. The robot readings carry a repeatability error (0.02 deg, 0.05 mm
/// per view, as real arms), the detections image noise; the true error of view k is the
/// calibration without k (solved here, independently of the pipeline's own refits)
/// predicting k's exact image points from its robot reading. The two agree within a
/// factor 1.5 in median.
#[test]
fn leave_one_out_agrees_with_the_true_prediction_error() {
    use stripecal::calib::conic::{predict_centre, CentreModel};
    use stripecal::model::geometry::iso_from_rotvec;
    let t = twin(10);
    let rig: Rig = t.rig().unwrap();
    let exact = t.exact_observations().unwrap();
    let mut rng = Rng::new(7, 3);
    let mut views = noisy_observations(&exact, 0.03, 0.05, &mut Rng::new(5, 11));
    for v in &mut views {
        let g = |rng: &mut Rng, s: f64| s * rng.normal();
        let w = [
            g(&mut rng, 0.02f64.to_radians()),
            g(&mut rng, 0.02f64.to_radians()),
            g(&mut rng, 0.02f64.to_radians()),
        ];
        let d = [g(&mut rng, 0.05), g(&mut rng, 0.05), g(&mut rng, 0.05)];
        let e = iso_from_rotvec(&w.into(), &d.into());
        v.base_hand = Some(v.base_hand.unwrap() * e);
    }
    let rep = calibrate_observations(&views, &rig, &CalibrateOptions::default()).unwrap();
    let loo = rep.leave_one_out.expect("a leave-one-out");
    assert_eq!(loo.views.len(), views.len());
    let no_loo = CalibrateOptions {
        leave_one_out: false,
        ..CalibrateOptions::default()
    };
    let mut ratios = Vec::new();
    for (k, lv) in loo.views.iter().enumerate() {
        assert_eq!(lv.view, views[k].view);
        let others: Vec<ViewObs> = views
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != k)
            .map(|(_, v)| v.clone())
            .collect();
        let c = calibrate_observations(&others, &rig, &no_loo)
            .unwrap()
            .calibration;
        let cb = (views[k].base_hand.unwrap() * c.hand_cam).inverse() * c.base_board;
        let mut ss = 0.0;
        for p in &exact[k].circles {
            let uv = predict_centre(
                &c.camera,
                &cb,
                &rig.board.center(p.row, p.col),
                0.5 * rig.board.diameter(p.row, p.col),
                CentreModel::ConicExact,
            )
            .unwrap();
            ss += (uv.x - p.u).powi(2) + (uv.y - p.v).powi(2);
        }
        let truth = (ss / exact[k].circles.len() as f64).sqrt();
        println!(
            "view {k}: leave-one-out {:.4} px, true prediction error {truth:.4} px",
            lv.board_rms_px
        );
        ratios.push(lv.board_rms_px / truth);
    }
    ratios.sort_by(f64::total_cmp);
    let med = 0.5 * (ratios[ratios.len() / 2 - 1] + ratios[ratios.len() / 2]);
    println!("median ratio leave-one-out / true error: {med:.3}");
    assert!((1.0 / 1.5..=1.5).contains(&med), "{med}");
}

fn noisy() -> CalibrateOptions {
    CalibrateOptions::default()
}
