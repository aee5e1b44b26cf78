//! The scene: the board plate lying on a table, spheres (the scan's ball on the table,
//! or the two balls of a ball bar), an optional free plate (a flat artefact: a rectangle
//! at any pose, [`FreePlate`]), and the laser sheet; ray casting and shading in the
//! camera frame of one image. The verification scenes ([`crate::verify`]) have no board
//! and no table (`World::table` false): their artefacts float, the rays that miss them
//! see black.
//!
//! Geometry is exact: a ray hits the plate plane, the point's board coordinates decide
//! exactly whether it lies on a printed feature ([`Board::ink_at`]: a circle of a circle
//! grid or a dark square of a chessboard; so imaged circle edges are exact ellipses and
//! square sides exact lines under perspective, curves under distortion, up to
//! anti-aliasing), the sphere is an exact quadric. The plate is the target points'
//! bounding box grown by the plate margin ([`crate::target::plate_extent`]).
//!
//! Reflectances: the plate `plate_reflectance`, the printed features ("ink": circles,
//! dark squares) `circle_reflectance` (swapped for light circles on a dark plate).
//!
//! Shading (linear radiance, 1.0 = full scale):
//! - ambient part: surface reflectance (the illumination level is applied later);
//! - laser part: `peak * reflectance * cos(incidence) * (100 mm / r) *
//!   exp(-dist^2 / (2 sigma^2))`, with `dist` the distance of the surface point from the
//!   laser plane, `r` its distance from the emitter, and the sphere casting shadows.

use nalgebra::{Matrix3, Vector3};

use stripecal::model::geometry::{Iso3, Plane};
use stripecal::{Board, BoardKind};

mod bow;
pub use bow::Bow;

/// Surface ids used in materials and truth.
pub const SURF_NONE: u32 = 0;
pub const SURF_PLATE: u32 = 1;
pub const SURF_TABLE: u32 = 2;
pub const SURF_SPHERE: u32 = 3;
/// The free plate ([`FreePlate`]).
pub const SURF_FREE_PLATE: u32 = 4;
/// Printed features ("ink") are `SURF_CIRCLE0 + id` with the id of [`Board::ink_at`]:
/// `row * cols + col` for a circle, `(j + 1) * (cols + 1) + i + 1` for chessboard square
/// `(i, j)`. Every such material is >= 16, so it never equals another surface's id, and
/// below `16 + 1001 * 1001` (boards have at most 1000 x 1000 points), far from
/// `u32::MAX`.
pub const SURF_CIRCLE0: u32 = 16;
/// The same base under a kind-neutral name.
pub const SURF_INK0: u32 = SURF_CIRCLE0;

/// Reference distance of the laser fall-off law, mm.
pub const LASER_REF_DISTANCE_MM: f64 = 100.0;

/// The world in the robot base frame.
#[derive(Debug, Clone)]
pub struct World {
    pub board: Board,
    /// Plate beyond the outer target points, mm (see [`crate::target::plate_extent`]).
    pub plate_margin_mm: f64,
    /// `T_base_board`.
    pub base_board: Iso3,
    /// Plate thickness: the table surface lies this far behind the plate surface.
    pub plate_thickness_mm: f64,
    /// Whether the board plate and its table are in the scene (false: only the spheres
    /// and the free plate).
    pub table: bool,
    /// Sphere centres (base frame) and radii: none, the scan's ball, or a ball bar's two
    /// balls (which must not overlap).
    pub spheres: Vec<(Vector3<f64>, f64)>,
    /// A free plate, if any.
    pub free_plate: Option<FreePlate>,
    pub plate_reflectance: f64,
    /// Reflectance of the printed features: circles or dark squares ("ink").
    pub circle_reflectance: f64,
    pub table_reflectance: f64,
    pub sphere_reflectance: f64,
}

/// A flat rectangle at any pose (a flatness artefact): its surface is the plane z = 0 of
/// `T_base_plate`, `|x| <= half_size_mm[0]`, `|y| <= half_size_mm[1]`; seen from either
/// side, casting no shadows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FreePlate {
    /// `T_base_plate`.
    pub base_plate: Iso3,
    pub half_size_mm: [f64; 2],
    pub reflectance: f64,
}

/// The free plate in the camera frame.
#[derive(Debug, Clone, Copy)]
struct FreeRect {
    /// Plane `n . p = d`, `d >= 0` (n away from the camera).
    n: Vector3<f64>,
    d: f64,
    center: Vector3<f64>,
    ex: Vector3<f64>,
    ey: Vector3<f64>,
    half: [f64; 2],
    refl: f64,
}

