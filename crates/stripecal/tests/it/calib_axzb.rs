//! Two-stage calibration pieces (issue 4): `A_i X = Z B_i` and the laser plane from
//! stripe points, on exact synthetic transforms and on the twin's exact truth; degenerate
//! inputs give typed errors that name the figure.

use nalgebra::{Point3, Vector3};
use stripecal::calib::axzb::{solve_axzb, solve_axzb_with, AxzbOptions};
use stripecal::calib::laser_plane::{fit_laser_plane, stripe_line_in_view};
use stripecal::model::geometry::{iso_from_rotvec, Iso3};
use stripecal::Error;
use stripecal_sim::rng::Rng;
use stripecal_sim::truth::stripe_truth;
use stripecal_sim::{SimConfig, Twin};

fn random_iso(rng: &mut Rng, max_angle: f64, t_scale: f64) -> Iso3 {
    let axis = Vector3::new(rng.normal(), rng.normal(), rng.normal()).normalize();
    let angle = rng.range(0.0, max_angle);
    let t = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * t_scale;
    iso_from_rotvec(&(axis * angle), &t)
}

fn iso_err(a: &Iso3, b: &Iso3) -> (f64, f64) {
    let rot = (a.rotation.inverse() * b.rotation).angle();
    let tr = (a.translation.vector - b.translation.vector).norm();
    (rot, tr)
}

#[test]
fn axzb_exact_on_random_noise_free_transforms() {
    let mut worst = (0.0_f64, 0.0_f64);
    for seed in 0..50u64 {
        let mut rng = Rng::new(seed, 7);
        let x = random_iso(&mut rng, 3.1, 100.0);
        let z = random_iso(&mut rng, 3.1, 1000.0);
        let n = 3 + (seed as usize % 10);
        let a: Vec<Iso3> = (0..n).map(|_| random_iso(&mut rng, 3.1, 500.0)).collect();
        let b: Vec<Iso3> = a.iter().map(|ai| z.inverse() * ai * x).collect();
        for refine in [false, true] {
            let s = solve_axzb_with(&a, &b, &AxzbOptions { refine }).unwrap();
            for (est, truth) in [(&s.x, &x), (&s.z, &z)] {
                let (r, t) = iso_err(est, truth);
                worst.0 = worst.0.max(r);
                worst.1 = worst.1.max(t);
            }
            assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        }
    }
    println!(
        "noise-free AX = ZB, 50 random sets of 3..12 poses: worst rotation error {:.2e} rad, \
         translation {:.2e} mm",
        worst.0, worst.1
    );
    assert!(worst.0 < 1e-9 && worst.1 < 1e-9, "{worst:?}");
}

fn twin(overrides: serde_json::Value) -> Twin {
    let cfg = SimConfig::hp3_paper().with_overrides(&overrides).unwrap();
    Twin::new(cfg).unwrap()
}

/// `(A_i, T_cam_board(i), stripe points on the board)` of the twin's calibration poses.
fn twin_views(t: &Twin) -> Vec<(Iso3, Iso3, Vec<[f64; 2]>)> {
    t.calibration_poses()
        .unwrap()
        .iter()
        .map(|p| {
            let a = t.robot_true.forward(&p.q_deg).unwrap();
            let scene = t.scene(&p.q_deg, false).unwrap();
            let stripe = stripe_truth(&scene, &t.camera, t.direction)
                .into_iter()
                .filter(|s| s.surface == "board")
                .map(|s| [s.u, s.v])
                .collect();
            (a, scene.cam_board, stripe)
        })
        .collect()
}

