//! A profiler's one-stage adjustment: `X = T_hand_sensor`, the sphere's centre `c` in
//! the base frame, its diameter `D` (when not declared) and the robot's DH corrections,
//! over every sphere point of every profile, in the adjustment's parameter layout
//! ([`super::layout::ParamLayout::profiler`]) and solver.
//!
//! ## Residuals
//!
//! A profile point `p = (x, 0, z)` of view i is at `P = A_i (R_X p + t_X)` in the base
//! frame; its residual is its distance from the sphere, `e = |P - c| - D / 2` (mm). With
//! `u = (P - c) / |P - c|`, `u_f = R_Ai^T u` (flange frame) and `q = R_X p + t_X`:
//!
//! ```text
//! de/dw_X = p x (R_X^T u_f)      (X's increment R_X Exp(w))
//! de/dt_X = u_f
//! de/dc   = -u,   de/dD = -1/2
//! de/dk   = w_k . (q x u_f) + v_k . u_f   (DH correction k: the flange's own
//!                                          perturbation (w_k, v_k), super::robot)
//! ```
//!
//! checked against central differences in the tests.
//!
//! ## Points on the sphere
//!
//! A profile also shows the table, the stand and spikes. The adjustment starts from the
//! points of each profile's arc ([`crate::calib::profile::arc`]) and, after each solve,
//! takes the points of the profile near the sphere, until the selection settles; the
//! rest are counted per view as rejected. Near: within [`BAND_SIGMAS`] robust sigmas
//! (`1.4826 MAD`, at least [`MIN_BAND_MM`]) of the view's own median residual, the
//! view's sigma from its own points, capped by the band of all points used (a view whose
//! robot pose is off by a little sits off the sphere as a whole, its points still on a
//! sphere).
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

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::covariance::named_covariance;
use super::layout::{Block, ParamLayout, SphereStart};
use super::robot::{candidates, RobotBlock, RobotMode};
use super::robot_select::{information, select};
use super::robot_solve::{report, RobotOptions, RobotOutcome};
use crate::error::{Error, Result};
use crate::model::geometry::Iso3;
use crate::model::{NamedCovariance, RobotCalibration};
use crate::numerics::lm::{
    dense_jacobian_from_rows, levenberg_marquardt, JacobianRows, LeastSquares, LmOptions,
    StopReason,
};

pub use crate::calib::profile::arc::{BAND_SIGMAS, MIN_BAND_MM};

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

/// The residual rows of the points used.
struct Terms {
    /// `(view index, x, z)` per point.
    points: Vec<(usize, f64, f64)>,
    a: Vec<Iso3>,
}

impl Terms {
    /// The points `selected` (per view, indices into its points) of `views`, their
    /// flange poses `a`.
    fn of(views: &[ProfileViewObs], selected: &[Vec<usize>], a: &[Iso3]) -> Terms {
        Terms {
            points: views
                .iter()
                .zip(selected)
                .enumerate()
                .flat_map(|(v, (o, sel))| {
                    sel.iter()
                        .map(move |&i| (v, o.points[i][0], o.points[i][1]))
                })
                .collect(),
            a: a.to_vec(),
        }
    }
}

struct ProfileProblem<'a> {
    layout: &'a ParamLayout,
    terms: &'a Terms,
}

/// What every point of a view shares at a parameter vector.
struct ViewState {
    ra: Matrix3<f64>,
    ta: Vector3<f64>,
    /// The flange perturbation per DH correction.
    twists: Vec<[f64; 6]>,
}

/// What every point shares at a parameter vector: `X`'s rotation and translation, the
/// sphere's centre and radius, every view's flange pose.
struct State {
    rx: Matrix3<f64>,
    tx: Vector3<f64>,
    c: Vector3<f64>,
    rho: f64,
    views: Vec<ViewState>,
}

impl ProfileProblem<'_> {
    fn state(&self, p: &[f64]) -> State {
        let x = self.layout.transform(p, Block::HandCam);
        State {
            rx: x.rotation.to_rotation_matrix().into_inner(),
            tx: x.translation.vector,
            c: self.layout.sphere_centre(p),
            rho: 0.5 * self.layout.sphere_diameter(p),
            views: self.views(p),
        }
    }

    fn views(&self, p: &[f64]) -> Vec<ViewState> {
        let (flanges, twists) = match &self.layout.robot {
            Some(rb) => {
                let v = &p[self.layout.robot_columns()];
                (rb.flanges(v), rb.flange_jacobians(v, &[]))
            }
            None => (self.terms.a.clone(), vec![Vec::new(); self.terms.a.len()]),
        };
        flanges
            .iter()
            .zip(twists)
            .map(|(a, twists)| ViewState {
                ra: a.rotation.to_rotation_matrix().into_inner(),
                ta: a.translation.vector,
                twists,
            })
            .collect()
    }
}

