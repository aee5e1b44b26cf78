//! The pairing search: which views' robot poses do not fit their images.
//!
//! A view pairs a robot pose `A_i = T_base_hand` with an image, whose board pose is
//! `B_i = T_board_cam`; through the rig, `A_i X = Z B_i`. A view whose robot pose
//! belongs to another image (two views swapped, every pose shifted by a row, a mistyped
//! joint reading) breaks that equation, and a least-squares solve over all views hides
//! it by spreading the error over every view. The search is robust instead:
//!
//! 1. **Least median of squares over minimal subsets.** Every triple of views (a random,
//!    seeded sample of them when there are more than [`PairingOptions::max_subsets`])
//!    gives `X` and `Z` (linear `AX = ZB`, [`crate::calib::axzb`]); each view's
//!    disagreement under it is scored, and the triple whose `h`-th smallest score is
//!    the lowest (`h = n/2 + 1`) wins. A triple of good views fits the good views; a
//!    triple with a wrong view fits almost nothing. Up to just under half the views may
//!    be wrong.
//! 2. **Agreement from the agreeing views' own scatter.** `X`, `Z` are solved again from
//!    the views within the limits; each member's disagreement is its leave-one-out
//!    prediction error (solved without it), each other view's its prediction error under
//!    the members' solution; the limits are `factor` times the members' median rotation
//!    and translation errors, never below the floors ([`PairingOptions`]); repeated until
//!    the members do not change. Every limit comes from the data's own scatter: a robot
//!    that is off by a millimetre everywhere raises the median, not the count of views
//!    that disagree.
//! 3. For every view that disagrees, the view whose robot pose its image fits
//!    ([`Consensus::fits_pose_of`]): two views that fit each other's poses were swapped.
//! 4. **Coherence.** Limits relative to the scatter cannot see a pairing that is wrong
//!    everywhere (a shifted pose column): then everything scatters alike. The members'
//!    median errors are therefore also compared with the motions between the views
//!    (median rotation angle and translation between pairs of robot poses): a set whose
//!    disagreement is above [`PairingOptions::coherence`] of the motion that should
//!    determine `X` and `Z` is not a consensus ([`Consensus::coherent`]). Real robots
//!    are off by a thousandth of their motions, mispaired views by a third or more.
//!
//! [`find_shift`] asks the same question of the pairing of image `k` with the robot pose
//! of row `k + s`: a pose column exported one row off agrees almost everywhere at
//! `s = 1` (or `-1`) and almost nowhere at `s = 0`.

use crate::calib::axzb::{solve_axzb_with, AxzbOptions, AxzbSolution};
use crate::error::{Error, Result};
use crate::model::geometry::Iso3;
use crate::numerics::rng::SplitMix64;
use crate::numerics::robust::median;

/// The limits of [`find_consensus`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairingOptions {
    /// A view disagrees when its rotation or translation error exceeds this many times
    /// the agreeing views' median (default 8).
    pub factor: f64,
    /// Floor of the rotation limit, degrees (default 0.1).
    pub min_deg: f64,
    /// Floor of the translation limit, relative to the median stand-off `|t_B|`
    /// (default 0.005).
    pub min_rel: f64,
    /// Most triples tried (default 500: all of them up to 15 views). Each scores every
    /// view, so the search costs triples times views. With just under half the views
    /// wrong a random triple is all good with probability about 1/8, and 500 miss every
    /// good one with probability 0.875^500, about 1e-29 (the winner's members are then
    /// solved again, step 2, so a better good triple changes nothing); 2000 made the
    /// search a tenth of a 60-view calibration and quadratic in the views.
    pub max_subsets: usize,
    /// The members' median disagreement may be at most this fraction of the median
    /// motion between views (rotation angle and translation; default 0.1).
    pub coherence: f64,
}

impl Default for PairingOptions {
    fn default() -> Self {
        PairingOptions {
            factor: 8.0,
            min_deg: 0.1,
            min_rel: 0.005,
            max_subsets: 500,
            coherence: 0.1,
        }
    }
}

