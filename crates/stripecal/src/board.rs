//! The calibration target's layout (spec/DATASET.md, "Board").
//!
//! ## Conventions
//!
//! Circle `(row, col)` has its centre at board coordinates `(col * pitch, row * pitch, 0)`
//! mm. Board x runs along columns, y along rows, z = x cross y points into the plate.
//! Circles listed in `markers` (default the L `[0,0], [0,1], [1,0]`) have the larger
//! `marker_diameter_mm`.

use nalgebra::Vector3;

use crate::error::{Error, Result};

/// What kind of target a board is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BoardKind {
    /// Filled circles on a plate (the paper's target).
    #[default]
    Circles,
    /// A chessboard (inner corners `rows x cols`); reserved, not detected yet.
    Chessboard,
}

/// A circle-grid board.
#[derive(Debug, Clone, PartialEq)]
pub struct Board {
    pub kind: BoardKind,
    /// Grid rows (circles along board y).
    pub rows: usize,
    /// Grid columns (circles along board x).
    pub cols: usize,
    /// Centre-to-centre distance, mm.
    pub pitch_mm: f64,
    /// Diameter of ordinary circles, mm.
    pub circle_diameter_mm: f64,
    /// Diameter of marker circles, mm.
    pub marker_diameter_mm: f64,
    /// Marker circles as `[row, col]`.
    pub markers: Vec<[usize; 2]>,
    /// Dark circles on a light plate (`true`) or light on dark.
    pub dark_circles: bool,
    /// Chessboard square size (chessboards only).
    pub square_mm: Option<f64>,
}

impl Board {
    /// The default marker L: `[0,0], [0,1], [1,0]`.
    pub fn default_markers() -> Vec<[usize; 2]> {
        vec![[0, 0], [0, 1], [1, 0]]
    }

    /// A circle board with the default markers and dark circles, checked.
    pub fn circles(
        rows: usize,
        cols: usize,
        pitch_mm: f64,
        circle_diameter_mm: f64,
        marker_diameter_mm: f64,
    ) -> Result<Board> {
        let b = Board {
            kind: BoardKind::Circles,
            rows,
            cols,
            pitch_mm,
            circle_diameter_mm,
            marker_diameter_mm,
            markers: Self::default_markers(),
            dark_circles: true,
            square_mm: None,
        };
        b.validate()?;
        Ok(b)
    }

    /// The paper-like board of the `hp3-paper` preset: 8 x 11, pitch 5, circles 2.5,
    /// markers 3.5 mm.
    pub fn hp3_paper() -> Board {
        Board {
            kind: BoardKind::Circles,
            rows: 8,
            cols: 11,
            pitch_mm: 5.0,
            circle_diameter_mm: 2.5,
            marker_diameter_mm: 3.5,
            markers: Self::default_markers(),
            dark_circles: true,
            square_mm: None,
        }
    }

    /// Checks sizes (at least 2 x 2, circles smaller than the pitch so none overlap,
    /// markers inside the grid).
    pub fn validate(&self) -> Result<()> {
        if self.rows < 2 || self.cols < 2 {
            return Err(Error::InvalidInput(format!(
                "board must have at least 2 x 2 circles, got {} x {}",
                self.rows, self.cols
            )));
        }
        let ok = |x: f64| x.is_finite() && x > 0.0;
        if !ok(self.pitch_mm) || !ok(self.circle_diameter_mm) || !ok(self.marker_diameter_mm) {
            return Err(Error::InvalidInput(format!(
                "board pitch {} mm and diameters {} / {} mm must be positive",
                self.pitch_mm, self.circle_diameter_mm, self.marker_diameter_mm
            )));
        }
        if self.kind == BoardKind::Circles
            && (self.circle_diameter_mm >= self.pitch_mm
                || self.marker_diameter_mm >= self.pitch_mm)
        {
            return Err(Error::InvalidInput(format!(
                "circle diameters ({} / {} mm) must be smaller than the pitch ({} mm)",
                self.circle_diameter_mm, self.marker_diameter_mm, self.pitch_mm
            )));
        }
        for m in &self.markers {
            if m[0] >= self.rows || m[1] >= self.cols {
                return Err(Error::InvalidInput(format!(
                    "marker [{}, {}] lies outside the {} x {} grid",
                    m[0], m[1], self.rows, self.cols
                )));
            }
        }
        Ok(())
    }

    /// Number of circles.
    pub fn len(&self) -> usize {
        self.rows * self.cols
    }

    /// Always false for a validated board.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether circle `(row, col)` is a marker.
    pub fn is_marker(&self, row: usize, col: usize) -> bool {
        self.markers.iter().any(|m| m[0] == row && m[1] == col)
    }

    /// Diameter (mm) of circle `(row, col)`.
    pub fn diameter(&self, row: usize, col: usize) -> f64 {
        if self.is_marker(row, col) {
            self.marker_diameter_mm
        } else {
            self.circle_diameter_mm
        }
    }

    /// Centre of circle `(row, col)` in board coordinates (mm).
    pub fn center(&self, row: usize, col: usize) -> Vector3<f64> {
        Vector3::new(col as f64 * self.pitch_mm, row as f64 * self.pitch_mm, 0.0)
    }

    /// All circles as `(row, col)` in row-major order.
    pub fn indices(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        (0..self.rows).flat_map(move |r| (0..self.cols).map(move |c| (r, c)))
    }

    /// The circle (row, col) whose disc contains board point `(x, y)`, if any.
    #[inline]
    pub fn circle_at(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let c = (x / self.pitch_mm).round();
        let r = (y / self.pitch_mm).round();
        if c < 0.0 || r < 0.0 || c >= self.cols as f64 || r >= self.rows as f64 {
            return None;
        }
        let (ri, ci) = (r as usize, c as usize);
        let dx = x - c * self.pitch_mm;
        let dy = y - r * self.pitch_mm;
        let rad = 0.5 * self.diameter(ri, ci);
        (dx * dx + dy * dy <= rad * rad).then_some((ri, ci))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_and_membership() {
        let b = Board::hp3_paper();
        b.validate().unwrap();
        assert_eq!(b.len(), 88);
        assert_eq!(b.center(2, 3), Vector3::new(15.0, 10.0, 0.0));
        assert_eq!(b.diameter(0, 1), 3.5);
        assert_eq!(b.diameter(1, 1), 2.5);
        assert_eq!(b.circle_at(15.0 + 1.2, 10.0), Some((2, 3)));
        assert_eq!(b.circle_at(15.0 + 1.3, 10.0), None);
        assert_eq!(b.circle_at(5.0 + 1.7, 0.0), Some((0, 1)));
        assert_eq!(b.circle_at(-10.0, 0.0), None);
    }

    #[test]
    fn invalid_boards() {
        assert!(Board::circles(1, 5, 5.0, 2.0, 3.0).is_err());
        assert!(Board::circles(4, 5, 5.0, 5.0, 3.0).is_err());
        let mut b = Board::hp3_paper();
        b.markers.push([8, 0]);
        assert!(b.validate().is_err());
    }
}