impl LeastSquares for ProfileProblem<'_> {
    fn num_params(&self) -> usize {
        self.layout.num_params()
    }
    fn num_residuals(&self) -> usize {
        self.terms.points.len()
    }
    fn residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
        let State {
            rx,
            tx,
            c,
            rho,
            views,
        } = self.state(p);
        r.par_iter_mut()
            .zip(self.terms.points.par_iter())
            .for_each(|(out, &(v, px, pz))| {
                let s = &views[v];
                let q = rx * Vector3::new(px, 0.0, pz) + tx;
                *out = (s.ra * q + s.ta - c).norm() - rho;
            });
        Ok(())
    }
    fn residuals_and_jacobian(
        &self,
        p: &[f64],
        r: &mut [f64],
        jac: faer::MatMut<'_, f64>,
    ) -> Result<()> {
        dense_jacobian_from_rows(self, p, r, jac)
    }
    fn jacobian_row_width(&self) -> Option<usize> {
        Some(self.layout.num_params())
    }
    fn residuals_and_jacobian_rows(
        &self,
        p: &[f64],
        r: &mut [f64],
        rows: &mut JacobianRows,
    ) -> Result<()> {
        let n = self.layout.num_params();
        let State {
            rx,
            tx,
            c,
            rho,
            views,
        } = self.state(p);
        let cx = self.layout.column(self.layout.slots(Block::HandCam).start);
        let cc = self.layout.slotless_columns(Block::SphereCentre);
        let cd = self.layout.slotless_columns(Block::SphereDiameter);
        let cr = self.layout.robot_columns();
        let (_, vals) = rows.parts_mut();
        r.par_iter_mut()
            .zip(vals.par_chunks_mut(n))
            .zip(self.terms.points.par_iter())
            .for_each(|((out, row), &(v, px, pz))| {
                let s = &views[v];
                let pp = Vector3::new(px, 0.0, pz);
                let q = rx * pp + tx;
                let d = s.ra * q + s.ta - c;
                let len = d.norm().max(1e-300);
                *out = len - rho;
                let u = d / len;
                let uf = s.ra.transpose() * u;
                if let Some(c0) = cx {
                    let gw = pp.cross(&(rx.transpose() * uf));
                    row[c0..c0 + 3].copy_from_slice(gw.as_slice());
                    row[c0 + 3..c0 + 6].copy_from_slice(uf.as_slice());
                }
                for (k, col) in cc.clone().enumerate() {
                    row[col] = -u[k];
                }
                for col in cd.clone() {
                    row[col] = -0.5;
                }
                let qu = q.cross(&uf);
                for (col, t) in cr.clone().zip(&s.twists) {
                    row[col] = t[0] * qu.x
                        + t[1] * qu.y
                        + t[2] * qu.z
                        + t[3] * uf.x
                        + t[4] * uf.y
                        + t[5] * uf.z;
                }
            });
        Ok(())
    }
    fn retract(&self, p: &[f64], dp: &[f64], out: &mut [f64]) {
        self.layout.retract(p, dp, out);
    }
}

/// Every point's distance from the sphere of `p` (per view, all its points).
fn all_residuals(
    layout: &ParamLayout,
    p: &[f64],
    views: &[ProfileViewObs],
    a: &[Iso3],
) -> Result<Vec<Vec<f64>>> {
    let terms = Terms {
        points: views
            .iter()
            .enumerate()
            .flat_map(|(v, o)| o.points.iter().map(move |q| (v, q[0], q[1])))
            .collect(),
        a: a.to_vec(),
    };
    let prob = ProfileProblem {
        layout,
        terms: &terms,
    };
    let mut r = vec![0.0; terms.points.len()];
    prob.residuals(p, &mut r)?;
    let mut out = Vec::with_capacity(views.len());
    let mut k = 0;
    for o in views {
        out.push(r[k..k + o.points.len()].to_vec());
        k += o.points.len();
    }
    Ok(out)
}

/// One solve over the points `selected`; the parameters and the LM result.
fn solve(
    layout: &ParamLayout,
    p0: &[f64],
    views: &[ProfileViewObs],
    a: &[Iso3],
    selected: &[Vec<usize>],
    lm: &LmOptions,
) -> Result<crate::numerics::lm::LmResult> {
    let terms = Terms::of(views, selected, a);
    if terms.points.len() <= layout.num_params() {
        return Err(Error::Degenerate(format!(
            "{} sphere points for {} unknowns",
            terms.points.len(),
            layout.num_params()
        )));
    }
    let prob = ProfileProblem {
        layout,
        terms: &terms,
    };
    levenberg_marquardt(&prob, p0, lm)
}

