//! The model against brute-force integration, flat surfaces, and its sigma scaling.

use super::*;
use crate::model::geometry::Iso3;
use crate::model::StripeDirection;
use crate::reconstruct::triangulate::tests::camera;
use crate::reconstruct::triangulate::Triangulator;
use crate::reconstruct::ScanPoints;
use crate::stripe_model::image::*;
use crate::stripe_model::profile::*;
use crate::vision::stripe::profile_centre;
use crate::vision::stripe::FLAG_SATURATED;

fn plane() -> Plane {
    Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 80.0).unwrap()
}

/// The modelled bias (px) and width of the point `p` of the sphere of radius `r`
/// whose outward normal there is `nrm`, for sheet sigma `s` and PSF `b`.
fn bias_at(p: Vector3<f64>, nrm: Vector3<f64>, r: f64, s: f64, b: f64) -> (f64, f64) {
    let cam = camera([0.0; 5]);
    let pl = plane();
    let so = StripeOptions::default();
    let rig = twin_rig(&cam, &pl, &so, 89.0);
    let c = p - nrm.normalize() * r;
    let line = cam.project(&p).unwrap().y;
    let mut prof = PointProfile::default();
    assert!(point_profile(
        &rig,
        &SphereSurface { c: &c, r },
        line,
        &p,
        s,
        b,
        &mut prof
    ));
    let (d, w, _) = extractor_response(&prof, b, &so, &mut Vec::new()).unwrap();
    (d, w)
}

/// The rig of these tests: the emitter at the foot of the plane, scan lines along `v`,
/// incidence up to `max_incidence_deg`.
fn twin_rig<'a>(
    cam: &'a Camera,
    pl: &Plane,
    so: &'a StripeOptions,
    max_incidence_deg: f64,
) -> Rig<'a> {
    Rig::new(
        cam,
        pl,
        pl.normal * pl.d,
        StripeDirection::Cols,
        so,
        max_incidence_deg,
    )
}

/// A point of the plane on the optical axis.
fn p0() -> Vector3<f64> {
    let pl = plane();
    Vector3::new(0.0, 0.0, pl.d / pl.normal.z)
}

/// The extractor's centre minus the t = 0 image on the scan line through `p`, by
/// brute force: rays cast through a fine grid of the image around the scan line,
/// each shaded as the twin does (Gaussian sheet, cos / r from the emitter, seen and
/// lit), integrated over the pixel box and the Gaussian PSF in both directions.
fn brute_force_bias(p: Vector3<f64>, nrm: Vector3<f64>, r: f64, s: f64, b: f64) -> f64 {
    let cam = camera([0.0; 5]);
    let pl = plane();
    let e = pl.normal * pl.d;
    let c = p - nrm.normalize() * r;
    let uv = cam.project(&p).unwrap();
    let (u_p, line) = (uv.x, uv.y);
    let hit = |u: f64, v: f64| -> Option<Vector3<f64>> {
        let d = cam.unproject(&nalgebra::Vector2::new(u, v)).ok()?;
        let a = d.norm_squared();
        let bb = d.dot(&c);
        let disc = bb * bb - a * (c.norm_squared() - r * r);
        (disc >= 0.0).then(|| d * ((bb - disc.sqrt()) / a))
    };
    let radiance = |u: f64, v: f64| -> f64 {
        let Some(q) = hit(u, v) else { return 0.0 };
        let n = (q - c) / r;
        let to_e = e - q;
        let cos = n.dot(&to_e) / to_e.norm();
        if cos <= 0.0 || n.dot(&(-q)) <= 0.0 {
            return 0.0;
        }
        let z = pl.signed_distance(&q) / s;
        cos / to_e.norm() * (-0.5 * z * z).exp()
    };
    let kern = |x: f64| {
        let k = 1.0 / (std::f64::consts::SQRT_2 * b);
        0.5 * (erf((x + 0.5) * k) - erf((x - 0.5) * k))
    };
    // The t = 0 image on the scan line: bisection of the signed distance.
    let dist = |u: f64| hit(u, line).map_or(f64::NAN, |q| pl.signed_distance(&q));
    let (mut lo, mut hi) = (u_p - 3.0, u_p + 3.0);
    assert!(dist(lo) * dist(hi) < 0.0);
    for _ in 0..60 {
        let m = 0.5 * (lo + hi);
        if dist(m) * dist(lo) > 0.0 {
            lo = m;
        } else {
            hi = m;
        }
    }
    let a0 = 0.5 * (lo + hi);
    let x0 = (a0 - 60.0).floor();
    let reach = 0.5 + 5.0 * b;
    let (hu, hl) = (0.02, 0.05);
    let nl = (2.0 * reach / hl) as i64;
    let nu = (120.0 / hu) as i64;
    let mut vals = vec![0.0; 121];
    for j in 0..=nl {
        let dl = -reach + j as f64 * hl;
        let kl = kern(dl);
        for i in 0..=nu {
            let uu = x0 + i as f64 * hu;
            let l = radiance(uu, line + dl);
            if l == 0.0 {
                continue;
            }
            for (k, v) in vals.iter_mut().enumerate() {
                let du = x0 + k as f64 - uu;
                if du.abs() < reach {
                    *v += l * kl * kern(du);
                }
            }
        }
    }
    let (cc, _, _) = profile_centre(&vals, &StripeOptions::default()).unwrap();
    cc + x0 - a0
}

