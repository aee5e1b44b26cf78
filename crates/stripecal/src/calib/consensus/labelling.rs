//! The labelling search: which of each view's candidate board poses agrees with the
//! robot poses of the others.
//!
//! A view's labelling may be undecided by its image (a symmetric board:
//! [`crate::vision::target::TargetDetection::alternatives`]); each labelling gives the
//! view a different board pose `B = T_board_cam`. The robot decides, through `A_i X = Z
//! B_i`: for two views, `A_j^-1 A_i X = X B_j^-1 B_i`, an `AX = XB` equation whose two
//! motions must have the same *screw invariants* whatever `X` is — the rotation angle
//! and the translation along the rotation axis. These pairwise tests need no estimate of
//! `X` or `Z`, so they work before any solve and are robust to other views being wrong.
//!
//! ## The search
//!
//! The cost of candidate `c` of view `i` against the decided views is the median over
//! them of the pair mismatch `(d_angle / 0.2 deg)^2 + (d_pitch / 1 mm)^2` (the pitch term
//! only where both rotations exceed 5 degrees, below which the axis is ill-defined).
//! Views with a single candidate start decided; if there are none, the first view's
//! first candidate does (that choice turns the board frame as a whole: it changes only
//! `T_base_board`, spec/DATASET.md), or the next view's if the first does not agree
//! with the others (a wrong robot pose). Then, repeatedly, the undecided view whose
//! best candidate is the most clearly better than its second is decided — clearly
//! meaning a best cost within five sigmas (25) and a second-best cost above that and
//! ten times the best. A view that cannot be decided that way is left undecided (the
//! caller leaves it out, saying why), never guessed: both when its labellings fit
//! equally well and when none fits (its robot pose or its image is wrong). A last pass
//! re-checks every decision against all the others.

use nalgebra::Vector3;

use crate::model::board::{Board, Symmetry};
use crate::model::geometry::Iso3;
use crate::numerics::robust::median;

/// The scales of the pair mismatch.
const SIGMA_ANGLE_DEG: f64 = 0.2;
const SIGMA_PITCH_MM: f64 = 1.0;
/// Below this rotation angle (deg) the pitch is not compared.
const MIN_ANGLE_FOR_PITCH_DEG: f64 = 5.0;
/// A decision needs the second-best cost above this and `RATIO` times the best.
const SECOND_MIN: f64 = 25.0;
const RATIO: f64 = 10.0;

/// One view's robot pose and candidate board poses.
#[derive(Debug, Clone)]
pub struct Candidates {
    /// `T_base_hand`.
    pub a: Iso3,
    /// Candidate `T_board_cam` (index 0: the labelling as detected).
    pub b: Vec<Iso3>,
}

/// The outcome for one view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Decision {
    /// Candidate `index` agrees with the others; `margin` is the second-best cost over
    /// the best (infinite for a single candidate).
    Chosen { index: usize, margin: f64 },
    /// No candidate is clearly best: `best` and `second` are their costs.
    Undecided { best: f64, second: f64 },
}

/// Rotation angle (rad) and translation along the rotation axis (mm) of a motion.
fn screw(m: &Iso3) -> (f64, f64) {
    let axis_angle = m.rotation.scaled_axis();
    let angle = axis_angle.norm();
    let pitch = if angle > 1e-9 {
        m.translation.vector.dot(&(axis_angle / angle))
    } else {
        0.0
    };
    (angle, pitch)
}

/// Mismatch of the screw invariants of `A_j^-1 A_i` and `B_j^-1 B_i`.
fn pair_cost(ai: &Iso3, bi: &Iso3, aj: &Iso3, bj: &Iso3) -> f64 {
    let (ta, pa) = screw(&(aj.inverse() * ai));
    let (tb, pb) = screw(&(bj.inverse() * bi));
    let da = (ta - tb).to_degrees() / SIGMA_ANGLE_DEG;
    let mut e = da * da;
    if ta.to_degrees() > MIN_ANGLE_FOR_PITCH_DEG && tb.to_degrees() > MIN_ANGLE_FOR_PITCH_DEG {
        // angles are in [0, pi] with their axes, so the pitches compare directly
        let dp = (pa - pb) / SIGMA_PITCH_MM;
        e += dp * dp;
    }
    e
}

