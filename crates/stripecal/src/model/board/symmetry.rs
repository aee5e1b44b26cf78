//! The rotations under which a board looks the same.
//!
//! A grid without markers, a chessboard with `rows + cols` even and an asymmetric grid
//! with an even number of rows look the same after a half turn; a square grid without
//! markers also after a quarter turn (spec/DATASET.md, "Orientation that nothing on the
//! board fixes"). Rather than list these cases, [`Board::symmetries`] tests every
//! rotation of the lattice against the board's points and appearance (marker sizes,
//! square colours), so any layout is handled. Mirror images are never symmetries: the
//! camera sees the printed side, and detection rejects mirrored labellings.

use super::{Board, BoardKind};

/// A rotation of the board's lattice by `quarter_turns * 90` degrees (from board +x
/// towards +y) followed by a lattice translation, mapping the board onto itself:
/// `(i, j) -> R (i, j) + t`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Symmetry {
    /// 1, 2 or 3 (0 is the identity).
    pub quarter_turns: u8,
    /// Lattice translation after the rotation.
    pub shift: (i64, i64),
}

#[inline]
fn rotate(k: u8, (i, j): (i64, i64)) -> (i64, i64) {
    // saturating: lattice points of a board are small; others must not overflow
    match k % 4 {
        0 => (i, j),
        1 => (j.saturating_neg(), i),
        2 => (i.saturating_neg(), j.saturating_neg()),
        _ => (j, i.saturating_neg()),
    }
}

impl Symmetry {
    /// The identity.
    pub const IDENTITY: Symmetry = Symmetry {
        quarter_turns: 0,
        shift: (0, 0),
    };

    /// Lattice coordinates after the map.
    #[inline]
    pub fn apply_lattice(&self, p: (i64, i64)) -> (i64, i64) {
        let (i, j) = rotate(self.quarter_turns, p);
        (
            i.saturating_add(self.shift.0),
            j.saturating_add(self.shift.1),
        )
    }

    /// The point that `(row, col)` maps to on `board` (`None` if the map leaves the
    /// board, which a symmetry of that board never does).
    pub fn apply(&self, board: &Board, row: usize, col: usize) -> Option<(usize, usize)> {
        let (i, j) = self.apply_lattice(board.lattice(row, col));
        board.from_lattice(i, j)
    }

    /// Rotation angle in degrees (90, 180 or 270).
    pub fn angle_deg(&self) -> f64 {
        90.0 * self.quarter_turns as f64
    }
}

impl Board {
    /// The non-identity rotations that map the board onto itself, points and
    /// appearance alike (empty when the board fixes its own orientation).
    pub fn symmetries(&self) -> Vec<Symmetry> {
        let pts: Vec<(i64, i64)> = self.indices().map(|(r, c)| self.lattice(r, c)).collect();
        let min = |v: &[(i64, i64)]| {
            (
                v.iter().map(|p| p.0).min().unwrap_or(0),
                v.iter().map(|p| p.1).min().unwrap_or(0),
            )
        };
        let lo = min(&pts);
        let mut out = Vec::new();
        for k in 1..4u8 {
            let rotated: Vec<(i64, i64)> = pts.iter().map(|&p| rotate(k, p)).collect();
            let rlo = min(&rotated);
            let s = Symmetry {
                quarter_turns: k,
                shift: (lo.0 - rlo.0, lo.1 - rlo.1),
            };
            let points_match = self.indices().all(|(r, c)| match s.apply(self, r, c) {
                Some((r2, c2)) => self.diameter(r, c) == self.diameter(r2, c2),
                None => false,
            });
            if points_match && self.squares_match(&s) {
                out.push(s);
            }
        }
        out
    }

    /// Whether a lattice map keeps every chessboard square's colour (always true for
    /// circle kinds). Square `(i, j)` has its centre at lattice `(i + 1/2, j + 1/2)`;
    /// in doubled coordinates `(2i + 1, 2j + 1)`.
    fn squares_match(&self, s: &Symmetry) -> bool {
        if self.kind != BoardKind::Chessboard {
            return true;
        }
        (-1..self.rows as i64).all(|j| {
            (-1..self.cols as i64).all(|i| {
                let (x, y) = rotate(s.quarter_turns, (2 * i + 1, 2 * j + 1));
                let (x, y) = (x + 2 * s.shift.0, y + 2 * s.shift.1);
                let (i2, j2) = ((x - 1).div_euclid(2), (y - 1).div_euclid(2));
                self.square_is_dark(i, j) == self.square_is_dark(i2, j2)
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn turns(b: &Board) -> Vec<u8> {
        b.symmetries().iter().map(|s| s.quarter_turns).collect()
    }

    #[test]
    fn the_contract_cases() {
        // the paper's board: the marker L fixes everything
        assert!(turns(&Board::hp3_paper()).is_empty());
        // no markers: a half turn; square: quarter turns too
        let mut b = Board::hp3_paper();
        b.markers.clear();
        assert_eq!(turns(&b), vec![2]);
        let mut sq = Board::circles(7, 7, 5.0, 2.0, 3.0).unwrap();
        sq.markers.clear();
        assert_eq!(turns(&sq), vec![1, 2, 3]);
        // one marker at a corner fixes a square grid
        sq.markers = vec![[0, 0]];
        assert!(turns(&sq).is_empty());
        // one marker at the centre of a square grid fixes nothing
        sq.markers = vec![[3, 3]];
        assert_eq!(turns(&sq), vec![1, 2, 3]);
        // chessboards: rows + cols odd is fixed by the colours, even is not
        assert!(turns(&Board::chessboard(6, 9, 20.0).unwrap()).is_empty());
        assert_eq!(turns(&Board::chessboard(6, 8, 20.0).unwrap()), vec![2]);
        assert_eq!(turns(&Board::chessboard(7, 9, 20.0).unwrap()), vec![2]);
        // asymmetric grids: even rows are half-turn symmetric, odd rows are not
        assert_eq!(
            turns(&Board::asymmetric_circles(4, 11, 20.0, 5.0).unwrap()),
            vec![2]
        );
        assert!(turns(&Board::asymmetric_circles(5, 11, 20.0, 5.0).unwrap()).is_empty());
    }

    #[test]
    fn symmetries_map_points_onto_points() {
        for b in [
            Board::chessboard(6, 8, 20.0).unwrap(),
            Board::asymmetric_circles(4, 11, 20.0, 5.0).unwrap(),
        ] {
            let s = b.symmetries()[0];
            let mut seen = std::collections::HashSet::new();
            for (r, c) in b.indices() {
                let (r2, c2) = s.apply(&b, r, c).unwrap();
                assert!(seen.insert((r2, c2)));
                // a half turn about the pattern's centre
                let (p, q) = (b.center(r, c), b.center(r2, c2));
                let mid = 0.5 * (p + q);
                let ctr = 0.5 * (b.center(0, 0) + b.center(b.rows - 1, b.cols - 1));
                let ctr = if b.kind == BoardKind::AsymmetricCircles {
                    // the extent runs to the shifted last column of odd rows
                    let e = b.pattern_extent();
                    nalgebra::Vector3::new(0.5 * (e[0] + e[1]), 0.5 * (e[2] + e[3]), 0.0)
                } else {
                    ctr
                };
                assert!((mid - ctr).norm() < 1e-9, "{:?}: ({r}, {c})", b.kind);
            }
        }
    }
}