impl FreeRect {
    /// Signed distance (mm, in the plate) of a point of its plane from the outline:
    /// positive inside.
    #[inline]
    fn inside_distance(&self, p: &Vector3<f64>) -> f64 {
        let l = p - self.center;
        (self.half[0] - self.ex.dot(&l).abs()).min(self.half[1] - self.ey.dot(&l).abs())
    }
}

/// Laser sheet parameters in the camera frame.
#[derive(Debug, Clone, Copy)]
pub struct Laser {
    pub plane: Plane,
    pub emitter: Vector3<f64>,
    pub sigma_mm: f64,
    pub peak: f64,
}

/// The scene as seen by one camera pose, everything in the camera frame.
#[derive(Debug, Clone)]
pub struct ImageScene {
    board: Board,
    /// Rows 0 and 1 of `R_board_cam` and the translation (board x, y of a camera point).
    bx: Vector3<f64>,
    by: Vector3<f64>,
    bt: Vector3<f64>,
    /// Plate plane `n . p = d` (n points into the plate, away from the camera).
    plate_n: Vector3<f64>,
    plate_d: f64,
    table_d: f64,
    extent: [f64; 4],
    table: bool,
    spheres: Vec<(Vector3<f64>, f64)>,
    free: Option<FreeRect>,
    pub laser: Laser,
    refl: [f64; 4],
    /// `T_cam_board`, kept for truth computations.
    pub cam_board: Iso3,
    /// A cylindrical bend of the board sheet ([`Bow`]); `None`: flat.
    bow: Option<Bow>,
}

/// How a pixel's footprint must be integrated (see [`ImageScene::classify`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Footprint {
    Uniform(Hit),
    Smooth,
    Edge,
    /// An edge pixel that also holds a chessboard junction (where square corners meet).
    Corner,
}

/// What one ray sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Surface / circle id (`SURF_*`).
    pub material: u32,
    /// Ray parameter: the point is `s * dir`.
    pub s: f64,
    pub reflectance: f64,
    /// Laser radiance at the point.
    pub laser: f64,
}

/// A flat-plate hit: the point `s * dir` and its board coordinates (x, y).
type PlateXy = (Vector3<f64>, f64, f64);

/// What a ray that hits nothing sees.
const MISS: Hit = Hit {
    material: SURF_NONE,
    s: f64::INFINITY,
    reflectance: 0.0,
    laser: 0.0,
};

impl World {
    /// The scene in the camera frame for `T_base_cam`.
    pub fn image_scene(&self, base_cam: &Iso3, laser: Laser) -> ImageScene {
        let cam_board = base_cam.inverse() * self.base_board;
        let board_cam = cam_board.inverse();
        let rbc: Matrix3<f64> = board_cam.rotation.to_rotation_matrix().into_inner();
        let bt = board_cam.translation.vector;
        let plate_n = cam_board.rotation * Vector3::z();
        let plate_d = plate_n.dot(&cam_board.translation.vector);
        let extent = crate::target::plate_extent(&self.board, self.plate_margin_mm);
        let cam_base = base_cam.inverse();
        ImageScene {
            board: self.board.clone(),
            bx: rbc.row(0).transpose(),
            by: rbc.row(1).transpose(),
            bt,
            plate_n,
            plate_d,
            table_d: plate_d + self.plate_thickness_mm,
            extent,
            table: self.table,
            spheres: self
                .spheres
                .iter()
                .map(|&(c, r)| ((cam_base * nalgebra::Point3::from(c)).coords, r))
                .collect(),
            free: self.free_plate.map(|f| {
                let t = cam_base * f.base_plate;
                let mut n = t.rotation * Vector3::z();
                let center = t.translation.vector;
                let mut d = n.dot(&center);
                if d < 0.0 {
                    n = -n;
                    d = -d;
                }
                FreeRect {
                    n,
                    d,
                    center,
                    ex: t.rotation * Vector3::x(),
                    ey: t.rotation * Vector3::y(),
                    half: f.half_size_mm,
                    refl: f.reflectance,
                }
            }),
            laser,
            refl: [
                self.plate_reflectance,
                self.circle_reflectance,
                self.table_reflectance,
                self.sphere_reflectance,
            ],
            cam_board,
            bow: None,
        }
    }
}

impl ImageScene {
    /// The board the scene shows.
    pub fn board(&self) -> &Board {
        &self.board
    }

