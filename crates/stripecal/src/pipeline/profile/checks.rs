//! A profiler calibration's checks: views whose points do not fit, the mirror test,
//! undetermined numbers, convergence, and the declared diameter against the data.
//!
//! ## The mirror test
//!
//! Flipping the side of every view is the mirror image of the solution. When the
//! sphere's centres as the sensor sees them, `p_i = (A_i X)^-1 c`, lie in one plane (the
//! same stand-off, the same place along the line, or the same offset from the laser
//! plane in every view), a proper rigid motion maps the mirrored centres onto the true
//! ones and a mirrored hand-eye fits exactly as well. So the adjustment is run again from
//! the mirrored start over the same points, and the two costs compared:
//! `dchi2 = (SSR_mirror - SSR_chosen) / (k s^2)` (`s^2` the chosen fit's variance factor,
//! `k` its view-clustered factor). The mirror starts from the closed form with every side
//! flipped and from the chosen solution moved by the proper motion that best maps the
//! mirrored centres onto the chosen ones (Kabsch); the better is kept. Below
//! [`MIRROR_CHI2`] the data cannot decide: the
//! calibration fails and names the plane the centres lie in. A mirrored start whose
//! adjustment flips the sides back (the sides of the two solutions agree, weighted by
//! `|y_i|`) found no mirror minimum: `dchi2` is then infinite. For speed both solves use
//! every k-th point of the chosen selection (at most [`MIRROR_POINTS`]), and `dchi2` is
//! scaled back by k.

use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};

use crate::model::geometry::nearest_rotation;

use crate::calib::joint::profile::{
    profile_adjustment, ProfileFit, ProfileOptions, ProfileStart, ProfileViewObs,
};
use crate::calib::profile::start::MIN_VIEWS;
use crate::error::Result;
use crate::model::QualityCheck;

/// The mirror must fit worse by this many variances. Under a true ambiguity the two
/// fits are equally valid models and differ only by what each adjusts to the noise (the
/// fitted centres are never exactly coplanar): a chi-square of about as many degrees of
/// freedom as unknowns (10); 60 is its 5-sigma quantile.
pub const MIRROR_CHI2: f64 = 60.0;
/// Points the mirror test solves with at most.
pub const MIRROR_POINTS: usize = 6000;
/// A view whose fit keeps less than this share of its arc's points does not fit.
pub const MIN_KEPT_SHARE: f64 = 0.5;
/// ... or whose sphere points' RMS exceeds this many times the views' median.
pub const POOR_RMS_FACTOR: f64 = 10.0;
/// The declared diameter is contradicted beyond 3 sigma and this share of it.
pub const DIAMETER_TOLERANCE: f64 = 0.002;

/// The mirror test's figures (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct MirrorTest {
    pub ssr_chosen_mm2: f64,
    pub ssr_mirror_mm2: f64,
    /// `(SSR_mirror - SSR_chosen) / s^2`, scaled to every point.
    pub delta_chi2: f64,
    /// The spread of the sphere's centres as the sensor saw them: standard deviations
    /// along sensor x (place along the line), y (offset from the laser plane), z
    /// (stand-off), and across their best-fitting plane, mm.
    pub spread_mm: [f64; 4],
    pub passed: bool,
}

impl MirrorTest {
    /// What the spread says: the plane the centres lie in, nearly or exactly.
    pub fn plane(&self) -> String {
        let [x, y, z, n] = self.spread_mm;
        let (what, s) = [
            ("the same place along the line (sensor x)", x),
            ("the same offset from the laser plane (sensor y)", y),
            ("the same stand-off (sensor z)", z),
        ]
        .into_iter()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or(("", 0.0));
        // an axis whose spread is (nearly) as small as the least across any plane is
        // the one the poses held; otherwise the centres lie in a tilted plane
        if s <= (3.0 * n).max(0.5) {
            format!("{what}: spread {s:.3} mm")
        } else {
            format!("one tilted plane (spread across it {n:.3} mm)")
        }
    }

