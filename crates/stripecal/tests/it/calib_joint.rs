//! The calibration pipeline (issue 4) against the twin's truth: exact recovery from
//! exact observations, honest uncertainty under known noise, outlier views and
//! degenerate inputs. The rendered-image acceptance runs are in `calib_rendered.rs`.
//!
//! `cargo test -p stripecal --test it calib_joint:: -- --nocapture` prints the figures.

use stripecal::calib::conic::{predict_centre, CentreModel};
use stripecal::calib::laser_plane::stripe_line_in_view;
use stripecal::calib::{CircleObs, ViewObs};
use stripecal::model::geometry::iso_to_rotvec;
use stripecal::model::{Calibration, Rig};
use stripecal::pipeline::{calibrate_observations, CalibrateOptions, Method};
use stripecal::{Error, Iso3};
use stripecal_sim::rng::Rng;
use stripecal_sim::{noisy_observations, SimConfig, Twin};

fn twin(count: usize) -> Twin {
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"poses": {"count": count}}))
        .unwrap();
    Twin::new(cfg).unwrap()
}

/// The twin's exact observations: imaged-circle centres, stripe points on the board,
/// `T_base_hand` from the robot.
fn exact_views(t: &Twin) -> Vec<ViewObs> {
    t.exact_observations().unwrap()
}

fn noisy(views: &[ViewObs], sc: f64, ss: f64, seed: u64) -> Vec<ViewObs> {
    noisy_observations(views, sc, ss, &mut Rng::new(seed, 11))
}

fn iso_err(a: &Iso3, b: &Iso3) -> (f64, f64) {
    (
        a.rotation.angle_to(&b.rotation).to_degrees(),
        (a.translation.vector - b.translation.vector).norm(),
    )
}

fn rig(t: &Twin) -> Rig {
    t.rig().unwrap()
}

#[test]
fn exact_observations_recover_every_parameter_to_1e_6() {
    for count in [5, 15] {
        let t = twin(count);
        let views = exact_views(&t);
        let rep = calibrate_observations(&views, &rig(&t), &CalibrateOptions::default()).unwrap();
        let c = &rep.calibration;
        let (p, q) = (c.camera.params(), t.camera.params());
        let mut worst = 0.0f64;
        for i in 0..9 {
            let rel = (p[i] - q[i]).abs() / q[i].abs().max(1e-3);
            worst = worst.max(rel);
        }
        let dn = (c.laser_plane.unwrap().normal - t.laser_plane.normal).norm();
        let dd = (c.laser_plane.unwrap().d - t.laser_plane.d).abs() / t.laser_plane.d;
        let (xr, xt) = iso_err(&c.hand_cam, &t.hand_cam);
        let (zr, zt) = iso_err(&c.base_board, &t.base_board);
        let xt_rel = xt / t.hand_cam.translation.vector.norm();
        let zt_rel = zt / t.base_board.translation.vector.norm();
        println!(
            "{count} poses exact: camera worst rel {worst:.1e}, plane |dn| {dn:.1e} d rel \
             {dd:.1e}, X {xr:.1e} deg {xt_rel:.1e} rel, Z {zr:.1e} deg {zt_rel:.1e} rel; rms \
             circles {:.1e} stripe {:.1e} px; {} iterations",
            c.quality.circle_rms_px, c.quality.stripe_rms_px, rep.adjustment.iterations
        );
        assert!(worst < 1e-6, "camera {worst:e}");
        assert!(dn < 1e-6 && dd < 1e-6, "plane {dn:e} {dd:e}");
        assert!(
            xr.to_radians() < 1e-6 && xt_rel < 1e-6,
            "X {xr:e} {xt_rel:e}"
        );
        assert!(
            zr.to_radians() < 1e-6 && zt_rel < 1e-6,
            "Z {zr:e} {zt_rel:e}"
        );
        assert_eq!(c.quality.views_used, count);
    }
}

