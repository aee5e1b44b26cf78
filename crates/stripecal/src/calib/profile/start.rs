//! The closed-form start of a profiler's calibration: `T_hand_sensor` and the sphere's
//! centre from the circles of the profiles, in the Kronecker style of the paper.
//!
//! ## Maths
//!
//! View i's circle (centre `(x_i, z_i)`, radius `r_i` in the profile plane y = 0) puts
//! the sphere's centre at `p_i = (x_i, s_i h_i, z_i)` in the sensor frame,
//! `h_i = sqrt(R^2 - r_i^2)`, on the side `s_i = +-1` of the plane that the profile
//! cannot tell. With the flange pose `A_i = (R_Ai, t_Ai)`, `X = (M, t)` and the centre
//! `c` in the base frame, every view says `A_i X p_i = c`:
//!
//! ```text
//! (p_i^T (x) R_Ai) vec(M) + R_Ai t - c = -t_Ai        (3 rows per view, 15 unknowns)
//! ```
//!
//! linear in `vec(M)`, `t`, `c` (the point-coincidence form of the paper's Kronecker
//! solve). `M` is then made a rotation: with `Q = [q1 q2 q3]` the principal directions
//! of the `p_i` (`q3` the one they vary least along), `u = M q1` and `v = M q2` are
//! determined even when the `p_i` lie in one plane (then `M q3` is not), so `R` is the
//! rotation nearest `[u, v, u x v] Q^T`; `t` and `c` are solved again with `R` held.
//!
//! **Sides.** A wrong side for some views makes the equations inconsistent; flipping
//! every side is the mirror image, which the linear `M` fits exactly (`M D`,
//! `D = diag(1, -1, 1)`, is not a rotation). So: the sides of the views whose `h_i` are
//! largest (up to [`SIDE_SUBSET`]) are chosen by trying every combination with the first
//! fixed, the rest follow from the solution's prediction of their centres, and of the
//! two global choices the one whose `M` is a rotation (`det M > 0`; the other fits only
//! when the `p_i` are coplanar) is taken; the other is returned as the mirror start. The
//! pipeline decides between them by the full adjustment's cost, never by this start.
//!
//! **Diameter.** When it is not declared, `R` is found by a golden-section search of the
//! rotation-constrained solve's residual over `[max r_i, 3 max r_i]`, the sides chosen at
//! the bracket's centre and again at the found `R`.

use nalgebra::{DMatrix, DVector, Matrix3, SymmetricEigen, Vector3};

use crate::error::{Error, Result};
use crate::model::geometry::{iso_from_parts, nearest_rotation, Iso3};

/// Views whose sides are chosen by trying every combination.
pub const SIDE_SUBSET: usize = 8;
/// The fewest views the linear start needs (15 unknowns, and redundancy to tell sides).
pub const MIN_VIEWS: usize = 6;

/// One view's circle and flange pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleView {
    /// `T_base_hand`.
    pub a: Iso3,
    /// The circle's centre `(x, z)` in the sensor frame and its radius, mm.
    pub centre: [f64; 2],
    pub radius: f64,
}

/// A start: `X`, the centre, the radius and the sides.
#[derive(Debug, Clone, PartialEq)]
pub struct Start {
    pub hand_sensor: Iso3,
    pub centre: Vector3<f64>,
    pub radius: f64,
    /// `s_i` per view (+1: the centre at sensor y > 0).
    pub sides: Vec<f64>,
    /// Per view: `|A_i X p_i - c|`, mm.
    pub misfit_mm: Vec<f64>,
}

impl Start {
    /// RMS of the views' misfits, mm.
    pub fn rms_mm(&self) -> f64 {
        let n = self.misfit_mm.len().max(1) as f64;
        (self.misfit_mm.iter().map(|e| e * e).sum::<f64>() / n).sqrt()
    }
}

/// The two starts: the chosen one and its mirror image (every side flipped).
#[derive(Debug, Clone, PartialEq)]
pub struct Starts {
    pub chosen: Start,
    pub mirror: Start,
}

fn centres(views: &[CircleView], radius: f64, sides: &[f64]) -> Vec<Vector3<f64>> {
    views
        .iter()
        .zip(sides)
        .map(|(v, s)| {
            let h = (radius * radius - v.radius * v.radius).max(0.0).sqrt();
            Vector3::new(v.centre[0], s * h, v.centre[1])
        })
        .collect()
}