/// The outcome of [`find_consensus`].
#[derive(Debug, Clone)]
pub struct Consensus {
    /// Per view: whether its robot pose agrees with its image.
    pub agrees: Vec<bool>,
    /// Per view: rotation (deg) and translation (mm) disagreement of `A_i X` and `Z B_i`
    /// (a member's from the solution without it, a non-member's from the members').
    pub rotation_deg: Vec<f64>,
    pub translation_mm: Vec<f64>,
    /// The members' median errors (deg, mm).
    pub median: (f64, f64),
    /// The median motion between pairs of robot poses (rotation deg, translation mm).
    pub motion: (f64, f64),
    /// Whether the members' median errors are within [`PairingOptions::coherence`] of
    /// the motion (module docs); `false` means no consensus at all. `true` when no
    /// subset of views determines `X` and `Z` (nothing can be told).
    pub coherent: bool,
    /// The limits applied (deg, mm).
    pub limit: (f64, f64),
    /// Per disagreeing view: another view whose robot pose its image fits within the
    /// limits (the closest), if any.
    pub fits_pose_of: Vec<Option<usize>>,
    /// `X`, `Z` from the agreeing views (`None` when fewer than 3 agree).
    pub solution: Option<AxzbSolution>,
}

impl Consensus {
    /// How many views agree (0 when the consensus is not coherent).
    pub fn agreeing(&self) -> usize {
        if self.coherent {
            self.agrees.iter().filter(|&&x| x).count()
        } else {
            0
        }
    }

    /// Indices of the views that agree.
    pub fn members(&self) -> Vec<usize> {
        (0..self.agrees.len()).filter(|&i| self.agrees[i]).collect()
    }

    /// Indices of the views that disagree.
    pub fn outliers(&self) -> Vec<usize> {
        (0..self.agrees.len())
            .filter(|&i| !self.agrees[i])
            .collect()
    }

    /// Pairs `(i, j)`, `i < j`, of disagreeing views whose images fit each other's
    /// robot poses.
    pub fn swapped_pairs(&self) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        for (i, f) in self.fits_pose_of.iter().enumerate() {
            if let Some(j) = *f {
                if i < j && self.fits_pose_of.get(j).copied().flatten() == Some(i) {
                    out.push((i, j));
                }
            }
        }
        out
    }
}

/// Rotation (deg) and translation (mm) disagreement of `A X` and `Z B`.
pub fn pose_error(a: &Iso3, x: &Iso3, z: &Iso3, b: &Iso3) -> (f64, f64) {
    let l = a * x;
    let r = z * b;
    (
        l.rotation.angle_to(&r.rotation).to_degrees(),
        (l.translation.vector - r.translation.vector).norm(),
    )
}

/// Linear `AX = ZB` (no refinement) of the views `idx`.
fn solve_subset(a: &[Iso3], b: &[Iso3], idx: &[usize], refine: bool) -> Result<AxzbSolution> {
    let sa: Vec<Iso3> = idx.iter().map(|&i| a[i]).collect();
    let sb: Vec<Iso3> = idx.iter().map(|&i| b[i]).collect();
    solve_axzb_with(&sa, &sb, &AxzbOptions { refine })
}

/// The triples tried: all of them, or a seeded sample of `max` distinct ones.
fn triples(n: usize, max: usize) -> Vec<[usize; 3]> {
    let total = n * (n - 1) * (n - 2) / 6;
    if total <= max {
        let mut out = Vec::with_capacity(total);
        for i in 0..n {
            for j in i + 1..n {
                for k in j + 1..n {
                    out.push([i, j, k]);
                }
            }
        }
        return out;
    }
    let mut rng = SplitMix64(0x5EED_0FC0_5E05);
    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::with_capacity(max);
    while out.len() < max {
        let mut t = [rng.below(n), rng.below(n), rng.below(n)];
        t.sort_unstable();
        if t[0] != t[1] && t[1] != t[2] && seen.insert(t) {
            out.push(t);
        }
    }
    out
}

