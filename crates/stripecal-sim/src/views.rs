//! Random board-only views for detection tests, for every board kind.
//!
//! [`RandomViews`] samples camera poses relative to the board (no robot): any in-plane
//! rotation, tilts up to `max_tilt_deg`, stand-offs `standoff_scale` times the nominal
//! one (the middle of the twin's `poses.standoff_mm`), looking at points spread beyond
//! the grid so that part of the board may leave the image. A pose is kept when at least
//! `min_imaged` of the board's points are imaged ([`target_truth`]) or, with
//! `whole_board`, when the whole printed pattern is inside the image. Each kept view
//! carries its exact per-image truth; [`RandomView::render`] renders its board image
//! (board lit, laser off: the twin's cheapest render).
//!
//! The sampling is deterministic by `seed` (one [`Rng`] stream, candidates drawn and
//! tested in order; the exact truth of a batch of candidates is computed in parallel,
//! which changes nothing in the result). With the defaults it reproduces the 200 views
//! of the circle detector's robustness test as they were sampled inline before.
//!
//! ```no_run
//! use stripecal_sim::{views::RandomViews, SimConfig, Twin};
//! let twin = Twin::new(SimConfig::preset("hp3-chessboard").unwrap()).unwrap();
//! let views = RandomViews { count: 20, ..RandomViews::whole_board() }.sample(&twin).unwrap();
//! let img = views[0].render(&twin, 0).unwrap();
//! ```

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use rayon::prelude::*;

use stripecal::model::geometry::{iso_from_parts, Iso3};
use stripecal::model::image::AnyGray;

use crate::rng::Rng;
use crate::target::{pattern_inside, points_bbox, points_inside_quick};
use crate::truth::{target_truth, PointTruth};
use crate::{SimError, Twin};

/// The random stream of the view sampler (with [`RandomViews::seed`]).
const STREAM: u64 = 7;

/// Candidates whose exact truth is computed together (in parallel).
const BATCH: usize = 32;

/// How random views are drawn (see the module docs). `Default`: 200 views, seed 2024,
/// tilt <= 45 deg, 0.7x..1.5x the nominal stand-off, look-at points over -25 %..125 % of
/// the points' bounding box, at least 70 % of the points imaged.
#[derive(Debug, Clone, PartialEq)]
pub struct RandomViews {
    /// Number of views.
    pub count: usize,
    pub seed: u64,
    /// Largest angle between the optical axis and the board normal, degrees (uniform).
    pub max_tilt_deg: f64,
    /// Stand-off range as multiples of the nominal stand-off (uniform).
    pub standoff_scale: [f64; 2],
    /// Where the optical axis meets the board, as fractions of the points' bounding
    /// box along x and y (uniform; beyond `[0, 1]` the board leaves the image).
    pub look_range: [f64; 2],
    /// Smallest fraction of the board's points that must be imaged (ignored with
    /// `whole_board`).
    pub min_imaged: f64,
    /// Keep only views that show the whole printed pattern ([`stripecal::Board::pattern_extent`])
    /// inside the image with `margin_px`, so every point is imaged.
    pub whole_board: bool,
    /// Margin of `whole_board`, px.
    pub margin_px: f64,
    /// Give up after this many candidate poses.
    pub max_attempts: usize,
}

impl Default for RandomViews {
    fn default() -> Self {
        RandomViews {
            count: 200,
            seed: 2024,
            max_tilt_deg: 45.0,
            standoff_scale: [0.7, 1.5],
            look_range: [-0.25, 1.25],
            min_imaged: 0.7,
            whole_board: false,
            margin_px: 0.0,
            max_attempts: 100_000,
        }
    }
}

/// One sampled view with its truth.
#[derive(Debug, Clone)]
pub struct RandomView {
    /// `T_board_cam`: the camera pose in the board frame.
    pub board_cam: Iso3,
    /// The imaged target points (row-major), as [`target_truth`] with margin 0.
    pub truth: Vec<PointTruth>,
    /// Tilt (optical axis to board normal) and in-plane rotation, degrees.
    pub tilt_deg: f64,
    pub roll_deg: f64,
    /// Stand-off as a multiple of the nominal one.
    pub standoff_scale: f64,
}

impl RandomView {
    /// The board image of this view (board lit, laser off), noise from the twin's seed
    /// and `stream`.
    pub fn render(&self, twin: &Twin, stream: u64) -> Result<AnyGray, SimError> {
        twin.render_board_image(&self.board_cam, stream)
    }
}

impl RandomViews {
    /// Views that keep the whole board in the image (2 px margin), looking at points
    /// inside the grid; otherwise the defaults.
    pub fn whole_board() -> Self {
        RandomViews {
            whole_board: true,
            margin_px: 2.0,
            look_range: [0.0, 1.0],
            ..Default::default()
        }
    }

