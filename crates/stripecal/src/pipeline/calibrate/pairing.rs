//! Step 4: the views' robot poses against their images ([`consensus::pairing`]), and
//! `AX = ZB` from the views that agree.
//!
//! Views that disagree (a swapped pair, a mistyped joint reading) are named; they are
//! left out when the rest is consistent and large enough ([`enough_left`]); otherwise the
//! `pairing` gate fails (DECISIONS 1), and the calibration of the views that agree is
//! kept only for inspection. When no consensus exists at all, shifted pairings are tried
//! ([`consensus::find_shift`]): a pose column one row off is reported in those words.

use super::{CalibrateOptions, ViewStatus};
use crate::calib::axzb::{solve_axzb, solve_axzb_with, AxzbOptions, AxzbSolution};
use crate::calib::consensus::{self, Consensus, PairingOptions};
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::geometry::Iso3;
use crate::model::{QualityCheck, QualityFailure};

/// The outcome of the pairing stage.
pub(super) struct Paired {
    /// `AX = ZB` from the views kept.
    pub axzb: AxzbSolution,
    /// Which of the views are kept.
    pub keep: Vec<bool>,
    /// The `pairing` gate's verdict.
    pub check: QualityCheck,
}

/// Whether `kept` views may stand for `total` (views with a robot pose whose board was
/// found): at least 4, so that every kept view can still be checked against the others
/// (leaving one out leaves 3, which determine `X` and `Z` with redundancy), and at least
/// two thirds of them, so that the views left out are a clear minority.
pub(super) fn enough_left(kept: usize, total: usize) -> bool {
    kept >= 4 && 3 * kept >= 2 * total
}

/// Views with a robot pose and a found board that a calibration without an earlier one
/// (`--from`) needs: with 3, `AX = ZB` is determined with nothing to spare, so neither
/// the pairing nor the robot-pose noise can be checked (rosi_10x10's views in threes: the
/// hand-eye and robot-world up to 3.5 stated sigmas from the 15 views' result; in fours
/// within 2.4).
pub(super) const MIN_ROBOT_VIEWS: usize = 4;

/// The refusal of a robot calibration from fewer than [`MIN_ROBOT_VIEWS`] views.
fn too_few_robot_views(n: usize) -> String {
    format!(
        "robot poses: only {n} view{} with a robot pose and a found board; at least \
         {MIN_ROBOT_VIEWS} are needed to check the poses against the images and to estimate \
         the robot's pose noise (fewer determine the hand-eye and robot-world with nothing \
         left to check them, and their sigmas would not hold); add views, or start from an \
         earlier calibration of the camera (--from CALIBRATION.json, e.g. a bench \
         calibration)",
        if n == 1 { "" } else { "s" }
    )
}

/// "view 3" / "views 1 and 3" / "views 1, 3 and 7".
pub(super) fn name_views(v: &[usize]) -> String {
    match v {
        [] => "no view".into(),
        [a] => format!("view {a}"),
        _ => {
            let (last, first) = v.split_last().unwrap_or((&0, &[]));
            let head: Vec<String> = first.iter().map(|x| x.to_string()).collect();
            format!("views {} and {last}", head.join(", "))
        }
    }
}