/// Finds the views whose robot pose (`a[i] = T_base_hand`) agrees with their image
/// (`b[i] = T_board_cam`) and those that do not (module docs). With fewer than 4
/// views nothing can be told apart: every view is reported as agreeing.
///
/// Errors: [`Error::InvalidInput`] for different lengths or non-finite poses.
pub fn find_consensus(a: &[Iso3], b: &[Iso3], opts: &PairingOptions) -> Result<Consensus> {
    let n = a.len();
    if b.len() != n {
        return Err(Error::InvalidInput(format!(
            "consensus: {} robot poses for {} board poses",
            n,
            b.len()
        )));
    }
    let finite = |t: &Iso3| t.to_homogeneous().iter().all(|x| x.is_finite());
    if let Some(i) = (0..n).find(|&i| !finite(&a[i]) || !finite(&b[i])) {
        return Err(Error::InvalidInput(format!(
            "consensus: pose {i} is not finite"
        )));
    }
    let standoff = {
        let mut d: Vec<f64> = b.iter().map(|p| p.translation.vector.norm()).collect();
        median(&mut d).unwrap_or(0.0)
    };
    let floor = (opts.min_deg, opts.min_rel * standoff);
    let all: Vec<usize> = (0..n).collect();
    if n < 4 {
        let solution = solve_subset(a, b, &all, true).ok();
        return Ok(finish(
            a,
            b,
            vec![true; n],
            solution,
            (0.0, 0.0),
            floor,
            opts,
        ));
    }
    // 1. least median of squares over triples
    let h = n / 2 + 1;
    let score = |e: (f64, f64)| e.0 / floor.0.max(1e-12) + e.1 / floor.1.max(1e-12);
    let mut best: Option<(f64, AxzbSolution, [usize; 3])> = None;
    for t in triples(n, opts.max_subsets) {
        let Ok(s) = solve_subset(a, b, &t, false) else {
            continue;
        };
        let mut sc: Vec<f64> = (0..n)
            .map(|i| score(pose_error(&a[i], &s.x, &s.z, &b[i])))
            .collect();
        sc.sort_by(f64::total_cmp);
        let obj = sc[h - 1];
        if best.as_ref().is_none_or(|(o, _, _)| obj < *o) {
            best = Some((obj, s, t));
        }
    }
    let Some((_, seed, triple)) = best else {
        // no triple determines X and Z: let the caller's solve say why
        let solution = solve_subset(a, b, &all, true).ok();
        return Ok(finish(
            a,
            b,
            vec![true; n],
            solution,
            (0.0, 0.0),
            floor,
            opts,
        ));
    };
    // the h best-fitting views under the seed set the first limits
    let errs: Vec<(f64, f64)> = (0..n)
        .map(|i| {
            let e = pose_error(&a[i], &seed.x, &seed.z, &b[i]);
            if triple.contains(&i) {
                in_sample(e)
            } else {
                e
            }
        })
        .collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| score(errs[i]).total_cmp(&score(errs[j])));
    let core: Vec<(f64, f64)> = order[..h].iter().map(|&i| errs[i]).collect();
    let mut med = medians(&core);
    let mut agrees: Vec<bool> = errs
        .iter()
        .map(|e| within(*e, limits(med, floor, opts.factor)))
        .collect();
    // 2. iterate: members' solution, leave-one-out errors, limits from their scatter
    let mut solution = None;
    for _ in 0..6 {
        let members: Vec<usize> = (0..n).filter(|&i| agrees[i]).collect();
        if members.len() < 3 {
            break;
        }
        let Ok(s) = solve_subset(a, b, &members, true) else {
            break;
        };
        let e = prediction_errors(a, b, &members, &s);
        let member_errs: Vec<(f64, f64)> = members.iter().map(|&i| e[i]).collect();
        med = medians(&member_errs);
        let lim = limits(med, floor, opts.factor);
        let next: Vec<bool> = e.iter().map(|x| within(*x, lim)).collect();
        solution = Some(s);
        if next == agrees {
            break;
        }
        agrees = next;
    }
    Ok(finish(a, b, agrees, solution, med, floor, opts))
}

