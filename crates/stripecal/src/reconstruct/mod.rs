//! Reconstruction: stripe pixels -> camera ray -> laser plane -> hand -> robot base.
//!
//! ## The chain (spec/DATASET.md)
//!
//! For a stripe point at pixel `(u, v)` of a frame taken at encoder readings `q`:
//!
//! 1. Distorted normalised coordinates `xd = (u - u0) / fu`, `yd = (v - v0) / fv`;
//!    undistorted `(xn, yn)` by Newton's method, started at the previous point's
//!    solution (neighbouring stripe points converge in 1-2 steps): for radial-only
//!    models (`p1 = p2 = 0`: `radial1`, `radial2`) a 1D iteration on the scale
//!    `r_n / r_d`, otherwise the 2D one of [`Camera::undistort_from`]. Both stop at
//!    ~1e-15 relative (far below 1e-9 px).
//! 2. The viewing ray `r = (xn, yn, 1)` (camera frame, through the optical centre).
//! 3. Its intersection with the laser plane `n . p = d` (camera frame, `d > 0`):
//!    `s = d / (n . r)`, `p_cam = s r` (mm).
//! 4. `p_base = T_base_hand(q) * T_hand_cam * p_cam` (mm).
//!
//! ## Dropped points
//!
//! A ray that meets the laser plane at a grazing angle gives a point whose depth is
//! `1 / sin(angle)` times as sensitive to the pixel error and that lies far away; the
//! camera cannot see the stripe there in a working rig. Rays whose angle to the plane
//! is below [`ReconstructOptions::min_ray_plane_angle_deg`] (default
//! [`DEFAULT_MIN_RAY_PLANE_ANGLE_DEG`] = 2 deg: `|n . r| / |r| < sin(2 deg) = 0.035`)
//! are dropped and counted, never turned into far points. So are rays meeting the plane
//! behind the camera (`n . r <= 0`) and pixels where the undistortion fails (outside the
//! distortion model's valid zone). For the paper's rig the rays of the whole image meet
//! the plane at 34 to 69 deg (k1 neglected).
//!
//! ## Entry points
//!
//! - [`Triangulator`]: points only, from `(u, v)` and `T_base_hand` (benchmarks, tests,
//!   callers with their own stripe extraction).
//! - [`Reconstructor`]: one frame at a time for line software: an image plus joint
//!   readings (or a flange pose) in, points appended to a [`ScanPoints`] out. It owns a
//!   [`StripeExtractor`] and its buffers: after the first frame of a given size it does
//!   not allocate (when the caller clears and reuses its `ScanPoints`).
//! - [`reconstruct_frames`]: many in-memory frames in parallel (rayon), points in frame
//!   order; [`reconstruct_scan`]: a scan folder (scan.csv + images), decoding images in
//!   parallel, with progress reports.
//!
//! Fits of the points (sphere, plane) are in [`fit`].

pub mod fit;

use std::path::Path;

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::model::image::AnyView;
use crate::model::kinematics::Robot;
use crate::model::{Calibration, Cloud, RobotReading, Scan, StripeDirection};
use crate::vision::stripe::{StripeExtractor, StripeOptions, StripePoint};

pub use fit::{fit_plane, fit_sphere, FitOptions, PlaneFit, SphereFitResult};

/// Default smallest angle between a viewing ray and the laser plane, degrees.
pub const DEFAULT_MIN_RAY_PLANE_ANGLE_DEG: f64 = 2.0;

/// Options of the reconstruction.
#[derive(Debug, Clone, PartialEq)]
pub struct ReconstructOptions {
    /// Stripe extraction. `direction: Auto` is replaced by the direction the laser plane
    /// gives in the image ([`stripe_direction_from_plane`]): a scan's rig.json hint, when
    /// there is one, should be set here.
    pub stripe: StripeOptions,
    /// Rays meeting the laser plane at a smaller angle are dropped, degrees (0..90).
    pub min_ray_plane_angle_deg: f64,
    /// Stripe points with any of these `FLAG_*` bits are dropped (0 = keep all; the
    /// flags are reported per point).
    pub drop_flags: u8,
}

impl Default for ReconstructOptions {
    fn default() -> Self {
        ReconstructOptions {
            stripe: StripeOptions::default(),
            min_ray_plane_angle_deg: DEFAULT_MIN_RAY_PLANE_ANGLE_DEG,
            drop_flags: 0,
        }
    }
}