/// Every estimated number with its truth and one-sigma, from a calibration.
fn estimates(t: &Twin, c: &Calibration) -> Vec<(String, f64, f64, f64)> {
    let mut out = Vec::new();
    let u = &c.uncertainty;
    let get = |path: &[&str], k: Option<usize>| -> f64 {
        let mut v = &u[path[0]];
        for p in &path[1..] {
            v = &v[*p];
        }
        match k {
            Some(i) => v[i].as_f64().unwrap_or(f64::NAN),
            None => v.as_f64().unwrap_or(f64::NAN),
        }
    };
    let (e, tr) = (&c.camera, &t.camera);
    for (name, a, b) in [
        ("fu", e.fu, tr.fu),
        ("fv", e.fv, tr.fv),
        ("u0", e.u0, tr.u0),
        ("v0", e.v0, tr.v0),
    ] {
        out.push((name.to_string(), a, b, get(&["camera", name], None)));
    }
    for (i, f) in e.model.free_coefficients().iter().enumerate() {
        if *f {
            out.push((
                format!("k[{i}]"),
                e.distortion[i],
                tr.distortion[i],
                get(&["camera", "distortion"], Some(i)),
            ));
        }
    }
    for i in 0..3 {
        out.push((
            format!("n[{i}]"),
            c.laser_plane.unwrap().normal[i],
            t.laser_plane.normal[i],
            get(&["laser_plane", "normal"], Some(i)),
        ));
    }
    out.push((
        "d".into(),
        c.laser_plane.unwrap().d,
        t.laser_plane.d,
        get(&["laser_plane", "d_mm"], None),
    ));
    for (key, est, truth) in [
        ("hand_cam", &c.hand_cam, &t.hand_cam),
        ("base_board", &c.base_board, &t.base_board),
    ] {
        let (mut re, te) = iso_to_rotvec(est);
        let (rt, tt) = iso_to_rotvec(truth);
        // Near 180 deg the rotation vector has two branches: compare on the truth's.
        if (re - rt).norm() > std::f64::consts::PI {
            re *= 1.0 - std::f64::consts::TAU / re.norm();
        }
        for i in 0..3 {
            out.push((
                format!("{key}.r[{i}]"),
                re[i],
                rt[i],
                get(&[key, "rotation_vector"], Some(i)),
            ));
            out.push((
                format!("{key}.t[{i}]"),
                te[i],
                tt[i],
                get(&[key, "translation_mm"], Some(i)),
            ));
        }
    }
    out
}

#[test]
fn uncertainty_is_honest_under_known_noise() {
    // 20 seeds of Gaussian noise on the exact observations (0.01 px circles, 0.03 px
    // stripe points, the detectors' figures): each parameter within its 3-sigma in at
    // least 95 % of the runs (19 of 20), and the z-scores' RMS near 1.
    let t = twin(5);
    let views = exact_views(&t);
    let r = rig(&t);
    let mut inside: Vec<(String, usize)> = Vec::new();
    let mut zsum: Vec<f64> = Vec::new();
    let seeds = 20;
    for seed in 0..seeds {
        let rep = calibrate_observations(
            &noisy(&views, 0.01, 0.03, seed),
            &r,
            &CalibrateOptions::default(),
        )
        .unwrap();
        let est = estimates(&t, &rep.calibration);
        if inside.is_empty() {
            inside = est.iter().map(|e| (e.0.clone(), 0)).collect();
            zsum = vec![0.0; est.len()];
        }
        for (k, (_, a, b, s)) in est.iter().enumerate() {
            assert!(s.is_finite() && *s > 0.0, "{}: sigma {s}", est[k].0);
            let z = (a - b) / s;
            zsum[k] += z * z;
            if z.abs() <= 3.0 {
                inside[k].1 += 1;
            }
        }
    }
    for (k, (name, n)) in inside.iter().enumerate() {
        let zrms = (zsum[k] / seeds as f64).sqrt();
        println!("{name}: within 3 sigma {n}/{seeds}, z rms {zrms:.2}");
        assert!(*n >= 19, "{name}: only {n}/{seeds} within 3 sigma");
        assert!(zrms < 2.0, "{name}: z rms {zrms:.2} (sigma too small)");
    }
}

#[test]
fn a_view_with_swapped_joints_is_left_out_as_an_outlier() {
    let t = twin(6);
    let mut views = noisy(&exact_views(&t), 0.01, 0.03, 3);
    let q = t.calibration_poses().unwrap()[2].q_deg.clone();
    let mut bad = q.clone();
    bad.swap(1, 2);
    views[2].base_hand = Some(t.robot_true.forward(&bad).unwrap());
    let rep = calibrate_observations(&views, &rig(&t), &CalibrateOptions::default()).unwrap();
    println!("warnings: {:?}", rep.warnings);
    assert!(rep
        .warnings
        .iter()
        .any(|w| w.starts_with("view 2: its robot pose does not fit its image")));
    assert_eq!(rep.calibration.quality.views_used, 5);
    let pairing = &rep.calibration.quality.checks[0];
    assert!(pairing.passed && pairing.views == [2], "{pairing:?}");
    let (xr, xt) = iso_err(&rep.calibration.hand_cam, &t.hand_cam);
    assert!(xr < 0.01 && xt < 0.05, "X {xr} deg {xt} mm");
}