/// A view's residual in a solve from 3 views (12 unknowns from 18 equations: leverage
/// about 2/3) is about a third of its error when predicted by the others (`sigma
/// sqrt(1 - h)` against `sigma / sqrt(1 - h)`); this many times it stands for the
/// prediction errors the limits are made of. Without it 3 members' residuals set limits
/// a third of the scatter: etna_calib4's even views (5) refused two views by 0.73 and
/// 1.85 deg (limit 0.42 deg) that all 9 views accept (limit 3.66 deg).
const IN_SAMPLE_FACTOR: f64 = 3.0;

/// A residual in a solve from 3 views as the prediction error it stands for.
fn in_sample(e: (f64, f64)) -> (f64, f64) {
    (IN_SAMPLE_FACTOR * e.0, IN_SAMPLE_FACTOR * e.1)
}

/// Each view's error: a member's under the members' solution without it (when at least
/// 4 members leave 3; with 3 members their residual, [`in_sample`]), every other view's
/// under `s`.
fn prediction_errors(
    a: &[Iso3],
    b: &[Iso3],
    members: &[usize],
    s: &AxzbSolution,
) -> Vec<(f64, f64)> {
    (0..a.len())
        .map(|i| {
            if members.len() >= 4 && members.contains(&i) {
                let others: Vec<usize> = members.iter().copied().filter(|&j| j != i).collect();
                if let Ok(si) = solve_subset(a, b, &others, true) {
                    return pose_error(&a[i], &si.x, &si.z, &b[i]);
                }
            }
            let e = pose_error(&a[i], &s.x, &s.z, &b[i]);
            if members.len() == 3 && members.contains(&i) {
                in_sample(e)
            } else {
                e
            }
        })
        .collect()
}

fn medians(e: &[(f64, f64)]) -> (f64, f64) {
    let mut r: Vec<f64> = e.iter().map(|x| x.0).collect();
    let mut t: Vec<f64> = e.iter().map(|x| x.1).collect();
    (median(&mut r).unwrap_or(0.0), median(&mut t).unwrap_or(0.0))
}

fn limits(med: (f64, f64), floor: (f64, f64), factor: f64) -> (f64, f64) {
    ((factor * med.0).max(floor.0), (factor * med.1).max(floor.1))
}

fn within(e: (f64, f64), lim: (f64, f64)) -> bool {
    e.0 <= lim.0 && e.1 <= lim.1
}

/// The consensus record: the final errors and, for each disagreeing view, whose robot
/// pose its image fits.
fn finish(
    a: &[Iso3],
    b: &[Iso3],
    agrees: Vec<bool>,
    solution: Option<AxzbSolution>,
    med: (f64, f64),
    floor: (f64, f64),
    opts: &PairingOptions,
) -> Consensus {
    let n = a.len();
    let limit = limits(med, floor, opts.factor);
    let motion = motion(a);
    // without any solution nothing can be told (the caller's solve says why)
    let coherent = solution.is_none()
        || (med.0 <= opts.coherence * motion.0 && med.1 <= opts.coherence * motion.1);
    let members: Vec<usize> = (0..n).filter(|&i| agrees[i]).collect();
    let (errs, fits_pose_of) = match &solution {
        Some(s) => {
            let e = prediction_errors(a, b, &members, s);
            let fits = (0..n)
                .map(|i| {
                    if agrees[i] {
                        return None;
                    }
                    (0..n)
                        .filter(|&j| j != i)
                        .map(|j| (j, pose_error(&a[j], &s.x, &s.z, &b[i])))
                        .filter(|(_, e)| within(*e, limit))
                        .min_by(|x, y| {
                            (x.1 .0 / limit.0 + x.1 .1 / limit.1)
                                .total_cmp(&(y.1 .0 / limit.0 + y.1 .1 / limit.1))
                        })
                        .map(|(j, _)| j)
                })
                .collect();
            (e, fits)
        }
        None => (vec![(f64::NAN, f64::NAN); n], vec![None; n]),
    };
    Consensus {
        agrees,
        rotation_deg: errs.iter().map(|e| e.0).collect(),
        translation_mm: errs.iter().map(|e| e.1).collect(),
        median: med,
        motion,
        coherent,
        limit,
        fits_pose_of,
        solution,
    }
}

