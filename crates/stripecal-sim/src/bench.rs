//! The bench mode of the twin (issue 17): the sensor calibrated on its own, no robot.
//!
//! A FIXED sensor (the rig's true camera and laser plane, the camera frame is the world)
//! looks at the board placed by hand: `bench.views` poses, each with a board image and a
//! laser image. The dataset is the contract's bench dataset (spec/DATASET.md, "No pose
//! columns at all"): `views.csv` with the header `board_image,laser_image`, rig.json
//! without a robot, and truth.json with the true camera and laser plane and, per image,
//! the true `T_cam_board` (key `cam_board`). Deterministic per seed.
//!
//! ## Board poses ([`Twin::bench_views`])
//!
//! Drawn as a hand places a board: an image point is drawn uniformly in the middle 80 %
//! of the image and its ray cut with the laser plane; the cut must lie within
//! `bench.standoff_mm` (default the rig's `working_range_mm`): the board is placed
//! with a random point of its grid there, so the laser line always crosses it. Its
//! normal is tilted from the optical axis by up to `max_tilt_deg` (uniform) about an
//! axis at a uniform azimuth, and it is rotated in its plane by a uniform angle (any
//! turn). A pose is kept when the laser line crosses the grid over at least
//! `min_stripe_mm` of lit, imaged board, and either the whole printed pattern is inside
//! the image (`margin_px`) or, for the `partial_views` views spread over the set (view
//! indices `(2k + 1) N / (2 P)`), between `min_imaged` of the points and all but one are
//! imaged (the board partly out of the view), with `partial_keep_markers` (default) the
//! marker circles among them (so the view can be indexed).
//!
//! ## Real bench habits
//!
//! - `bench.floor`: the board stands on a floor (a plane of `reflectance`; the camera
//!   looks down at it by `camera_pitch_deg`), touching it at the plate's lowest corner;
//!   the laser line continues onto the floor in front of and behind the board (the
//!   board shadows the floor behind it); a pose is kept only when at least
//!   `min_stripe_mm / 2` of the line on the floor is lit and imaged. truth.json gives
//!   each view's floor plane.
//! - `bench.bow`: the views `bow.views` are of a paper board bent into a cylinder
//!   ([`crate::scene::Bow`]: sag `sag_mm` at the middle across the grid's width, axis at
//!   `axis_deg` from board x), rendered exactly; truth.json gives each view's `sag_mm`
//!   (0 for flat ones) and the bend. A bent view's stripe truth on the board is empty
//!   (the stripe is a curve there; the truth traces straight lines only).
//!
//! - `bench.scan`: a fixed-sensor scan of a ball on a conveyor ([`crate::bench_scan`]).
//!
//! Without a table, the board floats in a dark room: the scene's table is pushed
//! [`BACKDROP_MM`] behind the board with reflectance 0.

use nalgebra::{Matrix3, Point3, Rotation3, Unit, Vector2, Vector3};
use serde::{Deserialize, Serialize};

use stripecal::model::geometry::{iso_from_parts, Iso3};

use crate::rng::Rng;
use crate::scene::{Bow, FreePlate, ImageScene, World};
use crate::target::{pattern_inside, points_bbox, points_inside_quick};
use crate::{SimError, Twin};

/// How far behind the board the (black) backdrop lies, mm.
pub const BACKDROP_MM: f64 = 1.0e4;
/// The random stream of the bench poses.
const STREAM: u64 = 0x6265_6e63_6800;
/// Candidate poses per view before giving up.
const MAX_ATTEMPTS: usize = 20_000;

/// A cylindrical bend of some views' board ([`crate::scene::Bow`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BowCfg {
    /// Indices of the bent views (none by default).
    pub views: Vec<usize>,
    /// Sag at the middle across the width, mm (positive: towards the camera).
    pub sag_mm: f64,
    /// The cylinder's axis, degrees from board x (90: bent across the board's x).
    pub axis_deg: f64,
}

impl Default for BowCfg {
    fn default() -> Self {
        BowCfg {
            views: vec![],
            sag_mm: 1.0,
            axis_deg: 90.0,
        }
    }
}

/// The floor the board stands on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FloorCfg {
    pub enabled: bool,
    pub reflectance: f64,
    /// How far the camera looks down at the floor, degrees.
    pub camera_pitch_deg: f64,
}

impl Default for FloorCfg {
    fn default() -> Self {
        FloorCfg {
            enabled: false,
            reflectance: 0.35,
            camera_pitch_deg: 30.0,
        }
    }
}

