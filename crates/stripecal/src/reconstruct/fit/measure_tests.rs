//! The budgets' calibration and robot parts against Monte Carlo: a sphere and a plane
//! swept by the stripe, the calibration (or the joint readings) drawn, every draw
//! reconstructed from the same pixels and refitted.

use nalgebra::{DMatrix, Vector3};

use super::*;
use crate::model::geometry::Iso3;
use crate::model::{Calibration, RobotReading};
use crate::numerics::rng::SplitMix64;
use crate::reconstruct::uncertainty::tests::{calibration, Q};
use crate::reconstruct::uncertainty::{
    perturbed_calibration, UncertaintyModel, UncertaintyOptions,
};
use crate::reconstruct::{ScanPoints, Triangulator};

/// Frames: joint 1 turned by -0.8 .. 0.8 deg (the stripe sweeps ~14 mm).
fn readings() -> Vec<RobotReading> {
    (0..17)
        .map(|i| {
            let mut q = Q.to_vec();
            q[0] += -0.8 + 0.1 * i as f64;
            RobotReading::Joints(q)
        })
        .collect()
}

/// The stripe pixels of a sphere (`plane_instead`: a tilted plane) seen by every frame.
fn scan(cal: &Calibration, plane_instead: bool) -> (ScanPoints, Vector3<f64>) {
    let robot = cal.robot.as_ref().unwrap();
    let lp = cal.laser_plane.unwrap();
    let bc0: Iso3 = robot.forward(&Q).unwrap() * cal.hand_cam;
    // The object: around the plane point on the optical axis of the middle frame.
    let on_axis = Vector3::z() * (lp.d / lp.normal.z);
    let centre = bc0 * nalgebra::Point3::from(on_axis);
    let mut pts = ScanPoints::default();
    let radius = 10.0;
    for (f, rd) in readings().iter().enumerate() {
        let bc = rd.base_hand(Some(robot)).unwrap() * cal.hand_cam;
        let inv = bc.inverse();
        let c_cam = inv * centre;
        // Circle: the plane n.p = d cut with the object, sampled by angle.
        let e1 = lp.normal.cross(&Vector3::y()).normalize();
        let e2 = lp.normal.cross(&e1);
        let foot = c_cam.coords - lp.normal * (lp.normal.dot(&c_cam.coords) - lp.d);
        for k in 0..200 {
            let a = std::f64::consts::TAU * k as f64 / 200.0;
            let p = if plane_instead {
                // The object plane through the centre with normal m; its line with the
                // laser plane, sampled by parameter.
                let m = (inv.rotation * Vector3::new(0.2, 0.1, 1.0)).normalize();
                let dir = lp.normal.cross(&m).normalize();
                let t = -12.0 + 24.0 * k as f64 / 200.0;
                // A point on both planes near the foot.
                let a_m = m.dot(&(c_cam.coords - foot));
                let w = m - lp.normal * lp.normal.dot(&m);
                foot + w * (a_m / m.dot(&w)) + dir * t
            } else {
                let h = lp.normal.dot(&c_cam.coords) - lp.d;
                if h.abs() >= radius {
                    continue;
                }
                let rho = (radius * radius - h * h).sqrt();
                let p = foot + (e1 * a.cos() + e2 * a.sin()) * rho;
                if (p - c_cam.coords).dot(&p) >= 0.0 {
                    continue; // faces away from the camera
                }
                p
            };
            let Ok(uv) = cal.camera.project(&p) else {
                continue;
            };
            let b = bc * nalgebra::Point3::from(p);
            pts.points_mm.push([b.x, b.y, b.z]);
            pts.frame.push(f as u32);
            pts.u_px.push(uv.x);
            pts.v_px.push(uv.y);
            pts.intensity.push(1.0);
            pts.width_px.push(3.0);
            pts.flags.push(0);
        }
    }
    (pts, centre.coords)
}

/// The points of `pts`' pixels with another calibration / readings.
fn retriangulate(cal: &Calibration, rd: &[RobotReading], pts: &ScanPoints) -> Vec<[f64; 3]> {
    let tri = Triangulator::from_calibration(cal, 0.0).unwrap();
    let robot = cal.robot.as_ref();
    (0..pts.len())
        .map(|i| {
            let bh = rd[pts.frame[i] as usize].base_hand(robot).unwrap();
            let (mut o, mut ix) = (Vec::new(), Vec::new());
            tri.triangulate_into(&bh, &[[pts.u_px[i], pts.v_px[i]]], &mut o, &mut ix);
            o[0]
        })
        .collect()
}

