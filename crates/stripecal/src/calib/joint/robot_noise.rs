//! The robot-pose noise: a per-view correction of the robot's flange pose, its prior
//! (pseudo-observation) rows, the variance components of its translation and rotation,
//! their floors, and the per-view test.
//!
//! ## Model
//!
//! Every robot is off by something (repeatability, kinematic errors). View i is imaged
//! from `A_i' = A_i D_i`, `D_i = (R_D, t_D)` a small rigid correction in the flange
//! frame, stored as rotation vector `w` and translation (mm) and updated like the other
//! transforms (`R_D Exp(dw)`, `t_D + dv`). Its prior is the robot-pose noise: six
//! pseudo-observations of zero per view,
//!
//! ```text
//! rotvec(R_D) / sigma_r,   t_D / sigma_t        (rad, mm; per component)
//! ```
//!
//! `sigma_t` (mm) and `sigma_r` (rad) are two more variance components, estimated with
//! the circles' and the stripe points' (module docs of [`super`]).
//!
//! ## The image's part
//!
//! A view's correction also takes up what its own image gets wrong beyond white noise:
//! detector biases that depend on the viewing angle, a board that is not quite flat, a
//! lens the distortion model does not quite fit. On real data this part is large along
//! the directions the image determines worst (a tilt against a shift), where an isotropic
//! flange prior can only follow it by growing in every direction (rosi_10x10: 9.9 mm and
//! 0.62 deg, with which the robot's poses no longer inform `X` and `Z` and the held-out
//! views are predicted twice as badly). With [`super::JointOptions::image_pose_noise`]
//! (the default) the correction is the sum of the robot's part and an image part `e_i`
//! shaped like the image's own uncertainty of the view's pose:
//!
//! ```text
//! D_i - e_i ~ N(0, diag(sigma_r^2 I, sigma_t^2 I)),    e_i ~ N(0, k^2 Q_i)
//! ```
//!
//! `Q_i = I_i^-1`, `I_i` the information the view's circles and stripe points give its
//! correction (with their weights, at the start of each solve), and `k` (dimensionless)
//! a third variance component: 0 when the images are as good as their residuals say. Its
//! prior rows are `k^-1 U_i e_i`, `U_i^T U_i = I_i`. Marginally the correction's prior
//! covariance is `diag(sigma_r^2 I, sigma_t^2 I) + k^2 Q_i` (equivalently: each view's
//! image residuals have, besides their white noise, a correlated part in the directions
//! its pose moves them, of variance `k^2` times the white noise's there); `e_i` does not
//! enter the chain. `e_i` is stored as a plain 6-vector (rotation vector's components,
//! rad, then mm), compared with `D_i`'s rotation vector and translation.
//!
//! ## Jacobian
//!
//! `D_i` enters view i's chain `A_i D_i X`. Perturbing it by `(dw, dv)` moves the chain
//! as a perturbation `(w, v)` of `X` does with `w = R_X^T dw`, `v = -[t_X]x dw + R_D^T
//! dv` (`A D Exp(dw) X = A D X Exp(R_X^T dw)`, and the translations match to first
//! order), so a view's correction columns are its rows' derivatives over `X`'s slots
//! (the dual numbers run over every slot, held or not) times that 6 x 6 map
//! ([`correction_map`]). The prior rows' derivatives: the inverse right Jacobian of the
//! rotation vector for `rotvec(R_D Exp(dw))`, the identity for the translation.
//!
//! ## Floors
//!
//! A sigma is never below its floor, the larger of
//! - the robot's figures when rig.json gives them ([`crate::Robot::pose_noise_floor`]:
//!   `repeatability_mm` for the translation, the flange rotation of `encoder_sigma_deg`
//!   for the rotation);
//! - and the adjustment's own floor: [`ABSOLUTE_FLOOR_MM`] and [`ABSOLUTE_FLOOR_DEG`]
//!   (an order of magnitude below the best industrial arms' repeatability and encoder
//!   figures), but at most [`RESOLUTION_CAP`] times the precision with which a view's
//!   own image determines a component of its flange pose (the median over the views of
//!   the RMS over the three components of `1 / sqrt(I_kk)`, `I` the information of the
//!   correction from the view's circles and stripe points alone).
//!
//! Why a floor: robot-pose noise far below what the views resolve cannot be told from
//! what the images themselves get wrong. On a perfect robot with white image noise the
//! estimate would creep towards zero re-weighting after re-weighting; on the rendered
//! twin the images disagree among themselves by a little more than their noise (the
//! detectors' small pose-dependent biases: about 0.02-0.08 um and 3e-5 deg of apparent
//! robot noise), which the adjustment would otherwise report as robot-pose noise and
//! hold each view's correction against, so that a perfect robot's views would fail
//! their tests. Why the cap: on exact observations the images resolve the poses to
//! round-off, and a prior far weaker than the images along the directions only the
//! prior determines (a correction common to every view is X's or Z's own) leaves the
//! normal equations unable to resolve them; at most 100 times the images' precision
//! keeps that ratio below 1e4.
//!
//! The variance components start at the floors (the corrections start at zero), and
//! a group whose prior is much tighter than the images keeps being re-estimated: its
//! redundancy is small but so is its sum of squares.
//!
//! ## The per-view test
//!
//! A view's pseudo-observations (six, or twelve with the image's part) have the
//! residuals `v` with the cofactor `Q_vv = s^2 (P^-1 - A N^-1 A^T)` (`A` their design
//! rows, `P` their weights, `s^2` the variance factor): the part of the prior's variance
//! that the rest of the adjustment does not explain (its redundancy). `T = v^T Q_vv^+ v`
//! is chi-square with `k = rank Q_vv` (6: the view's image takes the other six with the
//! image's part) degrees of freedom when the view agrees with the noise model; it
//! is reported as the standard normal deviate of the same tail probability
//! (Wilson-Hilferty), `((T/k)^(1/3) - 1 + 2/(9k)) / sqrt(2/(9k))`: Baarda's w-test
//! generalised to the view's six-dimensional correction, about N(0, 1) for a view that
//! agrees, above about 4 for one that does not (a one-sided probability of 3e-5).
//!
//! The sigmas in a view's `P` are the variance components without that view (externally
//! studentised: its share of the groups' sums of squares and redundancies taken out,
//! floors kept), so that a view that disagrees is not measured against the sigmas it
//! inflates itself.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, Vector3, Vector6};