/// The bench mode's knobs (module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BenchCfg {
    pub enabled: bool,
    pub views: usize,
    /// Range of the laser line's depth where the board is placed, mm; `None`: the rig's
    /// `working_range_mm`.
    pub standoff_mm: Option<[f64; 2]>,
    pub max_tilt_deg: f64,
    /// How many views show the board partly out of the image.
    pub partial_views: usize,
    /// Smallest fraction of the points imaged in a partial view.
    pub min_imaged: f64,
    /// A partial view keeps the board's marker circles inside the image (so a detector
    /// can index it); `false`: anything may leave the image.
    pub partial_keep_markers: bool,
    /// Margin of the whole pattern in the other views, px.
    pub margin_px: f64,
    /// Shortest imaged, lit stripe across the grid, mm.
    pub min_stripe_mm: f64,
    pub bow: BowCfg,
    pub floor: FloorCfg,
    /// The fixed-sensor scan ([`crate::bench_scan`]).
    pub scan: crate::bench_scan::BenchScanCfg,
}

impl Default for BenchCfg {
    fn default() -> Self {
        BenchCfg {
            enabled: false,
            views: 15,
            standoff_mm: None,
            max_tilt_deg: 45.0,
            partial_views: 3,
            min_imaged: 0.5,
            partial_keep_markers: true,
            margin_px: 4.0,
            min_stripe_mm: 20.0,
            bow: BowCfg::default(),
            floor: FloorCfg::default(),
            scan: Default::default(),
        }
    }
}

impl BenchCfg {
    /// Checks the knobs; errors name them.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |k: &str, m: String| Err(SimError::Config(format!("bench.{k}: {m}")));
        if self.views == 0 {
            return bad("views", "must be >= 1".into());
        }
        if self.partial_views > self.views {
            return bad(
                "partial_views",
                format!("{} > views {}", self.partial_views, self.views),
            );
        }
        if let Some([a, b]) = self.standoff_mm {
            if !(a > 0.0 && b > a && b.is_finite()) {
                return bad("standoff_mm", format!("[{a}, {b}] is not a range"));
            }
        }
        if !(0.0..80.0).contains(&self.max_tilt_deg) {
            return bad(
                "max_tilt_deg",
                format!("{} outside [0, 80)", self.max_tilt_deg),
            );
        }
        if !(self.min_imaged > 0.0 && self.min_imaged < 1.0) {
            return bad("min_imaged", format!("{} outside (0, 1)", self.min_imaged));
        }
        if !(self.margin_px.is_finite() && self.min_stripe_mm.is_finite()) {
            return bad(
                "margin_px",
                "margin_px and min_stripe_mm must be finite".into(),
            );
        }
        let partial = self.partial_indices();
        for &v in &self.bow.views {
            if v >= self.views || partial.contains(&v) {
                return bad(
                    "bow.views",
                    format!(
                        "view {v} is not a whole-board view (views {}, partly out of view: {partial:?})",
                        self.views
                    ),
                );
            }
        }
        if !(self.bow.sag_mm.is_finite() && self.bow.axis_deg.is_finite()) {
            return bad("bow", "sag_mm and axis_deg must be finite".into());
        }
        let f = &self.floor;
        if !(0.0..=1.0).contains(&f.reflectance) || !(0.0..80.0).contains(&f.camera_pitch_deg) {
            return bad(
                "floor",
                "reflectance in [0, 1] and camera_pitch_deg in [0, 80) expected".into(),
            );
        }
        self.scan.validate()
    }

    /// The indices of the views partly out of the image: `(2k + 1) N / (2 P)`.
    pub fn partial_indices(&self) -> Vec<usize> {
        let (n, p) = (self.views, self.partial_views);
        (0..p).map(|k| (2 * k + 1) * n / (2 * p)).collect()
    }
}

/// One bench view: the board pose and what it shows.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchView {
    /// `T_cam_board` (of the flat sheet's frame; a bent sheet's edges across the bend lie
    /// in its plane z = 0).
    pub cam_board: Iso3,
    /// Depth of the grid's centre, mm.
    pub standoff_mm: f64,
    /// Angle between the optical axis and the board normal, degrees.
    pub tilt_deg: f64,
    /// Whether the board is partly out of the image.
    pub partial: bool,
    /// The bend of a bent view.
    pub bow: Option<Bow>,
    /// The floor in the camera frame `(n, d)`: `n . p = d`, `n` up (towards the
    /// camera's side), with `bench.floor`.
    pub floor: Option<(Vector3<f64>, f64)>,
}

