//! The target's geometry as the twin needs it, for every board kind (spec/DATASET.md,
//! "Target kinds"): the points' bounding box and centre, the plate, its margin check,
//! and whether a view shows the printed pattern.
//!
//! The plate is the bounding box of the target POINTS (circle centres, a chessboard's
//! inner corners) grown by `board.plate_margin_mm` on each side. For the symmetric
//! circle grid this is the plate the twin always had (`[-m, (cols - 1) p + m] x [-m,
//! (rows - 1) p + m]`), to the bit.

use nalgebra::{Point3, Vector3};

use stripecal::{Board, BoardKind, Camera};

use crate::scene::ImageScene;

/// Bounding box `[x0, x1, y0, y1]` (board mm) of the target points.
pub fn points_bbox(board: &Board) -> [f64; 4] {
    let last = board.center(board.rows - 1, board.cols - 1);
    let mut x1 = last.x;
    if board.kind == BoardKind::AsymmetricCircles && board.rows > 1 {
        // odd rows are shifted by half a pitch: their last circle is the rightmost
        x1 = x1.max(board.center(1, board.cols - 1).x);
    }
    [0.0, x1, 0.0, last.y]
}

/// Centre of the points' bounding box (board frame, z = 0).
pub fn points_center(board: &Board) -> Vector3<f64> {
    let [x0, x1, y0, y1] = points_bbox(board);
    Vector3::new(0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.0)
}

/// The plate `[x0, x1, y0, y1]` (board mm): the points' bounding box grown by `margin_mm`.
pub fn plate_extent(board: &Board, margin_mm: f64) -> [f64; 4] {
    let [x0, x1, y0, y1] = points_bbox(board);
    [
        x0 - margin_mm,
        x1 + margin_mm,
        y0 - margin_mm,
        y1 + margin_mm,
    ]
}

/// Largest circle radius (mm) of a circle grid; 0 for a chessboard.
pub fn max_radius(board: &Board) -> f64 {
    match board.kind {
        BoardKind::Chessboard => 0.0,
        _ if board.markers.is_empty() => 0.5 * board.circle_diameter_mm,
        _ => 0.5 * board.circle_diameter_mm.max(board.marker_diameter_mm),
    }
}

/// Checks that a plate margin (beyond the outer points) covers the printed pattern:
/// at least the largest circle radius for circle grids; more than a square for a
/// chessboard, whose outer squares reach one square beyond the outer corners (so a
/// light border of `margin - square_mm` remains around them). The error says why.
pub fn check_plate_margin(board: &Board, margin_mm: f64) -> Result<(), String> {
    if !margin_mm.is_finite() {
        return Err(format!("{margin_mm} must be a finite length"));
    }
    match board.kind {
        BoardKind::Chessboard => {
            let s = board.pitch_mm;
            if margin_mm <= s {
                return Err(format!(
                    "{margin_mm} mm must exceed square_mm ({s} mm): the plate reaches \
                     plate_margin_mm beyond the outer corner points, and a chessboard's outer \
                     squares reach one square beyond them (e.g. {} mm leaves a one-square \
                     light border)",
                    2.0 * s
                ));
            }
        }
        _ => {
            let r = max_radius(board);
            if margin_mm < r {
                return Err(format!(
                    "{margin_mm} mm must cover the outer circles (>= half a diameter, {r} mm): \
                     the plate reaches plate_margin_mm beyond the outer circle centres"
                ));
            }
        }
    }
    Ok(())
}

/// Number of circles (circle kinds) whose outline, sampled at `n` points, projects
/// inside the image with `margin_px`; for a chessboard, the number of corners that do.
/// A quick count: the exact truth samples the outline far more densely.
pub fn points_inside_quick(scene: &ImageScene, cam: &Camera, margin_px: f64, n: usize) -> usize {
    let board = scene.board();
    let t = scene.cam_board;
    let inside = |pb: Point3<f64>| matches!(cam.project(&(t * pb).coords), Ok(uv) if cam.contains(&uv, margin_px));
    board
        .indices()
        .filter(|&(r, c)| {
            let ctr = board.center(r, c);
            let rad = 0.5 * board.diameter(r, c);
            if rad == 0.0 {
                return inside(Point3::from(ctr));
            }
            (0..n).all(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                inside(Point3::new(
                    ctr.x + rad * a.cos(),
                    ctr.y + rad * a.sin(),
                    0.0,
                ))
            })
        })
        .count()
}

/// Whether the whole printed pattern (the rectangle [`Board::pattern_extent`], its
/// outline sampled at `per_side` points a side) projects inside the image with
/// `margin_px`. The projection maps the plate one-to-one, so the pattern is inside
/// when its outline is.
pub fn pattern_inside(scene: &ImageScene, cam: &Camera, margin_px: f64, per_side: usize) -> bool {
    let [x0, x1, y0, y1] = scene.board().pattern_extent();
    let t = scene.cam_board;
    let corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)];
    (0..4).all(|e| {
        let (a, b) = (corners[e], corners[(e + 1) % 4]);
        (0..per_side).all(|k| {
            let f = k as f64 / per_side as f64;
            let p = Point3::new(a.0 + f * (b.0 - a.0), a.1 + f * (b.1 - a.1), 0.0);
            matches!(cam.project(&(t * p).coords), Ok(uv) if cam.contains(&uv, margin_px))
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bbox_and_plate_per_kind() {
        let b = Board::hp3_paper();
        assert_eq!(points_bbox(&b), [0.0, 50.0, 0.0, 35.0]);
        assert_eq!(plate_extent(&b, 4.0), [-4.0, 54.0, -4.0, 39.0]);
        assert_eq!(points_center(&b), Vector3::new(25.0, 17.5, 0.0));
        // asymmetric: odd rows reach half a pitch further
        let a = Board::asymmetric_circles(3, 4, 10.0, 3.0).unwrap();
        assert_eq!(points_bbox(&a), [0.0, 35.0, 0.0, 10.0]);
        let c = Board::chessboard(7, 10, 5.0).unwrap();
        assert_eq!(points_bbox(&c), [0.0, 45.0, 0.0, 30.0]);
        assert_eq!(max_radius(&c), 0.0);
        assert_eq!(max_radius(&b), 1.75);
    }

    #[test]
    fn plate_margin_is_checked_per_kind() {
        let c = Board::chessboard(7, 10, 5.0).unwrap();
        let e = check_plate_margin(&c, 5.0).unwrap_err();
        assert!(e.contains("square_mm"), "{e}");
        check_plate_margin(&c, 5.01).unwrap();
        let b = Board::hp3_paper();
        assert!(check_plate_margin(&b, 1.7).is_err());
        check_plate_margin(&b, 1.75).unwrap();
        let mut nm = Board::hp3_paper();
        nm.markers.clear();
        check_plate_margin(&nm, 1.25).unwrap();
        assert!(check_plate_margin(&b, f64::NAN).is_err());
    }
}