#[test]
fn degenerate_inputs_are_typed_errors() {
    let t = twin(5);
    let views = exact_views(&t);
    let r = rig(&t);
    let o = CalibrateOptions::default();
    // 2 views.
    let e = calibrate_observations(&views[..2], &r, &o).unwrap_err();
    assert!(matches!(e, Error::InvalidInput(_)), "{e}");
    // NaN robot pose.
    let mut nan = views.clone();
    let mut m = nan[1].base_hand.unwrap();
    m.translation.vector.x = f64::NAN;
    nan[1].base_hand = Some(m);
    let e = calibrate_observations(&nan, &r, &o).unwrap_err();
    assert!(e.to_string().contains("view 1"), "{e}");
    // All stripes from one view repeated: one line, no plane.
    let mut one = views.clone();
    for v in one.iter_mut().skip(1) {
        v.stripe.clear();
    }
    let e = calibrate_observations(&one, &r, &o).unwrap_err();
    assert!(matches!(e, Error::Degenerate(_)), "{e}");
    // Robot poses rotating about one axis only (the hand turning about its own z, the
    // observations consistent with it): X and Z are not unique.
    let board = &t.board;
    let a0 = views[0].base_hand.unwrap();
    let axis: Vec<ViewObs> = (0..5)
        .map(|i| {
            let a = a0 * Iso3::rotation(nalgebra::Vector3::z() * (0.08 * i as f64 - 0.16));
            let cb = (a * t.hand_cam).inverse() * t.base_board;
            let circles = board
                .indices()
                .filter_map(|(r, c)| {
                    let uv = predict_centre(
                        &t.camera,
                        &cb,
                        &board.center(r, c),
                        0.5 * board.diameter(r, c),
                        CentreModel::ConicExact,
                    )
                    .ok()?;
                    Some(CircleObs {
                        row: r,
                        col: c,
                        u: uv.x,
                        v: uv.y,
                    })
                })
                .collect();
            let l = stripe_line_in_view(&t.laser_plane, &cb, &t.camera).unwrap();
            let stripe = (-15..15)
                .filter_map(|s| {
                    let uv = t
                        .camera
                        .project(&(l.point_cam + l.direction_cam * s as f64))
                        .ok()?;
                    Some([uv.x, uv.y])
                })
                .collect();
            ViewObs {
                view: i,
                circles,
                stripe,
                reading: None,
                base_hand: Some(a),
                alternatives: Vec::new(),
                stripe_shape: None,
            }
        })
        .collect();
    let e = calibrate_observations(&axis, &r, &o).unwrap_err();
    println!("one axis: {e}");
    assert!(matches!(e, Error::Degenerate(_)), "{e}");
    // The paper method runs and reports.
    let rep = calibrate_observations(
        &views,
        &r,
        &CalibrateOptions {
            method: Method::Paper,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(rep.method, Method::Paper);
}

#[test]
fn robust_loss_resists_gross_stripe_outliers() {
    // 5 % of the stripe points of every view moved by 2-4 px (reflections): the Huber
    // adjustment stays near the truth, the plain one is pulled away.
    let t = twin(5);
    let mut views = noisy(&exact_views(&t), 0.01, 0.03, 9);
    let mut rng = Rng::new(17, 3);
    for v in &mut views {
        for (k, p) in v.stripe.iter_mut().enumerate() {
            if k % 20 == 7 {
                p[0] += 2.0 + 2.0 * rng.uniform();
            }
        }
    }
    let r = rig(&t);
    let plain = calibrate_observations(&views, &r, &CalibrateOptions::default()).unwrap();
    let robust = calibrate_observations(
        &views,
        &r,
        &CalibrateOptions {
            robust: true,
            ..Default::default()
        },
    )
    .unwrap();
    let e = |c: &Calibration| {
        let (_, xt) = iso_err(&c.hand_cam, &t.hand_cam);
        let dd = (c.laser_plane.unwrap().d - t.laser_plane.d).abs();
        (xt, dd)
    };
    let (p, q) = (e(&plain.calibration), e(&robust.calibration));
    println!("X translation / plane d error: plain {p:?}, robust {q:?}");
    assert!(q.0 < 0.01 && q.1 < 0.01, "robust {q:?}");
    assert!(q.0 < p.0 && q.1 < p.1, "robust {q:?} vs plain {p:?}");
}