    /// Board coordinates (x, y) of a camera-frame point on the plate plane.
    #[inline]
    pub fn board_xy(&self, p: &Vector3<f64>) -> (f64, f64) {
        (self.bx.dot(p) + self.bt.x, self.by.dot(p) + self.bt.y)
    }

    /// Whether board point (x, y) lies on the plate.
    #[inline]
    pub fn on_plate(&self, x: f64, y: f64) -> bool {
        x >= self.extent[0] && x <= self.extent[1] && y >= self.extent[2] && y <= self.extent[3]
    }

    /// Plate extent in board coordinates `[x0, x1, y0, y1]`.
    pub fn plate_extent(&self) -> [f64; 4] {
        self.extent
    }

    /// Plate plane in the camera frame (normal into the plate).
    pub fn plate_plane(&self) -> (Vector3<f64>, f64) {
        (self.plate_n, self.plate_d)
    }

    /// Table plane in the camera frame (normal into the table).
    pub fn table_plane(&self) -> (Vector3<f64>, f64) {
        (self.plate_n, self.table_d)
    }

    /// The first sphere in the camera frame.
    pub fn sphere(&self) -> Option<(Vector3<f64>, f64)> {
        self.spheres.first().copied()
    }

    /// Every sphere in the camera frame.
    pub fn spheres(&self) -> &[(Vector3<f64>, f64)] {
        &self.spheres
    }

    /// Whether the board plate and the table are in the scene.
    pub fn has_table(&self) -> bool {
        self.table
    }

    /// The free plate's plane in the camera frame `(n, d)` (n away from the camera).
    pub fn free_plate_plane(&self) -> Option<(Vector3<f64>, f64)> {
        self.free.map(|f| (f.n, f.d))
    }

    /// Distance (mm) of a point of the free plate's plane from its outline, positive
    /// inside; `None` without a free plate.
    pub fn free_plate_inside(&self, p: &Vector3<f64>) -> Option<f64> {
        self.free.map(|f| f.inside_distance(p))
    }

    /// The index of the sphere whose surface is nearest to p.
    #[inline]
    fn sphere_index(&self, p: &Vector3<f64>) -> usize {
        if self.spheres.len() < 2 {
            return 0;
        }
        let mut best = (0, f64::INFINITY);
        for (i, (c, r)) in self.spheres.iter().enumerate() {
            let e = ((p - c).norm() - r).abs();
            if e < best.1 {
                best = (i, e);
            }
        }
        best.0
    }

    /// The first surface a ray `s * dir` (s > 0) hits: `(surface, s)` with surface
    /// `SURF_PLATE` (plate, printed features not distinguished), `SURF_TABLE` or `SURF_SPHERE`.
    #[inline]
    pub fn first_hit(&self, dir: &Vector3<f64>) -> Option<(u32, f64)> {
        self.first_hit_xy(dir).map(|(surface, s, _)| (surface, s))
    }

    /// [`Self::first_hit`], with the point and its board coordinates when the ray hits
    /// the flat plate (`Some` only for `SURF_PLATE` without a bow): the very values
    /// [`Self::shade_at`] would compute again.
    #[inline(always)]
    fn first_hit_xy(&self, dir: &Vector3<f64>) -> Option<(u32, f64, Option<PlateXy>)> {
        let mut best: Option<(u32, f64)> = None;
        let mut plate: Option<PlateXy> = None;
        let den = self.plate_n.dot(dir);
        if self.table && den > 1e-12 {
            let s = self.plate_d / den;
            if s > 0.0 {
                if let Some(b) = &self.bow {
                    best = self.bow_hit(b, dir).map(|sb| (SURF_PLATE, sb));
                } else {
                    let p = dir * s;
                    let (x, y) = self.board_xy(&p);
                    if self.on_plate(x, y) {
                        best = Some((SURF_PLATE, s));
                        plate = Some((p, x, y));
                    }
                }
                if best.is_none() {
                    let st = self.table_d / den;
                    if st > 0.0 {
                        best = Some((SURF_TABLE, st));
                    }
                }
            }
        }
        let a = if self.spheres.is_empty() {
            0.0
        } else {
            dir.norm_squared()
        };
        for &(c, r) in &self.spheres {
            // |s dir - c|^2 = r^2
            let b = dir.dot(&c);
            let cc = c.norm_squared() - r * r;
            let disc = b * b - a * cc;
            if disc >= 0.0 {
                let s = (b - disc.sqrt()) / a;
                if s > 0.0 && best.is_none_or(|(_, sb)| s < sb) {
                    best = Some((SURF_SPHERE, s));
                }
            }
        }
        if let Some(f) = &self.free {
            let den = f.n.dot(dir);
            if den > 1e-12 {
                let s = f.d / den;
                if s > 0.0
                    && best.is_none_or(|(_, sb)| s < sb)
                    && f.inside_distance(&(dir * s)) >= 0.0
                {
                    best = Some((SURF_FREE_PLATE, s));
                }
            }
        }
        best.map(|(surface, s)| (surface, s, plate.filter(|_| surface == SURF_PLATE)))
    }