/// Checks every view's robot pose against its image (`obs` with their `T_cam_board`
/// `poses`) and solves `AX = ZB` from the views that agree. `earlier` counts views
/// already left out because their robot pose fit none of their image's labellings; they
/// count against [`enough_left`]. Errors: [`Error::Quality`] (with no calibration) when
/// no consensus exists at all; `AX = ZB`'s errors.
pub(super) fn check_pairing(
    obs: &[ViewObs],
    poses: &[Iso3],
    earlier: &[usize],
    opts: &CalibrateOptions,
    warnings: &mut Vec<String>,
    status: &mut [ViewStatus],
) -> Result<Paired> {
    let mut keep: Vec<bool> = obs.iter().map(|v| v.base_hand.is_some()).collect();
    for (v, k) in obs.iter().zip(&keep) {
        if !k {
            warnings.push(format!("view {}: left out, no robot pose", v.view));
        }
    }
    let idx: Vec<usize> = (0..obs.len()).filter(|&i| keep[i]).collect();
    let a: Vec<Iso3> = idx.iter().filter_map(|&i| obs[i].base_hand).collect();
    let b: Vec<Iso3> = idx.iter().map(|&i| poses[i].inverse()).collect();
    let rows: Vec<usize> = idx.iter().map(|&i| obs[i].view).collect();
    if (1..MIN_ROBOT_VIEWS).contains(&a.len()) && opts.from.is_none() {
        return Err(Error::Degenerate(too_few_robot_views(a.len())));
    }
    let popts = PairingOptions {
        factor: opts.outlier_factor,
        min_deg: opts.outlier_min_deg,
        min_rel: opts.outlier_min_rel,
        ..Default::default()
    };
    let c = consensus::find_consensus(&a, &b, &popts)?;
    if !c.coherent && a.len() >= 4 {
        let check = incoherent(&c, &rows, &a, &b, &popts);
        return Err(Error::Quality(Box::new(QualityFailure::new(vec![check]))));
    }
    let out: Vec<usize> = c.outliers();
    let total = a.len() + earlier.len();
    let members = a.len() - out.len();
    let mut named: Vec<usize> = out.iter().map(|&k| rows[k]).collect();
    for k in &out {
        let msg = view_message(&c, *k, &rows);
        warnings.push(msg.clone());
        if let Some(s) = status.iter_mut().find(|s| s.view == rows[*k]) {
            s.note = Some(msg);
        }
    }
    let check = if out.is_empty() {
        QualityCheck::pass(
            "pairing",
            format!(
                "the robot poses of all {} views agree with their images (median {:.4} deg / \
                 {:.4} mm; limits {:.3} deg / {:.3} mm)",
                a.len(),
                c.median.0,
                c.median.1,
                c.limit.0,
                c.limit.1
            ),
        )
    } else {
        let swapped = swapped_note(&c, &rows);
        if enough_left(members, total) {
            warnings.push(format!(
                "{} left out: their robot poses do not fit their images{swapped}; {members} \
                 of {total} views agree",
                name_views(&named)
            ));
            QualityCheck {
                name: "pairing".into(),
                passed: true,
                message: format!(
                    "{} left out (robot pose does not fit the image{swapped}); the other \
                     {members} views agree (median {:.4} deg / {:.4} mm)",
                    name_views(&named),
                    c.median.0,
                    c.median.1
                ),
                views: named.clone(),
            }
        } else {
            named.extend_from_slice(earlier);
            named.sort_unstable();
            // a pose row deleted or inserted is said in those words
            let message = break_message(&rows, &a, &b, members, &popts).unwrap_or_else(|| {
                format!(
                    "the robot poses of {} do not fit their images{swapped} ({} against the \
                     other views' X and Z; limits {:.3} deg / {:.3} mm); only {members} of \
                     {total} views agree, too few to calibrate without them (at least 4 and \
                     two thirds are needed): check how the images and the poses were paired",
                    name_views(&named),
                    figures(&c, &out, &rows),
                    c.limit.0,
                    c.limit.1
                )
            });
            QualityCheck::fail("pairing", message, named.clone())
        }
    };
    // the calibration goes on with the views that agree (for inspection if the gate
    // failed), or with all of them when fewer than 3 agree
    if members >= 3 {
        for &k in &out {
            keep[idx[k]] = false;
        }
    }
    let axzb = match (&c.solution, members >= 3 && !out.is_empty()) {
        (Some(s), true) => s.clone(),
        _ => solve(obs, poses, &keep)?,
    };
    Ok(Paired { axzb, keep, check })
}

/// `AX = ZB` from the views marked in `keep` (`A` = `T_base_hand`, `B` = `T_board_cam`).
fn solve(obs: &[ViewObs], poses: &[Iso3], keep: &[bool]) -> Result<AxzbSolution> {
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for ((v, cb), k) in obs.iter().zip(poses).zip(keep) {
        if let (true, Some(bh)) = (*k, v.base_hand) {
            a.push(bh);
            b.push(cb.inverse());
        }
    }
    solve_axzb(&a, &b)
}

