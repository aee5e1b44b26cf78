//! The calibration target's layout (spec/DATASET.md, "Board" and "Target kinds").
//!
//! ## Conventions
//!
//! Every target is a grid of *points* indexed `(row, col)` on a flat plate, with board x
//! along increasing columns, y along increasing rows and z = x cross y pointing into
//! the plate (away from a camera that sees the printed side):
//!
//! | kind | point `(r, c)` at board `(x, y, 0)` | lattice `(i, j)` | lattice unit |
//! |---|---|---|---|
//! | `circles` | `(c p, r p)` | `(c, r)` | `p = pitch_mm` |
//! | `asymmetric_circles` | `((2c + r mod 2) p / 2, r p / 2)` | `(2c + r mod 2, r)` | `p / 2` |
//! | `chessboard` (inner corners) | `(c s, r s)` | `(c, r)` | `s = square_mm` |
//!
//! The *lattice* coordinates are integers with `point = lattice * unit`; detection grows
//! grids in them, and [`Board::symmetries`] are rotations of the lattice.
//!
//! - Circles listed in `markers` (default the L `[0,0], [0,1], [1,0]`; any number,
//!   none included) have the diameter `marker_diameter_mm`.
//! - A chessboard's squares are `(i, j)` for `i` in `-1..=cols - 1`, `j` in
//!   `-1..=rows - 1`, covering `x` in `[i s, (i + 1) s]`, `y` in `[j s, (j + 1) s]`; square
//!   `(i, j)` is dark when `i + j` is even (so the square outside corner `(0, 0)`,
//!   `(-1, -1)`, is dark, as the contract says).
//! - A chessboard corner is a point target: [`Board::diameter`] is 0, and its image is
//!   the projection of the point (no perspective bias, unlike a circle's centroid).

mod symmetry;

pub use symmetry::Symmetry;

use nalgebra::Vector3;

use crate::error::{Error, Result};

/// What kind of target a board is (`"kind"` in rig.json).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum BoardKind {
    /// A symmetric grid of filled circles (the paper's target), with optional markers.
    #[default]
    Circles,
    /// OpenCV's asymmetric circle grid: odd rows shifted by half a pitch.
    AsymmetricCircles,
    /// A chessboard; the points are its inner corners.
    Chessboard,
}

impl BoardKind {
    /// Every kind, in the contract's order.
    pub const ALL: [BoardKind; 3] = [
        BoardKind::Circles,
        BoardKind::AsymmetricCircles,
        BoardKind::Chessboard,
    ];

    /// The contract's name: `circles`, `asymmetric_circles`, `chessboard`.
    pub fn name(self) -> &'static str {
        match self {
            BoardKind::Circles => "circles",
            BoardKind::AsymmetricCircles => "asymmetric_circles",
            BoardKind::Chessboard => "chessboard",
        }
    }

    /// Parses a contract name.
    pub fn from_name(s: &str) -> Result<BoardKind> {
        BoardKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                Error::InvalidInput(format!(
                    "unknown board kind {s:?}: expected \"circles\", \"asymmetric_circles\" or \
                     \"chessboard\""
                ))
            })
    }

    /// Whether the points are circle centres (`circles`, `asymmetric_circles`).
    pub fn is_circles(self) -> bool {
        self != BoardKind::Chessboard
    }
}

/// A calibration target.
#[derive(Debug, Clone, PartialEq)]
pub struct Board {
    pub kind: BoardKind,
    /// Grid rows (points along board y).
    pub rows: usize,
    /// Grid columns (points along board x).
    pub cols: usize,
    /// Circles: centre-to-centre distance along a row, mm. Chessboards: the square side.
    pub pitch_mm: f64,
    /// Diameter of ordinary circles, mm (unused for chessboards).
    pub circle_diameter_mm: f64,
    /// Diameter of marker circles, mm (used only when `markers` is not empty).
    pub marker_diameter_mm: f64,
    /// Marker circles as `[row, col]` (`circles` only; empty for the other kinds).
    pub markers: Vec<[usize; 2]>,
    /// Dark circles on a light plate (`true`) or light on dark (circle kinds).
    pub dark_circles: bool,
    /// Chessboard square size, mm (chessboards only; equals `pitch_mm`).
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