fn exact_fit() -> FitOptions {
    FitOptions {
        trim_sigma: 0.0,
        robust_start: false,
        ..Default::default()
    }
}

/// Each point's outward unit normal of the sphere centred at `centre`.
fn outward_normals(pts: &ScanPoints, centre: &Vector3<f64>) -> Vec<Vector3<f64>> {
    pts.points_mm
        .iter()
        .map(|p| (Vector3::from(*p) - centre).normalize())
        .collect()
}

fn sd(x: &[f64]) -> f64 {
    let m = x.iter().sum::<f64>() / x.len() as f64;
    (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (x.len() - 1) as f64).sqrt()
}

/// Sphere diameter, centre and the distance to a fixed point: the calibration part
/// against 400 calibration draws (sigmas within 10 %: the sample sigma's scatter is
/// 3.5 %).
#[test]
fn sphere_calibration_part_matches_monte_carlo() {
    let cal = calibration();
    let (pts, _) = scan(&cal, false);
    assert!(pts.len() > 1000, "{} points", pts.len());
    let rd = readings();
    let opts = UncertaintyOptions {
        stripe_sigma_px: Some(0.0),
        ..Default::default()
    };
    let model = UncertaintyModel::new(&cal, &opts).unwrap();
    let mut frames = ScanFrames::new(&model, &rd);
    let fit = fit_sphere(&pts.points_mm, &exact_fit()).unwrap();
    let m = measure_sphere(
        &mut frames,
        &pts,
        &pts.points_mm,
        &fit,
        &SphereSystematic::default(),
    )
    .unwrap();
    assert!(
        m.diameter.random < 1e-9,
        "noise-free points: {:?}",
        m.diameter
    );
    let named = cal.covariance.as_ref().unwrap();
    let chol = named.matrix.clone().cholesky().unwrap();
    let mut rng = SplitMix64(21);
    let (mut d, mut c) = (Vec::new(), vec![Vec::new(); 3]);
    for _ in 0..400 {
        let z = DMatrix::from_fn(named.parameters.len(), 1, |_, _| rng.normal());
        let delta = chol.l() * z;
        let pc = perturbed_calibration(&cal, &named.parameters, delta.as_slice()).unwrap();
        let f = fit_sphere(&retriangulate(&pc, &rd, &pts), &exact_fit()).unwrap();
        d.push(f.diameter_mm);
        for (ck, v) in c.iter_mut().zip(f.center_mm.iter()) {
            ck.push(*v);
        }
    }
    let check = |name: &str, an: f64, mc: f64| {
        eprintln!("{name}: budget {an:.3e}, Monte Carlo {mc:.3e}");
        assert!((an / mc - 1.0).abs() < 0.1, "{name}: {an} vs {mc}");
    };
    check("diameter", m.diameter.calibration, sd(&d));
    for (k, ck) in c.iter().enumerate() {
        check(&format!("centre {k}"), m.center[k].calibration, sd(ck));
    }
}