    /// The `mirror` gate.
    pub fn check(&self) -> QualityCheck {
        if self.passed {
            QualityCheck::pass(
                "mirror",
                format!(
                    "the mirrored hand-eye fits worse by chi2 {:.0} (needs > {MIRROR_CHI2:.0})",
                    self.delta_chi2
                ),
            )
        } else {
            QualityCheck::fail(
                "mirror",
                format!(
                    "a mirrored hand-eye fits as well (its cost against the chosen one: chi2 \
                     {:+.1}, needs > {MIRROR_CHI2:.0}): the sphere's centres as the sensor \
                     sees them lie in one plane, {}; vary the stand-off, the sphere's place \
                     along the line and the laser plane's offset from its centre (both sides) \
                     between the poses",
                    self.delta_chi2,
                    self.plane()
                ),
                vec![],
            )
        }
    }
}

/// The declared diameter against the data's estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct DiameterCheck {
    pub declared_mm: f64,
    pub estimate_mm: f64,
    pub sigma_mm: f64,
    pub disagrees: bool,
}

impl DiameterCheck {
    /// The warning of a disagreement.
    pub fn message(&self) -> String {
        format!(
            "the sphere's declared diameter {:.4} mm disagrees with the profiles: they say \
             {:.4} +- {:.4} mm ({:+.4} mm, {:.1} sigma); check rig.json's artefact.diameter_mm \
             (or set it to null to estimate it)",
            self.declared_mm,
            self.estimate_mm,
            self.sigma_mm,
            self.estimate_mm - self.declared_mm,
            (self.estimate_mm - self.declared_mm).abs() / self.sigma_mm.max(1e-300)
        )
    }
}

/// The start at a fit's values.
pub(super) fn start_at(fit: &ProfileFit, diameter_free: bool) -> ProfileStart {
    ProfileStart {
        hand_sensor: fit.hand_sensor,
        centre: fit.centre,
        diameter: fit.diameter,
        diameter_free,
    }
}

/// The views with the fit's selection as their points to keep, every `step`-th, their
/// flange poses the fit's (the robot held at the refined one).
pub(super) fn held(obs: &[ProfileViewObs], fit: &ProfileFit, step: usize) -> Vec<ProfileViewObs> {
    obs.iter()
        .zip(&fit.selected)
        .zip(&fit.flanges)
        .map(|((o, s), a)| ProfileViewObs {
            a: *a,
            arc: s.iter().step_by(step).copied().collect(),
            q: None,
            ..o.clone()
        })
        .collect()
}

/// The options of a solve over fixed points with the robot held (its poses the fit's).
pub(super) fn kept_only(popts: &ProfileOptions) -> ProfileOptions {
    ProfileOptions {
        robot: None,
        keep_selection: true,
        ..popts.clone()
    }
}

/// The views kept, and `(views.csv row, note)` of those left out.
type Kept = (Vec<ProfileViewObs>, Vec<(usize, String)>);

/// Views whose fit keeps less than [`MIN_KEPT_SHARE`] of their arc's points, or whose
/// sphere points lie [`POOR_RMS_FACTOR`] times farther from the sphere than the views'
/// median, worst first, left out and the adjustment re-run, while more than
/// [`MIN_VIEWS`] remain.
pub(super) fn poor_views(
    mut obs: Vec<ProfileViewObs>,
    fit: &mut ProfileFit,
    start: &ProfileStart,
    popts: &ProfileOptions,
) -> Result<Kept> {
    let mut left = Vec::new();
    loop {
        let mut rms = fit.view_rms_mm.clone();
        rms.sort_by(f64::total_cmp);
        let med = rms.get(rms.len() / 2).copied().unwrap_or(0.0).max(1e-300);
        // how far each view is beyond either limit (> 1: beyond)
        let severity: Vec<(f64, String)> = obs
            .iter()
            .zip(&fit.selected)
            .zip(&fit.view_rms_mm)
            .map(|((o, s), r)| {
                let share = s.len() as f64 / o.arc.len().max(1) as f64;
                let by_share = MIN_KEPT_SHARE / share.max(1e-300);
                let by_rms = r / (POOR_RMS_FACTOR * med);
                if by_share >= by_rms {
                    (
                        by_share,
                        format!(
                            "only {:.0} % of its arc's points lie on the sphere its robot pose \
                             predicts",
                            100.0 * share
                        ),
                    )
                } else {
                    (
                        by_rms,
                        format!(
                            "its points lie {r:.4} mm (RMS) from the sphere its robot pose \
                             predicts, the other views' {med:.4} mm (median)"
                        ),
                    )
                }
            })
            .collect();
        let Some((k, (worst, why))) = severity
            .into_iter()
            .enumerate()
            .max_by(|a, b| a.1 .0.total_cmp(&b.1 .0))
        else {
            break;
        };
        if worst <= 1.0 || obs.len() <= MIN_VIEWS {
            break;
        }
        let o = obs.remove(k);
        left.push((
            o.view,
            format!(
                "view {}: {why} (its profile does not fit: a pose paired with the wrong \
                 profile?); left out",
                o.view
            ),
        ));
        *fit = profile_adjustment(&obs, start, popts)?;
    }
    Ok((obs, left))
}

