//! The labelling of views whose image leaves it open (a symmetric board), chosen from
//! the robot poses by [`consensus`]: the views that agree are relabelled, the others
//! left out with the reason.

use crate::calib::consensus::{self, Candidates, Decision};
use crate::calib::ViewObs;
use crate::model::board::{Board, Symmetry};
use crate::model::geometry::Iso3;

/// A view after the labelling choice: the relabelled view with its `T_cam_board`, or
/// `(view, why it is left out)`.
pub(super) type Labelled = std::result::Result<(ViewObs, Iso3), (usize, String)>;

/// Chooses, for every view whose image leaves its labelling open (a symmetric board),
/// the labelling that agrees with the robot poses of the others ([`consensus`]), and
/// relabels its points and board pose. Views that cannot be decided are left out with
/// the reason (and a warning). Returns the views in `poses` order and, when the board
/// frame itself was fixed by the first view's labelling (no view's image fixes it), the
/// contract's note `"first view"`.
pub(super) fn resolve_labellings(
    views: &[ViewObs],
    poses: &[(usize, Iso3)],
    board: &Board,
    warnings: &mut Vec<String>,
) -> (Vec<Labelled>, Option<String>) {
    let items: Vec<(&ViewObs, Iso3)> = poses
        .iter()
        .filter_map(|(view, cb)| views.iter().find(|v| v.view == *view).map(|v| (v, *cb)))
        .collect();
    if items.iter().all(|(v, _)| v.alternatives.is_empty()) {
        return (
            items
                .into_iter()
                .map(|(v, cb)| Ok((v.clone(), cb)))
                .collect(),
            None,
        );
    }
    // candidates: the detected labelling, then each alternative (T_board_cam = M B)
    let motions: Vec<Vec<(Option<Symmetry>, Iso3)>> = items
        .iter()
        .map(|(v, _)| {
            std::iter::once((None, Iso3::identity()))
                .chain(
                    v.alternatives
                        .iter()
                        .map(|s| (Some(*s), consensus::symmetry_motion(board, s))),
                )
                .collect()
        })
        .collect();
    // views without a robot pose cannot take part (left as detected)
    let with_robot: Vec<usize> = (0..items.len())
        .filter(|&k| items[k].0.base_hand.is_some())
        .collect();
    let cands: Vec<Candidates> = with_robot
        .iter()
        .map(|&k| Candidates {
            a: items[k].0.base_hand.unwrap_or_else(Iso3::identity),
            b: motions[k]
                .iter()
                .map(|(_, m)| m * items[k].1.inverse())
                .collect(),
        })
        .collect();
    let decisions = consensus::choose(&cands);
    let frame_fixed_by_first = items.iter().all(|(v, _)| !v.alternatives.is_empty());
    let mut out = Vec::with_capacity(items.len());
    for (k, (v, cb)) in items.iter().enumerate() {
        let Some(pos) = with_robot.iter().position(|&j| j == k) else {
            out.push(Ok(((*v).clone(), *cb)));
            continue;
        };
        match decisions[pos] {
            Decision::Chosen { index, .. } => {
                let (sym, m) = motions[k][index];
                let v2 = relabel(v, board, sym);
                // T_cam_board of the new labelling: T_cam_board M^-1
                out.push(Ok((v2, cb * m.inverse())));
            }
            Decision::Undecided { best, second } => {
                let why = if best > 25.0 {
                    "none of its labellings agrees with the robot poses of the other views \
                     (its robot pose, or its image, is wrong?)"
                } else {
                    "its labellings agree about equally well with the robot poses of the other \
                     views"
                };
                let msg = format!(
                    "view {}: left out: its orientation on the symmetric board cannot be told: \
                     {why} (the two best disagree by {:.1} and {:.1} sigma; sigma = 0.2 deg / \
                     1 mm of screw motion)",
                    v.view,
                    best.sqrt(),
                    second.sqrt()
                );
                warnings.push(msg.clone());
                out.push(Err((v.view, msg)));
            }
        }
    }
    let note = frame_fixed_by_first.then(|| "first view".to_string());
    (out, note)
}

/// View `v` with its points relabelled by the board symmetry `sym` (`None`: as
/// detected), its labelling decided (no alternatives left).
pub(super) fn relabel(v: &ViewObs, board: &Board, sym: Option<Symmetry>) -> ViewObs {
    let mut v2 = v.clone();
    if let Some(s) = sym {
        for c in v2.circles.iter_mut() {
            if let Some((r, cc)) = s.apply(board, c.row, c.col) {
                (c.row, c.col) = (r, cc);
            }
        }
        v2.circles.sort_by_key(|c| (c.row, c.col));
    }
    v2.alternatives.clear();
    v2
}