impl ReconstructOptions {
    /// Checks the values.
    pub fn validate(&self) -> Result<()> {
        self.stripe.validate()?;
        let a = self.min_ray_plane_angle_deg;
        if !(a.is_finite() && (0.0..90.0).contains(&a)) {
            return Err(Error::InvalidInput(format!(
                "min_ray_plane_angle_deg = {a} must be in [0, 90)"
            )));
        }
        Ok(())
    }
}

/// The direction the stripe runs in the image, from the laser plane alone.
///
/// On a surface facing the camera (`z = const`) the stripe is the image line
/// `n_x xn + n_y yn = const`, whose normal in pixels is `(n_x / fu, n_y / fv)`: when that
/// normal is mostly along `u` the stripe runs along the columns ([`StripeDirection::Cols`],
/// one point per row), otherwise along the rows ([`StripeDirection::Rows`]). Depth changes
/// move the stripe along the normal, so the direction holds for any object.
pub fn stripe_direction_from_plane(camera: &Camera, plane: &Plane) -> StripeDirection {
    let gu = plane.normal.x / camera.fu;
    let gv = plane.normal.y / camera.fv;
    if gu.abs() >= gv.abs() {
        StripeDirection::Cols
    } else {
        StripeDirection::Rows
    }
}

/// Why points were dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DropCounts {
    /// Rays meeting the laser plane below the angle threshold or behind the camera.
    pub grazing: usize,
    /// Pixels where the undistortion failed (outside the distortion's valid zone).
    pub undistort: usize,
    /// Stripe points with a flag in `drop_flags`.
    pub flagged: usize,
}

impl DropCounts {
    /// Adds another count.
    pub fn add(&mut self, o: &DropCounts) {
        self.grazing += o.grazing;
        self.undistort += o.undistort;
        self.flagged += o.flagged;
    }

    /// All dropped points.
    pub fn total(&self) -> usize {
        self.grazing + self.undistort + self.flagged
    }
}

/// Triangulation of stripe pixels with a fixed calibration (camera, laser plane,
/// `T_hand_cam`). Cheap to copy; shares nothing.
#[derive(Debug, Clone)]
pub struct Triangulator {
    camera: Camera,
    /// Laser plane normal and offset (camera frame, mm).
    n: Vector3<f64>,
    d_mm: f64,
    hand_cam: Iso3,
    /// `sin(min angle)`.
    min_sin: f64,
    /// True when all distortion coefficients are zero (no Newton iteration).
    no_distortion: bool,
    /// True when the tangential coefficients are zero (a 1D Newton iteration).
    radial_only: bool,
    /// `1 / fu`, `1 / fv`.
    inv_fu: f64,
    inv_fv: f64,
}

impl Triangulator {
    /// A triangulator; checks the camera, the plane (`|n| = 1`, `d > 0`, finite) and the
    /// angle threshold (degrees, in `[0, 90)`).
    pub fn new(
        camera: &Camera,
        laser_plane: &Plane,
        hand_cam: &Iso3,
        min_ray_plane_angle_deg: f64,
    ) -> Result<Triangulator> {
        camera.validate()?;
        let n = laser_plane.normal;
        if !(n.iter().all(|x| x.is_finite())
            && (n.norm() - 1.0).abs() < 1e-6
            && laser_plane.d.is_finite()
            && laser_plane.d > 0.0)
        {
            return Err(Error::InvalidInput(format!(
                "laser plane normal {:?} / d_mm {} must be a unit normal with d > 0",
                n.as_slice(),
                laser_plane.d
            )));
        }
        let a = min_ray_plane_angle_deg;
        if !(a.is_finite() && (0.0..90.0).contains(&a)) {
            return Err(Error::InvalidInput(format!(
                "min_ray_plane_angle_deg = {a} must be in [0, 90)"
            )));
        }
        let t = hand_cam.translation.vector;
        if !(t.iter().all(|x| x.is_finite())
            && hand_cam.rotation.coords.iter().all(|x| x.is_finite()))
        {
            return Err(Error::InvalidInput("hand_cam is not finite".into()));
        }
        Ok(Triangulator {
            camera: camera.clone(),
            n: n / n.norm(),
            d_mm: laser_plane.d,
            hand_cam: *hand_cam,
            min_sin: a.to_radians().sin(),
            no_distortion: camera.distortion.iter().all(|&k| k == 0.0),
            radial_only: camera.distortion[2] == 0.0 && camera.distortion[3] == 0.0,
            inv_fu: 1.0 / camera.fu,
            inv_fv: 1.0 / camera.fv,
        })
    }