use super::covariance::inverse_right_jacobian;
use super::layout::{Block, JointParams, ParamLayout};
use crate::model::geometry::matrix_to_rotvec;
use crate::model::{RobotPoseNoise, RobotPoseView};

/// The adjustment's own floor of the translation sigma, mm (module docs).
pub(super) const ABSOLUTE_FLOOR_MM: f64 = 1e-3;

/// The adjustment's own floor of the rotation sigma, degrees (module docs).
pub(super) const ABSOLUTE_FLOOR_DEG: f64 = 1e-4;

/// The adjustment's own floors are at most this many times the precision a view's own
/// image gives a component of its flange pose (module docs).
pub(super) const RESOLUTION_CAP: f64 = 100.0;

/// The floor of the image part's factor `k` (module docs): a part 1 % of the image's
/// own precision is nothing.
pub const IMAGE_FACTOR_FLOOR: f64 = 0.01;

/// Weights `1 / sigma` of a view's prior rows: the robot's rotation (1/rad) and
/// translation (1/mm), and the image part's `1 / k` (`None`: no image part).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PriorWeights {
    pub rotation: f64,
    pub translation: f64,
    pub image: Option<f64>,
}

impl PriorWeights {
    /// Prior rows per view: 6, or 12 with the image's part.
    pub fn rows(&self) -> usize {
        if self.image.is_some() {
            12
        } else {
            6
        }
    }
}

