//! The profiler adjustment's point selection settled over ONE set of normal equations
//! ([`super::profile`], "Points on the sphere").
//!
//! After the first solve (over every k-th arc point) the parameters `p0` are within a
//! few sigmas of the minimum over all the points, where the problem is nearly linear: a
//! point's Jacobian row turns with the direction to the sphere's centre, by `|dp| / R`
//! (parts in 10^5 for micrometres on a 40 mm radius). So the normal equations `N` are
//! formed once, at `p0`, over the points selected (view by view, `N_v`), and kept as the
//! metric of every step. Each round, at the current point `p` with the per-view
//! gradients `g_v` (exact at `p0`; after a step, the quadratic model's `g_v + N_v dp`):
//!
//! 1. the step `dp = -N^-1 g` and what it promises, `pred = g^T N^-1 g / 2`;
//! 2. when `pred` is below the solves' own tolerance ([`super::profile`] "Stopping":
//!    within 0.003 sigma of the minimum), the model says `p` is the minimum. With the
//!    model's gradients that is only a claim: the exact gradients at `p` are computed
//!    (`g_v = B_v sum f_i e_i`, the normal equations' work without the Gram matrix) and
//!    the round repeats with them; with exact gradients `p` is the result;
//! 3. otherwise the step is taken: every point's distance at `p1 = p [+] dp` (no
//!    derivatives) gives the cost of the selection there, which must be lower (else, with
//!    the model's gradients, the exact ones at `p` are computed and the round repeats;
//!    with exact ones, the rounds give up and the caller iterates full solves); then the
//!    points are re-selected from those distances, and the points that joined or left
//!    change `N_v`, `g_v` and the cost by their rows at `p1` (a handful of points).
//!
//! So the result meets the iterated solves' stopping rule, tested at the result itself
//! with its exact gradient, for a selection made there. The metric `N` from `p0`
//! differs from the result's own by about `|dp| / R` relatively, which scales `pred` by
//! as little; the covariance is formed from it. The per-view gradients (the
//! view-clustered variance factor's), the residuals, their sum of squares and sigma are
//! the result's own. The tests check the result against the iterated solves:
//! parameters within 0.006 sigma (each within 0.003 of the minimum), sigmas within 1e-3
//! relatively.

use nalgebra::{DMatrix, DVector};

use super::layout::ParamLayout;
use super::profile::{reselect, stop_ftol, ProfileViewObs};
use super::profile_problem::{all_residuals, ProfileProblem, Terms};
use crate::error::Result;
use crate::model::geometry::Iso3;
use crate::numerics::lm::{covariance, sigmas, LmOptions, LmResult, StopReason};

/// What the rounds settled on.
pub(super) struct Settled {
    /// The result (module docs), as the solver's.
    pub result: LmResult,
    /// Per view: `g_v` at the result.
    pub gradients: Vec<DVector<f64>>,
    /// The selection `result` is over.
    pub selected: Vec<Vec<usize>>,
    /// Steps taken.
    pub rounds: usize,
}

/// Rounds (steps and exact-gradient evaluations) at most.
const MAX_ROUNDS: usize = 12;

/// The exact per-view gradients and half sums of squares at `p` over the points of
/// `terms`, their residuals into `r`.
fn gradients_at(
    layout: &ParamLayout,
    p: &[f64],
    terms: &Terms,
    r: &mut Vec<f64>,
) -> Vec<(DVector<f64>, f64)> {
    r.resize(terms.len(), 0.0);
    ProfileProblem::new(layout, terms).view_gradients(p, r)
}