    /// From a calibration.
    pub fn from_calibration(c: &Calibration, min_ray_plane_angle_deg: f64) -> Result<Self> {
        Self::new(
            &c.camera,
            &c.laser_plane,
            &c.hand_cam,
            min_ray_plane_angle_deg,
        )
    }

    /// The camera.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// `T_base_cam = T_base_hand * T_hand_cam` as a rotation matrix and translation (mm).
    #[inline]
    fn base_cam(&self, base_hand: &Iso3) -> (Matrix3<f64>, Vector3<f64>) {
        let t = base_hand * self.hand_cam;
        (
            t.rotation.to_rotation_matrix().into_inner(),
            t.translation.vector,
        )
    }

    /// The laser-plane point of one pixel in the camera frame (mm), updating the Newton
    /// start `warm` (the previous point's solution).
    #[inline]
    fn point_cam(
        &self,
        u: f64,
        v: f64,
        warm: &mut Warm,
    ) -> std::result::Result<Vector3<f64>, DropReason> {
        let c = &self.camera;
        let xd = (u - c.u0) * self.inv_fu;
        let yd = (v - c.v0) * self.inv_fv;
        let (xn, yn) = if self.no_distortion {
            (xd, yd)
        } else if self.radial_only {
            match self.undistort_radial(xd, yd, warm.scale) {
                Some(s) => {
                    warm.scale = s;
                    (xd * s, yd * s)
                }
                None => {
                    warm.scale = 1.0;
                    self.undistort_general(xd, yd, warm)?
                }
            }
        } else {
            self.undistort_general(xd, yd, warm)?
        };
        let r = Vector3::new(xn, yn, 1.0);
        let den = self.n.dot(&r);
        // |n . r| / |r| >= sin(angle), and the plane in front (den > 0 since d > 0).
        if !(den > 0.0 && den * den >= self.min_sin * self.min_sin * r.norm_squared()) {
            return Err(DropReason::Grazing);
        }
        Ok(r * (self.d_mm / den))
    }

    /// Radial-only distortion (`p1 = p2 = 0`): the undistorted point is the distorted one
    /// scaled by `s = r_n / r_d`, the root of the 1D equation
    /// `f(s) = s (1 + k1 rho s^2 + k2 rho^2 s^4 + k3 rho^3 s^6) - 1 = 0` with
    /// `rho = r_d^2`, solved by Newton's method from `s0` (the previous point's scale: a
    /// neighbouring stripe point converges in one or two steps) to `|ds| <= 1e-15 s`.
    /// `None` where it does not converge in 20 steps or the model folds there
    /// (`f'(s) <= 0`, the radial factor `<= 0`): the general 2D solver then decides.
    #[inline]
    fn undistort_radial(&self, xd: f64, yd: f64, s0: f64) -> Option<f64> {
        let [k1, k2, _, _, k3] = self.camera.distortion;
        let rho = xd * xd + yd * yd;
        let (a1, a2, a3) = (k1 * rho, k2 * rho * rho, k3 * rho * rho * rho);
        let mut s = if s0 > 0.0 && s0.is_finite() { s0 } else { 1.0 };
        for _ in 0..20 {
            let s2 = s * s;
            let poly = 1.0 + s2 * (a1 + s2 * (a2 + s2 * a3));
            // f'(s) and f''(s) / s.
            let dpoly = 1.0 + s2 * (3.0 * a1 + s2 * (5.0 * a2 + s2 * 7.0 * a3));
            let ddpoly = 6.0 * a1 + s2 * (20.0 * a2 + s2 * 42.0 * a3);
            if !(dpoly > 1e-12 && poly > 0.0) {
                return None;
            }
            let ds = (s * poly - 1.0) / dpoly;
            s -= ds;
            // Newton's error after the step is about |f'' / (2 f')| ds^2: stop when that
            // is below 1e-16 (s is about 1), without the extra step a |ds| test needs.
            if (ddpoly * s).abs() * ds * ds <= 2e-16 * dpoly {
                return (s > 0.0).then_some(s);
            }
        }
        None
    }