/// The robot part (encoder noise, independent per frame) against draws of the joint
/// readings; the plane's offset and flatness parts against calibration draws.
#[test]
fn robot_part_and_plane_match_monte_carlo() {
    let cal = calibration();
    let rd = readings();
    let (pts, _) = scan(&cal, false);
    let enc = 0.002;
    let opts = UncertaintyOptions {
        calibration: false,
        stripe_sigma_px: Some(0.0),
        encoder_sigma_deg: Some(enc),
        ..Default::default()
    };
    let model = UncertaintyModel::new(&cal, &opts).unwrap();
    let mut frames = ScanFrames::new(&model, &rd);
    let fit = fit_sphere(&pts.points_mm, &exact_fit()).unwrap();
    let m = measure_sphere(&mut frames, &pts, &pts.points_mm, &fit, &Default::default()).unwrap();
    let mut rng = SplitMix64(8);
    let (mut d, mut cx) = (Vec::new(), Vec::new());
    for _ in 0..300 {
        let noisy: Vec<RobotReading> = rd
            .iter()
            .map(|r| match r {
                RobotReading::Joints(q) => {
                    RobotReading::Joints(q.iter().map(|x| x + enc * rng.normal()).collect())
                }
                other => other.clone(),
            })
            .collect();
        let f = fit_sphere(&retriangulate(&cal, &noisy, &pts), &exact_fit()).unwrap();
        d.push(f.diameter_mm);
        cx.push(f.center_mm.x);
    }
    for (name, an, mc) in [
        ("diameter", m.diameter.robot, sd(&d)),
        ("centre x", m.center[0].robot, sd(&cx)),
    ] {
        eprintln!("robot {name}: budget {an:.3e}, Monte Carlo {mc:.3e}");
        assert!((an / mc - 1.0).abs() < 0.12, "{name}: {an} vs {mc}");
    }
    // A plane.
    let (pp, _) = scan(&cal, true);
    let model = UncertaintyModel::new(
        &cal,
        &UncertaintyOptions {
            stripe_sigma_px: Some(0.0),
            ..Default::default()
        },
    )
    .unwrap();
    let mut frames = ScanFrames::new(&model, &rd);
    let pf = fit_plane(&pp.points_mm, &exact_fit()).unwrap();
    let pm = measure_plane(&mut frames, &pp, &pp.points_mm, &pf).unwrap();
    let named = cal.covariance.as_ref().unwrap();
    let chol = named.matrix.clone().cholesky().unwrap();
    let (mut off, mut flat) = (Vec::new(), Vec::new());
    for _ in 0..300 {
        let z = DMatrix::from_fn(named.parameters.len(), 1, |_, _| rng.normal());
        let delta = chol.l() * z;
        let pc = perturbed_calibration(&cal, &named.parameters, delta.as_slice()).unwrap();
        let pts2 = retriangulate(&pc, &rd, &pp);
        let f = fit_plane(&pts2, &exact_fit()).unwrap();
        // The offset along the nominal normal at the nominal centroid.
        let c = pts2
            .iter()
            .fold(Vector3::zeros(), |a, p| a + Vector3::from(*p))
            / pts2.len() as f64;
        off.push(pf.plane.normal.dot(&c));
        flat.push(f.flatness_mm);
    }
    let (an, mc) = (pm.offset.calibration, sd(&off));
    eprintln!("plane offset: budget {an:.3e}, Monte Carlo {mc:.3e}");
    assert!((an / mc - 1.0).abs() < 0.1, "plane offset: {an} vs {mc}");
    // A range is first order only where its extremes stay the same points: on this
    // perfectly flat surface (flatness 0) it is not (the draws' flatness is an absolute
    // value), so only the order of magnitude is checked.
    let (an, mc) = (pm.flatness.calibration, sd(&flat));
    eprintln!("flatness: budget {an:.3e}, Monte Carlo {mc:.3e}");
    assert!(an > 0.3 * mc && an < 3.0 * mc, "flatness: {an} vs {mc}");
}