#[test]
fn model_matches_brute_force_integration() {
    // On the ball (convex, several orientations) and on a flat surface (a sphere of
    // 100 m radius: only the perspective and the shading's slow change remain).
    for (nrm, r) in [
        (Vector3::new(0.3, 0.1, -1.0), 22.43),
        (Vector3::new(-0.1, 0.3, -1.0), 22.43),
        (Vector3::new(0.9, -0.3, -1.0), 22.43),
        (Vector3::new(1.5, 0.0, -1.0), 12.7),
        (Vector3::new(1.5, 0.0, -1.0), 1e5),
    ] {
        for (s, b) in [(0.12, 0.7), (0.25, 1.0)] {
            let (m, _) = bias_at(p0(), nrm, r, s, b);
            let bf = brute_force_bias(p0(), nrm, r, s, b);
            eprintln!(
                "nrm {:?} r {r} s {s} b {b}: model {m:+.5} brute force {bf:+.5} px",
                nrm.as_slice()
            );
            assert!(
                (m - bf).abs() < 5e-4 + 0.01 * bf.abs(),
                "model {m} brute force {bf}"
            );
        }
    }
}

#[test]
fn scan_bias_has_a_part_independent_of_the_sheet() {
    // Not second order in sigma alone: the PSF and the pixel's extent across the scan
    // line average neighbouring scan lines of the curved stripe, a shift of about
    // a'' (b^2 + 1/12) / 2 whatever the sheet's thickness.
    let cam = camera([0.0; 5]);
    let d0 = |s: f64, b: f64| {
        let (sp, poses, _) = synthetic_scan(22.43, s, b);
        let opts = StripeBiasOptions {
            sheet_sigma_mm: Some(s),
            psf_sigma_px: Some(b),
            ..Default::default()
        };
        let res = correct_sphere_bias(&sp, &poses, &cam, &plane(), &opts).unwrap();
        -res.diameter_change_mm
    };
    let (thin, thin_sharp, thick) = (d0(0.03, 0.7), d0(0.03, 0.3), d0(0.12, 0.7));
    assert!(thin > 0.001 && thick > thin, "{thin} {thick}");
    assert!(
        thin_sharp < 0.5 * thin,
        "PSF 0.3 px: {thin_sharp}, 0.7 px: {thin}"
    );
}