#[test]
fn axzb_and_laser_plane_exact_on_the_twin() {
    for (name, over) in [
        ("paper rig, 5 poses", serde_json::json!({})),
        ("15 poses", serde_json::json!({"poses": {"count": 15}})),
    ] {
        let t = twin(over);
        let views = twin_views(&t);
        let a: Vec<Iso3> = views.iter().map(|v| v.0).collect();
        let b: Vec<Iso3> = views.iter().map(|v| v.1.inverse()).collect();
        let s = solve_axzb(&a, &b).unwrap();
        let (xr, xt) = iso_err(&s.x, &t.hand_cam);
        let (zr, zt) = iso_err(&s.z, &t.base_board);
        let c = s.conditioning;
        println!(
            "{name}: X err {xr:.2e} rad {xt:.2e} mm, Z err {zr:.2e} rad {zt:.2e} mm; axis \
             spread {:.1} deg, rotations {:.1}..{:.1} deg, condition {:.1}; warnings {:?}",
            c.axis_spread_deg,
            c.min_rotation_deg,
            c.max_rotation_deg,
            c.rotation_condition,
            s.warnings
        );
        assert!(xr < 1e-9 && xt < 1e-9 && zr < 1e-9 && zt < 1e-9);

        let pv: Vec<(Iso3, Vec<[f64; 2]>)> = views.iter().map(|v| (v.1, v.2.clone())).collect();
        let fit = fit_laser_plane(&pv, &t.camera).unwrap();
        let truth = t.laser_plane;
        let dn = (fit.plane.normal - truth.normal).norm();
        let dd = (fit.plane.d - truth.d).abs();
        // Distance between the planes over the points' region (|dn| * range + |dd|).
        println!(
            "{name}: laser plane |dn| {dn:.2e}, |dd| {dd:.2e} mm, rms {:.2e} mm, {} points, \
             line angle up to {:.1} deg, sigma n {:?} d {:.2e}",
            fit.rms_mm,
            fit.n_points,
            fit.max_line_angle_deg,
            fit.sigma.normal.as_slice(),
            fit.sigma.d_mm
        );
        assert!(dn < 1e-11 && dd < 1e-9, "{dn:e} {dd:e}");
        assert!(fit.plane.d > 0.0);
        assert_eq!(fit.n_outliers, 0);

        // The predicted stripe line passes through the exact stripe points.
        let mut worst = 0.0_f64;
        for (cam_board, pts) in &pv {
            let line = stripe_line_in_view(&truth, cam_board, &t.camera).unwrap();
            for uv in pts {
                worst = worst.max(line.signed_distance_px(&t.camera, uv).unwrap().abs());
                let ray = t
                    .camera
                    .unproject(&nalgebra::Vector2::new(uv[0], uv[1]))
                    .unwrap();
                assert!(line.normalized.dot(&ray).abs() < 1e-9);
            }
            // Board-frame line lies on the laser plane.
            let p = cam_board * Point3::new(line.point_board.x, line.point_board.y, 0.0);
            assert!(truth.signed_distance(&p.coords).abs() < 1e-9);
        }
        println!("{name}: exact stripe points vs predicted line: max {worst:.2e} px");
        assert!(worst < 1e-6);
    }
}

#[test]
fn axzb_degenerate_pose_sets_are_typed_errors_with_the_figure() {
    let mut rng = Rng::new(3, 1);
    let x = random_iso(&mut rng, 3.0, 100.0);
    let z = random_iso(&mut rng, 3.0, 1000.0);
    let make_b = |a: &[Iso3]| -> Vec<Iso3> { a.iter().map(|ai| z.inverse() * ai * x).collect() };

    // All rotations about one axis (plus translations).
    let axis = Vector3::new(0.3, -0.5, 0.8).normalize();
    let a: Vec<Iso3> = (0..8)
        .map(|k| {
            iso_from_rotvec(
                &(axis * (0.3 * k as f64)),
                &Vector3::new(10.0 * k as f64, 5.0, -3.0 * k as f64),
            )
        })
        .collect();
    let e = solve_axzb(&a, &make_b(&a)).unwrap_err();
    println!("one axis: {e}");
    assert!(matches!(e, Error::Degenerate(_)));
    assert!(
        e.to_string()
            .contains("relative rotation axes span only 0.000 deg"),
        "{e}"
    );

    // Nearly one axis: 0.3 deg off.
    let tilt = iso_from_rotvec(
        &(Vector3::new(1.0, 0.0, 0.0) * 0.3_f64.to_radians()),
        &Vector3::zeros(),
    );
    let mut a2 = a.clone();
    a2[5] *= tilt;
    let e = solve_axzb(&a2, &make_b(&a2)).unwrap_err();
    println!("nearly one axis: {e}");
    assert!(
        e.to_string().contains("relative rotation axes span only"),
        "{e}"
    );

    // Two poses.
    let e = solve_axzb(&a[..2], &make_b(&a[..2])).unwrap_err();
    println!("two poses: {e}");
    assert!(matches!(e, Error::Degenerate(_)) && e.to_string().contains("got 2"));

    // Too little rotation (0.8 deg at most).
    let a3: Vec<Iso3> = (0..6)
        .map(|k| {
            let r = Vector3::new(rng.normal(), rng.normal(), rng.normal()).normalize()
                * 0.4_f64.to_radians();
            iso_from_rotvec(&r, &Vector3::new(100.0 * k as f64, 0.0, 0.0))
        })
        .collect();
    let e = solve_axzb(&a3, &make_b(&a3)).unwrap_err();
    println!("tiny rotations: {e}");
    assert!(
        e.to_string().contains("largest rotation between poses"),
        "{e}"
    );

    // Weak but solvable: warnings, still exact.
    let mut a4 = a.clone();
    a4[5] *= iso_from_rotvec(&(Vector3::new(1.0, 0.0, 0.0) * 0.1), &Vector3::zeros());
    let s = solve_axzb(&a4, &make_b(&a4)).unwrap();
    println!(
        "weak set: spread {:.2} deg, warnings {:?}",
        s.conditioning.axis_spread_deg, s.warnings
    );
    assert!(s.warnings.iter().any(|w| w.contains("axes span only")));
    assert!(iso_err(&s.x, &x).0 < 1e-8);
}

