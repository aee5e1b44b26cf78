//! A profiler's one-stage adjustment: `X = T_hand_sensor`, the sphere's centre `c` in
//! the base frame, its diameter `D` (when not declared) and the robot's DH corrections,
//! over every sphere point of every profile, in the adjustment's parameter layout
//! ([`super::layout::ParamLayout::profiler`]) and solver.
//!
//! ## Residuals
//!
//! A profile point `p = (x, 0, z)` of view i is at `P = A_i (R_X p + t_X)` in the base
//! frame; its residual is its distance from the sphere, `e = |P - c| - D / 2` (mm). The
//! problem, its Jacobian rows and its normal equations (formed view by view without
//! storing the Jacobian): [`super::profile_problem`].
//!
//! ## Points on the sphere
//!
//! A profile also shows the table, the stand and spikes. The adjustment starts from the
//! points of each profile's arc ([`crate::calib::profile::arc`]) (from the closed-form
//! start over every k-th of them only, at most [`COARSE_POINTS`]: a minimum within
//! about two sigmas of the full one for a fraction of the work) and, after each step,
//! takes the points of the profile near the sphere, until the selection settles; the
//! rest are counted per view as rejected. From that first minimum the selection
//! settles over ONE linearisation of the problem (normal equations formed once, a
//! Gauss-Newton step per re-selection, the points that join or leave added to them;
//! [`super::profile_rounds`], with its test of the quadratic model), or, when that test
//! fails, by iterated solves. A refit over kept points from near its minimum (the
//! checks', the leave-one-out's) takes one such step the same way. Near: within [`BAND_SIGMAS`] robust sigmas
//! (`1.4826 MAD`, at least [`MIN_BAND_MM`]) of the view's own median residual, the
//! view's sigma from its own points, capped by the band of all points used (a view whose
//! robot pose is off by a little sits off the sphere as a whole, its points still on a
//! sphere).
//!
//! ## Stopping
//!
//! A solve stops when the next step promises less than `1e-5 / m` of the cost (`m`
//! points): a step of `a` sigmas lowers the cost `m s^2 / 2` by about `a^2 s^2 / 2`, so
//! the solve stops within 0.003 sigma of the minimum, and a solve after a
//! re-selection that moved the minimum by less than that takes no step at all. The
//! rounds over one linearisation hold to the same tolerance (their module docs).
//!
//! ## Uncertainty
//!
//! `k s^2 (J^T J)^-1`, `s^2 = SSR / (m - n)` over the points used, mapped to the file's
//! names (`hand_cam.rotation_vector[k]` through the inverse right Jacobian,
//! `sphere.center_mm[k]`, `sphere.diameter_mm`, the DH corrections'), as the camera's.
//!
//! `k` is the view-clustered variance factor: a profile's thousands of points share its
//! robot pose, so a pose error (a robot that is off by a little, as every real robot is)
//! moves them together and does not average out over them. The cluster-robust
//! (sandwich) covariance with the views as clusters, `G/(G-1) N^-1 (sum_v g_v g_v^T)
//! N^-1` (`g_v = sum_{i in v} J_i^T r_i`, `N = J^T J`), is compared with the i.i.d. one
//! parameter by parameter; `k` is the median of the ratios, at least 1 (1 when the
//! residuals are independent noise, large when the views' poses are off). One factor
//! keeps the i.i.d. covariance's correlations.

use nalgebra::{DVector, Vector3};

use super::covariance::named_covariance;
use super::layout::{Block, ParamLayout, SphereStart};
use super::profile_problem::{all_residuals, ProfileProblem, Terms};
use super::profile_rounds::settle;
use super::robot::{candidates, RobotBlock, RobotMode};
use super::robot_select::{information, select};
use super::robot_solve::{report, RobotOptions, RobotOutcome};
use crate::error::{Error, Result};
use crate::model::geometry::Iso3;
use crate::model::{NamedCovariance, RobotCalibration};
use crate::numerics::lm::{levenberg_marquardt, LmOptions, LmResult, StopReason};

pub use crate::calib::profile::arc::{BAND_SIGMAS, MIN_BAND_MM};