    /// The general case: 2D Newton ([`Camera::undistort_from`]) from the previous
    /// solution when it is near.
    #[inline]
    fn undistort_general(
        &self,
        xd: f64,
        yd: f64,
        warm: &mut Warm,
    ) -> std::result::Result<(f64, f64), DropReason> {
        let (x0, y0) = match warm.xy {
            Some((gx, gy)) if (gx - xd).abs() + (gy - yd).abs() < 0.05 => (gx, gy),
            _ => (xd, yd),
        };
        match self.camera.undistort_from(xd, yd, x0, y0) {
            Ok(p) => {
                warm.xy = Some(p);
                Ok(p)
            }
            Err(_) => {
                warm.xy = None;
                Err(DropReason::Undistort)
            }
        }
    }

    /// The laser-plane point of pixel `(u, v)` in the camera frame (mm), or `None` when
    /// it is dropped (grazing ray, plane behind the camera, undistortion failure).
    pub fn point_cam_mm(&self, u: f64, v: f64) -> Option<Vector3<f64>> {
        self.point_cam(u, v, &mut Warm::default()).ok()
    }

    /// Triangulates pixels `uv_px` of one frame taken at `T_base_hand`: the kept points
    /// (base frame, mm) are appended to `out_mm` and their indices into `uv_px` to
    /// `index`. Returns why the others were dropped. Allocates nothing when the vectors
    /// have room.
    pub fn triangulate_into(
        &self,
        base_hand: &Iso3,
        uv_px: &[[f64; 2]],
        out_mm: &mut Vec<[f64; 3]>,
        index: &mut Vec<u32>,
    ) -> DropCounts {
        let (r, t) = self.base_cam(base_hand);
        let mut drops = DropCounts::default();
        let mut warm = Warm::default();
        for (i, &[u, v]) in uv_px.iter().enumerate() {
            match self.point_cam(u, v, &mut warm) {
                Ok(p) => {
                    let b = r * p + t;
                    out_mm.push([b.x, b.y, b.z]);
                    index.push(i as u32);
                }
                Err(DropReason::Grazing) => drops.grazing += 1,
                Err(DropReason::Undistort) => drops.undistort += 1,
            }
        }
        drops
    }
}

/// Newton starts carried from one stripe point to the next.
#[derive(Debug, Clone, Copy)]
struct Warm {
    /// Radial-only models: the previous point's `r_n / r_d`.
    scale: f64,
    /// General models: the previous point's undistorted coordinates.
    xy: Option<(f64, f64)>,
}

impl Default for Warm {
    fn default() -> Self {
        Warm {
            scale: 1.0,
            xy: None,
        }
    }
}

#[derive(Debug, Clone, Copy)]
enum DropReason {
    Grazing,
    Undistort,
}

/// Triangulates pixels of one frame: `(points_mm, index)` of the kept points (base
/// frame) and their indices into `uv_px`. Convenience over [`Triangulator`].
pub fn triangulate(
    calibration: &Calibration,
    base_hand: &Iso3,
    uv_px: &[[f64; 2]],
) -> Result<(Vec<[f64; 3]>, Vec<u32>)> {
    let tri = Triangulator::from_calibration(calibration, DEFAULT_MIN_RAY_PLANE_ANGLE_DEG)?;
    check_pose(base_hand)?;
    let mut pts = Vec::with_capacity(uv_px.len());
    let mut idx = Vec::with_capacity(uv_px.len());
    tri.triangulate_into(base_hand, uv_px, &mut pts, &mut idx);
    Ok((pts, idx))
}

fn check_pose(t: &Iso3) -> Result<()> {
    if t.translation.vector.iter().all(|x| x.is_finite())
        && t.rotation.coords.iter().all(|x| x.is_finite())
    {
        Ok(())
    } else {
        Err(Error::InvalidInput("T_base_hand is not finite".into()))
    }
}

/// Reconstructed points of one or many frames (struct of arrays, all the same length).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ScanPoints {
    /// Points in the robot base frame, mm.
    pub points_mm: Vec<[f64; 3]>,
    /// Index of the frame each point comes from (the row of the input / scan.csv).
    pub frame: Vec<u32>,
    /// Sub-pixel stripe centre, px.
    pub u_px: Vec<f64>,
    pub v_px: Vec<f64>,
    /// Stripe peak above the local background, gray levels of the image.
    pub intensity: Vec<f32>,
    /// The stripe point's `FLAG_*` bits.
    pub flags: Vec<u8>,
    /// Points dropped (all frames so far).
    pub dropped: DropCounts,
}