/// A synthetic scan: the sphere swept through the plane (camera translated along the
/// plane normal), each row's stripe point at the t = 0 image plus the model's bias,
/// triangulated. Returns the points, the frame poses, the sphere centre and radius.
fn synthetic_scan(r: f64, s: f64, b: f64) -> (ScanPoints, Vec<Iso3>, Vector3<f64>) {
    let (sp, poses, c, _) = synthetic_scan_with_bias(r, s, b);
    (sp, poses, c)
}

/// [`synthetic_scan`] with each point's bias put in (px along its row).
fn synthetic_scan_with_bias(
    r: f64,
    s: f64,
    b: f64,
) -> (ScanPoints, Vec<Iso3>, Vector3<f64>, Vec<f64>) {
    let cam = camera([0.0; 5]);
    let pl = plane();
    let so = StripeOptions::default();
    let rig = twin_rig(&cam, &pl, &so, 75.0);
    let tri = Triangulator::new(&cam, &pl, &Iso3::identity(), 0.0).unwrap();
    let c_mid = p0() + Vector3::new(0.0, 0.0, 0.3 * r);
    let h_mid = pl.normal.dot(&c_mid) - pl.d;
    let mut sp = ScanPoints::default();
    let mut poses = Vec::new();
    let mut biases = Vec::new();
    let (mut prof, mut buf) = (PointProfile::default(), Vec::new());
    for k in 0..15 {
        let shift = -h_mid + (k as f64 / 14.0 * 1.8 - 0.9) * r;
        let c = c_mid + pl.normal * shift;
        // T_base_cam: the sphere fixed at c_mid in the base frame.
        let t = c_mid - c;
        poses.push(Iso3::translation(t.x, t.y, t.z));
        let (e1, e2) = (rig.e1, rig.e2);
        let h = pl.normal.dot(&c) - pl.d;
        let rho = (r * r - h * h).sqrt();
        let ctr = c - pl.normal * h;
        let pt = |phi: f64| ctr + (e1 * phi.cos() + e2 * phi.sin()) * rho;
        let m = 4000;
        let mut prev: Option<(f64, f64)> = None;
        for j in 0..=m {
            let phi = std::f64::consts::TAU * j as f64 / m as f64;
            let p = pt(phi);
            let seen = shading(&rig, &c, r, &p) > 0.0;
            let v = cam.project(&p).unwrap().y;
            if let (true, Some((pv, pphi))) = (seen, prev) {
                if pv.floor() != v.floor() {
                    let line = pv.max(v).floor();
                    let Some(s0) = section_point(&rig, &c, r, 0.0, line, pphi) else {
                        continue;
                    };
                    if point_profile(
                        &rig,
                        &SphereSurface { c: &c, r },
                        line,
                        &s0.p,
                        s,
                        b,
                        &mut prof,
                    ) {
                        if let Some((d, w, peak)) = extractor_response(&prof, b, &so, &mut buf) {
                            let u = prof.a0 + d;
                            let q = tri.point_cam_mm(u, line).unwrap() + t;
                            sp.points_mm.push([q.x, q.y, q.z]);
                            sp.frame.push(k);
                            sp.u_px.push(u);
                            sp.v_px.push(line);
                            sp.intensity.push((1e4 * peak) as f32);
                            sp.width_px.push(w as f32);
                            sp.flags.push(0);
                            biases.push(d);
                        }
                    }
                }
            }
            prev = seen.then_some((v, phi));
        }
    }
    (sp, poses, c_mid, biases)
}