/// The robot's figures as floors of the sigmas: rotation rad, translation mm (0: none).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Floors {
    pub rotation_rad: f64,
    pub translation_mm: f64,
}

/// What the robot-pose groups keep between an evaluation and the re-weighting that
/// follows it.
#[derive(Debug, Clone, Default)]
pub(super) struct RobotNoiseState {
    /// Per view: the information (unit weight) of its correction from its circles and
    /// from its stripe points, `sum g g^T` over the rows' correction columns.
    pub info: Vec<[Matrix6<f64>; 2]>,
    /// The floors in force (the figures and the resolution), rotation rad, translation
    /// mm.
    pub floors: Floors,
    /// Whether the rotation and the translation sigma sit at their floor.
    pub at_floor: (bool, bool),
    /// Whether the image part's factor sits at its floor.
    pub image_at_floor: bool,
    /// Per view: `U_i` of the image part's prior rows (`U_i^T U_i` the information of
    /// the view's correction from its image, weighted; module docs), fixed during a
    /// solve; empty before the first.
    pub image_prior: Vec<Matrix6<f64>>,
}

/// `U` with `U^T U = I` (`I` symmetric, positive semi-definite; a tiny ridge keeps a
/// direction the image does not determine from breaking the factorisation).
pub(super) fn image_prior_factor(info: &Matrix6<f64>) -> Matrix6<f64> {
    let sym = 0.5 * (info + info.transpose());
    let ridge = 1e-12 * sym.trace().abs().max(1e-300) / 6.0;
    let m = sym + Matrix6::identity() * ridge;
    match m.cholesky() {
        Some(c) => c.l().transpose(),
        None => Matrix6::from_diagonal(&m.diagonal().map(|x| x.max(ridge).sqrt())),
    }
}

/// `(w, v) = M (dw, dv)`: the perturbation of `X` that a perturbation of the correction
/// `D = (r_d, .)` is, for `X = (x_rot, x_t)` (module docs).
pub(super) fn correction_map(
    x_rot: &Matrix3<f64>,
    x_t: &Vector3<f64>,
    r_d: &Matrix3<f64>,
) -> Matrix6<f64> {
    let mut m = Matrix6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&x_rot.transpose());
    m.fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&(-x_t.cross_matrix()));
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&r_d.transpose());
    m
}

/// A row's correction columns from its derivatives `g` over `X`'s six slots.
#[inline]
pub(super) fn correction_columns(g: &[f64; 6], m: &Matrix6<f64>) -> [f64; 6] {
    std::array::from_fn(|j| (0..6).map(|k| g[k] * m[(k, j)]).sum())
}

/// The prior's raw values of each view: `[rotvec(R_D); t_D]`.
pub(super) fn prior_values(s: &JointParams) -> Vec<Vector6<f64>> {
    s.corrections
        .iter()
        .map(|(r, t)| {
            let w = matrix_to_rotvec(r);
            Vector6::new(w.x, w.y, w.z, t.x, t.y, t.z)
        })
        .collect()
}

/// The raw values of view `i`'s prior rows: the robot's `[rotvec(R_D); t_D] - e_i` and,
/// with the image part, `U_i e_i` (unweighted).
fn raw_rows(s: &JointParams, i: usize, d: &Vector6<f64>, u: &[Matrix6<f64>]) -> Vec<f64> {
    let e = s
        .image_pose
        .get(i)
        .map_or(Vector6::zeros(), |e| Vector6::from_column_slice(e));
    let mut out: Vec<f64> = (d - e).iter().copied().collect();
    if !s.image_pose.is_empty() {
        let ue = u.get(i).copied().unwrap_or_else(Matrix6::identity) * e;
        out.extend(ue.iter());
    }
    out
}

/// The weights of a view's prior rows, in row order.
fn row_weights(w: &PriorWeights) -> Vec<f64> {
    let mut out = vec![w.rotation; 3];
    out.extend([w.translation; 3]);
    if let Some(k) = w.image {
        out.extend([k; 6]);
    }
    out
}