impl ScanPoints {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.points_mm.len()
    }

    /// No points.
    pub fn is_empty(&self) -> bool {
        self.points_mm.is_empty()
    }

    /// Empties every vector, keeping their memory.
    pub fn clear(&mut self) {
        self.points_mm.clear();
        self.frame.clear();
        self.u_px.clear();
        self.v_px.clear();
        self.intensity.clear();
        self.flags.clear();
        self.dropped = DropCounts::default();
    }

    /// Appends another set (its frame indices kept as they are).
    pub fn append(&mut self, o: &ScanPoints) {
        self.points_mm.extend_from_slice(&o.points_mm);
        self.frame.extend_from_slice(&o.frame);
        self.u_px.extend_from_slice(&o.u_px);
        self.v_px.extend_from_slice(&o.v_px);
        self.intensity.extend_from_slice(&o.intensity);
        self.flags.extend_from_slice(&o.flags);
        self.dropped.add(&o.dropped);
    }

    /// The PLY cloud: `x y z` and the properties `view` (frame index), `u`, `v`,
    /// `intensity`, `flags` (spec/DATASET.md "The point cloud").
    pub fn to_cloud(&self) -> Cloud {
        Cloud {
            points: self.points_mm.clone(),
            properties: vec![
                (
                    "view".into(),
                    self.frame.iter().map(|&f| f as f64).collect(),
                ),
                ("u".into(), self.u_px.clone()),
                ("v".into(), self.v_px.clone()),
                (
                    "intensity".into(),
                    self.intensity.iter().map(|&f| f as f64).collect(),
                ),
                (
                    "flags".into(),
                    self.flags.iter().map(|&f| f as f64).collect(),
                ),
            ],
        }
    }
}

/// Puts `frame i` (and the scan.csv line, when known) in front of an error's message,
/// keeping its kind.
pub fn at_frame(e: Error, frame: usize, line: Option<usize>) -> Error {
    let tag = match line {
        Some(l) => format!("frame {frame} (scan.csv line {l})"),
        None => format!("frame {frame}"),
    };
    match e {
        Error::InvalidInput(m) => Error::InvalidInput(format!("{tag}: {m}")),
        Error::Degenerate(m) => Error::Degenerate(format!("{tag}: {m}")),
        Error::Detection(m) => Error::Detection(format!("{tag}: {m}")),
        Error::Format {
            path,
            location,
            message,
        } => Error::Format {
            path,
            location: format!("{tag}: {location}"),
            message,
        },
        other => other,
    }
}

/// One-frame reconstruction for line software (see the module docs). Not `Sync`-shared:
/// use one per thread.
#[derive(Debug, Clone)]
pub struct Reconstructor {
    tri: Triangulator,
    robot: Option<Robot>,
    extractor: StripeExtractor,
    drop_flags: u8,
    stripe: Vec<StripePoint>,
    /// Pixels of the stripe points not dropped by flag, and their stripe indices.
    uv: Vec<[f64; 2]>,
    sel: Vec<u32>,
    /// Indices into `uv` of the triangulated points.
    kept: Vec<u32>,
}

impl Reconstructor {
    /// A reconstructor for a calibration (its robot is used for joint readings).
    pub fn new(calibration: &Calibration, opts: &ReconstructOptions) -> Result<Reconstructor> {
        opts.validate()?;
        let tri = Triangulator::from_calibration(calibration, opts.min_ray_plane_angle_deg)?;
        let mut so = opts.stripe.clone();
        if so.direction == StripeDirection::Auto {
            so.direction =
                stripe_direction_from_plane(&calibration.camera, &calibration.laser_plane);
        }
        if let Some(r) = &calibration.robot {
            r.validate()?;
        }
        Ok(Reconstructor {
            tri,
            robot: calibration.robot.clone(),
            extractor: StripeExtractor::new(so)?,
            drop_flags: opts.drop_flags,
            stripe: Vec::new(),
            uv: Vec::new(),
            sel: Vec::new(),
            kept: Vec::new(),
        })
    }

    /// The stripe direction used.
    pub fn direction(&self) -> StripeDirection {
        self.extractor.options().direction
    }

    /// The triangulator.
    pub fn triangulator(&self) -> &Triangulator {
        &self.tri
    }

    /// `T_base_hand` of a reading (errors name nothing; callers add the frame).
    pub fn base_hand(&self, reading: &RobotReading) -> Result<Iso3> {
        let t = reading.base_hand(self.robot.as_ref())?;
        check_pose(&t)?;
        Ok(t)
    }

