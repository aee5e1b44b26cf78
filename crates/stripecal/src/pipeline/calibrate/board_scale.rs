//! The board's scale against the robot: the robot's translations fix the metric scale,
//! so the printed board's size can be checked (a board printed at 125 %, or a pitch
//! typed wrong, is the most common real-world mistake).
//!
//! The adjustment is solved once more with the board scale `s` free (every board
//! coordinate times `s`), warm-started at the calibration. `s` and its one-sigma (honest:
//! the robot's pose noise and the views' own scatter are in it) are reported; rig.json
//! disagrees with the robot when `|s - 1|` exceeds both 3 sigma and a tolerance (default
//! 1 %: a scale error smaller than that is within what real robots' kinematic errors
//! imply, and not the gross mistake this check is for). DECISIONS 5 (wave three): beyond
//! [`FAIL_SIGMAS`] (and the tolerance) the calibration FAILS (the `board_scale` gate:
//! nothing written, the message naming the implied size and `--estimate-board-scale`);
//! between 3 and 5 sigmas it is a warning with the figure. With
//! `--estimate-board-scale` the calibration itself frees `s` and this reports it.

use crate::calib::joint::{joint_adjustment, FreeBlocks, JointOptions, JointResult, JointStart};
use crate::calib::ViewObs;
use crate::error::Result;
use crate::model::board::{Board, BoardKind};
use crate::model::{BoardScaleCheck, QualityCheck};

/// A board scale this many sigmas (and the tolerance) off rig.json's fails the
/// calibration (DECISIONS 5).
pub const FAIL_SIGMAS: f64 = 5.0;

/// From this many sigmas (and beyond the tolerance) rig.json disagrees: a warning.
pub const WARN_SIGMAS: f64 = 3.0;

/// The check from the calibration `full` over the views `used` (solved with `jopts`).
/// `tolerance` is the relative scale error below which no disagreement is reported.
pub(super) fn check_board_scale(
    used: &[ViewObs],
    board: &Board,
    full: &JointResult,
    jopts: &JointOptions,
    tolerance: f64,
) -> Result<BoardScaleCheck> {
    let (scale, sigma, estimated) = if full.free.board_scale {
        (full.board_scale, full.sigma.board_scale, true)
    } else {
        let start = JointStart {
            camera: full.camera.clone(),
            plane: full.plane,
            hand_cam: full.hand_cam,
            base_board: full.base_board,
        };
        let opts = JointOptions {
            free: FreeBlocks {
                board_scale: true,
                ..full.free
            },
            board_scale: full.board_scale,
            ..jopts.continuing(full)
        };
        let r = joint_adjustment(used, board, &start, &opts)?;
        (r.board_scale, r.sigma.board_scale, false)
    };
    let declared_mm = declared_size(board);
    let off = (scale - 1.0).abs();
    Ok(BoardScaleCheck {
        scale,
        sigma,
        declared_mm,
        implied_mm: scale * declared_mm,
        estimated,
        disagrees: off > WARN_SIGMAS * sigma && off > tolerance,
        tolerance,
    })
}

/// rig.json's pitch (circle grids) or square side (chessboards, whose pitch is the
/// square), mm.
pub(super) fn declared_size(board: &Board) -> f64 {
    board.square_mm.unwrap_or(board.pitch_mm)
}

/// The warning of a disagreeing check.
pub(super) fn warning(c: &BoardScaleCheck, board: &Board) -> String {
    let what = if board.kind == BoardKind::Chessboard {
        "square"
    } else {
        "pitch"
    };
    format!(
        "board scale: the robot's motions imply a board {:.4} +- {:.4} times rig.json's \
         ({what} {:.3} mm implies {:.3} mm, {:.1} sigma off): check the printed size (a print \
         at the wrong scale or a mistyped {what}) or calibrate with --estimate-board-scale",
        c.scale,
        c.sigma,
        c.declared_mm,
        c.implied_mm,
        sigmas_off(c)
    )
}

/// How many of its sigmas the scale is off rig.json's.
fn sigmas_off(c: &BoardScaleCheck) -> f64 {
    (c.scale - 1.0).abs() / c.sigma
}

/// The `board_scale` gate (DECISIONS 5): fails when the scale the robot implies is more
/// than [`FAIL_SIGMAS`] of its sigmas and the tolerance off rig.json's; `None` when the
/// scale was estimated (`--estimate-board-scale`: nothing to check).
pub(super) fn gate(c: &BoardScaleCheck, board: &Board) -> Option<QualityCheck> {
    if c.estimated {
        return None;
    }
    let off = (c.scale - 1.0).abs();
    if off > c.tolerance && off > FAIL_SIGMAS * c.sigma {
        return Some(QualityCheck::fail(
            "board_scale",
            format!(
                "{} (more than {FAIL_SIGMAS} sigma and {:.1} % off)",
                warning(c, board),
                100.0 * c.tolerance
            ),
            Vec::new(),
        ));
    }
    Some(QualityCheck::pass(
        "board_scale",
        format!(
            "the robot implies {:.4} +- {:.4} times rig.json's board ({:.1} sigma off; a \
             warning from {WARN_SIGMAS}, a failure from {FAIL_SIGMAS} sigma, either beyond \
             {:.1} %)",
            c.scale,
            c.sigma,
            sigmas_off(c),
            100.0 * c.tolerance
        ),
    ))
}