#[test]
fn laser_plane_degenerate_inputs_are_typed_errors_with_the_figure() {
    let t = twin(serde_json::json!({}));
    let views = twin_views(&t);
    let pv: Vec<(Iso3, Vec<[f64; 2]>)> = views.iter().map(|v| (v.1, v.2.clone())).collect();

    // The same stripe line in every view: the board moved within its own plane.
    let (cb0, pts0) = pv[0].clone();
    let shift = iso_from_rotvec(&Vector3::new(0.0, 0.0, 0.7), &Vector3::new(12.0, -7.0, 0.0));
    let same = vec![(cb0, pts0.clone()), (cb0 * shift, pts0.clone())];
    let e = fit_laser_plane(&same, &t.camera).unwrap_err();
    println!("one line: {e}");
    assert!(matches!(e, Error::Degenerate(_)));
    assert!(e.to_string().contains("lie on nearly one 3D line"), "{e}");

    // One stripe view only.
    let one = vec![pv[0].clone(), (pv[1].0, vec![])];
    let e = fit_laser_plane(&one, &t.camera).unwrap_err();
    println!("one view: {e}");
    assert!(e.to_string().contains("at least 2 views") && e.to_string().contains("got 1"));

    // Parallel but separated lines (the board translated along its normal) do fix the
    // plane: the fit succeeds, warns about the parallel lines and is exact.
    let laser = t.laser_plane;
    let cb1 = cb0 * iso_from_rotvec(&Vector3::zeros(), &Vector3::new(0.0, 0.0, -15.0));
    let line = stripe_line_in_view(&laser, &cb1, &t.camera).unwrap();
    let pts1: Vec<[f64; 2]> = (-10..=10)
        .filter_map(|k| {
            let p = line.point_cam + line.direction_cam * (2.0 * k as f64);
            let uv = t.camera.project(&p).ok()?;
            Some([uv.x, uv.y])
        })
        .collect();
    let par = vec![(cb0, pts0), (cb1, pts1)];
    let fit = fit_laser_plane(&par, &t.camera).unwrap();
    println!(
        "parallel lines 15 mm apart: angle {:.2e} deg, |dn| {:.2e}, warnings {:?}",
        fit.max_line_angle_deg,
        (fit.plane.normal - laser.normal).norm(),
        fit.warnings
    );
    assert!(fit.warnings.iter().any(|w| w.contains("nearly parallel")));
    assert!((fit.plane.normal - laser.normal).norm() < 1e-9);

    // Non-finite input.
    let bad = vec![pv[0].clone(), (pv[1].0, vec![[f64::NAN, 1.0]])];
    assert!(matches!(
        fit_laser_plane(&bad, &t.camera),
        Err(Error::InvalidInput(_))
    ));
}

#[test]
fn laser_plane_trims_outliers() {
    let t = twin(serde_json::json!({}));
    let mut pv: Vec<(Iso3, Vec<[f64; 2]>)> =
        twin_views(&t).iter().map(|v| (v.1, v.2.clone())).collect();
    let mut rng = Rng::new(11, 2);
    // Noise 0.05 px and 1 % gross outliers (5 px).
    let mut total = 0;
    for (_, pts) in &mut pv {
        for p in pts.iter_mut() {
            p[0] += 0.05 * rng.normal();
            p[1] += 0.05 * rng.normal();
            if rng.uniform() < 0.01 {
                p[1] += 5.0;
            }
            total += 1;
        }
    }
    let fit = fit_laser_plane(&pv, &t.camera).unwrap();
    let ang = fit.plane.normal.angle(&t.laser_plane.normal).to_degrees();
    println!(
        "noisy + outliers: {} of {total} points kept, {} trimmed, rms {:.4} mm, normal off by \
         {ang:.4} deg (1-sigma {:?}), d off by {:.4} mm (1-sigma {:.4})",
        fit.n_points,
        fit.n_outliers,
        fit.rms_mm,
        fit.sigma.normal.as_slice(),
        (fit.plane.d - t.laser_plane.d).abs(),
        fit.sigma.d_mm
    );
    assert!(fit.n_outliers > 0);
    assert!(ang < 0.1);
}