    /// Samples the views for `twin`'s camera and board, deterministic by `seed`.
    pub fn sample(&self, twin: &Twin) -> Result<Vec<RandomView>, SimError> {
        let bad = |m: String| Err(SimError::Config(format!("random views: {m}")));
        let [s0, s1] = self.standoff_scale;
        let [l0, l1] = self.look_range;
        if !(s0 > 0.0 && s1 >= s0 && s1.is_finite()) {
            return bad(format!(
                "standoff_scale [{s0}, {s1}] is not a positive range"
            ));
        }
        if !(l0.is_finite() && l1.is_finite() && l1 >= l0) {
            return bad(format!("look_range [{l0}, {l1}] is not a range"));
        }
        if !(0.0..90.0).contains(&self.max_tilt_deg) {
            return bad(format!(
                "max_tilt_deg {} outside [0, 90)",
                self.max_tilt_deg
            ));
        }
        if !(self.min_imaged > 0.0 && self.min_imaged <= 1.0) {
            return bad(format!("min_imaged {} outside (0, 1]", self.min_imaged));
        }
        let board = &twin.board;
        let camera = &twin.camera;
        let sp = twin.cfg.poses.standoff_mm;
        let nominal = 0.5 * (sp[0] + sp[1]);
        let [x0, x1, y0, y1] = points_bbox(board);
        let (bw, bh) = (x1 - x0, y1 - y0);
        let n = board.len();
        // at least min_imaged of the points (1e-9: 0.7 * 10 must ask for 7)
        let need = if self.whole_board {
            n
        } else {
            ((self.min_imaged * n as f64 - 1e-9).ceil() as usize).clamp(1, n)
        };
        let mut rng = Rng::new(self.seed, STREAM);
        let mut out: Vec<RandomView> = Vec::with_capacity(self.count);
        let mut tries = 0usize;
        while out.len() < self.count {
            // Draw candidates in order, cheap tests first ...
            let mut batch = Vec::with_capacity(BATCH);
            while batch.len() < BATCH && tries < self.max_attempts {
                tries += 1;
                let tilt = rng.range(0.0, self.max_tilt_deg.to_radians());
                let az = rng.range(0.0, std::f64::consts::TAU);
                let roll = rng.range(0.0, std::f64::consts::TAU);
                let s = nominal * rng.range(s0, s1);
                let look = Vector3::new(
                    x0 + rng.range(l0, l1) * bw,
                    y0 + rng.range(l0, l1) * bh,
                    0.0,
                );
                let t = board_cam(look, s, tilt, az, roll);
                let scene = twin.board_scene(&t);
                let keep = if self.whole_board {
                    pattern_inside(&scene, camera, self.margin_px, 32)
                } else {
                    // a coarse count first (16 outline points per circle)
                    points_inside_quick(&scene, camera, 0.0, 16) >= need
                };
                if keep {
                    batch.push((t, tilt, roll, s));
                }
            }
            if batch.is_empty() {
                break;
            }
            // ... then the exact truth of the batch (in parallel), kept in order.
            let truths: Vec<Vec<PointTruth>> = batch
                .par_iter()
                .map(|(t, ..)| target_truth(&twin.board_scene(t), camera, 0.0))
                .collect();
            for ((t, tilt, roll, s), truth) in batch.into_iter().zip(truths) {
                if out.len() < self.count && truth.len() >= need {
                    out.push(RandomView {
                        board_cam: t,
                        truth,
                        tilt_deg: tilt.to_degrees(),
                        roll_deg: roll.to_degrees(),
                        standoff_scale: s / nominal,
                    });
                }
            }
        }
        if out.len() < self.count {
            return Err(SimError::Poses(format!(
                "random views: found {} of the {} requested in {} attempts; widen \
                 standoff_scale or look_range, or lower min_imaged",
                out.len(),
                self.count,
                self.max_attempts
            )));
        }
        Ok(out)
    }
}

/// `T_board_cam` of a camera looking at board point `look` (board frame, mm) from
/// `standoff` mm along its optical axis, the axis tilted by `tilt` from the board's z
/// about an axis at azimuth `az` in the board plane, rolled by `roll` about the optical
/// axis (radians; roll 0 keeps the image x axis along board x as far as the tilt allows).
pub fn board_cam(look: Vector3<f64>, standoff: f64, tilt: f64, az: f64, roll: f64) -> Iso3 {
    let axis = Unit::new_normalize(Vector3::new(az.cos(), az.sin(), 0.0));
    let z = Rotation3::from_axis_angle(&axis, tilt) * Vector3::z();
    let x0 = (Vector3::x() - z * z.x).normalize();
    let x = Rotation3::from_axis_angle(&Unit::new_normalize(z), roll) * x0;
    let y = z.cross(&x);
    let r = Matrix3::from_columns(&[x, y, z]);
    iso_from_parts(&r, &(look - z * standoff))
}