/// The random part against Monte Carlo when the points are not equally noisy: noise
/// along the sphere's normal growing from the cap's middle to its rim (as weak, oblique
/// profiles do), 400 draws. The budget's random part (the heteroscedasticity-consistent
/// covariance) matches the draws' scatter of the diameter and centre within 10 %; the
/// textbook `s^2 N^-1` with one variance for all points would understate the diameter's
/// by more than 15 %.
#[test]
fn random_part_matches_monte_carlo_with_unequal_noise() {
    let cal = calibration();
    let (pts, centre) = scan(&cal, false);
    let rd = readings();
    let model = UncertaintyModel::new(&cal, &UncertaintyOptions::default()).unwrap();
    let mut frames = ScanFrames::new(&model, &rd);
    // Each point's normal and noise: sd 1 um in the cap's middle to 5 um at its rim.
    let normals = outward_normals(&pts, &centre);
    let mid = normals.iter().sum::<Vector3<f64>>().normalize();
    let ang: Vec<f64> = normals
        .iter()
        .map(|n| n.dot(&mid).clamp(-1.0, 1.0).acos())
        .collect();
    let amax = ang.iter().cloned().fold(0.0, f64::max);
    let sigma: Vec<f64> = ang
        .iter()
        .map(|a| 1e-3 * (1.0 + 4.0 * (a / amax).powi(2)))
        .collect();
    let mut rng = SplitMix64(7);
    let (mut d, mut cx, mut cz, mut rand_d, mut rand_cx, mut rand_cz, mut iid_d) =
        (vec![], vec![], vec![], vec![], vec![], vec![], vec![]);
    for _ in 0..400 {
        let noisy: Vec<[f64; 3]> = pts
            .points_mm
            .iter()
            .zip(&normals)
            .zip(&sigma)
            .map(|((p, n), s)| {
                let q = Vector3::from(*p) + n * (s * rng.normal());
                [q.x, q.y, q.z]
            })
            .collect();
        let fit = fit_sphere(&noisy, &exact_fit()).unwrap();
        let m = measure_sphere(
            &mut frames,
            &pts,
            &noisy,
            &fit,
            &SphereSystematic::default(),
        )
        .unwrap();
        d.push(fit.diameter_mm);
        cx.push(fit.center_mm.x);
        cz.push(fit.center_mm.z);
        rand_d.push(m.diameter.random);
        rand_cx.push(m.center[0].random);
        rand_cz.push(m.center[2].random);
        // s^2 N^-1 for the radius: one variance for every point.
        let mut n = nalgebra::Matrix4::<f64>::zeros();
        let mut ss = 0.0;
        for p in &noisy {
            let q = Vector3::from(*p) - fit.center_mm;
            let u = q.normalize();
            let j = nalgebra::Vector4::new(-u.x, -u.y, -u.z, -1.0);
            n += j * j.transpose();
            ss += (q.norm() - 0.5 * fit.diameter_mm).powi(2);
        }
        let s2 = ss / (noisy.len() - 4) as f64;
        iid_d.push(2.0 * (n.try_inverse().unwrap()[(3, 3)] * s2).sqrt());
    }
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    for (name, draws, part) in [
        ("diameter", &d, &rand_d),
        ("centre x", &cx, &rand_cx),
        ("centre z", &cz, &rand_cz),
    ] {
        let (mc, b) = (sd(draws), mean(part));
        eprintln!("{name}: random part {b:.3e}, Monte Carlo {mc:.3e}");
        assert!(
            (b / mc - 1.0).abs() < 0.10,
            "{name}: random part {b:.3e} vs Monte Carlo {mc:.3e}"
        );
    }
    let (mc, iid) = (sd(&d), mean(&iid_d));
    eprintln!("diameter: s^2 N^-1 {iid:.3e}");
    assert!(
        iid < 0.85 * mc,
        "the premise: s^2 N^-1 {iid:.3e} vs Monte Carlo {mc:.3e}"
    );
}

/// A ball bar's length: the model's shared part cancels when both spheres are corrected
/// alike, each scan's own estimates add (independent sources), an assumed emitter's
/// shared part cancels too.
#[test]
fn shared_systematic_parts_cancel_in_a_distance_and_own_ones_add() {
    let cal = calibration();
    let (pts, _) = scan(&cal, false);
    let rd = readings();
    let model = UncertaintyModel::new(&cal, &UncertaintyOptions::default()).unwrap();
    let mut frames = ScanFrames::new(&model, &rd);
    let fit = fit_sphere(&pts.points_mm, &exact_fit()).unwrap();
    let part = |source, c: [f64; 3], d| SystematicSource {
        source,
        center_mm: c,
        diameter_mm: d,
    };
    let sphere = |own: u64, frames: &mut ScanFrames<'_>| {
        let sys = SphereSystematic {
            parts: vec![
                part(MODEL_SOURCE, [4e-4, -1e-4, 2e-4], 5e-4),
                part(assumed_emitter_source(1), [1e-4, 0.0, 0.0], 0.0),
                part((own, 3, 0), [3e-4, 0.0, -1e-4], 2e-4),
            ],
        };
        measure_sphere(frames, &pts, &pts.points_mm, &fit, &sys).unwrap()
    };
    let a = sphere(new_source_id(), &mut frames);
    let mut b = sphere(new_source_id(), &mut frames);
    // Each sphere alone: all three parts in quadrature.
    let want = (4e-4f64.powi(2) + 1e-4f64.powi(2) + 3e-4f64.powi(2)).sqrt();
    assert!(
        (a.center[0].systematic - want).abs() < 1e-12,
        "{:?}",
        a.center[0]
    );
    let dia = (5e-4f64.powi(2) + 2e-4f64.powi(2)).sqrt();
    assert!(
        (a.diameter.systematic - dia).abs() < 1e-12,
        "{:?}",
        a.diameter
    );
    // The second sphere 100 mm along x: the length's direction is x.
    b.center[0].value += 100.0;
    let (len, _) = sphere_distance(&a, &b, model.covariance());
    assert!((len.value - 100.0).abs() < 1e-9);
    // Shared parts cancel; the two own x parts (3e-4 each) add in quadrature.
    let own = 3e-4 * 2f64.sqrt();
    assert!((len.systematic - own).abs() < 1e-12, "{len:?}");
    // The calibration part cancels too (same points, same calibration).
    assert!(len.calibration < 1e-12, "{len:?}");
}