/// The rounds (module docs) from `p0` over `selected` (per view, indices into its points;
/// `a` the views' flange poses), with at most `reselections` re-selections (0: the
/// selection is kept). `None` when a step does not lower the cost or the normal
/// equations are singular: the caller solves instead.
pub(super) fn settle(
    layout: &ParamLayout,
    p0: &[f64],
    views: &[ProfileViewObs],
    a: &[Iso3],
    selected: &[Vec<usize>],
    reselections: usize,
    lm: &LmOptions,
) -> Result<Option<Settled>> {
    let n = layout.num_params();
    let mut sel = selected.to_vec();
    let mut terms = Terms::of(views, &sel, a);
    // the per-view normal equations at p0 (the metric) and the exact gradients and
    // costs at the current point
    let mut r = vec![0.0; terms.len()];
    let (mut nv, mut gc) = normals_at(layout, p0, &terms, &mut r);
    let mut p = p0.to_vec();
    // whether gc's gradients are p's own (else the quadratic model's)
    let mut exact = true;
    let mut reselected = 0;
    let initial_cost: f64 = gc.iter().map(|v| v.1).sum();
    for round in 1..=MAX_ROUNDS {
        let m: usize = sel.iter().map(|s| s.len()).sum();
        if m <= n {
            return Ok(None);
        }
        let (big_n, g, cost) = summed(&nv, &gc, n);
        let Some(chol) = big_n.clone().cholesky() else {
            return Ok(None);
        };
        let dp = chol.solve(&(-&g));
        let pred = -0.5 * g.dot(&dp);
        if !(pred.is_finite() && cost.is_finite()) {
            return Ok(None);
        }
        if pred <= stop_ftol(m, lm) * cost {
            if !exact {
                // the model says the minimum: the exact gradient there says whether it is
                gc = gradients_at(layout, &p, &terms, &mut r);
                exact = true;
                continue;
            }
            // the minimum, by its own gradient, for a selection made here
            let ssr = 2.0 * cost;
            let sigma2 = ssr / (m - n) as f64;
            let (cov, unobservable) = covariance(&big_n, sigma2, lm.rank_tol);
            let sigma = sigmas(&cov);
            let result = LmResult {
                params: p,
                residuals: r,
                ssr,
                cost,
                initial_cost,
                iterations: round,
                reason: StopReason::CostConverged,
                jtj: big_n,
                sigma2,
                covariance: cov,
                sigma,
                unobservable,
            };
            return Ok(Some(Settled {
                result,
                gradients: gc.into_iter().map(|v| v.0).collect(),
                selected: sel,
                rounds: round,
            }));
        }
        // the step, every point's distance at its point, the cost (which must be lower)
        // and the model's gradients there
        let mut p1 = vec![0.0; n];
        layout.retract(&p, dp.as_slice(), &mut p1);
        let res = all_residuals(layout, &p1, views, a);
        let costs: Vec<f64> = sel
            .iter()
            .zip(&res)
            .map(|(s, rv)| 0.5 * s.iter().map(|&i| rv[i] * rv[i]).sum::<f64>())
            .collect();
        // (not lower, or not a number)
        let lower = costs.iter().sum::<f64>() < cost;
        if !lower {
            if exact {
                return Ok(None);
            }
            // the model's gradient led nowhere: the exact one at p, and step again
            gc = gradients_at(layout, &p, &terms, &mut r);
            exact = true;
            continue;
        }
        for (v, ((gv, cv), c)) in gc.iter_mut().zip(costs).enumerate() {
            *gv += &nv[v] * &dp;
            *cv = c;
        }
        (p, exact) = (p1, false);
        // the selection there: the points that joined or left, by their rows at p
        if reselected < reselections {
            let next = reselect(&res, &sel);
            if next != sel {
                reselected += 1;
                let prob = ProfileProblem::new(layout, &terms);
                update(&prob, &p, views, &sel, &next, &mut nv, &mut gc);
                sel = next;
                terms.select(views, &sel);
            }
        }
        r.clear();
        r.extend(
            sel.iter()
                .zip(&res)
                .flat_map(|(s, rv)| s.iter().map(|&i| rv[i])),
        );
    }
    Ok(None)
}

/// A view's gradient `g_v` and half sum of squares.
type GradCost = (DVector<f64>, f64);

/// Each view's normal matrix `N_v` at `p`, and its gradient `g_v` with its half sum
/// of squares (the residuals left in `r`).
fn normals_at(
    layout: &ParamLayout,
    p: &[f64],
    terms: &Terms,
    r: &mut [f64],
) -> (Vec<DMatrix<f64>>, Vec<GradCost>) {
    let normals = ProfileProblem::new(layout, terms).view_normals(p, r);
    let mut nv: Vec<DMatrix<f64>> = Vec::with_capacity(normals.len());
    let mut gc: Vec<(DVector<f64>, f64)> = Vec::with_capacity(normals.len());
    for (v, g) in normals.into_iter().zip(&terms.ranges) {
        nv.push(v.jtj);
        gc.push((v.g, 0.5 * r[g.clone()].iter().map(|x| x * x).sum::<f64>()));
    }
    (nv, gc)
}