/// "view 1 by 43.100 deg / 88.200 mm, view 3 by 40.200 deg / 85.000 mm".
fn figures(c: &Consensus, out: &[usize], rows: &[usize]) -> String {
    out.iter()
        .map(|&k| {
            format!(
                "view {} by {:.3} deg / {:.3} mm",
                rows[k], c.rotation_deg[k], c.translation_mm[k]
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The warning for one view that disagrees.
fn view_message(c: &Consensus, k: usize, rows: &[usize]) -> String {
    let fits = match c.fits_pose_of[k] {
        Some(j) => format!("; its image fits the robot pose of view {}", rows[j]),
        None => String::new(),
    };
    format!(
        "view {}: its robot pose does not fit its image: off by {:.3} deg / {:.3} mm \
         against the other views' X and Z (their median {:.4} deg / {:.4} mm, limits {:.3} \
         deg / {:.3} mm){fits}; check its joint readings and its images",
        rows[k],
        c.rotation_deg[k],
        c.translation_mm[k],
        c.median.0,
        c.median.1,
        c.limit.0,
        c.limit.1
    )
}

/// " (views 1 and 3 look swapped: each image fits the other's robot pose)" or "".
fn swapped_note(c: &Consensus, rows: &[usize]) -> String {
    let pairs = c.swapped_pairs();
    if pairs.is_empty() {
        return String::new();
    }
    let names: Vec<String> = pairs
        .iter()
        .map(|&(i, j)| format!("views {} and {}", rows[i], rows[j]))
        .collect();
    format!(
        " ({} look swapped: each image fits the other's robot pose)",
        names.join(", ")
    )
}

/// The message of a pose column one row off from some view on (a deleted or an inserted
/// pose row, [`consensus::find_break`]), naming the view and its views.csv line; `None`
/// when no such break explains the views.
fn break_message(
    rows: &[usize],
    a: &[Iso3],
    b: &[Iso3],
    agree_unshifted: usize,
    popts: &PairingOptions,
) -> Option<String> {
    let br = consensus::find_break(rows, a, b, agree_unshifted, popts)?;
    // views.csv: the header is line 1, view k is on line k + 2
    let line = br.first + 2;
    let (fits, what, moved) = if br.rows < 0 {
        ("the row above", "deleted", "up")
    } else {
        ("the row below", "inserted", "down")
    };
    Some(format!(
        "the robot poses are one row off from view {} (views.csv line {line}) on: the views \
         before it agree as given, and from view {} on every image fits the robot pose of \
         {fits}, not its own ({} of {} views agree paired so). A pose row was {what} at line \
         {line} (the poses below it moved {moved} a row): re-pair the poses with their \
         images",
        br.first, br.first, br.agreeing, br.pairs
    ))
}

/// The scale `k` of the board's translations that makes `A X = Z B` hold best when only
/// the rotations agree: `Z`'s rotation from [`solve_axzb_with`]'s linear steps (a scale does not
/// change them), then `R_A t_X + t_A = R_Z (k t_B) + t_Z` in least squares for `t_X`,
/// `t_Z` and `k`. `None` when that fails or `k` is not positive.
fn implied_board_scale(a: &[Iso3], b: &[Iso3]) -> Option<f64> {
    // the linear steps only: the rotations from the rotations alone (the refinement
    // would bend them towards the translations a wrong scale spoils)
    let linear = AxzbOptions { refine: false };
    let sol = solve_axzb_with(a, b, &linear).ok()?;
    let rzm = sol.z.rotation.to_rotation_matrix();
    let n = a.len();
    let mut m = nalgebra::DMatrix::<f64>::zeros(3 * n, 7);
    let mut y = nalgebra::DVector::<f64>::zeros(3 * n);
    for (i, (ai, bi)) in a.iter().zip(b).enumerate() {
        let ra = ai.rotation.to_rotation_matrix();
        let tb = rzm * bi.translation.vector;
        for r in 0..3 {
            for col in 0..3 {
                m[(3 * i + r, col)] = ra[(r, col)];
                m[(3 * i + r, 3 + col)] = if r == col { -1.0 } else { 0.0 };
            }
            m[(3 * i + r, 6)] = -tb[r];
            y[3 * i + r] = -ai.translation.vector[r];
        }
    }
    let k = m.svd(true, true).solve(&y, 1e-12).ok()?[6];
    (k.is_finite() && k > 0.0).then_some(k)
}

/// The failed `pairing` check when no set of views agrees: a shifted pose column when a
/// shift explains it, otherwise the figures.
fn incoherent(
    c: &Consensus,
    rows: &[usize],
    a: &[Iso3],
    b: &[Iso3],
    popts: &PairingOptions,
) -> QualityCheck {
    let all = rows.to_vec();
    if let Some(s) = consensus::find_shift(rows, a, b, c.agreeing(), popts) {
        let n = s.rows.unsigned_abs();
        let (dir, sign) = if s.rows > 0 {
            ("next", "+")
        } else {
            ("previous", "-")
        };
        let dir = if n == 1 {
            dir.to_string()
        } else {
            format!("{dir} but one")
        };
        let rows_word = if n == 1 { "one row" } else { "two rows" };
        let example = rows
            .iter()
            .find_map(|&r| {
                let t = r as isize + s.rows;
                rows.contains(&(t as usize))
                    .then(|| format!("the image of view {r} fits the robot pose of view {t}"))
            })
            .unwrap_or_default();
        return QualityCheck::fail(
            "pairing",
            format!(
                "the robot poses are off by {rows_word} against the images: every image fits \
                 the robot pose {rows_word} {}, not its own ({example}; {} of {} views agree \
                 paired as k {sign} {n}, none as given). The pose column was exported or \
                 pasted {rows_word} off ({dir} row): re-pair the poses with their images",
                if s.rows > 0 {
                    "further down"
                } else {
                    "further up"
                },
                s.agreeing,
                s.pairs,
            ),
            all,
        );
    }
    if let Some(msg) = break_message(rows, a, b, c.agreeing(), popts) {
        return QualityCheck::fail("pairing", msg, all);
    }
    // The rotations agree and only the translations do not: the images and the poses
    // are paired right, but on two length scales (the board's size in rig.json, or the
    // pose columns' unit).
    let rotations_agree = c.median.0 <= popts.coherence * c.motion.0;
    let scale = if rotations_agree && c.median.1 > popts.coherence * c.motion.1 {
        let implied = implied_board_scale(a, b)
            .map(|k| {
                format!(
                    "; the robot's motions imply a board about {k:.2} times rig.json's (its \
                     pitch or square size times about {k:.2}; a rough figure from AX = ZB with \
                     the scale free: rosi_10x10 as if printed at 0.8x gave 0.76; \
                     --estimate-board-scale refines a scale within a few percent, not one this \
                     far off)"
                )
            })
            .unwrap_or_default();
        format!(
            " (the rotations agree, only the translations do not: the board's size and the \
             robot's translations are on different scales; check rig.json's board.pitch_mm (or \
             board.square_mm for a chessboard) and that the translation columns' unit, x_mm or \
             x_m, is the one the numbers are in{implied})"
        )
    } else {
        String::new()
    };
    QualityCheck::fail(
        "pairing",
        format!(
            "the robot poses do not agree with the images at all: the best-agreeing views \
             disagree by {:.3} deg / {:.3} mm (median), {:.0} % / {:.0} % of the motion between \
             the views ({:.2} deg / {:.2} mm; at most {:.0} %){scale}: check that the pose \
             columns are the flange poses of these images, in the units and convention their \
             names say",
            c.median.0,
            c.median.1,
            100.0 * c.median.0 / c.motion.0.max(1e-12),
            100.0 * c.median.1 / c.motion.1.max(1e-12),
            c.motion.0,
            c.motion.1,
            100.0 * popts.coherence
        ),
        all,
    )
}