impl Twin {
    /// The bench world: the board (the world frame is the board frame), the backdrop far
    /// away and black, and the floor of `floor` (camera frame) if any.
    pub(crate) fn bench_world(
        &self,
        board_cam: &Iso3,
        floor: Option<(Vector3<f64>, f64)>,
    ) -> World {
        let free_plate = floor.map(|(n, d)| {
            // the floor's frame: origin at the camera's foot, z = n, x = camera x
            let x = (Vector3::x() - n * n.x).normalize();
            let y = n.cross(&x);
            let cam_floor = iso_from_parts(&Matrix3::from_columns(&[x, y, n]), &(n * d));
            FreePlate {
                base_plate: board_cam * cam_floor,
                half_size_mm: [5.0e3, 5.0e3],
                reflectance: self.cfg.bench.floor.reflectance,
            }
        });
        World {
            base_board: Iso3::identity(),
            plate_thickness_mm: BACKDROP_MM,
            table_reflectance: 0.0,
            free_plate,
            ..self.calib_world.clone()
        }
    }

    /// The camera-frame scene of a bench view, laser on (`laser` false: off).
    pub fn bench_scene(&self, v: &BenchView, laser: bool) -> ImageScene {
        let board_cam = v.cam_board.inverse();
        let mut l = self.laser();
        if !laser {
            l.peak = 0.0;
        }
        let scene = self
            .bench_world(&board_cam, v.floor)
            .image_scene(&board_cam, l);
        match v.bow {
            Some(b) => scene.with_bow(b),
            None => scene,
        }
    }

    /// The floor under a board at `cam_board`: the plane through the plate's lowest
    /// corner, its normal the world's up for a camera pitched down by the knob.
    fn bench_floor(&self, cam_board: &Iso3) -> Option<(Vector3<f64>, f64)> {
        let f = &self.cfg.bench.floor;
        if !f.enabled {
            return None;
        }
        let a = f.camera_pitch_deg.to_radians();
        let up = Vector3::new(0.0, -a.cos(), -a.sin());
        let e = crate::target::plate_extent(&self.board, self.cfg.board.plate_margin_mm);
        let low = [(e[0], e[2]), (e[0], e[3]), (e[1], e[2]), (e[1], e[3])]
            .iter()
            .map(|&(x, y)| up.dot(&(cam_board * Point3::new(x, y, 0.0)).coords))
            .fold(f64::INFINITY, f64::min);
        Some((up, low))
    }

    /// The length (mm) of the laser line across the grid's bounding box that is lit and
    /// imaged (sampled every ~1 mm).
    fn bench_stripe_mm(&self, scene: &ImageScene) -> f64 {
        let t = scene.cam_board;
        let n = t.rotation.inverse() * self.laser_plane.normal;
        let c = self.laser_plane.d - self.laser_plane.normal.dot(&t.translation.vector);
        // a x + b y = c on the board plane, clipped to the grid's bounding box
        let [x0, x1, y0, y1] = points_bbox(&self.board);
        let (a, b) = (n.x, n.y);
        let dir = Vector2::new(-b, a);
        if dir.norm() < 1e-9 {
            return 0.0;
        }
        let p0 = Vector2::new(a, b) * (c / (a * a + b * b));
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for (k, (l, h)) in [(0, (x0, x1)), (1, (y0, y1))] {
            if dir[k].abs() < 1e-12 {
                if p0[k] < l || p0[k] > h {
                    return 0.0;
                }
            } else {
                let (ta, tb) = ((l - p0[k]) / dir[k], (h - p0[k]) / dir[k]);
                lo = lo.max(ta.min(tb));
                hi = hi.min(ta.max(tb));
            }
        }
        if hi <= lo {
            return 0.0;
        }
        let steps = ((hi - lo) * dir.norm()).ceil().max(1.0) as usize;
        let step_mm = (hi - lo) * dir.norm() / steps as f64;
        let cam = &self.camera;
        (0..steps)
            .filter(|&k| {
                let s = lo + (hi - lo) * (k as f64 + 0.5) / steps as f64;
                let q = p0 + dir * s;
                let p = (t * Point3::new(q.x, q.y, 0.0)).coords;
                p.z > 0.0
                    && cam.project(&p).is_ok_and(|uv| cam.contains(&uv, 2.0))
                    && scene.lit(crate::scene::SURF_PLATE, &p)
            })
            .count() as f64
            * step_mm
    }

    /// The length (mm) of the laser line on the floor that is lit and imaged (sampled
    /// every 1 mm within 150 mm of the point of the line nearest the camera).
    fn bench_floor_stripe_mm(&self, scene: &ImageScene, floor: (Vector3<f64>, f64)) -> f64 {
        let (fnrm, fd) = floor;
        let (n, d) = (self.laser_plane.normal, self.laser_plane.d);
        let dir = n.cross(&fnrm);
        if dir.norm() < 1e-9 {
            return 0.0;
        }
        let dir = dir.normalize();
        let nn = n.dot(&fnrm);
        let det = 1.0 - nn * nn;
        let p0 = n * ((d - fd * nn) / det) + fnrm * ((fd - d * nn) / det);
        let cam = &self.camera;
        (-150..=150)
            .filter(|&k| {
                let p = p0 + dir * k as f64;
                if p.z <= 1.0 || !cam.project(&p).is_ok_and(|uv| cam.contains(&uv, 2.0)) {
                    return false;
                }
                let ray = p / p.z;
                matches!(scene.first_hit(&ray), Some((crate::scene::SURF_FREE_PLATE, s))
                    if (s - p.z).abs() < 1e-6 * p.z)
                    && scene.lit(crate::scene::SURF_FREE_PLATE, &p)
            })
            .count() as f64
    }