/// Weighted prior residuals (`w.rows()` per view: the robot's rotation, translation,
/// then the image part's six) with the image part's factors `u`.
pub(super) fn prior_residuals(
    s: &JointParams,
    w: &PriorWeights,
    u: &[Matrix6<f64>],
    r: &mut [f64],
) {
    let rw = row_weights(w);
    for (i, (out, d)) in r
        .chunks_exact_mut(w.rows())
        .zip(prior_values(s))
        .enumerate()
    {
        for ((o, v), k) in out.iter_mut().zip(raw_rows(s, i, &d, u)).zip(&rw) {
            *o = k * v;
        }
    }
}

/// The weighted 6 x 6 Jacobian of a view's robot rows over its correction `D_i`.
pub(super) fn prior_jacobian(rotvec: &Vector3<f64>, (wr, wt): (f64, f64)) -> Matrix6<f64> {
    let mut j = Matrix6::zeros();
    j.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(inverse_right_jacobian(rotvec) * wr));
    j.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(Matrix3::identity() * wt));
    j
}

/// The weighted Jacobian of view `i`'s prior rows (`w.rows()`) over its per-view
/// columns (`D_i`'s six, then `e_i`'s six with the image part).
pub(super) fn view_prior_jacobian(
    d: &Vector6<f64>,
    w: &PriorWeights,
    u: Option<&Matrix6<f64>>,
) -> DMatrix<f64> {
    let n = w.rows();
    let mut j = DMatrix::zeros(n, n);
    let jd = prior_jacobian(&Vector3::new(d[0], d[1], d[2]), (w.rotation, w.translation));
    j.view_mut((0, 0), (6, 6)).copy_from(&jd);
    if let Some(k) = w.image {
        for a in 0..6 {
            j[(a, 6 + a)] = -if a < 3 { w.rotation } else { w.translation };
        }
        let u = u.copied().unwrap_or_else(Matrix6::identity) * k;
        j.view_mut((6, 6), (6, 6)).copy_from(&u);
    }
    j
}

/// The prior rows: weighted residuals `r` (`w.rows()` per view) and their rows of
/// `width` values, the view's per-view columns at `n_global..` (the row's columns are
/// the problem's: the global ones, then the view's).
pub(super) fn prior_rows(
    s: &JointParams,
    w: &PriorWeights,
    u: &[Matrix6<f64>],
    r: &mut [f64],
    vals: &mut [f64],
    width: usize,
    n_global: usize,
) {
    prior_residuals(s, w, u, r);
    let n = w.rows();
    for (i, (rows, v)) in vals
        .chunks_exact_mut(n * width)
        .zip(prior_values(s))
        .enumerate()
    {
        let j = view_prior_jacobian(&v, w, u.get(i));
        for (a, row) in rows.chunks_exact_mut(width).enumerate() {
            for b in 0..n {
                row[n_global + b] = j[(a, b)];
            }
        }
    }
}

/// The median over views of the precision their own images give a component of their
/// corrections (module docs): the RMS over the three components of `1 / sqrt(I_kk)`
/// for the rotation (rad) and the translation (mm), with the circles' and stripe
/// points' standard deviations `sigma_px` (views whose images leave a component
/// undetermined are skipped; `None` when no view is left).
pub(super) fn resolution(info: &[[Matrix6<f64>; 2]], sigma_px: (f64, f64)) -> Option<(f64, f64)> {
    let (mut rot, mut trans) = (Vec::new(), Vec::new());
    for [c, s] in info {
        let i = c / sigma_px.0.powi(2) + s / sigma_px.1.powi(2);
        let var = |o: usize| (0..3).map(|k| 1.0 / i[(o + k, o + k)]).sum::<f64>() / 3.0;
        let (a, b) = (var(0), var(3));
        if a.is_finite() && b.is_finite() && a > 0.0 && b > 0.0 {
            rot.push(a.sqrt());
            trans.push(b.sqrt());
        }
    }
    let median = |mut x: Vec<f64>| -> Option<f64> {
        x.sort_by(f64::total_cmp);
        (!x.is_empty()).then(|| 0.5 * (x[(x.len() - 1) / 2] + x[x.len() / 2]))
    };
    Some((median(rot)?, median(trans)?))
}