    /// Outward (towards the camera side) unit normal of a surface at point p.
    #[inline]
    pub fn normal_at(&self, surface: u32, p: &Vector3<f64>) -> Vector3<f64> {
        match surface {
            SURF_SPHERE => {
                let (c, r) = self.spheres[self.sphere_index(p)];
                (p - c) / r
            }
            SURF_FREE_PLATE => match &self.free {
                Some(f) => -f.n,
                None => -self.plate_n,
            },
            SURF_PLATE => match &self.bow {
                Some(b) => self.bow_normal(b, p),
                None => -self.plate_n,
            },
            _ => -self.plate_n,
        }
    }

    /// Whether the emitter sees point p (on `surface`): faces the emitter, no (other)
    /// sphere in between.
    #[inline]
    pub fn lit(&self, surface: u32, p: &Vector3<f64>) -> bool {
        let to_e = self.laser.emitter - p;
        self.lit_with(surface, p, &self.normal_at(surface, p), &to_e)
    }

    /// [`Self::lit`] given the normal at p and `emitter - p`.
    #[inline]
    fn lit_with(
        &self,
        surface: u32,
        p: &Vector3<f64>,
        normal: &Vector3<f64>,
        to_e: &Vector3<f64>,
    ) -> bool {
        let e = self.laser.emitter;
        if normal.dot(to_e) <= 0.0 {
            return false;
        }
        if surface == SURF_FREE_PLATE && self.table && self.plate_blocks(p, &e) {
            // the board shadows the free plate (the bench's floor) behind it
            return false;
        }
        let own = (surface == SURF_SPHERE).then(|| self.sphere_index(p));
        for (i, &(c, r)) in self.spheres.iter().enumerate() {
            if own != Some(i) {
                // segment p -> e against the sphere
                let dir = *to_e;
                let oc = p - c;
                let a = dir.norm_squared();
                let b = oc.dot(&dir);
                let cc = oc.norm_squared() - r * r;
                let disc = b * b - a * cc;
                if disc > 0.0 {
                    let sq = disc.sqrt();
                    let t1 = (-b - sq) / a;
                    let t2 = (-b + sq) / a;
                    if (t1 > 1e-9 && t1 < 1.0) || (t2 > 1e-9 && t2 < 1.0) {
                        return false;
                    }
                }
            }
        }
        true
    }

    /// Whether the segment from p to e crosses the board plate (its plane, within the
    /// plate's extent).
    #[inline]
    fn plate_blocks(&self, p: &Vector3<f64>, e: &Vector3<f64>) -> bool {
        let (dp, de) = (
            self.plate_n.dot(p) - self.plate_d,
            self.plate_n.dot(e) - self.plate_d,
        );
        if dp * de >= 0.0 {
            return false;
        }
        let q = p + (e - p) * (dp / (dp - de));
        let (x, y) = self.board_xy(&q);
        self.on_plate(x, y)
    }

    /// Laser radiance at point p of `surface` with reflectance `refl`.
    #[inline]
    pub fn laser_radiance(&self, surface: u32, p: &Vector3<f64>, refl: f64) -> f64 {
        let l = &self.laser;
        if l.peak == 0.0 {
            return 0.0;
        }
        let dist = l.plane.signed_distance(p);
        // |dist| > 7.5 sigma (sigma > 0) implies |dist / sigma| > 7, rounding included:
        // no division for the points far from the sheet
        if dist.abs() > 7.5 * l.sigma_mm && l.sigma_mm > 0.0 {
            return 0.0;
        }
        self.laser_radiance_near(surface, p, refl, dist)
    }