/// The corrected fit trims the CORRECTED residuals (module docs, "Which points are
/// fitted"): copies of every 40th point moved 20 mm outwards are not corrected at all;
/// copies moved 4 of the uncorrected fit's robust sigmas outwards (inside its candidate
/// band, outside its 3-sigma inliers) are corrected and then trimmed; neither moves the
/// corrected sphere. Fitting every given point untrimmed, as before, kept the near
/// copies.
#[test]
fn the_corrected_fit_trims_the_corrected_residuals() {
    let (r, s, b) = (22.43, 0.12, 0.7);
    let (sp, poses, c) = synthetic_scan(r, s, b);
    let cam = camera([0.0; 5]);
    let o = StripeBiasOptions::default();
    let clean = correct_sphere_bias(&sp, &poses, &cam, &plane(), &o).unwrap();
    let (used, modelled) = (
        clean.used.iter().filter(|&&u| u).count(),
        clean.modelled.iter().filter(|&&m| m).count(),
    );
    assert!(
        used * 10 >= modelled * 9,
        "{used} of {modelled} modelled points fitted"
    );
    let step = clean.uncorrected.robust_sigma_mm * 4.0;
    assert!(
        step > 1e-4,
        "uncorrected robust sigma {}",
        clean.uncorrected.robust_sigma_mm
    );
    let picks: Vec<usize> = (0..sp.len())
        .step_by(40)
        .filter(|&i| clean.used[i])
        .collect();
    let moved = |by: f64| {
        let mut m = sp.subset(&picks);
        for p in m.points_mm.iter_mut() {
            let v = Vector3::from(*p);
            let q = v + (v - c).normalize() * by;
            *p = [q.x, q.y, q.z];
        }
        m
    };
    let mut all = sp.clone();
    all.append(&moved(20.0));
    all.append(&moved(step));
    let n = sp.len();
    let k = picks.len();
    let res = correct_sphere_bias(&all, &poses, &cam, &plane(), &o).unwrap();
    let far = n..n + k;
    let near = n + k..n + 2 * k;
    assert!(
        far.clone().all(|i| !res.modelled[i] && !res.used[i]),
        "far copies corrected"
    );
    let near_modelled = near.clone().filter(|&i| res.modelled[i]).count();
    assert!(
        near_modelled * 10 >= k * 9,
        "{near_modelled} of {k} near copies corrected"
    );
    let near_used = near.clone().filter(|&i| res.used[i]).count();
    assert_eq!(near_used, 0, "near copies in the corrected fit");
    let dd = res.fit.diameter_mm - clean.fit.diameter_mm;
    let dc = (res.fit.center_mm - clean.fit.center_mm).norm();
    // The near copies, kept, would move the diameter by about 2 k / n of their offset.
    let kept_shift = 2.0 * step * k as f64 / n as f64;
    assert!(
        dd.abs() < 0.1 * kept_shift && dc < 0.1 * kept_shift,
        "moved by {dd}, {dc} (kept: {kept_shift})"
    );
}