    /// Reconstructs one frame taken at encoder readings `q_deg`, appending its points
    /// (tagged `frame`) to `out`. Errors (wrong joint count, NaN readings, an image whose
    /// size is not the calibration's) name the frame and append nothing.
    pub fn frame_joints(
        &mut self,
        img: AnyView<'_>,
        q_deg: &[f64],
        frame: u32,
        out: &mut ScanPoints,
    ) -> Result<usize> {
        let Some(robot) = &self.robot else {
            return Err(at_frame(
                Error::InvalidInput(
                    "joint readings given but the calibration has no robot (DH table)".into(),
                ),
                frame as usize,
                None,
            ));
        };
        let t = robot
            .forward(q_deg)
            .map_err(|e| at_frame(e, frame as usize, None))?;
        self.frame_pose(img, &t, frame, out)
    }

    /// Reconstructs one frame taken at flange pose `T_base_hand`; see
    /// [`Reconstructor::frame_joints`]. Returns the number of points appended.
    pub fn frame_pose(
        &mut self,
        img: AnyView<'_>,
        base_hand: &Iso3,
        frame: u32,
        out: &mut ScanPoints,
    ) -> Result<usize> {
        let cam = self.tri.camera();
        let (w, h) = img.size();
        if w != cam.width as usize || h != cam.height as usize {
            return Err(at_frame(
                Error::InvalidInput(format!(
                    "image is {w} x {h} pixels, the calibrated camera is {} x {}",
                    cam.width, cam.height
                )),
                frame as usize,
                None,
            ));
        }
        check_pose(base_hand).map_err(|e| at_frame(e, frame as usize, None))?;
        self.extractor
            .extract_into(img, &mut self.stripe)
            .map_err(|e| at_frame(e, frame as usize, None))?;
        let Self {
            tri,
            drop_flags,
            stripe,
            uv,
            sel,
            kept,
            ..
        } = self;
        uv.clear();
        sel.clear();
        kept.clear();
        let mut flagged = 0;
        for (i, p) in stripe.iter().enumerate() {
            if p.flags & *drop_flags != 0 {
                flagged += 1;
                continue;
            }
            uv.push([p.u, p.v]);
            sel.push(i as u32);
        }
        let n0 = out.points_mm.len();
        let mut drops = tri.triangulate_into(base_hand, uv, &mut out.points_mm, kept);
        drops.flagged = flagged;
        for &k in kept.iter() {
            let p = &stripe[sel[k as usize] as usize];
            out.frame.push(frame);
            out.u_px.push(p.u);
            out.v_px.push(p.v);
            out.intensity.push(p.peak);
            out.flags.push(p.flags);
        }
        out.dropped.add(&drops);
        Ok(out.points_mm.len() - n0)
    }

    /// Reconstructs one frame with a [`RobotReading`] (joints or flange pose).
    pub fn frame_reading(
        &mut self,
        img: AnyView<'_>,
        reading: &RobotReading,
        frame: u32,
        out: &mut ScanPoints,
    ) -> Result<usize> {
        match reading {
            RobotReading::Joints(q) => self.frame_joints(img, q, frame, out),
            RobotReading::FlangePose(t) => self.frame_pose(img, t, frame, out),
        }
    }
}

