//! The twin's target knobs (spec/DATASET.md, "Board" and "Target kinds") and the board
//! they make.

use serde::{Deserialize, Serialize};

use stripecal::{Board, BoardKind};

use super::{bad, SimConfig};
use crate::SimError;

/// The target (spec/DATASET.md, "Board" and "Target kinds").
///
/// Which knobs a kind uses:
/// - `circles`: `rows`, `cols`, `pitch_mm`, `circle_diameter_mm`, `markers`,
///   `marker_diameter_mm` (only when `markers` is not empty), `dark_circles`;
/// - `asymmetric_circles`: `rows`, `cols`, `pitch_mm` (between neighbours in a row),
///   `circle_diameter_mm`, `dark_circles`; it has no markers;
/// - `chessboard`: `rows`, `cols` (inner corners) and `square_mm` (`null`: `pitch_mm`);
///   the colours are the contract's (the square outside corner (0, 0) is dark).
///
/// The knobs a kind does not use are ignored, so switching the kind of a preset
/// (`--set board.kind=asymmetric_circles`) needs no other change; rig.json holds only
/// the ones the kind uses.
///
/// `plate_margin_mm` means the same for every kind: how far the plate reaches beyond
/// the OUTER TARGET POINTS (circle centres, a chessboard's outer inner corners) on each
/// side, so the plate is the points' bounding box grown by it. It must cover the
/// printed pattern: at least the largest circle radius for circle grids, and MORE than
/// `square_mm` for a chessboard (whose outer squares reach one square beyond its outer
/// corners); `plate_margin_mm - square_mm` is then the light border around the squares.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoardCfg {
    /// `circles` (default), `asymmetric_circles` or `chessboard`.
    #[serde(default = "default_board_kind")]
    pub kind: String,
    /// Grid rows: circles, or a chessboard's inner corners along board y.
    pub rows: usize,
    /// Grid columns: circles, or a chessboard's inner corners along board x.
    pub cols: usize,
    /// Circle kinds: centre distance between neighbours in a row, mm.
    pub pitch_mm: f64,
    pub circle_diameter_mm: f64,
    pub marker_diameter_mm: f64,
    pub markers: Vec<[usize; 2]>,
    pub dark_circles: bool,
    /// Chessboards: the square side, mm (`null`: `pitch_mm`).
    #[serde(default)]
    pub square_mm: Option<f64>,
    /// Plate beyond the outer target points, mm (each side); see the type's docs.
    pub plate_margin_mm: f64,
    /// Thickness of the plate (or sheet) the target is printed on: the table lies this
    /// far behind the printed surface, a depth step where the plate ends, mm (default
    /// [`crate::dataset::PLATE_THICKNESS_MM`]).
    #[serde(default = "default_plate_thickness")]
    pub plate_thickness_mm: f64,
}

fn default_board_kind() -> String {
    BoardKind::Circles.name().into()
}

fn default_plate_thickness() -> f64 {
    crate::dataset::PLATE_THICKNESS_MM
}

impl BoardCfg {
    /// The knobs [`SimConfig::board_model`] does not check: the plate's thickness.
    pub(super) fn validate_thickness(&self) -> Result<(), SimError> {
        let t = self.plate_thickness_mm;
        if !(t.is_finite() && t >= 0.0) {
            return bad(
                "board.plate_thickness_mm",
                format!("{t} must be finite and >= 0"),
            );
        }
        Ok(())
    }
}

impl SimConfig {
    /// The board of `board.kind` (see [`BoardCfg`] for the knobs each kind uses), with
    /// its plate margin checked.
    pub fn board_model(&self) -> Result<Board, SimError> {
        let b = &self.board;
        let kind = BoardKind::from_name(&b.kind)
            .map_err(|e| SimError::Config(format!("board.kind: {e}")))?;
        let board = match kind {
            BoardKind::Circles => Board {
                kind,
                rows: b.rows,
                cols: b.cols,
                pitch_mm: b.pitch_mm,
                circle_diameter_mm: b.circle_diameter_mm,
                marker_diameter_mm: b.marker_diameter_mm,
                markers: b.markers.clone(),
                dark_circles: b.dark_circles,
                square_mm: None,
            },
            BoardKind::AsymmetricCircles => Board {
                dark_circles: b.dark_circles,
                ..Board::asymmetric_circles(b.rows, b.cols, b.pitch_mm, b.circle_diameter_mm)
                    .map_err(|e| SimError::Config(format!("board: {e}")))?
            },
            BoardKind::Chessboard => {
                Board::chessboard(b.rows, b.cols, b.square_mm.unwrap_or(b.pitch_mm))
                    .map_err(|e| SimError::Config(format!("board: {e}")))?
            }
        };
        board
            .validate()
            .map_err(|e| SimError::Config(format!("board: {e}")))?;
        crate::target::check_plate_margin(&board, b.plate_margin_mm)
            .map_err(|m| SimError::Config(format!("board.plate_margin_mm: {m}")))?;
        Ok(board)
    }
}