/// The standard normal deviate of a chi-square value `t` with `k` degrees of freedom
/// (Wilson-Hilferty).
pub(super) fn chi2_to_normal(t: f64, k: usize) -> f64 {
    let k = k as f64;
    let c = 2.0 / (9.0 * k);
    ((t / k).cbrt() - (1.0 - c)) / c.sqrt()
}

/// The report of the solution `s` (parameter covariance `cov`, variance factor `s2`,
/// final weights `w`, the image part's factors `u`) over the views used (dataset rows
/// `used`).
pub(super) fn report(
    layout: &ParamLayout,
    s: &JointParams,
    cov: &DMatrix<f64>,
    s2: f64,
    w: &PriorWeights,
    state: &RobotNoiseState,
    used: &[usize],
) -> RobotPoseNoise {
    let n = w.rows();
    let rw = row_weights(w);
    let u = &state.image_prior;
    // Per view: weighted residuals, and the hat block H = J C J^T / s^2 of its rows.
    let per_view: Vec<(DVector<f64>, Option<DMatrix<f64>>)> = prior_values(s)
        .iter()
        .enumerate()
        .map(|(i, d)| {
            let raw = raw_rows(s, i, d, u);
            let res = DVector::from_fn(n, |k, _| raw[k] * rw[k]);
            let h = layout.view_columns(Block::RobotPose, i).and_then(|c| {
                let cvv = cov.view((c.start, c.start), (n, n)).into_owned();
                let j = view_prior_jacobian(d, w, u.get(i));
                let h = &j * cvv * j.transpose() / s2;
                (s2 > 0.0 && h.iter().all(|x| x.is_finite())).then_some(h)
            });
            (res, h)
        })
        .collect();
    // The groups' weighted sums of squares and redundancies (rotation, translation,
    // image part), for the sigmas without a view (module docs).
    let group = |k: usize| {
        if k < 3 {
            0
        } else if k < 6 {
            1
        } else {
            2
        }
    };
    let mut totals = [(0.0, 0.0); 3];
    for (res, h) in &per_view {
        for k in 0..n {
            let t = &mut totals[group(k)];
            t.0 += res[k] * res[k];
            t.1 += h.as_ref().map_or(1.0, |h| 1.0 - h[(k, k)]);
        }
    }
    let floors = [
        state.floors.rotation_rad * w.rotation,
        state.floors.translation_mm * w.translation,
        IMAGE_FACTOR_FLOOR * w.image.unwrap_or(0.0),
    ];
    let views = used
        .iter()
        .zip(&per_view)
        .zip(prior_values(s))
        .map(|((&view, (res, h)), v)| {
            let test = h.as_ref().map_or(f64::NAN, |h| {
                // Each group's sigma without the view, relative to the group's (both
                // in weighted units: 1 is the group's sigma), floored.
                let rel: [f64; 3] = std::array::from_fn(|g| {
                    let rows: Vec<usize> = (0..n).filter(|&k| group(k) == g).collect();
                    let ss = rows.iter().map(|&k| res[k] * res[k]).sum::<f64>();
                    let r = rows.iter().map(|&k| 1.0 - h[(k, k)]).sum::<f64>();
                    let (tss, tr) = totals[g];
                    if rows.is_empty() || tr - r < 0.5 {
                        return 1.0;
                    }
                    ((tss - ss).max(0.0) / (tr - r) / s2).sqrt().max(floors[g])
                });
                let scaled = DVector::from_fn(n, |k, _| res[k] / rel[group(k)]);
                view_test(&scaled, h, s2)
            });
            RobotPoseView {
                view,
                translation_mm: Vector3::new(v[3], v[4], v[5]).norm(),
                rotation_deg: Vector3::new(v[0], v[1], v[2]).norm().to_degrees(),
                test,
            }
        })
        .collect();
    RobotPoseNoise {
        sigma_translation_mm: 1.0 / w.translation,
        sigma_rotation_deg: (1.0 / w.rotation).to_degrees(),
        translation_at_floor: state.at_floor.1,
        rotation_at_floor: state.at_floor.0,
        floor_translation_mm: state.floors.translation_mm,
        floor_rotation_deg: state.floors.rotation_rad.to_degrees(),
        image_factor: w.image.map(|k| 1.0 / k),
        image_factor_at_floor: w.image.is_some() && state.image_at_floor,
        kinematic_mm: None,
        kinematic_deg: None,
        views,
        left_out: Vec::new(),
    }
}