/// The median rotation angle (deg) and translation (mm) between pairs of robot poses.
fn motion(a: &[Iso3]) -> (f64, f64) {
    let (mut r, mut t) = (Vec::new(), Vec::new());
    for i in 0..a.len() {
        for j in i + 1..a.len() {
            r.push(a[i].rotation.angle_to(&a[j].rotation).to_degrees());
            t.push((a[i].translation.vector - a[j].translation.vector).norm());
        }
    }
    (median(&mut r).unwrap_or(0.0), median(&mut t).unwrap_or(0.0))
}

/// A pairing of the images with the robot poses of other rows that agrees far better
/// than the given one.
#[derive(Debug, Clone, PartialEq)]
pub struct Shift {
    /// Image `k` pairs with the robot pose of row `k + rows`.
    pub rows: isize,
    /// Views that agree when shifted, and how many pairs the shift leaves.
    pub agreeing: usize,
    pub pairs: usize,
}

/// Tests whether the images pair with the robot poses of neighbouring rows: `rows[k]`
/// is view `k`'s row in views.csv, `a[k]`, `b[k]` its robot and board poses. Returns the
/// shift (1 or 2 rows either way) under which at least two thirds of the shifted pairs
/// agree, when that is more than twice as many as agree unshifted (`agree_unshifted`).
/// `None` too when `rows`, `a` and `b` differ in length.
pub fn find_shift(
    rows: &[usize],
    a: &[Iso3],
    b: &[Iso3],
    agree_unshifted: usize,
    opts: &PairingOptions,
) -> Option<Shift> {
    if rows.len() != a.len() || a.len() != b.len() {
        return None;
    }
    let mut best: Option<Shift> = None;
    for s in [1isize, -1, 2, -2] {
        let (mut sa, mut sb) = (Vec::new(), Vec::new());
        for (k, &r) in rows.iter().enumerate() {
            let target = r as isize + s;
            if let Some(j) = rows.iter().position(|&q| q as isize == target) {
                sa.push(a[j]);
                sb.push(b[k]);
            }
        }
        if sa.len() < 4 {
            continue;
        }
        let Ok(c) = find_consensus(&sa, &sb, opts) else {
            continue;
        };
        let agreeing = c.agreeing();
        let pairs = sa.len();
        if 3 * agreeing >= 2 * pairs
            && agreeing > agree_unshifted.saturating_mul(2)
            && best
                .as_ref()
                .is_none_or(|b| agreeing * b.pairs > b.agreeing * pairs)
        {
            best = Some(Shift {
                rows: s,
                agreeing,
                pairs,
            });
        }
    }
    best
}

/// A pose column that is off by one row from some row on: a pose row deleted (the poses
/// below it moved up) or inserted. See [`find_break`].
#[derive(Debug, Clone, PartialEq)]
pub struct Break {
    /// The first view (its row in views.csv, 0-based) whose image does not fit its own
    /// robot pose; the views before it agree as given.
    pub first: usize,
    /// From `first` on, image `k` pairs with the robot pose of row `k + rows` (`-1`: a
    /// pose row deleted, `+1`: one inserted).
    pub rows: isize,
    /// Views that agree paired so, and how many pairs that pairing has.
    pub agreeing: usize,
    pub pairs: usize,
}