    /// An asymmetric circle grid (dark circles), checked.
    pub fn asymmetric_circles(
        rows: usize,
        cols: usize,
        pitch_mm: f64,
        circle_diameter_mm: f64,
    ) -> Result<Board> {
        let b = Board {
            kind: BoardKind::AsymmetricCircles,
            rows,
            cols,
            pitch_mm,
            circle_diameter_mm,
            marker_diameter_mm: circle_diameter_mm,
            markers: Vec::new(),
            dark_circles: true,
            square_mm: None,
        };
        b.validate()?;
        Ok(b)
    }

    /// A chessboard of `rows x cols` inner corners, checked.
    pub fn chessboard(rows: usize, cols: usize, square_mm: f64) -> Result<Board> {
        let b = Board {
            kind: BoardKind::Chessboard,
            rows,
            cols,
            pitch_mm: square_mm,
            circle_diameter_mm: 0.0,
            marker_diameter_mm: 0.0,
            markers: Vec::new(),
            dark_circles: true,
            square_mm: Some(square_mm),
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

    /// Checks sizes: at least 2 x 2 points; positive lengths; circles that do not touch
    /// their nearest neighbours; markers inside the grid (circles only).
    pub fn validate(&self) -> Result<()> {
        if self.rows < 2 || self.cols < 2 {
            return Err(Error::InvalidInput(format!(
                "board must have at least 2 x 2 points, got {} x {}",
                self.rows, self.cols
            )));
        }
        if self.rows > 1000 || self.cols > 1000 {
            return Err(Error::InvalidInput(format!(
                "board of {} x {} points is larger than 1000 x 1000",
                self.rows, self.cols
            )));
        }
        let ok = |x: f64| x.is_finite() && x > 0.0;
        if !ok(self.pitch_mm) {
            return Err(Error::InvalidInput(format!(
                "board pitch {} mm must be positive",
                self.pitch_mm
            )));
        }
        match self.kind {
            BoardKind::Chessboard => {
                if self.square_mm != Some(self.pitch_mm) {
                    return Err(Error::InvalidInput(format!(
                        "a chessboard needs square_mm equal to pitch_mm (got {:?} and {})",
                        self.square_mm, self.pitch_mm
                    )));
                }
                if !self.markers.is_empty() {
                    return Err(Error::InvalidInput(
                        "a chessboard has no marker circles (markers must be empty)".into(),
                    ));
                }
            }
            BoardKind::Circles | BoardKind::AsymmetricCircles => {
                let spacing = self.neighbour_distance_mm();
                let limit = match self.kind {
                    BoardKind::Circles => format!("the pitch ({spacing} mm)"),
                    _ => format!(
                        "the distance between neighbouring circles (pitch / sqrt 2 = {spacing:.4} mm)"
                    ),
                };
                if !ok(self.circle_diameter_mm) || self.circle_diameter_mm >= spacing {
                    return Err(Error::InvalidInput(format!(
                        "circle diameter {} mm must be positive and smaller than {limit}",
                        self.circle_diameter_mm
                    )));
                }
                if !self.markers.is_empty()
                    && (!ok(self.marker_diameter_mm) || self.marker_diameter_mm >= spacing)
                {
                    return Err(Error::InvalidInput(format!(
                        "marker diameter {} mm must be positive and smaller than {limit}",
                        self.marker_diameter_mm
                    )));
                }
                if self.kind == BoardKind::AsymmetricCircles && !self.markers.is_empty() {
                    return Err(Error::InvalidInput(
                        "an asymmetric circle grid has no markers (markers must be empty)".into(),
                    ));
                }
            }
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

    /// Distance between nearest neighbouring points, mm.
    pub fn neighbour_distance_mm(&self) -> f64 {
        match self.kind {
            BoardKind::AsymmetricCircles => self.pitch_mm * std::f64::consts::FRAC_1_SQRT_2,
            _ => self.pitch_mm,
        }
    }

    /// Number of points.
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

    /// Diameter (mm) of circle `(row, col)`; 0 for a chessboard corner (a point).
    pub fn diameter(&self, row: usize, col: usize) -> f64 {
        match self.kind {
            BoardKind::Chessboard => 0.0,
            _ if self.is_marker(row, col) => self.marker_diameter_mm,
            _ => self.circle_diameter_mm,
        }
    }

    /// The lattice unit, mm (see the module docs).
    pub fn lattice_unit_mm(&self) -> f64 {
        match self.kind {
            BoardKind::AsymmetricCircles => 0.5 * self.pitch_mm,
            _ => self.pitch_mm,
        }
    }

    /// Integer lattice coordinates `(i, j)` of point `(row, col)` (module docs).
    #[inline]
    pub fn lattice(&self, row: usize, col: usize) -> (i64, i64) {
        // saturating: an index beyond the board (never one of its points) must not
        // overflow
        let (r, c) = (sat_i64(row), sat_i64(col));
        match self.kind {
            BoardKind::AsymmetricCircles => (c.saturating_mul(2).saturating_add(r % 2), r),
            _ => (c, r),
        }
    }

    /// The point `(row, col)` at lattice coordinates `(i, j)`, if there is one.
    #[inline]
    pub fn from_lattice(&self, i: i64, j: i64) -> Option<(usize, usize)> {
        if i < 0 || j < 0 || j >= self.rows as i64 {
            return None;
        }
        let row = j as usize;
        let col = match self.kind {
            BoardKind::AsymmetricCircles => {
                let k = i - (row % 2) as i64;
                if k < 0 || k % 2 != 0 {
                    return None;
                }
                (k / 2) as usize
            }
            _ => i as usize,
        };
        (col < self.cols).then_some((row, col))
    }

    /// Position of point `(row, col)` in board coordinates (mm): a circle's centre or a
    /// chessboard's inner corner.
    #[inline]
    pub fn center(&self, row: usize, col: usize) -> Vector3<f64> {
        let (i, j) = self.lattice(row, col);
        let (x, y) = self.site_xy(i, j);
        Vector3::new(x, y, 0.0)
    }

    /// Board coordinates (mm) of lattice site `(i, j)`: the site times the lattice unit.
    #[inline]
    fn site_xy(&self, i: i64, j: i64) -> (f64, f64) {
        let u = self.lattice_unit_mm();
        (i as f64 * u, j as f64 * u)
    }

    /// All points as `(row, col)` in row-major order.
    pub fn indices(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        (0..self.rows).flat_map(move |r| (0..self.cols).map(move |c| (r, c)))
    }

    /// The circle `(row, col)` whose disc contains board point `(x, y)`, if any (circle
    /// kinds; always `None` for a chessboard).
    #[inline]
    pub fn circle_at(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        if self.kind == BoardKind::Chessboard {
            return None;
        }
        let ((i, j), (r, c)) = self.nearest_point(x, y)?;
        // the centre of point (r, c), from its lattice site
        let (cx, cy) = self.site_xy(i, j);
        let (dx, dy) = (x - cx, y - cy);
        let rad = 0.5 * self.diameter(r, c);
        (dx * dx + dy * dy <= rad * rad).then_some((r, c))
    }

    /// The grid point nearest to board point `(x, y)` among the lattice sites next to
    /// it (circle kinds), or `None` outside the grid: its lattice coordinates and
    /// `(row, col)`, `((i, j), (row, col))`.
    #[inline]
    fn nearest_point(&self, x: f64, y: f64) -> Option<Site> {
        let u = self.lattice_unit_mm();
        let (fi, fj) = (x / u, y / u);
        match self.kind {
            BoardKind::AsymmetricCircles => {
                // Sites have i + j even: the nearest is among the four around (fi, fj).
                let (i0, j0) = (floor_i64(fi), floor_i64(fj));
                let mut best: Option<(f64, Site)> = None;
                for (di, dj) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (i, j) = (i0.saturating_add(di), j0.saturating_add(dj));
                    if let Some(rc) = self.from_lattice(i, j) {
                        let d = (i as f64 - fi).powi(2) + (j as f64 - fj).powi(2);
                        if best.is_none_or(|(bd, _)| d < bd) {
                            best = Some((d, ((i, j), rc)));
                        }
                    }
                }
                best.map(|(_, site)| site)
            }
            _ => {
                // `round(f) >= 0` exactly when `f > -0.5` (false for NaN)
                if !(fi > -0.5 && fj > -0.5) {
                    return None;
                }
                let (i, j) = (round_i64(fi), round_i64(fj));
                self.from_lattice(i, j).map(|rc| ((i, j), rc))
            }
        }
    }

    /// Chessboard square `(i, j)` (module docs) is dark; `false` outside the squares.
    #[inline]
    pub fn square_is_dark(&self, i: i64, j: i64) -> bool {
        self.kind == BoardKind::Chessboard
            && i >= -1
            && j >= -1
            && i < self.cols as i64
            && j < self.rows as i64
            && (i + j).rem_euclid(2) == 0
    }

    /// The printed feature at board point `(x, y)`: `Some(id)` on a circle (`id = row *
    /// cols + col`) or a dark chessboard square (`id = (j + 1) * (cols + 1) + i + 1`),
    /// `None` on the bare plate.
    #[inline]
    pub fn ink_at(&self, x: f64, y: f64) -> Option<usize> {
        match self.kind {
            BoardKind::Chessboard => {
                let s = self.pitch_mm;
                let (fx, fy) = (x / s, y / s);
                // floor keeps (non-)finiteness
                if !(fx.is_finite() && fy.is_finite()) {
                    return None;
                }
                let (i, j) = (floor_i64(fx), floor_i64(fy));
                self.square_is_dark(i, j)
                    .then(|| ((j + 1) * (self.cols as i64 + 1) + i + 1) as usize)
            }
            _ => self.circle_at(x, y).map(|(r, c)| r * self.cols + c),
        }
    }

    /// Distance (mm) from board point `(x, y)` to the nearest edge of the printed
    /// pattern (a circle's border, a square's side), an upper bound that is exact near
    /// the edges.
    pub fn ink_edge_distance(&self, x: f64, y: f64) -> f64 {
        match self.kind {
            BoardKind::Chessboard => {
                let s = self.pitch_mm;
                let (lo_x, hi_x) = (-s, self.cols as f64 * s);
                let (lo_y, hi_y) = (-s, self.rows as f64 * s);
                let dx_out = (lo_x - x).max(x - hi_x);
                let dy_out = (lo_y - y).max(y - hi_y);
                if dx_out > 0.0 || dy_out > 0.0 {
                    // Outside the squares: distance to the pattern's rectangle.
                    return if dx_out > 0.0 && dy_out > 0.0 {
                        dx_out.hypot(dy_out)
                    } else {
                        dx_out.max(dy_out)
                    };
                }
                // Inside: distance to the nearest grid line.
                let fx = x / s - (x / s).floor();
                let fy = y / s - (y / s).floor();
                (fx.min(1.0 - fx) * s).min(fy.min(1.0 - fy) * s)
            }
            _ => {
                // A circle whose border lies within e of the point has its centre within
                // r + e of it: less than 1.5 lattice units for every valid board (circles
                // do not touch: r < 0.5 unit for symmetric grids, < 0.71 for asymmetric
                // ones) and small e, so the 3 x 3 sites around the point hold it. (The
                // twin asks this once per rendered pixel: keep it cheap.)
                let u = self.lattice_unit_mm();
                let (i0, j0) = ((x / u).round() as i64, (y / u).round() as i64);
                let mut d = f64::INFINITY;
                for j in j0.saturating_sub(1)..=j0.saturating_add(1) {
                    for i in i0.saturating_sub(1)..=i0.saturating_add(1) {
                        if let Some((r, c)) = self.from_lattice(i, j) {
                            let p = self.center(r, c);
                            let dist = ((x - p.x).powi(2) + (y - p.y).powi(2)).sqrt();
                            d = d.min((dist - 0.5 * self.diameter(r, c)).abs());
                        }
                    }
                }
                d
            }
        }
    }

    /// Bounding box of the printed pattern in board coordinates, `[x0, x1, y0, y1]` mm:
    /// the circles' discs, or a chessboard's outer squares.
    pub fn pattern_extent(&self) -> [f64; 4] {
        let last = self.center(self.rows.saturating_sub(1), self.cols.saturating_sub(1));
        match self.kind {
            BoardKind::Chessboard => {
                let s = self.pitch_mm;
                [-s, last.x + s, -s, last.y + s]
            }
            BoardKind::Circles | BoardKind::AsymmetricCircles => {
                let r = 0.5
                    * self.circle_diameter_mm.max(if self.markers.is_empty() {
                        0.0
                    } else {
                        self.marker_diameter_mm
                    });
                let mut x1 = last.x;
                if self.kind == BoardKind::AsymmetricCircles && self.rows > 1 {
                    x1 = x1.max(self.center(1, self.cols - 1).x);
                }
                [-r, x1 + r, -r, last.y + r]
            }
        }
    }
}

/// A lattice site with its point: `((i, j), (row, col))`.
type Site = ((i64, i64), (usize, usize));

/// `x.floor() as i64` (saturating, NaN gives 0) without a library call (the baseline
/// x86-64 target has no rounding instruction): truncation, one less for a negative
/// non-integer.
#[inline]
fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    // `t as f64` is exact: `t` is the truncation of `x` or saturated (then the
    // comparison keeps it saturated)
    if t as f64 > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// `x.round() as i64` (half away from zero, saturating, NaN gives 0) without a library
/// call: truncation corrected by the exact fractional part `x - trunc(x)`.
#[inline]
fn round_i64(x: f64) -> i64 {
    let t = x as i64;
    let f = x - t as f64;
    if f >= 0.5 {
        t.saturating_add(1)
    } else if f <= -0.5 {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// `v` as an `i64`, `i64::MAX` when it does not fit.
fn sat_i64(v: usize) -> i64 {
    i64::try_from(v).unwrap_or(i64::MAX)
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
        assert!((b.ink_edge_distance(15.0, 10.0) - 1.25).abs() < 1e-12);
    }

    #[test]
    fn asymmetric_layout_follows_the_contract() {
        let b = Board::asymmetric_circles(4, 3, 20.0, 6.0).unwrap();
        // ((2c + r mod 2) p / 2, r p / 2)
        for (r, c) in b.indices() {
            let p = b.center(r, c);
            let want = ((2 * c + r % 2) as f64 * 10.0, r as f64 * 10.0);
            assert_eq!((p.x, p.y), want, "({r}, {c})");
            let (i, j) = b.lattice(r, c);
            assert_eq!(b.from_lattice(i, j), Some((r, c)));
            assert_eq!(b.circle_at(p.x + 2.9, p.y), Some((r, c)));
        }
        assert_eq!(b.from_lattice(1, 0), None, "odd i on an even row");
        assert_eq!(b.circle_at(10.0, 0.0), None, "between two circles of row 0");
        // nearest neighbours p / sqrt(2) apart; a 15 mm circle would touch them
        assert!(Board::asymmetric_circles(4, 3, 20.0, 15.0).is_err());
        assert_eq!(b.pattern_extent(), [-3.0, 53.0, -3.0, 33.0]);
    }

    #[test]
    fn chessboard_layout_and_colours() {
        let b = Board::chessboard(6, 9, 20.0).unwrap();
        assert_eq!(b.center(2, 3), Vector3::new(60.0, 40.0, 0.0));
        assert_eq!(b.diameter(2, 3), 0.0);
        // the square outside corner (0, 0) is dark, its neighbours light
        assert!(b.ink_at(-10.0, -10.0).is_some());
        assert!(b.ink_at(10.0, -10.0).is_none());
        assert!(b.ink_at(-10.0, 10.0).is_none());
        assert!(b.ink_at(10.0, 10.0).is_some());
        // outside the squares: the plate
        assert!(b.ink_at(-30.0, -10.0).is_none());
        assert!(b.ink_at(175.0, 115.0).is_none());
        assert_eq!(b.pattern_extent(), [-20.0, 180.0, -20.0, 120.0]);
        assert!((b.ink_edge_distance(3.0, 8.0) - 3.0).abs() < 1e-12);
        assert!((b.ink_edge_distance(-25.0, 5.0) - 5.0).abs() < 1e-12);
        let mut bad = b.clone();
        bad.square_mm = Some(21.0);
        assert!(bad.validate().is_err());
    }

    /// The 3 x 3 neighbourhood finds the nearest circle border wherever it is close
    /// (within 0.2 lattice units), for symmetric and asymmetric grids with circles that
    /// nearly touch.
    #[test]
    fn ink_edge_distance_is_exact_near_the_edges() {
        let mut near_touching = Board::hp3_paper();
        near_touching.marker_diameter_mm = 4.9;
        for b in [
            Board::hp3_paper(),
            near_touching,
            Board::asymmetric_circles(5, 4, 10.0, 7.0).unwrap(),
            Board::asymmetric_circles(4, 6, 10.0, 3.0).unwrap(),
        ] {
            let u = b.lattice_unit_mm();
            let e = b.pattern_extent();
            let brute = |x: f64, y: f64| {
                b.indices()
                    .map(|(r, c)| {
                        let p = b.center(r, c);
                        ((x - p.x).hypot(y - p.y) - 0.5 * b.diameter(r, c)).abs()
                    })
                    .fold(f64::INFINITY, f64::min)
            };
            let mut checked = 0;
            for iy in 0..200 {
                for ix in 0..200 {
                    let x = e[0] - u + (e[1] - e[0] + 2.0 * u) * ix as f64 / 199.0;
                    let y = e[2] - u + (e[3] - e[2] + 2.0 * u) * iy as f64 / 199.0;
                    let want = brute(x, y);
                    if want < 0.2 * u {
                        checked += 1;
                        assert!((b.ink_edge_distance(x, y) - want).abs() < 1e-12, "{x} {y}");
                    }
                }
            }
            assert!(checked > 1000);
        }
    }

    #[test]
    fn kind_names_round_trip() {
        for k in BoardKind::ALL {
            assert_eq!(BoardKind::from_name(k.name()).unwrap(), k);
        }
        assert!(BoardKind::from_name("charuco").is_err());
    }

    #[test]
    fn invalid_boards() {
        assert!(Board::circles(1, 5, 5.0, 2.0, 3.0).is_err());
        assert!(Board::circles(4, 5, 5.0, 5.0, 3.0).is_err());
        let mut b = Board::hp3_paper();
        b.markers.push([8, 0]);
        assert!(b.validate().is_err());
        // no markers: the marker diameter is not used
        let mut b = Board::hp3_paper();
        b.markers.clear();
        b.marker_diameter_mm = 0.0;
        b.validate().unwrap();
    }
}