/// Reconstructs many in-memory frames in parallel (rayon). `readings[i]` belongs to
/// `images[i]`; points come out in frame order, tagged with the frame index. The first
/// failing frame (by index) is the error, naming it; nothing is returned then.
pub fn reconstruct_frames(
    calibration: &Calibration,
    images: &[AnyView<'_>],
    readings: &[RobotReading],
    opts: &ReconstructOptions,
) -> Result<ScanPoints> {
    if images.len() != readings.len() {
        return Err(Error::InvalidInput(format!(
            "{} images but {} robot readings",
            images.len(),
            readings.len()
        )));
    }
    let proto = Reconstructor::new(calibration, opts)?;
    let parts: Vec<Result<ScanPoints>> = images
        .par_iter()
        .zip(readings.par_iter())
        .enumerate()
        .map_init(
            || proto.clone(),
            |rec, (i, (img, reading))| {
                let mut sp = ScanPoints::default();
                rec.frame_reading(*img, reading, i as u32, &mut sp)?;
                Ok(sp)
            },
        )
        .collect();
    let mut out = ScanPoints::default();
    for p in parts {
        out.append(&p?);
    }
    Ok(out)
}

/// Reconstructs a scan folder (scan.csv + images). The robot and camera come from the
/// calibration; `opts.stripe.direction: Auto` takes the scan's rig.json hint when it has
/// one, else the calibration's ([`stripe_direction_from_plane`]). Images are decoded and
/// processed in parallel in chunks; `progress(frames_done, frames_total, points_so_far)`
/// is called on the calling thread after each chunk. Errors name the frame, its scan.csv
/// line and the image file.
pub fn reconstruct_scan(
    calibration: &Calibration,
    scan: &Scan,
    opts: &ReconstructOptions,
    progress: &mut dyn FnMut(usize, usize, usize),
) -> Result<ScanPoints> {
    let mut opts = opts.clone();
    if opts.stripe.direction == StripeDirection::Auto {
        if let Some(rig) = &scan.rig {
            opts.stripe.direction = rig.stripe_direction;
        }
    }
    let proto = Reconstructor::new(calibration, &opts)?;
    let n = scan.frames.len();
    let chunk = (2 * rayon::current_num_threads()).max(2);
    let mut out = ScanPoints::default();
    progress(0, n, 0);
    let mut done = 0;
    for (c, frames) in scan.frames.chunks(chunk).enumerate() {
        let parts: Vec<Result<ScanPoints>> = frames
            .par_iter()
            .enumerate()
            .map_init(
                || proto.clone(),
                |rec, (k, f)| {
                    let i = c * chunk + k;
                    let path = scan.image_path(&f.image);
                    let img =
                        crate::io::load_gray(&path).map_err(|e| at_frame(e, i, Some(f.line)))?;
                    let view = img.view().map_err(|e| at_frame(e, i, Some(f.line)))?;
                    let mut sp = ScanPoints::default();
                    rec.frame_reading(view, &f.reading, i as u32, &mut sp)
                        .map_err(|e| match e {
                            Error::InvalidInput(m) => Error::InvalidInput(format!(
                                "{m} (scan.csv line {}, image {})",
                                f.line,
                                path.display()
                            )),
                            other => other,
                        })?;
                    Ok(sp)
                },
            )
            .collect();
        for p in parts {
            out.append(&p?);
        }
        done += frames.len();
        progress(done, n, out.len());
    }
    Ok(out)
}

/// Loads a scan folder for a calibration (checks joint counts against its robot).
pub fn load_scan(root: impl AsRef<Path>, calibration: &Calibration) -> Result<Scan> {
    Scan::load(root, calibration.robot.as_ref())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::camera::DistortionModel;
    use crate::model::geometry::iso_from_rotvec;

    fn camera(k: [f64; 5]) -> Camera {
        Camera::new(
            768,
            576,
            1271.65,
            1322.52,
            346.14,
            262.6,
            DistortionModel::OpenCv5,
            k,
        )
        .unwrap()
    }

    /// Points on the laser plane, projected, triangulated back: the chain inverts the
    /// projection to rounding (strong opencv5 distortion).
    #[test]
    fn triangulation_inverts_projection() {
        let cam = camera([-0.3, 0.12, 0.001, -0.002, 0.01]);
        let plane = Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 79.87).unwrap();
        let hand_cam = iso_from_rotvec(
            &Vector3::new(-0.3087, 0.2362, 3.0369),
            &Vector3::new(29.19, 5.37, 62.64),
        );
        let base_hand = iso_from_rotvec(
            &Vector3::new(0.1, 3.0, -0.2),
            &Vector3::new(480.0, 10.0, 365.0),
        );
        let tri = Triangulator::new(&cam, &plane, &hand_cam, 2.0).unwrap();
        // Points on the plane: p = n d + a e1 + b e2.
        let e1 = plane.normal.cross(&Vector3::y()).normalize();
        let e2 = plane.normal.cross(&e1);
        let mut uv = Vec::new();
        let mut truth = Vec::new();
        for i in -10..=10 {
            for j in -10..=10 {
                let p = plane.normal * plane.d + e1 * (2.0 * i as f64) + e2 * (2.5 * j as f64);
                let px = cam.project(&p).unwrap();
                uv.push([px.x, px.y]);
                truth.push(base_hand * hand_cam * nalgebra::Point3::from(p));
            }
        }
        let (mut out, mut idx) = (Vec::new(), Vec::new());
        let drops = tri.triangulate_into(&base_hand, &uv, &mut out, &mut idx);
        assert_eq!(drops.total(), 0);
        assert_eq!(out.len(), uv.len());
        for (k, p) in out.iter().enumerate() {
            let t = truth[idx[k] as usize];
            let e = (Vector3::from(*p) - t.coords).norm();
            assert!(e < 1e-9, "point {k}: error {e:.3e} mm");
        }
    }

    /// A plane containing the optical axis direction x = 0 (n = x, d = 50 mm): rays
    /// through pixels left of u0 meet it behind the camera, those near u0 at grazing
    /// angles; both are dropped, not turned into far points.
    #[test]
    fn grazing_and_backward_rays_are_dropped() {
        let cam = camera([0.0; 5]);
        let plane = Plane::new(Vector3::x(), 50.0).unwrap();
        let tri = Triangulator::new(&cam, &plane, &Iso3::identity(), 2.0).unwrap();
        // angle to the plane = atan(xn) for yn = 0: 2 deg at xn = tan(2 deg) = 0.0349.
        let u_at = |deg: f64| cam.u0 + cam.fu * deg.to_radians().tan();
        let uv = [
            [u_at(-10.0), cam.v0], // behind
            [u_at(0.5), cam.v0],   // grazing
            [u_at(1.99), cam.v0],  // grazing
            [u_at(2.01), cam.v0],  // kept
            [u_at(20.0), cam.v0],  // kept
        ];
        let (mut out, mut idx) = (Vec::new(), Vec::new());
        let d = tri.triangulate_into(&Iso3::identity(), &uv, &mut out, &mut idx);
        assert_eq!(idx, vec![3, 4]);
        assert_eq!(d.grazing, 3);
        for p in &out {
            assert!((p[0] - 50.0).abs() < 1e-9);
            assert!(p[2] > 0.0 && p[2] < 50.0 / (2.0f64).to_radians().tan() + 1.0);
        }
    }

    /// The 1D radial undistortion agrees with the camera's 2D Newton over the whole
    /// image of a strongly distorted lens (k1 = -0.25, k2 = 0.12, k3 = 0.01).
    #[test]
    fn radial_undistortion_matches_general() {
        let cam = Camera::new(
            1024,
            768,
            900.0,
            900.5,
            515.3,
            380.8,
            DistortionModel::OpenCv5,
            [-0.25, 0.12, 0.0, 0.0, 0.01],
        )
        .unwrap();
        let plane = Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 79.87).unwrap();
        let tri = Triangulator::new(&cam, &plane, &Iso3::identity(), 0.0).unwrap();
        assert!(tri.radial_only);
        let mut warm = Warm::default();
        for row in (0..768).step_by(7) {
            for col in (0..1024).step_by(13) {
                let (u, v) = (col as f64 + 0.3, row as f64 - 0.2);
                let s =
                    tri.undistort_radial((u - cam.u0) / cam.fu, (v - cam.v0) / cam.fv, warm.scale);
                let s = s.expect("converges inside the image");
                warm.scale = s;
                let (xd, yd) = ((u - cam.u0) / cam.fu, (v - cam.v0) / cam.fv);
                let (xn, yn) = cam.undistort(xd, yd).unwrap();
                assert!((xd * s - xn).abs() < 1e-13 && (yd * s - yn).abs() < 1e-13);
            }
        }
    }

    #[test]
    fn bad_triangulator_input() {
        let cam = camera([0.0; 5]);
        let plane = Plane::new(Vector3::z(), 100.0).unwrap();
        for a in [-1.0, 90.0, f64::NAN] {
            assert!(matches!(
                Triangulator::new(&cam, &plane, &Iso3::identity(), a),
                Err(Error::InvalidInput(_))
            ));
        }
        let bad = Plane {
            normal: Vector3::new(0.0, 0.0, 2.0),
            d: 100.0,
        };
        assert!(Triangulator::new(&cam, &bad, &Iso3::identity(), 2.0).is_err());
    }

    #[test]
    fn direction_from_plane() {
        let cam = camera([0.0; 5]);
        let p = |n: [f64; 3]| Plane::new(Vector3::from(n), 80.0).unwrap();
        assert_eq!(
            stripe_direction_from_plane(&cam, &p([0.629, -0.0492, 0.7759])),
            StripeDirection::Cols
        );
        assert_eq!(
            stripe_direction_from_plane(&cam, &p([0.05, 0.6, 0.8])),
            StripeDirection::Rows
        );
    }
}