    /// [`Self::laser_radiance`] of a point at `dist` from the laser plane (the part
    /// left out of line: most points are far from the sheet or the laser is off).
    #[inline(never)]
    fn laser_radiance_near(&self, surface: u32, p: &Vector3<f64>, refl: f64, dist: f64) -> f64 {
        let l = &self.laser;
        let z = dist / l.sigma_mm;
        if z.abs() > 7.0 {
            return 0.0;
        }
        let to_e = l.emitter - p;
        let normal = self.normal_at(surface, p);
        if !self.lit_with(surface, p, &normal, &to_e) {
            return 0.0;
        }
        let r = to_e.norm();
        let cos_inc = normal.dot(&to_e) / r;
        l.peak * refl * cos_inc * (LASER_REF_DISTANCE_MM / r) * (-0.5 * z * z).exp()
    }

    /// Distance in board coordinates from plate point (x, y) to the nearest reflectance
    /// edge: a printed edge ([`Board::ink_edge_distance`]: a circle's border, a square's
    /// side) or the plate's edge.
    #[inline]
    pub fn plate_edge_distance(&self, x: f64, y: f64) -> f64 {
        let e = self.extent;
        let d = (x - e[0]).min(e[1] - x).min(y - e[2]).min(e[3] - y);
        d.min(self.board.ink_edge_distance(x, y))
    }

    /// Distance (board mm) from (x, y) to the nearest corner of a chessboard's squares
    /// (`(i s, j s)` for `i` in `-1..=cols`, `j` in `-1..=rows`); infinite for circle
    /// grids.
    #[inline]
    pub fn square_corner_distance(&self, x: f64, y: f64) -> f64 {
        let b = &self.board;
        if b.kind != BoardKind::Chessboard {
            return f64::INFINITY;
        }
        let s = b.pitch_mm;
        let i = (x / s).round().clamp(-1.0, b.cols as f64);
        let j = (y / s).round().clamp(-1.0, b.rows as f64);
        (x - i * s).hypot(y - j * s)
    }

    /// Classifies the footprint of a pixel whose rays all lie within angle `alpha`
    /// (radians, an upper bound) of its central ray `dir`:
    /// - [`Footprint::Uniform`]: every ray provably sees the same material with
    ///   constant reflectance and no laser light, so the pixel's integral equals this
    ///   one sample exactly;
    /// - [`Footprint::Edge`]: a material edge, the plate's outline or a silhouette may
    ///   cross the footprint (needs fine sampling);
    /// - [`Footprint::Corner`]: an edge footprint that may also hold a corner of a
    ///   chessboard's squares (an inner corner or a corner of the outer squares), where
    ///   the renderer samples more finely still;
    /// - [`Footprint::Smooth`]: one material, but the laser sheet is near (smooth
    ///   integrand: regular supersampling is accurate).
    #[inline]
    pub fn classify(&self, dir: &Vector3<f64>, alpha: f64) -> Footprint {
        let Some((surface, s)) = self.first_hit(dir) else {
            if self.table || self.near_silhouette(dir, alpha) {
                return Footprint::Edge;
            }
            return Footprint::Uniform(MISS);
        };
        let p = dir * s;
        let range = p.norm();
        let cos_view = self.normal_at(surface, &p).dot(&(-p / range));
        if cos_view < 0.1 {
            return Footprint::Edge;
        }
        // Footprint radius on the surface.
        let rho = range * alpha / cos_view;
        for &(c, r) in &self.spheres {
            if near_sphere_outline(dir, alpha, &c, r) {
                return Footprint::Edge;
            }
        }
        if self.free.is_some() && self.near_free_outline(dir, alpha) {
            return Footprint::Edge;
        }
        match surface {
            SURF_PLATE => {
                let (x, y) = self.board_xy(&p);
                if self.plate_edge_distance(x, y) <= 1.5 * rho {
                    if self.square_corner_distance(x, y) <= 1.5 * rho {
                        return Footprint::Corner;
                    }
                    return Footprint::Edge;
                }
            }
            SURF_TABLE => {
                // The plate's outline (an occlusion edge) must be outside the footprint.
                let den = self.plate_n.dot(dir);
                if den > 1e-12 {
                    let q = dir * (self.plate_d / den);
                    let (x, y) = self.board_xy(&q);
                    let e = self.extent;
                    let dx = (e[0] - x).max(x - e[1]);
                    let dy = (e[2] - y).max(y - e[3]);
                    let outside = if dx > 0.0 && dy > 0.0 {
                        (dx * dx + dy * dy).sqrt()
                    } else {
                        dx.max(dy)
                    };
                    let rho_plate = q.norm() * alpha / cos_view;
                    if outside <= 1.5 * rho_plate {
                        return Footprint::Edge;
                    }
                }
            }
            _ => {}
        }
        if self.laser.peak > 0.0
            && self.laser.plane.signed_distance(&p).abs() < 7.0 * self.laser.sigma_mm + 2.0 * rho
        {
            return Footprint::Smooth;
        }
        let hit = self.shade_at(dir, surface, s);
        if hit.laser == 0.0 {
            Footprint::Uniform(hit)
        } else {
            Footprint::Smooth
        }
    }