/// Points of the first solve from the closed-form start at most (every k-th of the
/// arcs'; module docs).
const COARSE_POINTS: usize = 3000;
/// Rounds of the point selection at most.
const SELECTION_ROUNDS: usize = 5;
/// Rounds of `auto`'s robot selection at most.
const ROBOT_ROUNDS: usize = 4;

/// One profile in the adjustment.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileViewObs {
    /// Its row in views.csv (0-based).
    pub view: usize,
    /// `T_base_hand` from the reading (nominal robot or the flange pose).
    pub a: Iso3,
    /// Joint readings, when the view has them.
    pub q: Option<Vec<f64>>,
    /// Every point of the profile `(x, z)`, mm.
    pub points: Vec<[f64; 2]>,
    /// The points first taken as the sphere's (the arc's).
    pub arc: Vec<usize>,
}

/// What the adjustment starts from and estimates.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileStart {
    pub hand_sensor: Iso3,
    pub centre: Vector3<f64>,
    pub diameter: f64,
    /// Estimate the diameter (rig.json's `diameter_mm: null`).
    pub diameter_free: bool,
}

/// Options of [`profile_adjustment`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ProfileOptions {
    /// The robot's DH corrections (`None` or `fixed`: the DH table is exact).
    pub robot: Option<RobotOptions>,
    /// Keep each view's selection of points as given (no re-selection): for the
    /// leave-one-out refits and the mirror test.
    pub keep_selection: bool,
    pub lm: LmOptions,
}

/// The adjustment's result.
#[derive(Debug, Clone)]
pub struct ProfileFit {
    pub hand_sensor: Iso3,
    pub centre: Vector3<f64>,
    pub diameter: f64,
    /// The robot's calibration (`None`: not calibrated).
    pub robot: Option<RobotCalibration>,
    /// The corrected robot's flange poses of the views (the readings' `a` without a
    /// robot block).
    pub flanges: Vec<Iso3>,
    pub covariance: NamedCovariance,
    /// The a-posteriori sigma of a point's distance from the sphere, mm.
    pub sigma_mm: f64,
    /// The view-clustered variance factor the covariance carries (>= 1; module docs).
    pub view_variance_factor: f64,
    /// Sum of squared residuals of the points used, mm^2.
    pub ssr: f64,
    /// Per view: the points used (indices into its `points`).
    pub selected: Vec<Vec<usize>>,
    /// Per view: RMS distance of its points used, mm.
    pub view_rms_mm: Vec<f64>,
    pub iterations: usize,
    pub converged: bool,
}

impl ProfileFit {
    /// RMS distance of all points used from the sphere, mm.
    pub fn rms_mm(&self) -> f64 {
        let n: usize = self.selected.iter().map(|s| s.len()).sum();
        (self.ssr / n.max(1) as f64).sqrt()
    }
    /// Points used.
    pub fn points_used(&self) -> usize {
        self.selected.iter().map(|s| s.len()).sum()
    }
}

/// The relative cost decrease a step must promise for a solve over `m` points to go
/// on (module docs, "Stopping"): a step of `a` sigmas along any direction lowers the
/// cost `m s^2 / 2` by about `a^2 s^2 / 2`, so `1e-5 / m` stops within 0.003 sigma
/// (`sqrt(1e-5)`) of the minimum.
pub(super) fn stop_ftol(m: usize, lm: &LmOptions) -> f64 {
    lm.ftol.max(1e-5 / m.max(1) as f64)
}

/// One solve over the points `selected`: the LM result and the per-view gradients
/// `g_v = J_v^T r_v` at its parameters (the variance factor's; from the solver's last
/// normal equations, which it formed there).
fn solve(
    layout: &ParamLayout,
    p0: &[f64],
    views: &[ProfileViewObs],
    a: &[Iso3],
    selected: &[Vec<usize>],
    lm: &LmOptions,
) -> Result<(LmResult, Vec<DVector<f64>>)> {
    let terms = Terms::of(views, selected, a);
    if terms.len() <= layout.num_params() {
        return Err(Error::Degenerate(format!(
            "{} sphere points for {} unknowns",
            terms.len(),
            layout.num_params()
        )));
    }
    let prob = ProfileProblem::new(layout, &terms);
    let lm = LmOptions {
        ftol: stop_ftol(terms.len(), lm),
        ..lm.clone()
    };
    let res = levenberg_marquardt(&prob, p0, &lm)?;
    let gradients = prob.view_gradients_at(&res.params).unwrap_or_else(|| {
        let mut r = vec![0.0; terms.len()];
        prob.view_normals(&res.params, &mut r)
            .into_iter()
            .map(|v| v.g)
            .collect()
    });
    Ok((res, gradients))
}

