//! One entry point for every target kind: [`detect_target`] and its result.
//!
//! Whatever the kind (spec/DATASET.md, "Target kinds"), detection returns the points it
//! could index without doubt, sorted by `(row, col)`, each with its sub-pixel image
//! position and flags; the points it indexed but could not measure, with the reason;
//! and the board symmetries the view itself cannot decide ([`TargetDetection::alternatives`]).
//!
//! ## Orientation
//!
//! When nothing in the image fixes the labelling (a grid without markers, a chessboard
//! with `rows + cols` even, an asymmetric grid with an even number of rows; see
//! [`Board::symmetries`]), detection returns ONE labelling and lists the symmetries
//! that give the others: the calibration chooses among them from the robot poses of
//! the other views, never view by view. When the labelling is ambiguous in any other
//! way (a partial view of a board without markers, whose position on the board is
//! unknown) the view is refused with [`Error::Detection`] saying why.
//!
//! ## Conventions
//!
//! Pixel centres at integer coordinates (spec/DATASET.md); `u` along columns, `v` along
//! rows.

use nalgebra::Vector2;

use crate::error::Result;
use crate::model::board::{Board, BoardKind, Symmetry};
use crate::model::image::AnyView;
use crate::vision::circles::{detect_circles, CircleGrid, CircleOptions};

/// Per-point flags ([`TargetPoint::flags`]), a bit set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct PointFlags(pub u8);

impl PointFlags {
    /// The point is a marker circle.
    pub const MARKER: u8 = 1;
    /// A bright stripe crosses the point's measuring window (kept only when the
    /// detector was told to keep such points).
    pub const STRIPE_CROSSED: u8 = 2;
    /// The point's measuring window is within a few pixels of the image border.
    pub const NEAR_BORDER: u8 = 4;

    /// Whether every bit of `mask` is set.
    #[inline]
    pub fn has(self, mask: u8) -> bool {
        self.0 & mask == mask
    }
}

/// One indexed and measured point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetPoint {
    /// Board row and column (spec/DATASET.md's indexing for the kind).
    pub row: usize,
    pub col: usize,
    /// Sub-pixel image position, px: the centroid of a circle's image, or a
    /// chessboard corner.
    pub u: f64,
    pub v: f64,
    /// A quality figure, px: a circle's ellipse-fit RMS, a corner's refinement residual
    /// (NaN when not available).
    pub quality_px: f64,
    pub flags: PointFlags,
}

/// A point that was indexed but left out of [`TargetDetection::points`].
#[derive(Debug, Clone, PartialEq)]
pub struct DroppedPoint {
    pub row: usize,
    pub col: usize,
    /// Rough position, px.
    pub u: f64,
    pub v: f64,
    pub reason: &'static str,
}

/// The result of [`detect_target`].
#[derive(Debug, Clone, PartialEq)]
pub struct TargetDetection {
    pub kind: BoardKind,
    /// Indexed points, sorted by `(row, col)`.
    pub points: Vec<TargetPoint>,
    /// Indexed points left out (a stripe across them, a window outside the image, a
    /// failed fit), with the reason.
    pub dropped: Vec<DroppedPoint>,
    /// Board symmetries under which this view's labelling is not fixed by the image:
    /// the points could equally be labelled `s.apply(board, row, col)` for each `s`
    /// here (module docs). Empty when the labelling is unique.
    pub alternatives: Vec<Symmetry>,
    /// RMS and largest residual of a board-to-image homography fitted to the points,
    /// px (lens distortion shows here too; a diagnostic; NaN below 5 points).
    pub homography_rms_px: f64,
    pub homography_max_px: f64,
    /// The circle detector's full result (circle kinds only).
    pub circles: Option<CircleGrid>,
}

/// Options of [`detect_target`], one set per detector.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TargetOptions {
    pub circles: CircleOptions,
    pub chessboard: crate::vision::chessboard::ChessboardOptions,
}

/// Detects `board` in `img` (8- or 16-bit gray), whatever its kind.
///
/// Errors: [`crate::Error::InvalidInput`] for an invalid board or options or an image
/// too small; [`crate::Error::Detection`] when the board is not found, or cannot be
/// indexed without guessing, or does not match rig.json's size (the message says what
/// was found).
pub fn detect_target(
    img: AnyView<'_>,
    board: &Board,
    opts: &TargetOptions,
) -> Result<TargetDetection> {
    match board.kind {
        BoardKind::Circles | BoardKind::AsymmetricCircles => {
            let g = detect_circles(img, board, &opts.circles)?;
            Ok(TargetDetection::from_circles(board, g))
        }
        BoardKind::Chessboard => {
            crate::vision::chessboard::detect_chessboard(img, board, &opts.chessboard)
        }
    }
}

impl TargetDetection {
    /// The target result of a circle-grid detection.
    pub fn from_circles(board: &Board, g: CircleGrid) -> TargetDetection {
        let points = g
            .circles
            .iter()
            .map(|c| {
                let mut f = 0u8;
                if board.is_marker(c.row, c.col) {
                    f |= PointFlags::MARKER;
                }
                if c.stripe_crossed {
                    f |= PointFlags::STRIPE_CROSSED;
                }
                TargetPoint {
                    row: c.row,
                    col: c.col,
                    u: c.u,
                    v: c.v,
                    quality_px: c.quality_px,
                    flags: PointFlags(f),
                }
            })
            .collect();
        let dropped = g.dropped.clone();
        TargetDetection {
            kind: board.kind,
            points,
            dropped,
            alternatives: g.alternatives.clone(),
            homography_rms_px: g.homography_rms_px,
            homography_max_px: g.homography_max_px,
            circles: Some(g),
        }
    }
}

/// RMS and largest residual (px) of a normalised-DLT homography from the board points
/// (mm) to their image positions; NaN with fewer than 5 points or a degenerate fit.
pub fn homography_residuals(board: &Board, pts: &[(usize, usize, f64, f64)]) -> (f64, f64) {
    if pts.len() < 5 {
        return (f64::NAN, f64::NAN);
    }
    let plane: Vec<Vector2<f64>> = pts
        .iter()
        .map(|&(r, c, _, _)| board.center(r, c).xy())
        .collect();
    let image: Vec<Vector2<f64>> = pts.iter().map(|&(_, _, u, v)| Vector2::new(u, v)).collect();
    crate::numerics::homography::dlt_residuals(&plane, &image).unwrap_or((f64::NAN, f64::NAN))
}
