//! A board sheet bent into a cylinder (a paper board held by hand): the exact ray cast
//! against the bent sheet ([`Bow`], [`ImageScene::with_bow`]).
//!
//! The printed point at board coordinates `(x, y)` lies at `(x, y, z(x, y))` in the
//! board frame (`z` into the board, away from the camera), with
//!
//! ```text
//! z(x, y) = -sag (1 - (2 x' / W)^2),   x' = ((x, y) - c) . u
//! ```
//!
//! `u` the unit direction across the bend (the cylinder's axis is perpendicular to it,
//! in the board plane), `c` the centre of the grid's points, `W` the width of the grid's
//! points along `u`: the middle of the board lies `sag` mm nearer the camera than the
//! two edges of the pattern across the bend (the figure of
//! `stripecal::calib::flatness`). A ray meets this parabolic cylinder where a
//! quadratic in the ray parameter vanishes: solved exactly, the nearer root on the plate
//! is the hit.

use nalgebra::Vector3;

use super::ImageScene;

/// A cylindrical bend of the board sheet (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bow {
    /// mm, positive: the middle towards the camera.
    pub sag_mm: f64,
    /// Unit direction across the bend, board frame.
    pub u: [f64; 2],
    /// Centre of the bend, board mm.
    pub center: [f64; 2],
    /// Width across the bend, mm.
    pub width_mm: f64,
}

impl Bow {
    /// The bend of `board` by `sag_mm` with its axis at `axis_deg` from board x: centred
    /// on the grid's points, `W` their extent across the axis.
    pub fn for_board(board: &stripecal::Board, sag_mm: f64, axis_deg: f64) -> Bow {
        let a = axis_deg.to_radians();
        let u = [a.sin(), -a.cos()];
        let c = crate::target::points_center(board);
        let (lo, hi) = board.indices().map(|(r, k)| board.center(r, k)).fold(
            (f64::INFINITY, f64::NEG_INFINITY),
            |(lo, hi), p| {
                let x = u[0] * (p.x - c.x) + u[1] * (p.y - c.y);
                (lo.min(x), hi.max(x))
            },
        );
        Bow {
            sag_mm,
            u,
            center: [c.x, c.y],
            width_mm: hi - lo,
        }
    }

    /// `4 sag / W^2`.
    fn c(&self) -> f64 {
        4.0 * self.sag_mm / (self.width_mm * self.width_mm)
    }

    /// Coordinate across the bend of board point (x, y).
    fn across(&self, x: f64, y: f64) -> f64 {
        self.u[0] * (x - self.center[0]) + self.u[1] * (y - self.center[1])
    }

    /// Board-frame z of the sheet at board (x, y).
    pub fn z(&self, x: f64, y: f64) -> f64 {
        let xp = self.across(x, y);
        -self.sag_mm + self.c() * xp * xp
    }
}

impl ImageScene {
    /// The scene with its board sheet bent by `bow` (the table, if any, stays flat).
    pub fn with_bow(mut self, bow: Bow) -> ImageScene {
        self.bow = Some(bow);
        self
    }

    /// The bend of the sheet, if any.
    pub fn bow(&self) -> Option<Bow> {
        self.bow
    }

    /// The board-frame point of the sheet at board coordinates (x, y) (z = 0 when flat).
    pub fn sheet_point(&self, x: f64, y: f64) -> nalgebra::Point3<f64> {
        let z = self.bow.map_or(0.0, |b| b.z(x, y));
        nalgebra::Point3::new(x, y, z)
    }

    /// The nearest hit `s > 0` of ray `s * dir` on the bent sheet within the plate.
    pub(super) fn bow_hit(&self, b: &Bow, dir: &Vector3<f64>) -> Option<f64> {
        // board coordinates along the ray: x = s ax + bt.x, y = s ay + bt.y, z = s az - d
        let ax = self.bx.dot(dir);
        let ay = self.by.dot(dir);
        let az = self.plate_n.dot(dir);
        let m = b.u[0] * ax + b.u[1] * ay;
        let q = b.across(self.bt.x, self.bt.y);
        let c = b.c();
        // s az - d = -sag + c (s m + q)^2
        let qa = c * m * m;
        let qb = 2.0 * c * m * q - az;
        let qc = c * q * q + self.plate_d - b.sag_mm;
        let mut roots = [f64::NAN, f64::NAN];
        if qa.abs() < 1e-300 || (qa * qc / (qb * qb)).abs() < 1e-14 {
            roots[0] = -qc / qb;
        } else {
            let disc = qb * qb - 4.0 * qa * qc;
            if disc < 0.0 {
                return None;
            }
            // stable form
            let t = -0.5 * (qb + qb.signum() * disc.sqrt());
            roots = [t / qa, qc / t];
        }
        if roots[0] > roots[1] {
            roots.swap(0, 1);
        }
        roots
            .into_iter()
            .filter(|s| s.is_finite() && *s > 0.0)
            .find(|&s| {
                let (x, y) = self.board_xy(&(dir * s));
                self.on_plate(x, y)
            })
    }

    /// Outward (towards the camera side) unit normal of the bent sheet at p.
    pub(super) fn bow_normal(&self, b: &Bow, p: &Vector3<f64>) -> Vector3<f64> {
        let (x, y) = self.board_xy(p);
        let xp = b.across(x, y);
        // F(p) = z(p) - h(x(p), y(p)); grad F points into the board
        let g = self.plate_n - (self.bx * b.u[0] + self.by * b.u[1]) * (2.0 * b.c() * xp);
        -g.normalize()
    }
}