/// The test of one view (module docs) from its weighted prior residuals `u` and the hat
/// block `h` of its rows: `T = u^T (s^2 (I - H))^+ u` as a standard normal deviate.
fn view_test(u: &DVector<f64>, h: &DMatrix<f64>, s2: f64) -> f64 {
    let n = u.len();
    let q = (DMatrix::identity(n, n) - h) * s2;
    let q = 0.5 * (&q + q.transpose());
    let eig = q.symmetric_eigen();
    let (mut t, mut k) = (0.0, 0);
    for (e, w) in eig.eigenvalues.iter().zip(eig.eigenvectors.column_iter()) {
        if *e > 1e-6 * s2 {
            t += w.dot(u).powi(2) / e;
            k += 1;
        }
    }
    if k == 0 {
        f64::NAN
    } else {
        chi2_to_normal(t, k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geometry::{iso_from_parts, rotvec_to_matrix};

    /// `A D(dw, dv) X` equals `A D X(w, v)` with `(w, v) = M (dw, dv)` to first order.
    #[test]
    fn a_correction_is_a_perturbation_of_x() {
        let xr = rotvec_to_matrix(&Vector3::new(-0.3, 0.24, 3.0));
        let xt = Vector3::new(29.0, 5.4, 62.6);
        let dr = rotvec_to_matrix(&Vector3::new(0.01, -0.02, 0.015));
        let dt = Vector3::new(0.3, -0.1, 0.2);
        let m = correction_map(&xr, &xt, &dr);
        let x = |w: &Vector3<f64>, v: &Vector3<f64>| {
            iso_from_parts(&(xr * rotvec_to_matrix(w)), &(xt + v))
        };
        let d = |w: &Vector3<f64>, v: &Vector3<f64>| {
            iso_from_parts(&(dr * rotvec_to_matrix(w)), &(dt + v))
        };
        let z = Vector3::zeros();
        let h = 1e-6;
        for j in 0..6 {
            let mut e = Vector6::zeros();
            e[j] = h;
            let (dw, dv) = (e.fixed_rows::<3>(0).into(), e.fixed_rows::<3>(3).into());
            let wv = m * e;
            let (w, v) = (wv.fixed_rows::<3>(0).into(), wv.fixed_rows::<3>(3).into());
            let a = d(&dw, &dv) * x(&z, &z);
            let b = d(&z, &z) * x(&w, &v);
            let err = (a.to_homogeneous() - b.to_homogeneous()).abs().max();
            assert!(err < 1e-10, "column {j}: {err:e}");
        }
    }

    #[test]
    fn wilson_hilferty_matches_known_quantiles() {
        // chi2(6): median 5.348, 99.9 % 22.458, 99.997 % about 31.5.
        assert!(chi2_to_normal(5.348, 6).abs() < 0.01);
        assert!((chi2_to_normal(22.458, 6) - 3.090).abs() < 0.05);
        assert!((chi2_to_normal(31.5, 6) - 4.0).abs() < 0.1);
    }
}