/// Costs of every candidate of view `i` against the views in `decided`.
fn costs(views: &[Candidates], chosen: &[Option<usize>], i: usize) -> Vec<f64> {
    views[i]
        .b
        .iter()
        .map(|bi| {
            let mut e: Vec<f64> = chosen
                .iter()
                .enumerate()
                .filter_map(|(j, c)| {
                    let c = (*c)?;
                    (j != i).then(|| pair_cost(&views[i].a, bi, &views[j].a, &views[j].b[c]))
                })
                .collect();
            median(&mut e).unwrap_or(f64::INFINITY)
        })
        .collect()
}

/// (best index, best cost, second cost) of a cost list.
fn best_two(c: &[f64]) -> (usize, f64, f64) {
    let mut order: Vec<usize> = (0..c.len()).collect();
    order.sort_by(|&a, &b| c[a].total_cmp(&c[b]));
    let best = order[0];
    let second = order.get(1).map(|&k| c[k]).unwrap_or(f64::INFINITY);
    (best, c[best], second)
}

fn clear(best: f64, second: f64) -> bool {
    second > SECOND_MIN && second > RATIO * best
}

/// Whether a best cost agrees with the noise model (five sigmas).
fn consistent(best: f64) -> bool {
    best <= SECOND_MIN
}

/// Chooses a candidate for every view (module docs). When no view has a single
/// candidate, the first view whose first candidate agrees with the others fixes the
/// board frame (a view whose robot pose is wrong cannot).
pub fn choose(views: &[Candidates]) -> Vec<Decision> {
    let n = views.len();
    if n == 0 {
        return Vec::new();
    }
    if views.iter().any(|v| v.b.len() == 1) {
        return choose_from(views, None);
    }
    let first = choose_from(views, Some(0));
    if matches!(first[0], Decision::Chosen { .. }) {
        return first;
    }
    (1..n)
        .map(|r| choose_from(views, Some(r)))
        .zip(1..n)
        .find(|(d, r)| matches!(d[*r], Decision::Chosen { .. }))
        .map(|(d, _)| d)
        .unwrap_or(first)
}

/// [`choose`] with `reference`'s first candidate fixing the frame (if given).
fn choose_from(views: &[Candidates], reference: Option<usize>) -> Vec<Decision> {
    let n = views.len();
    let mut chosen: Vec<Option<usize>> = views
        .iter()
        .map(|v| (v.b.len() == 1).then_some(0))
        .collect();
    if let Some(r) = reference.filter(|&r| r < n && !views[r].b.is_empty()) {
        chosen[r] = Some(0);
    }
    // greedily, the clearest decision first
    loop {
        let mut best: Option<(f64, usize, usize)> = None;
        for i in (0..n).filter(|&i| chosen[i].is_none() && !views[i].b.is_empty()) {
            let c = costs(views, &chosen, i);
            let (k, b, s) = best_two(&c);
            if clear(b, s) && consistent(b) {
                let margin = s / b.max(1e-12);
                if best.is_none_or(|(m, _, _)| margin > m) {
                    best = Some((margin, i, k));
                }
            }
        }
        let Some((_, i, k)) = best else { break };
        chosen[i] = Some(k);
    }
    // re-check every multi-candidate view against all the others
    (0..n)
        .map(|i| {
            if views[i].b.len() == 1 {
                return Decision::Chosen {
                    index: 0,
                    margin: f64::INFINITY,
                };
            }
            if views[i].b.is_empty() {
                // no candidate at all: nothing to choose
                return Decision::Undecided {
                    best: f64::INFINITY,
                    second: f64::INFINITY,
                };
            }
            let others = chosen
                .iter()
                .enumerate()
                .any(|(j, c)| j != i && c.is_some());
            if !others {
                // alone: it fixes the frame only when there is nothing to check it with
                return if n == 1 && chosen[i].is_some() {
                    Decision::Chosen {
                        index: 0,
                        margin: f64::INFINITY,
                    }
                } else {
                    Decision::Undecided {
                        best: f64::INFINITY,
                        second: f64::INFINITY,
                    }
                };
            }
            let c = costs(views, &chosen, i);
            let (k, b, s) = best_two(&c);
            if Some(i) == reference {
                // its first candidate defines the frame: it must agree with the others
                let second = c.iter().skip(1).copied().fold(f64::INFINITY, f64::min);
                return if consistent(c[0]) && clear(c[0], second) {
                    Decision::Chosen {
                        index: 0,
                        margin: second / c[0].max(1e-12),
                    }
                } else {
                    Decision::Undecided { best: c[0], second }
                };
            }
            if chosen[i].is_some() && clear(b, s) && consistent(b) {
                Decision::Chosen {
                    index: k,
                    margin: s / b.max(1e-12),
                }
            } else {
                Decision::Undecided { best: b, second: s }
            }
        })
        .collect()
}

