//! Chessboard detection (inner corners). Scaffold: replaced by the detector.

use crate::board::Board;
use crate::error::{Error, Result};
use crate::vision::target::TargetDetection;
use crate::vision::AnyView;

/// Options of [`detect_chessboard`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ChessboardOptions {}

/// Detects the inner corners of a chessboard.
pub fn detect_chessboard(
    _img: AnyView<'_>,
    _board: &Board,
    _opts: &ChessboardOptions,
) -> Result<TargetDetection> {
    Err(Error::Detection(
        "chessboard detection is not built yet".into(),
    ))
}