/// Least squares by SVD with column scaling; `None` if not finite.
fn lstsq(a: DMatrix<f64>, b: DVector<f64>) -> Option<(DVector<f64>, f64)> {
    let scale: Vec<f64> = a
        .column_iter()
        .map(|c| {
            let n = c.norm();
            if n > 0.0 {
                1.0 / n
            } else {
                1.0
            }
        })
        .collect();
    let mut a_s = a.clone();
    for (j, s) in scale.iter().enumerate() {
        a_s.column_mut(j).scale_mut(*s);
    }
    let svd = a_s.svd(true, true);
    let x = svd.solve(&b, 1e-10 * svd.singular_values.max()).ok()?;
    let x = DVector::from_fn(x.len(), |j, _| x[j] * scale[j]);
    let r = (&a * &x - b).norm();
    x.iter().all(|v| v.is_finite()).then_some((x, r))
}

/// `(M, t, c)` of the linear solve and its residual norm.
type Linear = (Matrix3<f64>, Vector3<f64>, Vector3<f64>, f64);

/// The unconstrained linear solve (module docs): `(M, t, c)` and the residual norm.
fn linear(views: &[CircleView], p: &[Vector3<f64>]) -> Option<Linear> {
    let n = views.len();
    let mut a = DMatrix::zeros(3 * n, 15);
    let mut b = DVector::zeros(3 * n);
    for (i, (v, pi)) in views.iter().zip(p).enumerate() {
        let ra = v.a.rotation.to_rotation_matrix().into_inner();
        let ta = v.a.translation.vector;
        for k in 0..3 {
            let row = 3 * i + k;
            for j in 0..3 {
                for l in 0..3 {
                    a[(row, 3 * j + l)] = ra[(k, l)] * pi[j];
                }
                a[(row, 9 + j)] = ra[(k, j)];
            }
            a[(row, 12 + k)] = -1.0;
            b[row] = -ta[k];
        }
    }
    let (x, r) = lstsq(a, b)?;
    let m = Matrix3::from_fn(|l, j| x[3 * j + l]);
    Some((
        m,
        Vector3::new(x[9], x[10], x[11]),
        Vector3::new(x[12], x[13], x[14]),
        r,
    ))
}

/// The rotation nearest `m` made from its two well-determined directions (module docs).
fn rotation_from(m: &Matrix3<f64>, p: &[Vector3<f64>]) -> Matrix3<f64> {
    let mean = p.iter().sum::<Vector3<f64>>() / p.len().max(1) as f64;
    let cov = p
        .iter()
        .map(|x| (x - mean) * (x - mean).transpose())
        .sum::<Matrix3<f64>>();
    let eig = SymmetricEigen::new(cov);
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let mut q = Matrix3::from_columns(&[
        eig.eigenvectors.column(idx[0]).into_owned(),
        eig.eigenvectors.column(idx[1]).into_owned(),
        eig.eigenvectors.column(idx[2]).into_owned(),
    ]);
    if q.determinant() < 0.0 {
        q.column_mut(2).neg_mut();
    }
    let u = m * q.column(0);
    let v = m * q.column(1);
    let w = u.cross(&v) / (u.norm() * v.norm()).max(1e-300).sqrt();
    let rq = nearest_rotation(&Matrix3::from_columns(&[u, v, w]));
    rq * q.transpose()
}

/// `t`, `c` with `R` held, and every view's misfit.
fn translation(
    views: &[CircleView],
    p: &[Vector3<f64>],
    r: &Matrix3<f64>,
) -> Option<(Vector3<f64>, Vector3<f64>, Vec<f64>)> {
    let n = views.len();
    let mut a = DMatrix::zeros(3 * n, 6);
    let mut b = DVector::zeros(3 * n);
    for (i, (v, pi)) in views.iter().zip(p).enumerate() {
        let ra = v.a.rotation.to_rotation_matrix().into_inner();
        let rhs = -v.a.translation.vector - ra * r * pi;
        for k in 0..3 {
            for j in 0..3 {
                a[(3 * i + k, j)] = ra[(k, j)];
            }
            a[(3 * i + k, 3 + k)] = -1.0;
            b[3 * i + k] = rhs[k];
        }
    }
    let (x, _) = lstsq(a, b)?;
    let t = Vector3::new(x[0], x[1], x[2]);
    let c = Vector3::new(x[3], x[4], x[5]);
    let misfit = views
        .iter()
        .zip(p)
        .map(|(v, pi)| {
            (v.a * nalgebra::Point3::from(r * pi + t) - nalgebra::Point3::from(c)).norm()
        })
        .collect();
    Some((t, c, misfit))
}