/// The median of `v` ([`crate::numerics::robust::median`]; 0 when empty).
fn median(mut v: Vec<f64>) -> f64 {
    crate::numerics::robust::median(&mut v).unwrap_or(0.0)
}

/// The points of every view within the band of the sphere (module docs): the global
/// band `5 x 1.4826 MAD` of all points used; within it, each view's points within its own
/// band around its own median residual (a view whose robot pose is off by a little sits
/// off the sphere as a whole: its points are still the sphere's).
pub(super) fn reselect(res: &[Vec<f64>], selected: &[Vec<usize>]) -> Vec<Vec<usize>> {
    let used: Vec<f64> = res
        .iter()
        .zip(selected)
        .flat_map(|(r, s)| s.iter().map(|&i| r[i].abs()))
        .collect();
    if used.is_empty() {
        return selected.to_vec();
    }
    let band = (BAND_SIGMAS * 1.4826 * median(used)).max(MIN_BAND_MM);
    res.iter()
        .zip(selected)
        .map(|(r, s)| {
            let mid = median(s.iter().map(|&i| r[i]).collect());
            let mad = median(s.iter().map(|&i| (r[i] - mid).abs()).collect());
            let own = (BAND_SIGMAS * 1.4826 * mad).clamp(MIN_BAND_MM, band);
            (0..r.len()).filter(|&i| (r[i] - mid).abs() < own).collect()
        })
        .collect()
}

/// The view-clustered variance factor (module docs): the median over the parameters of
/// the cluster-robust variance (views as clusters) over the i.i.d. one, at least 1.
fn view_variance_factor(res: &LmResult, gradients: &[DVector<f64>]) -> f64 {
    let n = res.jtj.nrows();
    let g = gradients.len();
    if g < 3 {
        return 1.0;
    }
    let Some(ninv) = res.jtj.clone().try_inverse() else {
        return 1.0;
    };
    let mut b = nalgebra::DMatrix::<f64>::zeros(n, n);
    for gv in gradients {
        b += gv * gv.transpose();
    }
    let robust = &ninv * b * &ninv * (g as f64 / (g - 1) as f64);
    let mut ratios: Vec<f64> = (0..n)
        .filter_map(|k| {
            let s = res.covariance[(k, k)];
            (s.is_finite() && s > 0.0).then(|| robust[(k, k)] / s)
        })
        .collect();
    if ratios.is_empty() {
        return 1.0;
    }
    ratios.sort_by(f64::total_cmp);
    ratios[ratios.len() / 2].max(1.0)
}

/// The profiler's adjustment (module docs) of `views` from `start`.
pub fn profile_adjustment(
    views: &[ProfileViewObs],
    start: &ProfileStart,
    opts: &ProfileOptions,
) -> Result<ProfileFit> {
    adjust(views, start, opts, true)
}