    /// Whether every marker circle of the board is imaged whole (2 px margin).
    fn markers_imaged(&self, scene: &ImageScene) -> bool {
        let m = &self.board.markers;
        if m.is_empty() {
            return true;
        }
        let t = crate::truth::target_truth(scene, &self.camera, 2.0);
        m.iter()
            .all(|&[r, c]| t.iter().any(|p| p.row == r && p.col == c))
    }

    /// The bench views (module docs), deterministic per seed.
    pub fn bench_views(&self) -> Result<Vec<BenchView>, SimError> {
        let bc = &self.cfg.bench;
        bc.validate()?;
        let [z0, z1] = bc.standoff_mm.unwrap_or(self.cfg.working_range_mm);
        let partial = bc.partial_indices();
        let [x0, x1, y0, y1] = points_bbox(&self.board);
        let center = crate::target::points_center(&self.board);
        let cam = &self.camera;
        let n_pts = self.board.len();
        let need = ((bc.min_imaged * n_pts as f64).ceil() as usize).clamp(1, n_pts);
        let mut rng = Rng::new(self.cfg.seed, STREAM);
        let mut out = Vec::with_capacity(bc.views);
        for i in 0..bc.views {
            let is_partial = partial.contains(&i);
            let mut found = None;
            for _ in 0..MAX_ATTEMPTS {
                let u = rng.range(0.1, 0.9) * cam.width as f64;
                let v = rng.range(0.1, 0.9) * cam.height as f64;
                let tilt = rng.range(0.0, bc.max_tilt_deg.to_radians());
                let az = rng.range(0.0, std::f64::consts::TAU);
                let roll = rng.range(0.0, std::f64::consts::TAU);
                let (f0, f1) = if is_partial { (-0.3, 1.3) } else { (0.1, 0.9) };
                let look = Vector3::new(
                    x0 + rng.range(f0, f1) * (x1 - x0),
                    y0 + rng.range(f0, f1) * (y1 - y0),
                    0.0,
                );
                let Ok(ray) = cam.unproject(&Vector2::new(u, v)) else {
                    continue;
                };
                let den = self.laser_plane.normal.dot(&ray);
                if den.abs() < 1e-9 {
                    continue;
                }
                let p = ray * (self.laser_plane.d / den);
                if !(p.z >= z0 && p.z <= z1) {
                    continue;
                }
                let axis = Unit::new_normalize(Vector3::new(az.cos(), az.sin(), 0.0));
                let r = Rotation3::from_axis_angle(&axis, tilt)
                    * Rotation3::from_axis_angle(&Vector3::z_axis(), roll);
                let cam_board = iso_from_parts(r.matrix(), &(p - r * look));
                let view = BenchView {
                    cam_board,
                    standoff_mm: (cam_board * Point3::from(center)).z,
                    tilt_deg: tilt.to_degrees(),
                    partial: is_partial,
                    bow: None,
                    floor: self.bench_floor(&cam_board),
                };
                let scene = self.bench_scene(&view, true);
                let ok = if is_partial {
                    let k = points_inside_quick(&scene, cam, 0.0, 16);
                    k >= need
                        && k < n_pts
                        && (!bc.partial_keep_markers || self.markers_imaged(&scene))
                } else {
                    pattern_inside(&scene, cam, bc.margin_px, 32)
                };
                let floor_ok = view.floor.is_none_or(|f| {
                    self.bench_floor_stripe_mm(&scene, f) >= 0.5 * bc.min_stripe_mm
                });
                if ok && floor_ok && self.bench_stripe_mm(&scene) >= bc.min_stripe_mm {
                    found = Some(view);
                    break;
                }
            }
            let mut view = found.ok_or_else(|| {
                SimError::Poses(format!(
                    "bench view {i}: no pose found in {MAX_ATTEMPTS} attempts; widen \
                     bench.standoff_mm or max_tilt_deg, or lower min_stripe_mm"
                ))
            })?;
            if bc.bow.views.contains(&i) {
                view.bow = Some(Bow::for_board(&self.board, bc.bow.sag_mm, bc.bow.axis_deg));
            }
            out.push(view);
        }
        Ok(out)
    }
}