    /// Whether a footprint of a ray that hits nothing may hold a silhouette: a sphere's
    /// outline or the free plate's (scenes without a table).
    fn near_silhouette(&self, dir: &Vector3<f64>, alpha: f64) -> bool {
        if self
            .spheres
            .iter()
            .any(|(c, r)| near_sphere_outline(dir, alpha, c, *r))
        {
            return true;
        }
        self.free.is_some() && self.near_free_outline(dir, alpha)
    }

    /// Whether the free plate's outline may cross the footprint of a ray (a grazing view
    /// of its plane counts as near).
    fn near_free_outline(&self, dir: &Vector3<f64>, alpha: f64) -> bool {
        let Some(f) = &self.free else {
            return false;
        };
        let den = f.n.dot(dir);
        let cos_view = den / dir.norm();
        if cos_view < 0.1 {
            // grazing: near; away from the plane: never meets it
            return cos_view > -0.1;
        }
        let q = dir * (f.d / den);
        let rho = q.norm() * alpha / cos_view;
        f.inside_distance(&q).abs() <= 1.5 * rho
    }

    /// Shades one ray.
    #[inline]
    pub fn shade(&self, dir: &Vector3<f64>) -> Hit {
        match self.first_hit_xy(dir) {
            Some((surface, s, plate)) => self.shade_at_xy(dir, surface, s, plate),
            None => MISS,
        }
    }

    /// Shades the ray `dir` whose first hit ([`Self::first_hit`]) is `surface` at `s`.
    #[inline]
    fn shade_at(&self, dir: &Vector3<f64>, surface: u32, s: f64) -> Hit {
        self.shade_at_xy(dir, surface, s, None)
    }

    /// [`Self::shade_at`], with the point `dir * s` and its board coordinates when known
    /// ([`Self::first_hit_xy`]).
    #[inline(always)]
    fn shade_at_xy(&self, dir: &Vector3<f64>, surface: u32, s: f64, plate: Option<PlateXy>) -> Hit {
        let (p, xy) = match plate {
            Some((p, x, y)) => (p, Some((x, y))),
            None => (dir * s, None),
        };
        let (material, refl) = match surface {
            SURF_PLATE => {
                let (x, y) = xy.unwrap_or_else(|| self.board_xy(&p));
                match self.board.ink_at(x, y) {
                    Some(id) => (SURF_INK0 + id as u32, self.refl[1]),
                    None => (SURF_PLATE, self.refl[0]),
                }
            }
            SURF_TABLE => (SURF_TABLE, self.refl[2]),
            SURF_FREE_PLATE => (SURF_FREE_PLATE, self.free.map_or(self.refl[0], |f| f.refl)),
            _ => (SURF_SPHERE, self.refl[3]),
        };
        Hit {
            material,
            s,
            reflectance: refl,
            laser: self.laser_radiance(surface, &p, refl),
        }
    }
}

/// Whether the outline of the sphere `(c, r)` may cross the footprint of a ray `dir`
/// whose rays lie within `alpha` of it: the angle between `dir` and the centre is within
/// `1.5 alpha` of the outline's `asin(r / |c|)` (or the camera is inside the sphere).
///
/// `|cos a - cos b| <= |a - b|`, so where the two cosines already differ by more than
/// `1.5 alpha` so do the angles: that test needs no inverse trigonometry, and the exact
/// one runs only near the outline (the answer is the exact test's everywhere).
#[inline]
fn near_sphere_outline(dir: &Vector3<f64>, alpha: f64, c: &Vector3<f64>, r: f64) -> bool {
    let cn = c.norm();
    if cn <= r {
        return true;
    }
    let margin = 1.5 * alpha;
    let cos_beta = dir.dot(c) / (dir.norm() * cn);
    let cos_gamma = (1.0 - (r / cn).powi(2)).max(0.0).sqrt();
    // the slack covers the rounding of both cosines
    if (cos_beta - cos_gamma).abs() > margin * (1.0 + 1e-9) + 1e-12 {
        return false;
    }
    (dir.angle(c) - (r / cn).asin()).abs() < margin
}