/// The random part of a TRIMMED fit against Monte Carlo when the residuals have heavy
/// tails (as a stripe extractor's do): noise along the normal, 2 um with probability
/// 0.92 and 8 um with 0.08, the fit trimmed at 3 robust sigmas, 2000 draws (the sample
/// sigma's own scatter 1.6 %). With the trimmed bread ([`super::measure`]'s
/// `trimmed_bread`) the random part matches the draws' scatter within 5 % (measured:
/// +3.4 % for the diameter, +2.4 % for centre x: the box estimate of the density at the
/// threshold errs high); the sandwich with `N` alone (the inliers taken as a fixed set)
/// is 6 % smaller on the same draws (3.1 % below the scatter).
#[test]
fn random_part_of_a_trimmed_fit_matches_monte_carlo_with_heavy_tails() {
    let cal = calibration();
    let (pts, centre) = scan(&cal, false);
    let rd = readings();
    let model = UncertaintyModel::new(&cal, &UncertaintyOptions::default()).unwrap();
    let mut frames = ScanFrames::new(&model, &rd);
    let normals = outward_normals(&pts, &centre);
    let trimmed = FitOptions {
        trim_sigma: 3.0,
        robust_start: false,
        ..Default::default()
    };
    let mut rng = SplitMix64(11);
    let (mut d, mut cx, mut rand_d, mut rand_cx, mut fixed_d) =
        (vec![], vec![], vec![], vec![], vec![]);
    for _ in 0..2000 {
        let noisy: Vec<[f64; 3]> = pts
            .points_mm
            .iter()
            .zip(&normals)
            .map(|(p, n)| {
                let s = if rng.uniform() < 0.08 { 8e-3 } else { 2e-3 };
                let q = Vector3::from(*p) + n * (s * rng.normal());
                [q.x, q.y, q.z]
            })
            .collect();
        let fit = fit_sphere(&noisy, &trimmed).unwrap();
        assert!(fit.trim_threshold_mm > 0.0 && fit.outliers > 0);
        let m = measure_sphere(
            &mut frames,
            &pts,
            &noisy,
            &fit,
            &SphereSystematic::default(),
        )
        .unwrap();
        d.push(fit.diameter_mm);
        cx.push(fit.center_mm.x);
        rand_d.push(m.diameter.random);
        rand_cx.push(m.center[0].random);
        // The sandwich with N alone over the inliers.
        let (mut n, mut meat, mut k) = (
            nalgebra::Matrix4::<f64>::zeros(),
            nalgebra::Matrix4::<f64>::zeros(),
            0usize,
        );
        for (p, _) in noisy.iter().zip(&fit.inlier).filter(|(_, &i)| i) {
            let q = Vector3::from(*p) - fit.center_mm;
            let u = q.normalize();
            let j = nalgebra::Vector4::new(-u.x, -u.y, -u.z, -1.0);
            let r = q.norm() - 0.5 * fit.diameter_mm;
            n += j * j.transpose();
            meat += j * j.transpose() * (r * r);
            k += 1;
        }
        let ninv = n.try_inverse().unwrap();
        let v = ninv * meat * ninv * (k as f64 / (k - 4) as f64);
        fixed_d.push(2.0 * v[(3, 3)].sqrt());
    }
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    for (name, draws, part) in [("diameter", &d, &rand_d), ("centre x", &cx, &rand_cx)] {
        let (mc, b) = (sd(draws), mean(part));
        eprintln!("{name}: random part {b:.3e}, Monte Carlo {mc:.3e}");
        assert!(
            (b / mc - 1.0).abs() < 0.05,
            "{name}: random part {b:.3e} vs Monte Carlo {mc:.3e}"
        );
    }
    let (mc, fixed, b) = (sd(&d), mean(&fixed_d), mean(&rand_d));
    eprintln!("diameter: the sandwich with N alone {fixed:.3e} (Monte Carlo {mc:.3e})");
    assert!(
        fixed < 0.96 * b,
        "the premise: N alone {fixed:.3e} vs the trimmed bread's {b:.3e}"
    );
}
