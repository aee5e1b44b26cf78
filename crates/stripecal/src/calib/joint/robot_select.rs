//! Which DH corrections the data determine: the identifiability rule of the robot block
//! ([`super::robot`]), from the adjustment's own Jacobian.
//!
//! ## The rule
//!
//! At the adjustment's solution with the robot held, the candidates' columns are added
//! and the information `N = J^T W J` and gradient `g = J^T W r` are formed. The other
//! blocks (camera, plane, `X`, `Z`, robot-pose corrections) are eliminated: `S = N_rr -
//! N_ro N_oo^-1 N_or`, `b = g_r - N_ro N_oo^-1 g_o` (what the robot columns add beyond
//! what the other blocks already explain). Scaled to unit diagonal, `C = S / (s s^T)`,
//! `c = b / s`, a greedy pivoted Cholesky picks the corrections one by one:
//! - the part of candidate `k` no chosen correction explains is `r_k = C_kk - C_kK
//!   C_KK^-1 C_Kk` (1: independent, 0: a combination of the others); a candidate with
//!   `r_k <` [`IDENTIFIABLE`] is not identifiable (its sigma would be more than
//!   `1/sqrt(IDENTIFIABLE)` = 1000 times what it is alone) and is fixed;
//! - `full` and `offsets` take the candidates in their order (base to flange; `theta0`,
//!   `d`, `a`, `alpha`, `beta` within a row), each one that is identifiable given those
//!   taken before it: the same choice for the same poses whatever the noise, so that a
//!   plan ([`super::predict`]) and the calibration of its images agree (of the HP3's
//!   parallel rows 2 and 3, row 2's `d` is kept and row 3's held);
//! - `auto` takes the one that lowers the weighted sum of squares most, `e_k^2 / r_k`
//!   with `e_k = c_k - C_kK C_KK^-1 c_K` (Gauss-Newton, in units of the residuals'
//!   variance), and stops when no candidate lowers it by [`SIGNIFICANT`] (a 5-sigma
//!   chi-square(1) test: a correction the data do not show stays fixed, so a robot that
//!   matches its DH table keeps it). The adjustment is solved with the chosen ones and
//!   the selection repeated from there until nothing is added.
//!
//! Every candidate left fixed is reported with why: absorbed by `X` or `Z` (a candidate
//! whose column the other blocks explain, e.g. the last row's offset and `X`, the first
//! row's `theta0`/`d` and `Z`), a combination of chosen corrections (named), or not
//! shown by the data.

use nalgebra::{DMatrix, DVector};

use super::layout::ParamLayout;
use super::robot::{DhParam, RobotMode};
use crate::error::{Error, Result};
use crate::numerics::lm::{JacobianRows, LeastSquares};

/// A candidate is identifiable when at least this fraction of its (scaled) information
/// is its own.
pub const IDENTIFIABLE: f64 = 1e-6;

/// `auto` frees a correction when it lowers the weighted sum of squares by at least
/// this many residual variances (chi-square(1) at 5 sigma).
pub const SIGNIFICANT: f64 = 25.0;

/// The information of a problem at `p`.
pub(super) struct Information {
    pub n: DMatrix<f64>,
    pub g: DVector<f64>,
    /// `SSR / (m - n)` of the weighted residuals.
    pub variance: f64,
}

/// `N`, `g` and the variance factor of `problem` at `p`.
pub(super) fn information<P: LeastSquares + ?Sized>(problem: &P, p: &[f64]) -> Result<Information> {
    let n = problem.num_params();
    let m = problem.num_residuals();
    let w = problem.jacobian_row_width().unwrap_or(n);
    let mut rows = JacobianRows::new(m, w, n);
    let mut r = vec![0.0; m];
    problem.residuals_and_jacobian_rows(p, &mut r, &mut rows)?;
    let mut nm = DMatrix::zeros(n, n);
    let mut g = DVector::zeros(n);
    for (i, ri) in r.iter().enumerate() {
        let (cols, vals) = rows.row(i);
        for (a, (&ca, &va)) in cols.iter().zip(vals).enumerate() {
            if va == 0.0 {
                continue;
            }
            g[ca] += va * ri;
            for (&cb, &vb) in cols[a..].iter().zip(&vals[a..]) {
                nm[(ca, cb)] += va * vb;
            }
        }
    }
    // A row's columns increase (globals, then its view's), so the upper triangle was
    // filled; mirror it.
    for i in 0..n {
        for j in 0..i {
            nm[(i, j)] = nm[(j, i)];
        }
    }
    let ssr: f64 = r.iter().map(|x| x * x).sum();
    let dof = m.saturating_sub(n).max(1) as f64;
    Ok(Information {
        n: nm,
        g,
        variance: (ssr / dof).max(f64::MIN_POSITIVE),
    })
}