/// The rotation-constrained solve for given sides (no side search): the start of
/// `views` at `radius` with `sides`; `None` when the poses do not determine it.
pub fn with_sides(views: &[CircleView], radius: f64, sides: &[f64]) -> Option<Start> {
    constrained(views, radius, sides)
}

impl Start {
    /// `|A X p - c|` of a view (its circle at this start's radius, on `side`), mm.
    pub fn misfit_of(&self, view: &CircleView, side: f64) -> f64 {
        let p = centres(std::slice::from_ref(view), self.radius, &[side])[0];
        (view.a * self.hand_sensor * nalgebra::Point3::from(p)
            - nalgebra::Point3::from(self.centre))
        .norm()
    }
}

/// The rotation-constrained solve for given sides.
fn constrained(views: &[CircleView], radius: f64, sides: &[f64]) -> Option<Start> {
    let p = centres(views, radius, sides);
    let (m, _, _, _) = linear(views, &p)?;
    let r = rotation_from(&m, &p);
    let (t, c, misfit) = translation(views, &p, &r)?;
    Some(Start {
        hand_sensor: iso_from_parts(&r, &t),
        centre: c,
        radius,
        sides: sides.to_vec(),
        misfit_mm: misfit,
    })
}

/// The sides of every view at radius `radius` (module docs).
fn choose_sides(views: &[CircleView], radius: f64) -> Option<Vec<f64>> {
    let h = |v: &CircleView| (radius * radius - v.radius * v.radius).max(0.0);
    let mut order: Vec<usize> = (0..views.len()).collect();
    order.sort_by(|&a, &b| h(&views[b]).total_cmp(&h(&views[a])));
    let k = views.len().min(SIDE_SUBSET);
    let subset: Vec<CircleView> = order[..k].iter().map(|&i| views[i]).collect();
    let mut best: Option<(f64, Vec<f64>)> = None;
    for bits in 0..(1u32 << (k - 1)) {
        let sides: Vec<f64> = (0..k)
            .map(|j| {
                if j > 0 && bits & (1 << (j - 1)) != 0 {
                    -1.0
                } else {
                    1.0
                }
            })
            .collect();
        let p = centres(&subset, radius, &sides);
        let Some((_, _, _, res)) = linear(&subset, &p) else {
            continue;
        };
        if best.as_ref().is_none_or(|(r, _)| res < *r) {
            best = Some((res, sides));
        }
    }
    let (_, sub_sides) = best?;
    // The subset's own solution (its orientation as the linear M says) predicts the
    // other views' centres: their sides follow.
    let p = centres(&subset, radius, &sub_sides);
    let (m, t, c, _) = linear(&subset, &p)?;
    let mut sides = vec![1.0; views.len()];
    for (j, &i) in order[..k].iter().enumerate() {
        sides[i] = sub_sides[j];
    }
    let minv = m.try_inverse()?;
    for &i in &order[k..] {
        let v = &views[i];
        let ra = v.a.rotation.to_rotation_matrix().into_inner();
        let ph = ra.transpose() * (c - v.a.translation.vector);
        let ps = minv * (ph - t);
        sides[i] = if ps.y < 0.0 { -1.0 } else { 1.0 };
    }
    Some(sides)
}

/// The sum of squared misfits of the constrained solve at `radius` with `sides`.
fn cost_at(views: &[CircleView], radius: f64, sides: &[f64]) -> f64 {
    constrained(views, radius, sides)
        .map_or(f64::INFINITY, |s| s.misfit_mm.iter().map(|e| e * e).sum())
}

/// The chosen start and its mirror (module docs); `radius` the declared sphere radius
/// (`None`: searched).
pub fn closed_form(views: &[CircleView], radius: Option<f64>) -> Result<Starts> {
    if views.len() < MIN_VIEWS {
        return Err(Error::Degenerate(format!(
            "{} views with an arc of the sphere; the closed-form start needs at least {MIN_VIEWS}",
            views.len()
        )));
    }
    let rmax = views.iter().map(|v| v.radius).fold(0.0, f64::max);
    let radius = match radius {
        Some(r) => r.max(rmax),
        None => search_radius(views, rmax)?,
    };
    let fail = || {
        Error::Degenerate(
            "the closed-form start of the profiler's hand-eye has no solution (the poses do \
             not vary enough)"
                .into(),
        )
    };
    let sides = choose_sides(views, radius).ok_or_else(fail)?;
    let flipped: Vec<f64> = sides.iter().map(|s| -s).collect();
    let a = constrained(views, radius, &sides).ok_or_else(fail)?;
    let b = constrained(views, radius, &flipped).ok_or_else(fail)?;
    let (chosen, mirror) = if a.rms_mm() <= b.rms_mm() {
        (a, b)
    } else {
        (b, a)
    };
    Ok(Starts { chosen, mirror })
}