/// [`profile_adjustment`]; `settle_first`: settle the selection over one set of normal
/// equations (`profile_rounds`) when that holds, else (and always when `false`) iterate
/// the solves.
pub(super) fn adjust(
    views: &[ProfileViewObs],
    start: &ProfileStart,
    opts: &ProfileOptions,
    settle_first: bool,
) -> Result<ProfileFit> {
    let ids: Vec<usize> = views.iter().map(|v| v.view).collect();
    let a: Vec<Iso3> = views.iter().map(|v| v.a).collect();
    let sphere = SphereStart {
        centre: start.centre,
        diameter: start.diameter,
        diameter_free: start.diameter_free,
    };
    let layout = ParamLayout::profiler(&start.hand_sensor, true, sphere, &ids, None);
    // a solve after a re-selection starts at the last minimum: Gauss-Newton's step
    let warm = LmOptions {
        initial_lambda: 1e-9,
        ..opts.lm.clone()
    };
    let mut st = fit_selection(views, &a, layout, opts, settle_first, &warm)?;
    // The robot's DH corrections.
    let mut outcome: Option<RobotOutcome> = None;
    if let Some(ro) = opts.robot.as_ref().filter(|r| r.mode != RobotMode::Fixed) {
        outcome = Some(calibrate_robot(&mut st, views, &a, start, opts, ro, &warm)?);
    }
    let Adjusted {
        layout,
        p,
        res,
        grads,
        selected,
        iterations,
    } = st;
    let s = layout.decode(&p);
    let view_factor = view_variance_factor(&res, &grads);
    let covariance = named_covariance(&layout, &p, &s, &(&res.covariance * view_factor), 1.0);
    let robot = outcome
        .as_ref()
        .map(|o| report(o, &layout, &p, &res.covariance));
    let flanges = match &layout.robot {
        Some(rb) => rb.flanges(&p[layout.robot_columns()]),
        None => a.clone(),
    };
    // the last solve's residuals are the selected points', view after view
    let mut k = 0;
    let view_rms_mm = selected
        .iter()
        .map(|s| {
            let r = &res.residuals[k..k + s.len()];
            k += s.len();
            (r.iter().map(|x| x * x).sum::<f64>() / s.len().max(1) as f64).sqrt()
        })
        .collect();
    let converged = !matches!(res.reason, StopReason::MaxIterations);
    Ok(ProfileFit {
        hand_sensor: layout.transform(&p, Block::HandCam),
        centre: layout.sphere_centre(&p),
        diameter: layout.sphere_diameter(&p),
        robot,
        flanges,
        covariance,
        sigma_mm: res.sigma2.sqrt(),
        view_variance_factor: view_factor,
        ssr: res.ssr,
        selected,
        view_rms_mm,
        iterations,
        converged,
    })
}

/// Where a profiler's adjustment is between its phases: the layout, the vector, the
/// last solve's result and per-view gradients, the points selected, the iterations so
/// far.
struct Adjusted {
    layout: ParamLayout,
    p: Vec<f64>,
    res: LmResult,
    grads: Vec<DVector<f64>>,
    selected: Vec<Vec<usize>>,
    iterations: usize,
}

/// The points' selection settled from the closed-form start: first over every k-th
/// point, then re-selected and re-solved (`warm`: a solve from the last minimum),
/// or settled over one set of normal equations when `settle_first`.
fn fit_selection(
    views: &[ProfileViewObs],
    a: &[Iso3],
    layout: ParamLayout,
    opts: &ProfileOptions,
    settle_first: bool,
    warm: &LmOptions,
) -> Result<Adjusted> {
    let mut p = layout.encode();
    let mut selected: Vec<Vec<usize>> = views.iter().map(|v| v.arc.clone()).collect();
    let mut iterations = 0;
    let rounds = if opts.keep_selection {
        1
    } else {
        SELECTION_ROUNDS
    };
    // From the closed-form start, first over every k-th point (module docs, "Points on
    // the sphere"): its minimum is within a few sigmas of the full one, where the
    // selection settles over one set of normal equations (`profile_rounds`).
    let total: usize = selected.iter().map(|s| s.len()).sum();
    let stride = total.div_ceil(COARSE_POINTS);
    let mut settled = None;
    let mut first = &opts.lm;
    if !opts.keep_selection && stride > 1 {
        let coarse: Vec<Vec<usize>> = selected
            .iter()
            .map(|s| s.iter().step_by(stride).copied().collect())
            .collect();
        let (r0, _) = solve(&layout, &p, views, a, &coarse, &opts.lm)?;
        iterations += r0.iterations;
        p = r0.params;
        selected = reselect(&all_residuals(&layout, &p, views, a), &coarse);
        if settle_first {
            settled = settle(&layout, &p, views, a, &selected, rounds, &opts.lm)?;
        }
        first = warm;
    } else if opts.keep_selection && settle_first {
        // a refit from near its minimum (the checks'), its selection kept
        settled = settle(&layout, &p, views, a, &selected, 0, &opts.lm)?;
    }
    let (res, grads) = match settled {
        Some(s) => {
            iterations += s.rounds;
            selected = s.selected;
            p.clone_from(&s.result.params);
            (s.result, s.gradients)
        }
        None => {
            let (mut res, mut grads) = solve(&layout, &p, views, a, &selected, first)?;
            for round in 0..rounds {
                if round > 0 {
                    (res, grads) = solve(&layout, &p, views, a, &selected, warm)?;
                }
                iterations += res.iterations;
                p.clone_from(&res.params);
                if opts.keep_selection {
                    break;
                }
                let next = reselect(&all_residuals(&layout, &p, views, a), &selected);
                // the selection the last solve used stays with its result
                if next == selected || round + 1 == rounds {
                    break;
                }
                selected = next;
            }
            (res, grads)
        }
    };
    Ok(Adjusted {
        layout,
        p,
        res,
        grads,
        selected,
        iterations,
    })
}