/// The median of `v` (0 when empty).
fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The points of every view within the band of the sphere (module docs): the global
/// band `5 x 1.4826 MAD` of all points used; within it, each view's points within its own
/// band around its own median residual (a view whose robot pose is off by a little sits
/// off the sphere as a whole: its points are still the sphere's).
fn reselect(res: &[Vec<f64>], selected: &[Vec<usize>]) -> Vec<Vec<usize>> {
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
fn view_variance_factor(
    layout: &ParamLayout,
    p: &[f64],
    views: &[ProfileViewObs],
    flanges: &[Iso3],
    selected: &[Vec<usize>],
    res: &crate::numerics::lm::LmResult,
) -> Result<f64> {
    let n = layout.num_params();
    let g = views.len();
    if g < 3 {
        return Ok(1.0);
    }
    let Some(ninv) = res.jtj.clone().try_inverse() else {
        return Ok(1.0);
    };
    // the layout's flanges come from its robot block: rows at the fit's poses
    let terms = Terms::of(views, selected, flanges);
    let prob = ProfileProblem {
        layout,
        terms: &terms,
    };
    let m = terms.points.len();
    let mut r = vec![0.0; m];
    let mut rows = JacobianRows::new(m, n, n);
    prob.residuals_and_jacobian_rows(p, &mut r, &mut rows)?;
    let mut b = nalgebra::DMatrix::<f64>::zeros(n, n);
    let mut gv = nalgebra::DVector::<f64>::zeros(n);
    let mut cur = usize::MAX;
    for (i, &(v, _, _)) in terms.points.iter().enumerate() {
        if v != cur {
            if cur != usize::MAX {
                b += &gv * gv.transpose();
            }
            gv.fill(0.0);
            cur = v;
        }
        let (_, vals) = rows.row(i);
        for (k, x) in vals.iter().enumerate() {
            gv[k] += x * r[i];
        }
    }
    b += &gv * gv.transpose();
    let robust = &ninv * b * &ninv * (g as f64 / (g - 1) as f64);
    let mut ratios: Vec<f64> = (0..n)
        .filter_map(|k| {
            let s = res.covariance[(k, k)];
            (s.is_finite() && s > 0.0).then(|| robust[(k, k)] / s)
        })
        .collect();
    if ratios.is_empty() {
        return Ok(1.0);
    }
    ratios.sort_by(f64::total_cmp);
    Ok(ratios[ratios.len() / 2].max(1.0))
}

/// The profiler's adjustment (module docs) of `views` from `start`.
pub fn profile_adjustment(
    views: &[ProfileViewObs],
    start: &ProfileStart,
    opts: &ProfileOptions,
) -> Result<ProfileFit> {
    let ids: Vec<usize> = views.iter().map(|v| v.view).collect();
    let a: Vec<Iso3> = views.iter().map(|v| v.a).collect();
    let sphere = SphereStart {
        centre: start.centre,
        diameter: start.diameter,
        diameter_free: start.diameter_free,
    };
    let mut layout = ParamLayout::profiler(&start.hand_sensor, true, sphere, &ids, None);
    let mut p = layout.encode();
    let mut selected: Vec<Vec<usize>> = views.iter().map(|v| v.arc.clone()).collect();
    let mut iterations = 0;
    let rounds = if opts.keep_selection {
        1
    } else {
        SELECTION_ROUNDS
    };
    let mut res = solve(&layout, &p, views, &a, &selected, &opts.lm)?;
    for round in 0..rounds {
        if round > 0 {
            res = solve(&layout, &p, views, &a, &selected, &opts.lm)?;
        }
        iterations += res.iterations;
        p.clone_from(&res.params);
        if opts.keep_selection {
            break;
        }
        let next = reselect(&all_residuals(&layout, &p, views, &a)?, &selected);
        if next == selected {
            break;
        }
        selected = next;
    }
    // The robot's DH corrections.
    let mut outcome: Option<RobotOutcome> = None;
    if let Some(ro) = opts.robot.as_ref().filter(|r| r.mode != RobotMode::Fixed) {
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
        let hs = layout.transform(&p, Block::HandCam);
        let sp = |p: &[f64], l: &ParamLayout| SphereStart {
            centre: l.sphere_centre(p),
            diameter: l.sphere_diameter(p),
            diameter_free: start.diameter_free,
        };
        let mut cur = (hs, sp(&p, &layout));
        for _ in 0..rounds {
            let block = RobotBlock {
                reference: reference.clone(),
                params: cands.clone(),
                readings: readings.clone(),
            };
            let lc = ParamLayout::profiler(&cur.0, true, cur.1, &ids, Some(block));
            let terms = Terms::of(views, &selected, &a);
            let prob = ProfileProblem {
                layout: &lc,
                terms: &terms,
            };
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
            let r = solve(&lk, &pk, views, &a, &selected, &opts.lm)?;
            iterations += r.iterations;
            cur = (lk.transform(&r.params, Block::HandCam), sp(&r.params, &lk));
            if !opts.keep_selection {
                let flanges = block.flanges(&r.params[lk.robot_columns()]);
                selected = reselect(&all_residuals(&lk, &r.params, views, &flanges)?, &selected);
            }
            let done = !added || rounds == 1;
            if !done {
                reference = block.corrected(&r.params[lk.robot_columns()]);
            } else {
                layout = lk;
                p = r.params;
                res = solve(&layout, &p, views, &a, &selected, &opts.lm)?;
                iterations += res.iterations;
                p.clone_from(&res.params);
                break;
            }
        }
        outcome = Some(RobotOutcome {
            block: layout.robot.clone(),
            nominal: ro.nominal.clone(),
            mode: ro.mode,
            fixed: fixed.into_iter().map(|(i, why)| (cands[i], why)).collect(),
            layout: layout.clone(),
            p: p.clone(),
            weights: (1.0, 1.0),
        });
    }
    let s = layout.decode(&p);
    let flanges_now = match &layout.robot {
        Some(rb) => rb.flanges(&p[layout.robot_columns()]),
        None => a.clone(),
    };
    let view_factor = view_variance_factor(&layout, &p, views, &flanges_now, &selected, &res)?;
    let covariance = named_covariance(&layout, &p, &s, &(&res.covariance * view_factor), 1.0);
    let robot = outcome
        .as_ref()
        .map(|o| report(o, &layout, &p, &res.covariance));
    let flanges = match &layout.robot {
        Some(rb) => rb.flanges(&p[layout.robot_columns()]),
        None => a.clone(),
    };
    let all = all_residuals(&layout, &p, views, &flanges)?;
    let view_rms_mm = all
        .iter()
        .zip(&selected)
        .map(|(r, s)| {
            let ss: f64 = s.iter().map(|&i| r[i] * r[i]).sum();
            (ss / s.len().max(1) as f64).sqrt()
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geometry::iso_from_rotvec;
    use crate::model::kinematics::Robot;

    fn scene(robot: Option<&Robot>) -> (Vec<ProfileViewObs>, Iso3, Vector3<f64>, f64) {
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

    /// The analytic Jacobian rows against central differences, with X, the centre, the
    /// diameter and DH corrections free.
    #[test]
    fn jacobian_matches_central_differences() {
        let robot = Robot::hp3();
        let (views, x, c, d) = scene(Some(&robot));
        let ids: Vec<usize> = (0..views.len()).collect();
        let block = RobotBlock {
            reference: robot.clone(),
            params: candidates(&robot, RobotMode::Full),
            readings: views.iter().map(|v| v.q.clone().unwrap()).collect(),
        };
        let sphere = SphereStart {
            centre: c + Vector3::new(0.3, -0.2, 0.1),
            diameter: d + 0.1,
            diameter_free: true,
        };
        let layout = ParamLayout::profiler(&x, true, sphere, &ids, Some(block));
        let terms = Terms {
            points: views
                .iter()
                .enumerate()
                .flat_map(|(v, o)| o.points.iter().step_by(37).map(move |q| (v, q[0], q[1])))
                .collect(),
            a: views.iter().map(|v| v.a).collect(),
        };
        let prob = ProfileProblem {
            layout: &layout,
            terms: &terms,
        };
        let mut p = layout.encode();
        for (k, v) in p.iter_mut().enumerate() {
            *v += 1e-3 * ((k as f64) * 0.37).sin();
        }
        let (m, n) = (prob.num_residuals(), prob.num_params());
        let mut r = vec![0.0; m];
        let mut rows = JacobianRows::new(m, n, n);
        prob.residuals_and_jacobian_rows(&p, &mut r, &mut rows)
            .unwrap();
        let h = 1e-6;
        let mut worst: f64 = 0.0;
        for j in 0..n {
            let mut dp = vec![0.0; n];
            dp[j] = h;
            let (mut pp, mut pm) = (vec![0.0; n], vec![0.0; n]);
            prob.retract(&p, &dp, &mut pp);
            dp[j] = -h;
            prob.retract(&p, &dp, &mut pm);
            let (mut rp, mut rm) = (vec![0.0; m], vec![0.0; m]);
            prob.residuals(&pp, &mut rp).unwrap();
            prob.residuals(&pm, &mut rm).unwrap();
            for i in 0..m {
                let fd = (rp[i] - rm[i]) / (2.0 * h);
                let an = rows.row(i).1[j];
                worst = worst.max((fd - an).abs() / (1.0 + an.abs()));
            }
        }
        assert!(worst < 1e-5, "worst relative difference {worst:e}");
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