#[test]
fn synthetic_scan_bias_is_outward_and_corrected() {
    let (r, s, b) = (22.43, 0.12, 0.7);
    let (sp, poses, c) = synthetic_scan(r, s, b);
    assert!(sp.len() > 1000, "{} points", sp.len());
    let cam = camera([0.0; 5]);
    let res = correct_sphere_bias(&sp, &poses, &cam, &plane(), &Default::default()).unwrap();
    let d0 = res.uncorrected.diameter_mm - 2.0 * r;
    let d1 = res.fit.diameter_mm - 2.0 * r;
    let c1 = (res.fit.center_mm - c).norm();
    // Outward: the uncorrected sphere is too large.
    assert!(d0 > 0.002, "uncorrected diameter error {d0}");
    assert!(d1.abs() < 2e-4, "corrected diameter error {d1} (from {d0})");
    assert!(c1 < 2e-4, "corrected centre error {c1}");
    let sh = &res.sheet;
    assert!((sh.sheet_sigma_mm / s - 1.0).abs() < 0.03, "{sh:?}");
    assert!((sh.psf_sigma_px - b).abs() < 0.05, "{sh:?}");
    let e = res.emitter_estimate.expect("emitter estimated");
    let de = (e.emitter_cam_mm - plane().normal * plane().d).norm();
    assert!(de < 2.0, "emitter off by {de} mm");
    // The systematic part: mostly the model-error share of the correction.
    let sys = res.diameter_systematic_mm;
    let share = neglected_share(NEGLECTED_FRACTION) * res.diameter_change_mm.abs();
    assert!(sys >= share && sys < share + 2e-4, "{sys} vs {share}");
    // Its parts: the model's (signed as the correction), the estimated emitter's two
    // axes and the two sigmas, each the scan's own; their root sum of squares is it.
    let kinds: Vec<SystematicKind> = res.systematic_parts.iter().map(|p| p.kind).collect();
    for k in [0, 1, 2, 3] {
        assert!(kinds.contains(&SystematicKind::Estimate(k)), "{kinds:?}");
    }
    let model: Vec<_> = res
        .systematic_parts
        .iter()
        .filter(|p| p.kind == SystematicKind::Model)
        .collect();
    assert_eq!(model.len(), 1);
    assert_eq!(
        model[0].diameter_mm.signum(),
        res.diameter_change_mm.signum()
    );
    let rss = |q: &dyn Fn(&SystematicPart) -> f64| {
        res.systematic_parts
            .iter()
            .map(|p| q(p).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    assert!((rss(&|p| p.diameter_mm) - sys).abs() < 1e-15);
    for k in 0..3 {
        let c = rss(&|p| p.center_mm[k]);
        assert!((c - res.center_systematic_mm[k]).abs() < 1e-15);
    }
    // With the emitter assumed: one shared part per in-plane axis instead.
    let o = StripeBiasOptions {
        estimate_emitter: false,
        ..Default::default()
    };
    let assumed = correct_sphere_bias(&sp, &poses, &cam, &plane(), &o).unwrap();
    let kinds: Vec<SystematicKind> = assumed.systematic_parts.iter().map(|p| p.kind).collect();
    for k in [0, 1] {
        assert!(
            kinds.contains(&SystematicKind::AssumedEmitter(k)),
            "{kinds:?}"
        );
        assert!(!kinds.contains(&SystematicKind::Estimate(k)), "{kinds:?}");
    }
}

#[test]
fn grazing_view_points_are_left_out_and_the_limit_is_checked() {
    let (sp, poses, _) = synthetic_scan(22.43, 0.12, 0.7);
    let cam = camera([0.0; 5]);
    let count = |deg: f64| {
        let o = StripeBiasOptions {
            max_view_deg: deg,
            ..Default::default()
        };
        correct_sphere_bias(&sp, &poses, &cam, &plane(), &o)
            .map(|r| r.modelled.iter().filter(|&&m| m).count())
    };
    let (all, default) = (count(90.0).unwrap(), count(75.0).unwrap());
    assert!(all > default && default > all / 2, "{all} {default}");
    // A limit that leaves most points out is refused, not fitted on the few.
    assert!(matches!(count(45.0), Err(Error::Degenerate(_))));
    for bad in [-1.0, 90.5, f64::NAN] {
        assert!(matches!(count(bad), Err(Error::InvalidInput(_))), "{bad}");
    }
}

#[test]
fn the_outline_test_finds_the_sphere_image_edge() {
    // A sphere on the optical axis: its image is a disc about the principal point of
    // radius f tan(asin(r / z)) (no distortion).
    let cam = camera([0.0; 5]);
    let pl = plane();
    let so = StripeOptions::default();
    let rig = twin_rig(&cam, &pl, &so, 75.0);
    let (r, z) = (20.0f64, 400.0f64);
    let c = Vector3::new(0.0, 0.0, z);
    let radius_px = cam.fu * (r / z).asin().tan();
    let (u0, v0) = (cam.u0, cam.v0);
    let clear = |a: f64, reach: f64| clear_of_outline(&rig, &c, r, v0, a, reach);
    assert!(clear(u0, radius_px - 0.05));
    assert!(!clear(u0, radius_px + 0.05));
    // Off centre, the nearer edge decides.
    assert!(clear(u0 + 10.0, radius_px - 10.05));
    assert!(!clear(u0 + 10.0, radius_px - 9.95));
    // The support grows with the width and the flanks.
    assert_eq!(support_px(&so, 1.0), 1.5 + 1.5 + so.flank_px as f64);
    assert!(
        (support_px(&so, 4.0) - (4.0 * so.window_fwhm as f64 + 1.5 + so.flank_px as f64)).abs()
            < 1e-12
    );
}

#[test]
fn points_near_the_outline_are_left_out_and_the_margin_is_checked() {
    let (sp, poses, _) = synthetic_scan(22.43, 0.12, 0.7);
    let cam = camera([0.0; 5]);
    let count = |margin: f64| {
        let o = StripeBiasOptions {
            outline_margin_px: margin,
            max_view_deg: 90.0,
            ..Default::default()
        };
        correct_sphere_bias(&sp, &poses, &cam, &plane(), &o)
            .map(|r| r.modelled.iter().filter(|&&m| m).count())
    };
    let (near, default, far) = (
        count(0.0).unwrap(),
        count(OUTLINE_MARGIN_PX).unwrap(),
        count(2.0 * OUTLINE_MARGIN_PX).unwrap(),
    );
    assert!(
        near > default && default > far && far > near / 2,
        "{near} {default} {far}"
    );
    // A margin that leaves most points out is refused, not fitted on the few.
    assert!(matches!(count(1000.0), Err(Error::Degenerate(_))));
    for bad in [-1.0, f64::INFINITY, f64::NAN] {
        assert!(matches!(count(bad), Err(Error::InvalidInput(_))), "{bad}");
    }
}

#[test]
fn saturated_points_are_left_out_and_counted() {
    let (r, s, b) = (22.43, 0.12, 0.7);
    let (mut sp, poses, c) = synthetic_scan(r, s, b);
    let cam = camera([0.0; 5]);
    let n = sp.len();
    let unclipped = sp.clone();
    // Every third point clipped (the synthetic profiles are not: the flag alone must
    // keep them out).
    for i in (0..n).step_by(3) {
        sp.flags[i] = FLAG_SATURATED;
    }
    let res = correct_sphere_bias(&sp, &poses, &cam, &plane(), &Default::default()).unwrap();
    assert_eq!(res.saturated, n.div_ceil(3));
    for i in (0..n).step_by(3) {
        assert!(!res.modelled[i], "saturated point {i} modelled");
        assert_eq!(res.corrections_mm[i], [0.0; 3]);
    }
    // The others are modelled as without the flags (the same limits leave the same out).
    let unflagged = correct_sphere_bias(&unclipped, &poses, &cam, &plane(), &Default::default())
        .unwrap()
        .modelled;
    for (i, (m, u)) in res.modelled.iter().zip(&unflagged).enumerate() {
        assert_eq!(*m, i % 3 != 0 && *u, "point {i}");
    }
    let d1 = res.fit.diameter_mm - 2.0 * r;
    assert!(d1.abs() < 2e-4, "corrected diameter error {d1}");
    assert!((res.fit.center_mm - c).norm() < 2e-4);
    assert!(
        (res.sheet.sheet_sigma_mm / s - 1.0).abs() < 0.03,
        "{:?}",
        res.sheet
    );
    // Nearly everything saturated: refused, and the error says why.
    for f in sp.flags.iter_mut().skip(5) {
        *f = FLAG_SATURATED;
    }
    match correct_sphere_bias(&sp, &poses, &cam, &plane(), &Default::default()) {
        Err(Error::Degenerate(m)) => assert!(m.contains("saturated"), "{m}"),
        other => panic!("expected Degenerate, got {other:?}"),
    }
}

/// The model's diagnostics recover what the synthetic scan put in: each point was
/// placed at the t = 0 image plus the model's bias, so the predicted bias at the true
/// sphere and sigmas is that shift; with no image noise every noisy copy is the clean
/// profile, so the noise shift is exactly zero.
#[test]
fn the_diagnostics_recover_the_synthetic_bias() {
    let (r, s, b) = (22.43, 0.12, 0.7);
    let (sp, poses, c, put) = synthetic_scan_with_bias(r, s, b);
    let cam = camera([0.0; 5]);
    let pl = plane();
    let opts = StripeBiasOptions {
        emitter_cam_mm: Some((pl.normal * pl.d).into()),
        ..Default::default()
    };
    let inputs = ModelInputs {
        points: &sp,
        base_cam: &poses,
        camera: &cam,
        plane: &pl,
        opts: &opts,
    };
    let pred = predicted_bias_px(&inputs, (&c, r), (s, b)).unwrap();
    let mut n = 0;
    for (i, d) in pred.iter().enumerate() {
        let Some(d) = d else { continue };
        assert!((d - put[i]).abs() < 1e-6, "point {i}: {d} vs {}", put[i]);
        n += 1;
    }
    assert!(n > sp.len() / 2, "{n} of {} modelled", sp.len());
    let draws = NoiseDraws {
        gray: 0.0,
        pairs: 2,
        seed: 1,
    };
    let shifts = predicted_noise_shift_px(&inputs, (&c, r), (s, b), draws).unwrap();
    let m = shifts.iter().flatten().count();
    assert!(m > sp.len() / 2, "{m} of {}", sp.len());
    for x in shifts.iter().flatten() {
        assert_eq!((x.mean, x.median, x.trimmed, x.sd), (0.0, 0.0, 0.0, 0.0));
    }
    let mut d = [3.0, -1.0, 1.0, 100.0];
    let f = NoiseShift::of(&mut d).unwrap();
    assert_eq!((f.mean, f.median), (25.75, 3.0));
    assert!(NoiseShift::of(&mut []).is_none());
}

/// The emitter's fit and sensitivity terms model a point's profile from its sections
/// solved once ([`point_geometry`], [`profile_for_emitter`]): the same samples, in the
/// same order, as [`point_profile`] for every emitter, whether the emitter leaves the
/// whole profile lit, cuts it or leaves the point unmodelled.
#[test]
fn profiles_from_the_shared_geometry_equal_the_direct_ones() {
    let cam = camera([0.0; 5]);
    let pl = plane();
    let so = StripeOptions::default();
    let mut rig = twin_rig(&cam, &pl, &so, 89.0);
    rig.outline_margin_px = Some(OUTLINE_MARGIN_PX);
    let r = 12.7;
    let (mut checked, mut refused) = (0, 0);
    for (nrm, s, b) in [
        (Vector3::new(0.3, -0.2, -1.0), 0.12, 0.7),
        (Vector3::new(-0.5, 0.1, -1.0), 0.2, 0.3),
        (Vector3::new(0.1, 0.6, -1.0), 0.08, 0.0),
    ] {
        let p = p0();
        let c = p - nrm.normalize() * r;
        let surf = SphereSurface { c: &c, r };
        let line = cam.project(&p).unwrap().y;
        let mut geo = PointGeometry::default();
        let ok = point_geometry(&rig, &surf, line, &p, s, b, &mut Vec::new(), &mut geo);
        for (de1, de2) in [
            (0.0, 0.0),
            (30.0, -10.0),
            (-60.0, 40.0),
            (150.0, 0.0),
            (0.0, -400.0),
        ] {
            let mut r2 = rig.clone();
            r2.emitter = rig.emitter + rig.e1 * de1 + rig.e2 * de2;
            let (mut direct, mut shared) = (PointProfile::default(), PointProfile::default());
            let a = point_profile(&r2, &surf, line, &p, s, b, &mut direct);
            let b2 = ok && profile_for_emitter(&r2, &surf, &geo, &mut shared);
            assert_eq!(a, b2, "emitter {de1} {de2}");
            if a {
                assert_eq!(direct.samples, shared.samples);
                assert_eq!(
                    (direct.a0, direct.g, direct.slope),
                    (shared.a0, shared.g, shared.slope)
                );
                checked += 1;
            } else {
                refused += 1;
            }
        }
    }
    assert!(
        checked >= 8 && refused >= 1,
        "{checked} checked, {refused} refused"
    );
}

/// The runs of sections solve every second sheet offset and read the one between from
/// them where the image of the stripe bends little ([`run_outwards`],
/// [`Section::halfway`]): at the sheet offsets the model samples (`sheet_offsets`, two
/// sheet sigmas, the twin's PSF) every section visited lies within 1e-7 px (along the
/// line) and 1e-8 mm (the point) of the one solved at its own offset, its `|da/dt|`
/// within 1e-6 relative, on spheres (one seen near its outline) and a board, both
/// directions, runs of odd and even length.
#[test]
fn sections_read_between_solved_ones_match_the_solved_ones() {
    fn check<S: Surface>(rig: &Rig<'_>, surf: &S, line: f64, hint: f64) -> usize {
        let s0 = surf
            .section(rig, 0.0, line, hint)
            .expect("the t = 0 section");
        let mut visited = 0;
        for (sigma, dir) in [(0.12, -1.0), (0.12, 1.0), (0.3, -1.0), (0.3, 1.0)] {
            let (m, dt) = sheet_offsets(sigma, s0.da_dt.abs(), 0.7);
            let (mut k, mut last) = (0, s0.phi);
            run_outwards(rig, surf, line, &s0, (dir, m, dt), |t, s| {
                k += 1;
                assert!((t - dir * k as f64 * dt).abs() < 1e-15, "offset {k}: {t}");
                let Some(direct) = surf.section(rig, t, line, last) else {
                    return false;
                };
                last = direct.phi;
                // Near the outline two solves of one section from other starts differ in
                // `da/dt` (its derivatives are taken at Newton's last iterate): that much
                // is the solver's, not the reading's.
                let again = surf.section(rig, t, line, s.phi).expect("solved again");
                let solver = (again.da_dt - direct.da_dt).abs();
                assert!(
                    (s.a - direct.a).abs() < 1e-7,
                    "a at {t}: {} {}",
                    s.a,
                    direct.a
                );
                assert!((s.p - direct.p).norm() < 1e-8, "p at {t}");
                assert!(
                    (s.da_dt - direct.da_dt).abs() < 1e-5 * direct.da_dt.abs() + solver,
                    "da/dt at {t}: {} {}",
                    s.da_dt,
                    direct.da_dt
                );
                true
            });
            assert!(k >= m.min(HALF_SAMPLES), "{k} offsets visited of {m}");
            visited += k;
        }
        visited
    }
    let cam = camera([0.0; 5]);
    let pl = plane();
    let so = StripeOptions::default();
    let rig = twin_rig(&cam, &pl, &so, 89.0);
    let p = p0();
    let line = cam.project(&p).unwrap().y;
    let mut visited = 0;
    for nrm in [
        Vector3::new(0.3, -0.2, -1.0),
        Vector3::new(-0.5, 0.1, -1.0),
        Vector3::new(0.1, 0.6, -1.0),
    ] {
        let r = 12.7;
        let c = p - nrm.normalize() * r;
        let q = p - c;
        let phi0 = q.dot(&rig.e2).atan2(q.dot(&rig.e1));
        visited += check(&rig, &SphereSurface { c: &c, r }, line, phi0);
    }
    let n_board = Vector3::new(0.1, -0.2, 1.0).normalize();
    let board = Plane::new(n_board, n_board.dot(&p)).unwrap();
    let b = crate::stripe_model::BoardSurface::new(&rig, &board).unwrap();
    visited += check(&rig, &b, line, 0.0);
    assert!(visited > 16 * HALF_SAMPLES, "{visited} sections");
}