/// The verdict on the candidates.
#[derive(Debug, Clone)]
pub(super) struct Selection {
    /// Indices (into the candidates) of the corrections estimated, in the order chosen.
    pub chosen: Vec<usize>,
    /// The others, with why they are fixed.
    pub fixed: Vec<(usize, String)>,
}

/// Applies the rule (module docs) to the candidates `cands` whose columns in `layout`
/// are its robot columns; `keep` are chosen already (an earlier round's).
pub(super) fn select(
    info: &Information,
    layout: &ParamLayout,
    cands: &[DhParam],
    mode: RobotMode,
    keep: &[usize],
) -> Result<Selection> {
    let rc = layout.robot_columns();
    let n = info.n.nrows();
    let others: Vec<usize> = (0..n).filter(|c| !rc.contains(c)).collect();
    let robot: Vec<usize> = rc.clone().collect();
    let (s, b) = schur(&info.n, &info.g, &robot, &others)?;
    let k = robot.len();
    let d: Vec<f64> = (0..k).map(|i| s[(i, i)].max(0.0).sqrt()).collect();
    let c = DMatrix::from_fn(k, k, |i, j| {
        if d[i] > 0.0 && d[j] > 0.0 {
            s[(i, j)] / (d[i] * d[j])
        } else {
            0.0
        }
    });
    let cg = DVector::from_fn(k, |i, _| if d[i] > 0.0 { b[i] / d[i] } else { 0.0 });
    let own = |i: usize| -> f64 {
        let nn = info.n[(robot[i], robot[i])];
        if nn > 0.0 {
            s[(i, i)] / nn
        } else {
            0.0
        }
    };
    let mut chosen: Vec<usize> = keep.to_vec();
    if mode != RobotMode::Auto {
        // In the candidates' order (base to flange; theta0, d, a, alpha, beta): the
        // same choice for the same poses whatever the noise (a plan and its data agree).
        for i in 0..k {
            if chosen.contains(&i) || own(i) < IDENTIFIABLE {
                continue;
            }
            let inv = sub_inverse(&c, &chosen);
            if residual(&c, &cg, &chosen, &inv, i).0 >= IDENTIFIABLE {
                chosen.push(i);
            }
        }
    }
    if mode == RobotMode::Auto {
        // Forward selection by the fall of the weighted sum of squares.
        loop {
            let inv = sub_inverse(&c, &chosen);
            let mut best: Option<(usize, f64)> = None;
            for i in 0..k {
                if chosen.contains(&i) || own(i) < IDENTIFIABLE {
                    continue;
                }
                let (r, e) = residual(&c, &cg, &chosen, &inv, i);
                if r < IDENTIFIABLE {
                    continue;
                }
                let score = e * e / r / info.variance;
                if score < SIGNIFICANT {
                    continue;
                }
                if best.is_none_or(|(_, s0)| score > s0) {
                    best = Some((i, score));
                }
            }
            match best {
                Some((i, _)) => chosen.push(i),
                None => break,
            }
        }
    }
    let inv = sub_inverse(&c, &chosen);
    let sel = Chosen {
        c: &c,
        cg: &cg,
        chosen: &chosen,
        inv: &inv,
    };
    let fixed = (0..k)
        .filter(|i| !chosen.contains(i))
        .map(|i| (i, reason(info, layout, &robot, &sel, i, cands, mode)))
        .collect();
    Ok(Selection { chosen, fixed })
}

/// The outcome of the selection: the robot columns' scaled reduced system `c`, `cg`
/// (module docs), the `chosen` candidates and the inverse `inv` of `c` restricted to them.
struct Chosen<'a> {
    c: &'a DMatrix<f64>,
    cg: &'a DVector<f64>,
    chosen: &'a [usize],
    inv: &'a DMatrix<f64>,
}