/// The sphere's centre as the sensor saw it in each view.
pub(super) fn centres_in_sensor(fit: &ProfileFit) -> Vec<Vector3<f64>> {
    fit.flanges
        .iter()
        .map(|a| ((a * fit.hand_sensor).inverse() * Point3::from(fit.centre)).coords)
        .collect()
}

/// The proper rigid motion `F` (sensor frame) that best maps the mirrored centres `D p_i`
/// (`D = diag(1, -1, 1)`: every side flipped) onto `p_i` (Kabsch, determinant +1): `X F`
/// is the mirrored hand-eye.
fn mirror_motion(p: &[Vector3<f64>]) -> crate::model::geometry::Iso3 {
    let q: Vec<Vector3<f64>> = p.iter().map(|v| Vector3::new(v.x, -v.y, v.z)).collect();
    let n = p.len().max(1) as f64;
    let (mp, mq) = (
        p.iter().sum::<Vector3<f64>>() / n,
        q.iter().sum::<Vector3<f64>>() / n,
    );
    let h: Matrix3<f64> = q
        .iter()
        .zip(p)
        .map(|(a, b)| (a - mq) * (b - mp).transpose())
        .sum();
    // Kabsch: with H = U S V^T, R = V diag(1, 1, det) U^T, the rotation nearest H^T
    let r = nearest_rotation(&h.transpose());
    crate::model::geometry::iso_from_parts(&r, &(mp - r * mq))
}

/// How far two solutions put the sphere on the same sides of the profile planes:
/// `sum s_a s_b |y_a| / sum |y_a|` over the views (+1 the same sides, -1 every side
/// flipped: the mirror image).
fn side_agreement(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    let den: f64 = a.iter().map(|p| p.y.abs()).sum();
    let num: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| p.y.signum() * q.y.signum() * p.y.abs())
        .sum();
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

fn spread(p: &[Vector3<f64>]) -> [f64; 4] {
    let n = p.len().max(1) as f64;
    let mean = p.iter().sum::<Vector3<f64>>() / n;
    let cov = p
        .iter()
        .map(|x| (x - mean) * (x - mean).transpose())
        .sum::<Matrix3<f64>>()
        / n;
    let e = SymmetricEigen::new(cov);
    let least = e.eigenvalues.min().max(0.0).sqrt();
    [
        cov[(0, 0)].sqrt(),
        cov[(1, 1)].sqrt(),
        cov[(2, 2)].sqrt(),
        least,
    ]
}