/// The board-frame motion of a symmetry: board point `p` of a point labelled `(r, c)`
/// is at `M p` when labelled `s(r, c)` (a rotation about board z and a shift).
pub fn symmetry_motion(board: &Board, s: &Symmetry) -> Iso3 {
    let angle = s.angle_deg().to_radians();
    let u = board.lattice_unit_mm();
    Iso3::from_parts(
        nalgebra::Translation3::new(u * s.shift.0 as f64, u * s.shift.1 as f64, 0.0),
        nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geometry::iso_from_parts;
    use nalgebra::{Rotation3, Unit};

    fn pose(axis: [f64; 3], angle_deg: f64, t: [f64; 3]) -> Iso3 {
        let r = Rotation3::from_axis_angle(
            &Unit::new_normalize(Vector3::from(axis)),
            angle_deg.to_radians(),
        );
        iso_from_parts(&r.into_inner(), &Vector3::from(t))
    }

    /// A rig: X, Z and robot poses; `b_i = Z^-1 A_i X`.
    fn rig(n: usize) -> (Vec<Iso3>, Vec<Iso3>) {
        let x = pose([0.2, -0.5, 1.0], 170.0, [30.0, 5.0, 60.0]);
        let z = pose([0.1, 0.1, 1.0], 12.0, [400.0, -50.0, 20.0]);
        let mut a = Vec::new();
        let mut b = Vec::new();
        for k in 0..n {
            let f = k as f64;
            let ak = pose(
                [(f * 1.3).sin(), (f * 0.7).cos(), 1.0],
                160.0 + 7.0 * f,
                [
                    350.0 + 10.0 * f,
                    -40.0 + 9.0 * (f * 0.9).sin(),
                    250.0 + 5.0 * f,
                ],
            );
            a.push(ak);
            b.push(z.inverse() * ak * x);
        }
        (a, b)
    }

    #[test]
    fn half_turns_are_resolved_from_the_robot() {
        let board = Board::chessboard(6, 8, 20.0).unwrap();
        let s = board.symmetries()[0];
        let m = symmetry_motion(&board, &s);
        // the motion maps every point onto its relabelled self
        for (r, c) in board.indices() {
            let (r2, c2) = s.apply(&board, r, c).unwrap();
            let p = m * nalgebra::Point3::from(board.center(r, c));
            assert!((p.coords - board.center(r2, c2)).norm() < 1e-9);
        }
        let (a, b) = rig(8);
        // each view offers (true, flipped) in a view-dependent order; the reference's
        // first candidate is the truth
        let views: Vec<Candidates> = a
            .iter()
            .zip(&b)
            .enumerate()
            .map(|(k, (ak, bk))| {
                // T_board_cam of the alternative labelling: M B
                let flipped = m * bk;
                let cands = if k % 3 == 1 {
                    vec![flipped, *bk]
                } else {
                    vec![*bk, flipped]
                };
                Candidates { a: *ak, b: cands }
            })
            .collect();
        let d = choose(&views);
        for (k, dk) in d.iter().enumerate() {
            let want = if k % 3 == 1 { 1 } else { 0 };
            match dk {
                Decision::Chosen { index, margin } => {
                    assert_eq!(*index, want, "view {k}");
                    assert!(*margin > 100.0, "view {k}: margin {margin}");
                }
                other => panic!("view {k}: {other:?}"),
            }
        }
        // a view whose robot pose belongs to another view is not decided
        let mut bad = views.clone();
        bad[4].a = a[6];
        let d = choose(&bad);
        assert!(matches!(d[4], Decision::Undecided { .. }), "{:?}", d[4]);
        assert!(matches!(d[5], Decision::Chosen { index: 0, .. }));
    }

    #[test]
    fn screw_invariants_of_a_known_motion() {
        let m = pose([0.0, 0.0, 1.0], 30.0, [1.0, 2.0, 5.0]);
        let (t, p) = screw(&m);
        assert!((t.to_degrees() - 30.0).abs() < 1e-9 && (p - 5.0).abs() < 1e-9);
    }
}