fn search_radius(views: &[CircleView], rmax: f64) -> Result<f64> {
    let (mut lo, mut hi) = (rmax, 3.0 * rmax);
    let sides = choose_sides(views, 0.5 * (lo + hi)).ok_or_else(|| {
        Error::Degenerate("the sphere's radius cannot be started from these profiles".into())
    })?;
    let mut best = 0.5 * (lo + hi);
    for round in 0..2 {
        let s = if round == 0 {
            sides.clone()
        } else {
            choose_sides(views, best).unwrap_or_else(|| sides.clone())
        };
        let cost = |r: f64| {
            let flipped: Vec<f64> = s.iter().map(|x| -x).collect();
            cost_at(views, r, &s).min(cost_at(views, r, &flipped))
        };
        // A coarse scan, then golden section around its best.
        let n = 24;
        let grid: Vec<f64> = (0..=n)
            .map(|k| lo + (hi - lo) * k as f64 / n as f64)
            .collect();
        let k = (0..=n)
            .min_by(|&a, &b| cost(grid[a]).total_cmp(&cost(grid[b])))
            .unwrap_or(0);
        let (mut a, mut b) = (grid[k.saturating_sub(1)], grid[(k + 1).min(n)]);
        let g = 0.5 * (5f64.sqrt() - 1.0);
        for _ in 0..40 {
            let (c1, c2) = (b - g * (b - a), a + g * (b - a));
            if cost(c1) < cost(c2) {
                b = c2;
            } else {
                a = c1;
            }
        }
        best = 0.5 * (a + b);
        lo = (best - 0.1 * rmax).max(rmax);
        hi = best + 0.1 * rmax;
    }
    Ok(best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geometry::iso_from_rotvec;
    use crate::numerics::rng::SplitMix64;

    /// Views of a sphere from poses that vary stand-off, place and offset: the start
    /// recovers X and the centre exactly from exact circles, with the declared radius
    /// and without it; the mirror fits worse.
    #[test]
    fn recovers_hand_eye_and_centre_from_exact_circles() {
        let x = iso_from_rotvec(
            &Vector3::new(0.3, -2.9, 0.2),
            &Vector3::new(10.0, -5.0, 95.0),
        );
        let c = Vector3::new(600.0, 50.0, 40.0);
        let r_s = 40.0;
        let mut rng = SplitMix64(3);
        let mut views = Vec::new();
        for i in 0..15 {
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            let p = Vector3::new(
                30.0 * (rng.uniform() - 0.5),
                sign * r_s * (0.1 + 0.65 * rng.uniform()),
                250.0 + 50.0 * rng.uniform(),
            );
            let rot = iso_from_rotvec(
                &Vector3::new(
                    0.5 * (rng.uniform() - 0.5),
                    0.5 * (rng.uniform() - 0.5),
                    1.0 * (rng.uniform() - 0.5),
                ),
                &Vector3::zeros(),
            );
            // T_base_sensor maps p to c: R_bs p + t_bs = c
            let r_bs = rot.rotation.to_rotation_matrix().into_inner();
            let t_bs = c - r_bs * p;
            let bs = iso_from_parts(&r_bs, &t_bs);
            let a = bs * x.inverse();
            views.push(CircleView {
                a,
                centre: [p.x, p.z],
                radius: (r_s * r_s - p.y * p.y).sqrt(),
            });
        }
        for radius in [Some(r_s), None] {
            let s = closed_form(&views, radius).unwrap();
            let e = s.chosen.hand_sensor.inverse() * x;
            assert!(e.translation.vector.norm() < 1e-6, "{radius:?} {e:?}");
            assert!(e.rotation.angle() < 1e-8);
            assert!((s.chosen.centre - c).norm() < 1e-6);
            assert!((s.chosen.radius - r_s).abs() < 1e-5, "{}", s.chosen.radius);
            assert!(s.mirror.rms_mm() > 1.0, "{}", s.mirror.rms_mm());
        }
    }
}