/// The robot's DH corrections estimated with the profiler's (`ro`, not fixed): the
/// corrections selected round by round (`--robot auto`) or at once, the last solve
/// over the layout with the robot block.
fn calibrate_robot(
    st: &mut Adjusted,
    views: &[ProfileViewObs],
    a: &[Iso3],
    start: &ProfileStart,
    opts: &ProfileOptions,
    ro: &RobotOptions,
    warm: &LmOptions,
) -> Result<RobotOutcome> {
    let Adjusted {
        layout,
        p,
        res,
        grads,
        selected,
        iterations,
    } = st;
    let ids: Vec<usize> = views.iter().map(|v| v.view).collect();
    let readings: Vec<Vec<f64>> = views
        .iter()
        .map(|v| {
            v.q.clone().ok_or_else(|| {
                Error::InvalidInput(format!(
                    "view {}: robot calibration (--robot {}) needs joint readings; the \
                     view gives a flange pose",
                    v.view,
                    ro.mode.name()
                ))
            })
        })
        .collect::<Result<_>>()?;
    let cands = candidates(&ro.nominal, ro.mode);
    let mut reference = ro.nominal.clone();
    let mut chosen: Vec<usize> = Vec::new();
    let mut fixed = Vec::new();
    let rounds = if ro.mode == RobotMode::Auto {
        ROBOT_ROUNDS
    } else {
        1
    };
    let hs = layout.transform(p, Block::HandCam);
    let sp = |p: &[f64], l: &ParamLayout| SphereStart {
        centre: l.sphere_centre(p),
        diameter: l.sphere_diameter(p),
        diameter_free: start.diameter_free,
    };
    let mut cur = (hs, sp(p, layout));
    for _ in 0..rounds {
        let block = RobotBlock {
            reference: reference.clone(),
            params: cands.clone(),
            readings: readings.clone(),
        };
        let lc = ParamLayout::profiler(&cur.0, true, cur.1, &ids, Some(block));
        let terms = Terms::of(views, selected, a);
        let prob = ProfileProblem::new(&lc, &terms);
        let info = information(&prob, &lc.encode())?;
        let sel = select(&info, &lc, &cands, ro.mode, &chosen)?;
        let added = sel.chosen.len() > chosen.len();
        chosen = sel.chosen;
        fixed = sel.fixed;
        let block = RobotBlock {
            reference: reference.clone(),
            params: chosen.iter().map(|&i| cands[i]).collect(),
            readings: readings.clone(),
        };
        let lk = ParamLayout::profiler(&cur.0, true, cur.1, &ids, Some(block.clone()));
        let pk = lk.encode();
        let (r, _) = solve(&lk, &pk, views, a, selected, &opts.lm)?;
        *iterations += r.iterations;
        cur = (lk.transform(&r.params, Block::HandCam), sp(&r.params, &lk));
        if !opts.keep_selection {
            let flanges = block.flanges(&r.params[lk.robot_columns()]);
            *selected = reselect(&all_residuals(&lk, &r.params, views, &flanges), selected);
        }
        let done = !added || rounds == 1;
        if !done {
            reference = block.corrected(&r.params[lk.robot_columns()]);
        } else {
            *layout = lk;
            *p = r.params;
            (*res, *grads) = solve(layout, p, views, a, selected, warm)?;
            *iterations += res.iterations;
            p.clone_from(&res.params);
            break;
        }
    }
    Ok(RobotOutcome {
        block: layout.robot.clone(),
        nominal: ro.nominal.clone(),
        mode: ro.mode,
        fixed: fixed.into_iter().map(|(i, why)| (cands[i], why)).collect(),
        layout: layout.clone(),
        p: p.clone(),
        weights: [1.0; super::residuals::GROUPS],
    })
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::model::geometry::iso_from_rotvec;
    use crate::model::kinematics::Robot;

    pub(in crate::calib::joint) fn scene(
        robot: Option<&Robot>,
    ) -> (Vec<ProfileViewObs>, Iso3, Vector3<f64>, f64) {
        let x = iso_from_rotvec(
            &Vector3::new(0.2, -2.9, 0.3),
            &Vector3::new(8.0, -4.0, 90.0),
        );
        let c = Vector3::new(500.0, 30.0, 60.0);
        let radius = 40.0;
        let mut views = Vec::new();
        for i in 0..8 {
            let f = i as f64;
            // the sphere's centre as the sensor sees it, and the sensor's orientation
            let ps = Vector3::new(
                12.0 * (f * 1.7).sin(),
                if i % 2 == 0 { 1.0 } else { -1.0 } * (5.0 + 3.5 * f),
                260.0 + 7.0 * f,
            );
            let rot = crate::model::geometry::rotvec_to_matrix(&Vector3::new(
                0.3 * (f * 0.7).sin(),
                0.3 * (f * 1.3).cos(),
                0.6 * f.sin(),
            ));
            let bs = crate::model::geometry::iso_from_parts(&rot, &(c - rot * ps));
            let a = bs * x.inverse();
            let q: Option<Vec<f64>> = robot.map(|_| {
                vec![
                    10.0 * f.sin(),
                    -20.0 + 3.0 * f,
                    15.0,
                    5.0 * f.cos(),
                    -60.0 + f,
                    7.0 * f,
                ]
            });
            let a = match (robot, &q) {
                (Some(r), Some(q)) => r.forward(q).unwrap(),
                _ => a,
            };
            // points of the circle where the sensor's y = 0 plane meets the sphere
            let bs = a * x;
            let ci = bs.inverse() * nalgebra::Point3::from(c);
            let r = (radius * radius - ci.y * ci.y).max(0.0).sqrt();
            let points: Vec<[f64; 2]> = (0..200)
                .map(|k| {
                    let t = -1.2 + 2.4 * k as f64 / 199.0;
                    [ci.x + r * t.sin(), ci.z - r * t.cos()]
                })
                .collect();
            let arc = (0..points.len()).collect();
            views.push(ProfileViewObs {
                view: i,
                a,
                q,
                points,
                arc,
            });
        }
        (views, x, c, 2.0 * radius)
    }

    /// From a perturbed start the exact profiles give back X, the centre and the
    /// diameter.
    #[test]
    fn recovers_exact_geometry() {
        let (views, x, c, d) = scene(None);
        let start = ProfileStart {
            hand_sensor: x * iso_from_rotvec(
                &Vector3::new(0.01, -0.02, 0.01),
                &Vector3::new(1.0, -1.0, 2.0),
            ),
            centre: c + Vector3::new(1.0, 2.0, -1.0),
            diameter: d + 0.5,
            diameter_free: true,
        };
        let fit = profile_adjustment(&views, &start, &ProfileOptions::default()).unwrap();
        let e = fit.hand_sensor.inverse() * x;
        assert!(e.translation.vector.norm() < 1e-7, "{e:?}");
        assert!(e.rotation.angle() < 1e-9);
        assert!((fit.centre - c).norm() < 1e-7);
        assert!((fit.diameter - d).abs() < 1e-7);
        assert!(fit.rms_mm() < 1e-8);
        assert!(fit.covariance.index("sphere.diameter_mm").is_some());
        assert!(fit
            .covariance
            .index("hand_cam.rotation_vector[2]")
            .is_some());
    }
}