/// Why candidate `i` stays fixed.
fn reason(
    info: &Information,
    layout: &ParamLayout,
    robot: &[usize],
    sel: &Chosen<'_>,
    i: usize,
    cands: &[DhParam],
    mode: RobotMode,
) -> String {
    let Chosen { c, cg, chosen, inv } = *sel;
    let nn = info.n[(robot[i], robot[i])];
    if nn <= 0.0 {
        return "no observation depends on it".into();
    }
    // Absorbed by one transform alone?
    let names = layout.names();
    for (prefix, what) in [
        ("hand_cam_", "the hand-eye X"),
        ("base_board_", "the robot-world Z"),
        ("sphere_c", "the sphere's centre"),
    ] {
        let block: Vec<usize> = (0..names.len())
            .filter(|&j| names[j].starts_with(prefix))
            .collect();
        if block.is_empty() {
            continue;
        }
        if let Ok((s1, _)) = schur(&info.n, &info.g, &[robot[i]], &block) {
            if s1[(0, 0)] / nn < IDENTIFIABLE {
                return format!("absorbed by {what} (indistinguishable from it)");
            }
        }
    }
    let others: Vec<usize> = (0..info.n.nrows()).filter(|j| !robot.contains(j)).collect();
    if let Ok((s1, _)) = schur(&info.n, &info.g, &[robot[i]], &others) {
        if s1[(0, 0)] / nn < IDENTIFIABLE {
            return "absorbed by the hand-eye X, the robot-world Z and the camera together".into();
        }
    }
    let (r, e) = residual(c, cg, chosen, inv, i);
    if r < IDENTIFIABLE {
        // The chosen corrections it is a combination of: the largest coefficients.
        let coef: Vec<(usize, f64)> = chosen
            .iter()
            .enumerate()
            .map(|(a, &j)| {
                (
                    j,
                    (0..chosen.len())
                        .map(|b| inv[(a, b)] * c[(chosen[b], i)])
                        .sum(),
                )
            })
            .collect();
        let top = coef.iter().map(|x| x.1.abs()).fold(0.0, f64::max);
        let parts: Vec<String> = coef
            .iter()
            .filter(|x| x.1.abs() >= 0.1 * top && top > 0.0)
            .map(|x| cands[x.0].name())
            .collect();
        return format!(
            "a combination of {} (with X and Z): not identifiable",
            if parts.is_empty() {
                "the others".into()
            } else {
                parts.join(", ")
            }
        );
    }
    if mode == RobotMode::Auto {
        return format!(
            "not shown by the data: freeing it would lower the weighted sum of squares by {:.1} \
             residual variances (< {SIGNIFICANT})",
            e * e / r / info.variance
        );
    }
    "not identifiable".into()
}

/// `(r_i, e_i)` of candidate `i` given the chosen set (module docs).
fn residual(
    c: &DMatrix<f64>,
    cg: &DVector<f64>,
    chosen: &[usize],
    inv: &DMatrix<f64>,
    i: usize,
) -> (f64, f64) {
    let m = chosen.len();
    let cik: Vec<f64> = chosen.iter().map(|&j| c[(i, j)]).collect();
    let mut r = c[(i, i)];
    let mut e = cg[i];
    for a in 0..m {
        for b in 0..m {
            r -= cik[a] * inv[(a, b)] * cik[b];
            e -= cik[a] * inv[(a, b)] * cg[chosen[b]];
        }
    }
    (r, e)
}

/// The inverse of `c` restricted to `idx` (identity-sized 0x0 when empty).
fn sub_inverse(c: &DMatrix<f64>, idx: &[usize]) -> DMatrix<f64> {
    let m = DMatrix::from_fn(idx.len(), idx.len(), |a, b| c[(idx[a], idx[b])]);
    m.clone()
        .cholesky()
        .map(|ch| ch.inverse())
        .or_else(|| m.try_inverse())
        .unwrap_or_else(|| DMatrix::zeros(idx.len(), idx.len()))
}

/// The Schur complement of `n` on the columns `keep` with `elim` eliminated, and the
/// reduced gradient.
fn schur(
    n: &DMatrix<f64>,
    g: &DVector<f64>,
    keep: &[usize],
    elim: &[usize],
) -> Result<(DMatrix<f64>, DVector<f64>)> {
    let nkk = DMatrix::from_fn(keep.len(), keep.len(), |a, b| n[(keep[a], keep[b])]);
    let gk = DVector::from_fn(keep.len(), |a, _| g[keep[a]]);
    if elim.is_empty() {
        return Ok((nkk, gk));
    }
    let noo = DMatrix::from_fn(elim.len(), elim.len(), |a, b| n[(elim[a], elim[b])]);
    let nko = DMatrix::from_fn(keep.len(), elim.len(), |a, b| n[(keep[a], elim[b])]);
    let go = DVector::from_fn(elim.len(), |a, _| g[elim[a]]);
    // Scale to unit diagonal for a well-conditioned factorisation.
    let sd: Vec<f64> = (0..elim.len())
        .map(|a| noo[(a, a)].max(f64::MIN_POSITIVE).sqrt())
        .collect();
    let scaled = DMatrix::from_fn(elim.len(), elim.len(), |a, b| noo[(a, b)] / (sd[a] * sd[b]));
    let ch = scaled.cholesky().ok_or_else(|| {
        Error::Degenerate(
            "the robot block's identifiability: the other blocks are not determined".into(),
        )
    })?;
    let nko_s = DMatrix::from_fn(keep.len(), elim.len(), |a, b| nko[(a, b)] / sd[b]);
    let go_s = DVector::from_fn(elim.len(), |a, _| go[a] / sd[a]);
    let x = ch.solve(&nko_s.transpose());
    let y = ch.solve(&go_s);
    Ok((nkk - &nko_s * x, gk - &nko_s * y))
}