/// The mirror test (module docs) of `fit` against the mirrored start.
pub(super) fn mirror(
    obs: &[ProfileViewObs],
    fit: &ProfileFit,
    mirror_start: &ProfileStart,
    popts: &ProfileOptions,
) -> Result<MirrorTest> {
    let step = fit.points_used().div_ceil(MIRROR_POINTS).max(1);
    let sub = held(obs, fit, step);
    let o = kept_only(popts);
    let chosen = profile_adjustment(&sub, &start_at(fit, mirror_start.diameter_free), &o)?;
    let centres = centres_in_sensor(fit);
    // Two starts of the mirror: the closed form with every side flipped, and the chosen
    // solution moved by the proper motion that best maps the mirrored centres onto the
    // chosen ones (exact when they are coplanar: then the mirror fits exactly as well).
    let kabsch = ProfileStart {
        hand_sensor: fit.hand_sensor * mirror_motion(&centres),
        ..start_at(fit, mirror_start.diameter_free)
    };
    let ssr_m = [mirror_start, &kabsch]
        .into_iter()
        .filter_map(|st| match profile_adjustment(&sub, st, &o) {
            // A start whose adjustment flips the sides back (to the chosen solution)
            // found no mirror minimum; one that cannot be solved does not fit.
            Ok(m) if side_agreement(&centres, &centres_in_sensor(&m)) < 0.0 => Some(m.ssr),
            _ => None,
        })
        .fold(f64::INFINITY, f64::min);
    // the residuals' variance, with the views' shared pose errors (the view-clustered
    // factor): a chi-square in units of what the data can tell apart
    let s2 = (fit.sigma_mm * fit.sigma_mm * fit.view_variance_factor).max(1e-300);
    let delta = (ssr_m - chosen.ssr) / s2 * step as f64;
    Ok(MirrorTest {
        ssr_chosen_mm2: chosen.ssr * step as f64,
        ssr_mirror_mm2: ssr_m * step as f64,
        delta_chi2: delta,
        spread_mm: spread(&centres),
        passed: delta > MIRROR_CHI2,
    })
}

/// The declared diameter against the estimate with the diameter freed (the fit's
/// points, the robot held at the fit's).
pub(super) fn diameter(
    obs: &[ProfileViewObs],
    fit: &ProfileFit,
    declared: f64,
    popts: &ProfileOptions,
) -> Result<DiameterCheck> {
    let free = profile_adjustment(&held(obs, fit, 1), &start_at(fit, true), &kept_only(popts))?;
    let sigma = free
        .covariance
        .sigma("sphere.diameter_mm")
        .unwrap_or(f64::NAN);
    let d = free.diameter - declared;
    Ok(DiameterCheck {
        declared_mm: declared,
        estimate_mm: free.diameter,
        sigma_mm: sigma,
        disagrees: d.abs() > 3.0 * sigma && d.abs() > DIAMETER_TOLERANCE * declared,
    })
}

/// The `views` check: which views were left out and why (passes while enough remain).
pub(super) fn views_check(status: &[super::ProfileViewStatus], used: usize) -> QualityCheck {
    let out: Vec<usize> = status
        .iter()
        .filter(|s| s.note.is_some())
        .map(|s| s.view)
        .collect();
    let msg = if out.is_empty() {
        format!("all {used} profiles used")
    } else {
        format!(
            "{used} profiles used; left out (named in the views): {}",
            out.iter()
                .map(|v| v.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    QualityCheck {
        name: "views".into(),
        passed: used >= MIN_VIEWS,
        message: msg,
        views: out,
    }
}

/// The `determined` gate: every estimated number has a finite, positive sigma.
pub(super) fn determined(fit: &ProfileFit) -> QualityCheck {
    let bad: Vec<&String> = fit
        .covariance
        .parameters
        .iter()
        .enumerate()
        .filter(|(i, _)| {
            let v = fit.covariance.matrix[(*i, *i)];
            !(v.is_finite() && v > 0.0)
        })
        .map(|(_, n)| n)
        .collect();
    if bad.is_empty() {
        QualityCheck::pass(
            "determined",
            format!(
                "every one of the {} estimated numbers has a finite sigma",
                fit.covariance.parameters.len()
            ),
        )
    } else {
        QualityCheck::fail(
            "determined",
            format!(
                "not determined by these profiles: {}",
                bad.iter()
                    .map(|s| s.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            vec![],
        )
    }
}

/// The `converged` gate.
pub(super) fn converged(fit: &ProfileFit) -> QualityCheck {
    if fit.converged {
        QualityCheck::pass(
            "converged",
            format!("the adjustment converged in {} iterations", fit.iterations),
        )
    } else {
        QualityCheck::fail(
            "converged",
            format!(
                "the adjustment did not converge in {} iterations",
                fit.iterations
            ),
            vec![],
        )
    }
}
