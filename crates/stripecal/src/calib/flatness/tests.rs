//! Tests of the flatness figure on synthetic detections of a bent board (the model of
//! the module docs, with Gaussian pixel noise): the Jacobian against finite
//! differences, the sag and axis recovered within the noise, flat boards within 3 sigma.

use super::*;
use crate::model::geometry::iso_from_rotvec;
use crate::numerics::rng::SplitMix64;

fn camera() -> Camera {
    Camera::new(
        768,
        576,
        crate::model::camera::Intrinsics {
            fu: 1271.65,
            fv: 1322.52,
            u0: 346.14,
            v0: 262.6,
        },
        crate::DistortionModel::Radial1,
        [0.0002, 0.0, 0.0, 0.0, 0.0],
    )
    .unwrap()
}

fn board() -> Board {
    Board::circles(8, 11, 5.0, 2.5, 3.5).unwrap()
}

fn pose() -> Iso3 {
    iso_from_rotvec(
        &Vector3::new(0.25, -0.3, 0.4),
        &Vector3::new(-22.0, -20.0, 118.0),
    )
}

/// Detections of `board` bent by `sag` (mm, towards the camera) across direction `u`
/// (the axis perpendicular), the bend centred at the grid centre and zero at the
/// grid's extreme points along `u`: each circle's imaged centroid (the conic model's) in
/// the sheet's tangent plane at its centre; noise `sigma` px.
fn bent_points(sag: f64, axis_deg: f64, sigma: f64, seed: u64) -> Vec<FlatPoint> {
    let cam = camera();
    let b = board();
    let t = pose();
    let a = axis_deg.to_radians();
    let u = Vector2::new(a.sin(), -a.cos());
    let pts: Vec<Vector3<f64>> = b.indices().map(|(r, c)| b.center(r, c)).collect();
    let cx = pts.iter().map(|p| p.x).sum::<f64>() / pts.len() as f64;
    let cy = pts.iter().map(|p| p.y).sum::<f64>() / pts.len() as f64;
    let xs: Vec<f64> = pts
        .iter()
        .map(|p| u.x * (p.x - cx) + u.y * (p.y - cy))
        .collect();
    let w = xs.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - xs.iter().cloned().fold(f64::INFINITY, f64::min);
    let mut rng = SplitMix64(seed);
    pts.iter()
        .zip(&xs)
        .map(|(p, x)| {
            let z = -sag * (1.0 - (2.0 * x / w).powi(2));
            // the circle lies in the sheet's tangent plane at its centre
            let slope = 8.0 * sag * x / (w * w);
            let nrm = Vector3::new(-slope * u.x, -slope * u.y, 1.0).normalize();
            let tilt = UnitQuaternion::rotation_between(&Vector3::z(), &nrm).unwrap();
            let local = t * Iso3::from_parts(Vector3::new(p.x, p.y, z).into(), tilt);
            let uv = predict_centre(
                &cam,
                &local,
                &Vector3::zeros(),
                1.25,
                CentreModel::ConicExact,
            )
            .unwrap();
            FlatPoint {
                board_xy: [p.x, p.y],
                radius_mm: 1.25,
                uv: [uv.x + sigma * rng.normal(), uv.y + sigma * rng.normal()],
            }
        })
        .collect()
}

#[test]
fn jacobian_matches_finite_differences() {
    let cam = camera();
    let t = pose();
    let s = State {
        rot: t.rotation,
        t: t.translation.vector,
        h: [0.002, -0.001, 0.0015],
        center: [25.0, 17.5],
    };
    for xy in [[0.0, 0.0], [50.0, 35.0], [12.0, 30.0]] {
        let (_, j) = s.predict(&cam, xy).unwrap();
        for k in 0..NPAR {
            let e = 1e-6;
            let mut d = DVector::<f64>::zeros(NPAR);
            d[k] = e;
            let mut sp = s;
            sp.apply(&d, true);
            d[k] = -e;
            let mut sm = s;
            sm.apply(&d, true);
            let fd =
                (sp.predict(&cam, xy).unwrap().0 - sm.predict(&cam, xy).unwrap().0) / (2.0 * e);
            for r in 0..2 {
                let tol = 1e-5 * (1.0 + j[(r, k)].abs());
                assert!(
                    (fd[r] - j[(r, k)]).abs() < tol,
                    "d(uv[{r}])/d(p[{k}]) at {xy:?}: analytic {} fd {}",
                    j[(r, k)],
                    fd[r]
                );
            }
        }
    }
}

#[test]
fn bent_board_sag_and_axis_recovered() {
    let sigma = 0.05;
    for (seed, axis) in [(1u64, 90.0), (2, 0.0), (3, 30.0)] {
        let pts = bent_points(1.0, axis, sigma, seed);
        let f = fit_flatness(&camera(), &pts, &pose(), &FlatnessOptions::default()).unwrap();
        assert!(
            (f.sag_mm - 1.0).abs() < 4.0 * f.sigma_mm,
            "seed {seed}: sag {} +- {} (true 1)",
            f.sag_mm,
            f.sigma_mm
        );
        // the sigma follows from the noise: a 0.05 px noise gives a few hundredths of a mm
        assert!(f.sigma_mm > 0.0 && f.sigma_mm < 0.1, "sigma {}", f.sigma_mm);
        let mut da = (f.axis_deg - axis).rem_euclid(180.0);
        if da > 90.0 {
            da -= 180.0;
        }
        assert!(
            da.abs() < 3.0,
            "seed {seed}: axis {} (true {axis})",
            f.axis_deg
        );
        assert!(
            f.sag2_mm.abs() < 4.0 * f.sigma2_mm,
            "sag2 {} +- {}",
            f.sag2_mm,
            f.sigma2_mm
        );
        assert!(f.rms_flat_px > 3.0 * f.rms_px);
    }
}

#[test]
fn flat_board_sag_within_three_sigma() {
    let mut inside = 0;
    for seed in 0..20u64 {
        let pts = bent_points(0.0, 0.0, 0.05, 100 + seed);
        let f = fit_flatness(&camera(), &pts, &pose(), &FlatnessOptions::default()).unwrap();
        if f.sag_mm.abs() < 3.0 * f.sigma_mm {
            inside += 1;
        }
    }
    // |largest of two principal sags| < 3 sigma: nearly always for a flat board
    assert!(inside >= 19, "{inside} of 20 flat boards within 3 sigma");
}

#[test]
fn too_few_points_is_an_error() {
    let pts = bent_points(0.0, 0.0, 0.05, 7);
    let e = fit_flatness(&camera(), &pts[..5], &pose(), &FlatnessOptions::default());
    assert!(matches!(e, Err(Error::InvalidInput(_))));
    let e = fit_flatness(
        &camera(),
        &pts,
        &pose(),
        &FlatnessOptions {
            sigma_px: Some(-1.0),
        },
    );
    assert!(matches!(e, Err(Error::InvalidInput(_))));
}