/// Tests whether the poses are off by one row from some view on (a deleted or an
/// inserted pose row), as [`find_shift`] tests the whole column: for each view `k` and
/// `s = -1, +1`, the views before `k` paired as given and image `r >= k` with the pose of
/// row `r + s` (a pose row at or after `k`). Returns the break under which at least two
/// thirds of those pairs agree, every view before it among them, when that is more than
/// agree as given (`agree_unshifted`) and both sides hold at least 2 views; the one with
/// the most agreeing pairs. Costs one [`find_consensus`] per candidate: for the failure
/// message only.
pub fn find_break(
    rows: &[usize],
    a: &[Iso3],
    b: &[Iso3],
    agree_unshifted: usize,
    opts: &PairingOptions,
) -> Option<Break> {
    let n = rows.len();
    if a.len() != n || b.len() != n || n < 5 {
        return None;
    }
    let mut best: Option<Break> = None;
    for s in [-1isize, 1] {
        for k in 2..n.saturating_sub(1) {
            let first = rows[k];
            let (mut sa, mut sb) = (Vec::new(), Vec::new());
            for j in 0..k {
                sa.push(a[j]);
                sb.push(b[j]);
            }
            for (j, &r) in rows.iter().enumerate().skip(k) {
                let target = r as isize + s;
                if target < first as isize {
                    continue;
                }
                if let Some(t) = rows.iter().position(|&q| q as isize == target) {
                    sa.push(a[t]);
                    sb.push(b[j]);
                }
            }
            let pairs = sa.len();
            if pairs < 5 || pairs - k < 2 {
                continue;
            }
            let Ok(c) = find_consensus(&sa, &sb, opts) else {
                continue;
            };
            let agreeing = c.agreeing();
            let before_agree = c.coherent && c.agrees[..k].iter().all(|&x| x);
            if before_agree
                && 3 * agreeing >= 2 * pairs
                && agreeing > agree_unshifted
                && best.as_ref().is_none_or(|b| agreeing > b.agreeing)
            {
                best = Some(Break {
                    first,
                    rows: s,
                    agreeing,
                    pairs,
                });
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geometry::iso_from_parts;
    use nalgebra::{Rotation3, Unit, Vector3};

    fn pose(axis: [f64; 3], angle_deg: f64, t: [f64; 3]) -> Iso3 {
        let r = Rotation3::from_axis_angle(
            &Unit::new_normalize(Vector3::from(axis)),
            angle_deg.to_radians(),
        );
        iso_from_parts(&r.into_inner(), &Vector3::from(t))
    }

    /// A rig with `n` views: robot poses, board poses `B_i = Z^-1 A_i X` with a small
    /// deterministic disturbance (about 0.01 deg / 0.05 mm).
    fn rig(n: usize) -> (Vec<Iso3>, Vec<Iso3>) {
        let x = pose([0.2, -0.5, 1.0], 170.0, [30.0, 5.0, 60.0]);
        let z = pose([0.1, 0.1, 1.0], 12.0, [400.0, -50.0, 20.0]);
        let mut rng = SplitMix64(7);
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for k in 0..n {
            let f = k as f64;
            let ak = pose(
                [(f * 1.3).sin(), (f * 0.7).cos(), 1.0],
                150.0 + 9.0 * f,
                [
                    350.0 + 12.0 * f,
                    -40.0 + 30.0 * (f * 0.9).sin(),
                    250.0 + 7.0 * f,
                ],
            );
            let noise = pose(
                [rng.normal(), rng.normal(), rng.normal()],
                0.01,
                [
                    0.05 * rng.normal(),
                    0.05 * rng.normal(),
                    0.05 * rng.normal(),
                ],
            );
            a.push(ak);
            b.push(z.inverse() * ak * x * noise);
        }
        (a, b)
    }

    #[test]
    fn clean_views_all_agree() {
        for n in [4, 5, 8, 15] {
            let (a, b) = rig(n);
            let c = find_consensus(&a, &b, &PairingOptions::default()).unwrap();
            assert!(c.agrees.iter().all(|&x| x), "n = {n}: {:?}", c.agrees);
            assert!(c.coherent, "n = {n}: {:?} {:?}", c.median, c.motion);
            assert!(c.median.0 < 0.05 && c.median.1 < 0.5, "{:?}", c.median);
        }
    }

    #[test]
    fn swapped_pairs_are_found_and_named() {
        for (n, swaps) in [
            (5, vec![(1, 3)]),
            (15, vec![(2, 9)]),
            (15, vec![(0, 5), (7, 12)]),
        ] {
            let (mut a, b) = rig(n);
            for &(i, j) in &swaps {
                a.swap(i, j);
            }
            let c = find_consensus(&a, &b, &PairingOptions::default()).unwrap();
            let mut want: Vec<usize> = swaps.iter().flat_map(|&(i, j)| [i, j]).collect();
            want.sort_unstable();
            assert_eq!(c.outliers(), want, "n = {n}");
            let mut pairs = c.swapped_pairs();
            pairs.sort_unstable();
            let mut sw = swaps.clone();
            sw.sort_unstable();
            assert_eq!(pairs, sw, "n = {n}");
        }
    }

    #[test]
    fn a_shifted_pose_column_is_found() {
        let (a, b) = rig(15);
        let rows: Vec<usize> = (0..15).collect();
        // the pose column slid down a row: row k holds image k - 1's pose, so image k's
        // pose is on row k + 1
        let shifted_a: Vec<Iso3> = (0..15).map(|k| a[(k + 14) % 15]).collect();
        let c = find_consensus(&shifted_a, &b, &PairingOptions::default()).unwrap();
        assert!(!c.coherent, "{:?} {:?} {:?}", c.agrees, c.median, c.motion);
        let s = find_shift(&rows, &shifted_a, &b, c.agreeing(), &Default::default());
        let s = s.expect("a shift");
        assert_eq!(s.rows, 1);
        assert_eq!((s.agreeing, s.pairs), (14, 14));
        // the clean pairing has no shift
        assert_eq!(find_shift(&rows, &a, &b, 15, &Default::default()), None);
    }

    /// A pose row deleted at view 6 (the poses below moved up, the last image's row
    /// dropped): views 0..5 agree as given, image r > 6 fits the pose of row r - 1.
    /// Inserted at view 7: image r >= 7 fits the pose of row r + 1.
    #[test]
    fn a_deleted_or_inserted_pose_row_is_found() {
        let (a, b) = rig(15);
        let opts = PairingOptions::default();
        // deleted: 14 rows, row i holds pose i (i < 6) or i + 1
        let da: Vec<Iso3> = (0..14).map(|i| a[if i < 6 { i } else { i + 1 }]).collect();
        let db: Vec<Iso3> = b[..14].to_vec();
        let rows: Vec<usize> = (0..14).collect();
        let c = find_consensus(&da, &db, &opts).unwrap();
        let br = find_break(&rows, &da, &db, c.agreeing(), &opts).expect("a break");
        assert_eq!((br.first, br.rows), (6, -1), "{br:?}");
        assert!(br.agreeing >= 12, "{br:?}");
        // inserted: 15 rows, row 7 holds a stray pose, row i > 7 holds pose i - 1
        let stray = a[3] * pose([1.0, 0.0, 0.0], 20.0, [10.0, 0.0, 0.0]);
        let ia: Vec<Iso3> = (0..15)
            .map(|i| match i {
                7 => stray,
                i if i < 7 => a[i],
                i => a[i - 1],
            })
            .collect();
        let rows: Vec<usize> = (0..15).collect();
        let c = find_consensus(&ia, &b, &opts).unwrap();
        let br = find_break(&rows, &ia, &b, c.agreeing(), &opts).expect("a break");
        assert_eq!((br.first, br.rows), (7, 1), "{br:?}");
        // the clean pairing has none
        assert_eq!(find_break(&rows, &a, &b, 15, &opts), None);
    }
}