/// The views' normal equations summed: `N` (symmetrised), `g` and the cost.
fn summed(
    nv: &[DMatrix<f64>],
    gc: &[(DVector<f64>, f64)],
    n: usize,
) -> (DMatrix<f64>, DVector<f64>, f64) {
    let big_n = nv
        .iter()
        .fold(DMatrix::<f64>::zeros(n, n), |acc, v| acc + v);
    let big_n = (&big_n + big_n.transpose()) * 0.5;
    let g = gc
        .iter()
        .fold(DVector::<f64>::zeros(n), |acc, v| acc + &v.0);
    let cost: f64 = gc.iter().map(|v| v.1).sum();
    (big_n, g, cost)
}

/// The selection `sel` becomes `next`: the points that joined or left change `N_v`,
/// `g_v` and the half sums of squares by their rows at `p` (`prob`'s flange poses).
fn update(
    prob: &ProfileProblem,
    p: &[f64],
    views: &[ProfileViewObs],
    sel: &[Vec<usize>],
    next: &[Vec<usize>],
    nv: &mut [DMatrix<f64>],
    gc: &mut [(DVector<f64>, f64)],
) {
    let mut changes: Vec<(usize, f64, f64)> = Vec::new();
    let mut signs: Vec<f64> = Vec::new();
    for (v, (old, new)) in sel.iter().zip(next).enumerate() {
        let pts = &views[v].points;
        let mut mark = vec![0i8; pts.len()];
        for &i in old {
            mark[i] -= 1;
        }
        for &i in new {
            mark[i] += 1;
        }
        for (i, &k) in mark.iter().enumerate().filter(|(_, k)| **k != 0) {
            changes.push((v, pts[i][0], pts[i][1]));
            signs.push(f64::from(k));
        }
    }
    let rows = prob.point_rows(p, &changes);
    for ((&(v, _, _), sign), (e, row)) in changes.iter().zip(&signs).zip(rows) {
        nv[v].ger(*sign, &row, &row, 1.0);
        gc[v].0.axpy(sign * e, &row, 1.0);
        gc[v].1 += sign * 0.5 * e * e;
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::super::profile::tests::scene;
    use super::super::profile::{adjust, ProfileFit, ProfileOptions, ProfileStart};
    use super::*;
    use crate::model::geometry::iso_from_rotvec;

    /// The scene's profiles three times over with noise of 0.01 mm (a fixed generator)
    /// and 1 % spikes of 0.5-1.5 mm: 4,800 points, so that the adjustment first solves
    /// over every second one.
    fn noisy_views() -> (Vec<ProfileViewObs>, ProfileStart) {
        let (views, x, c, d) = scene(None);
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let views = views
            .into_iter()
            .map(|v| {
                let mut points = Vec::new();
                for _ in 0..3 {
                    for q in &v.points {
                        // Box-Muller
                        let g = (-2.0 * uniform().max(1e-300).ln()).sqrt()
                            * (std::f64::consts::TAU * uniform()).cos();
                        let spike = if uniform() < 0.01 {
                            0.5 + uniform()
                        } else {
                            0.0
                        };
                        points.push([q[0], q[1] + 0.01 * g + spike]);
                    }
                }
                ProfileViewObs {
                    arc: (0..points.len()).collect(),
                    points,
                    ..v
                }
            })
            .collect();
        let start = ProfileStart {
            hand_sensor: x * iso_from_rotvec(
                &Vector3::new(0.004, -0.003, 0.002),
                &Vector3::new(0.3, -0.2, 0.4),
            ),
            centre: c + Vector3::new(0.2, -0.3, 0.1),
            diameter: d,
            diameter_free: true,
        };
        (views, start)
    }

    /// `a` against `b`: each parameter within `6e-3` of its sigma (each result is within
    /// 0.003 sigma of the minimum), every sigma within 1e-3 relatively, the same points,
    /// sums of squares within 1e-9 relatively.
    fn assert_same(a: &ProfileFit, b: &ProfileFit) {
        assert_eq!(a.selected, b.selected);
        assert!((a.ssr - b.ssr).abs() <= 1e-9 * b.ssr, "{} {}", a.ssr, b.ssr);
        assert_eq!(a.covariance.parameters, b.covariance.parameters);
        let sa = a.covariance.matrix.diagonal().map(f64::sqrt);
        let sb = b.covariance.matrix.diagonal().map(f64::sqrt);
        for k in 0..sb.len() {
            assert!(
                (sa[k] - sb[k]).abs() <= 1e-3 * sb[k],
                "sigma {k}: {} {}",
                sa[k],
                sb[k]
            );
        }
        let sigma = |name: &str| b.covariance.sigma(name).unwrap();
        let dr = (a.hand_sensor.rotation.inverse() * b.hand_sensor.rotation).scaled_axis();
        let dt = a.hand_sensor.translation.vector - b.hand_sensor.translation.vector;
        let dc = a.centre - b.centre;
        for k in 0..3 {
            let sr = sigma(&format!("hand_cam.rotation_vector[{k}]"));
            assert!(dr.norm() <= 6e-3 * sr, "rotation {dr:?} sigma {sr}");
            let st = sigma(&format!("hand_cam.translation_mm[{k}]"));
            assert!(dt[k].abs() <= 6e-3 * st, "translation {dt:?} sigma {st}");
            let sc = sigma(&format!("sphere.center_mm[{k}]"));
            assert!(dc[k].abs() <= 6e-3 * sc, "centre {dc:?} sigma {sc}");
        }
        let sd = sigma("sphere.diameter_mm");
        assert!((a.diameter - b.diameter).abs() <= 6e-3 * sd);
        assert!(
            (a.view_variance_factor - b.view_variance_factor).abs()
                <= 1e-3 * b.view_variance_factor
        );
    }

    /// The rounds over one linearisation give the iterated solves' result: with the
    /// point selection (spikes rejected) and with a kept selection from near the minimum
    /// (the checks' refits).
    #[test]
    fn rounds_match_the_iterated_solve() {
        let (views, start) = noisy_views();
        let opts = ProfileOptions::default();
        let settled = adjust(&views, &start, &opts, true).unwrap();
        let iterated = adjust(&views, &start, &opts, false).unwrap();
        let rejected: usize =
            views.iter().map(|v| v.points.len()).sum::<usize>() - settled.points_used();
        assert!(rejected > 30, "the spikes are rejected: {rejected}");
        assert!(settled.converged && iterated.converged);
        assert_same(&settled, &iterated);
        // the checks' refit: the fit's points, from near the minimum
        let kept = ProfileOptions {
            keep_selection: true,
            ..ProfileOptions::default()
        };
        let held: Vec<ProfileViewObs> = views
            .iter()
            .zip(&settled.selected)
            .map(|(v, s)| ProfileViewObs {
                arc: s.clone(),
                ..v.clone()
            })
            .collect();
        let near = ProfileStart {
            hand_sensor: settled.hand_sensor
                * iso_from_rotvec(
                    &Vector3::new(2e-5, 0.0, -1e-5),
                    &Vector3::new(0.002, 0.0, 0.001),
                ),
            centre: settled.centre,
            diameter: settled.diameter,
            diameter_free: true,
        };
        let a = adjust(&held, &near, &kept, true).unwrap();
        let b = adjust(&held, &near, &kept, false).unwrap();
        assert_same(&a, &b);
        // and the rounds did hold there (not the solves' fallback), with the re-selection
        // from every point too
        let sphere = super::super::layout::SphereStart {
            centre: near.centre,
            diameter: near.diameter,
            diameter_free: true,
        };
        let ids: Vec<usize> = views.iter().map(|v| v.view).collect();
        let layout = ParamLayout::profiler(&near.hand_sensor, true, sphere, &ids, None);
        let flanges: Vec<Iso3> = views.iter().map(|v| v.a).collect();
        let p = layout.encode();
        let lm = LmOptions::default();
        let one = settle(&layout, &p, &views, &flanges, &settled.selected, 0, &lm).unwrap();
        assert!(one.is_some(), "the rounds hold");
        let all: Vec<Vec<usize>> = views.iter().map(|v| v.arc.clone()).collect();
        let re = settle(&layout, &p, &views, &flanges, &all, 5, &lm).unwrap();
        assert_eq!(re.expect("the rounds hold").selected, settled.selected);
    }
}
