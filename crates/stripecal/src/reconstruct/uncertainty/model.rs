//! The calibration side of the point uncertainty: which numbers of the covariance move
//! a point, their fixed map to the local vector `eta`, and the options ([`super`] docs).

use nalgebra::{DMatrix, Matrix3, Matrix6, Vector3, Vector6};

use crate::calib::joint::{flange_twists, DhKind, DhParam};
use crate::error::{Error, Result};
use crate::model::camera::PARAM_NAMES;
use crate::model::geometry::matrix_to_rotvec;
use crate::model::geometry::Iso3;
use crate::model::kinematics::Robot;
use crate::model::RobotReading;
use crate::model::{Calibration, NamedCovariance, ProfilerCalibration};
use crate::reconstruct::triangulate::laser_plane_of;
use crate::vision::stripe::StripeDirection;

use super::frame::{FrameUncertainty, ETA};

/// What goes into a point's covariance.
#[derive(Debug, Clone, PartialEq)]
pub struct UncertaintyOptions {
    /// The calibration's covariance (calibration.json `covariance`; an error when the
    /// file has none).
    pub calibration: bool,
    /// One-sigma of the stripe centre along the scan line, px; `None`: the calibration's
    /// `quality.stripe_rms_px` (the stripe points' scatter about the laser plane in the
    /// calibration's laser views).
    pub stripe_sigma_px: Option<f64>,
    /// The direction the stripe runs (which pixel coordinate the extractor measures);
    /// `Auto`: from the laser plane ([`crate::reconstruct::stripe_direction_from_plane`]).
    pub direction: StripeDirection,
    /// The robot's pose repeatability, mm, read as a one-sigma per axis (`None`: not in
    /// the budget).
    pub repeatability_mm: Option<f64>,
    /// One-sigma of an encoder reading, degrees (`None`: not in the budget; needs joint
    /// readings and a robot).
    pub encoder_sigma_deg: Option<f64>,
    /// One-sigma of the flange's rotation about each of its axes, degrees (`None`: not
    /// in the budget). Set from the calibration's estimated robot-pose noise where no
    /// encoder figure is given ([`Self::with_pose_noise`]).
    pub flange_rotation_deg: Option<f64>,
    /// A profiler's point noise: one-sigma along the sensor's z (the measuring
    /// direction), mm; `None`: the calibration's `quality.profile_rms_mm` (the sphere
    /// points' scatter about the fitted sphere). Read only by
    /// [`UncertaintyModel::profiler`]; a camera model reads `stripe_sigma_px`.
    pub profile_sigma_mm: Option<f64>,
}

impl Default for UncertaintyOptions {
    fn default() -> Self {
        UncertaintyOptions {
            calibration: true,
            stripe_sigma_px: None,
            direction: StripeDirection::Auto,
            repeatability_mm: None,
            encoder_sigma_deg: None,
            flange_rotation_deg: None,
            profile_sigma_mm: None,
        }
    }
}

impl UncertaintyOptions {
    /// The same options with the robot's figures taken from `robot` where these options
    /// leave them unset.
    pub fn with_robot_figures(mut self, robot: Option<&Robot>) -> Self {
        if let Some(r) = robot {
            self.repeatability_mm = self.repeatability_mm.or(r.repeatability_mm);
            self.encoder_sigma_deg = self.encoder_sigma_deg.or(r.encoder_sigma_deg);
        }
        self
    }

    /// The same options with the robot-pose noise the calibration estimated where
    /// neither these options nor the robot's figures give one: its translation sigma as
    /// the repeatability, its rotation sigma as the flange's rotation (without an
    /// encoder figure); a component at its floor is none (an exact robot as far as the
    /// views tell). Each is counted once: a figure given (here or in rig.json) is
    /// used instead of the estimate, never beside it; the part of the pose noise the
    /// calibration's own images made (`image_factor`) is not the robot's and does not
    /// enter. Call after [`Self::with_robot_figures`].
    pub fn with_pose_noise(mut self, calibration: &Calibration) -> Self {
        let Ok(Some(n)) = crate::io::calibration_robot_pose_noise(calibration) else {
            return self;
        };
        // At its floor a component is no estimate of the robot (the views resolve no
        // robot error): nothing to add.
        let ok = |x: f64, floor: bool| (x.is_finite() && x >= 0.0 && !floor).then_some(x);
        if self.repeatability_mm.is_none() {
            self.repeatability_mm = ok(n.sigma_translation_mm, n.translation_at_floor);
        }
        if self.encoder_sigma_deg.is_none() && self.flange_rotation_deg.is_none() {
            self.flange_rotation_deg = ok(n.sigma_rotation_deg, n.rotation_at_floor);
        }
        self
    }
}

/// Where a number of the covariance goes.
#[derive(Debug, Clone, Copy)]
enum Target {
    /// One `eta` entry.
    Eta(usize),
    /// `hand_cam.rotation_vector[k]`.
    XRot(usize),
    /// `hand_cam.translation_mm[k]`.
    XTrans(usize),
    /// A DH number.
    Robot(DhParam),
}

/// The sensor a model is of, with its calibration.
#[derive(Debug, Clone)]
pub(super) enum Sensor {
    /// A camera and a laser plane; the stripe's direction (resolved: `Rows` or `Cols`).
    Camera {
        calibration: Box<Calibration>,
        direction: StripeDirection,
    },
    /// A calibrated line profiler ([`super`] docs, "Profilers").
    Profiler {
        calibration: Box<ProfilerCalibration>,
    },
}

/// The calibration's uncertainty model: the covariance of the numbers that move a
/// point, and how they map to each frame's local vector ([`super`] docs).
#[derive(Debug, Clone)]
pub struct UncertaintyModel {
    pub(super) sensor: Sensor,
    /// Names of the numbers (a subset of calibration.json's `covariance`).
    names: Vec<String>,
    targets: Vec<Target>,
    /// Their covariance (zero-sized without the calibration part).
    cov: DMatrix<f64>,
    /// `eta` from the frame-independent numbers (19 x P; DH columns zero).
    m_fixed: DMatrix<f64>,
    /// `R_X^T` and `t_X` (carry flange twists to the camera).
    rx_t: Matrix3<f64>,
    tx: Vector3<f64>,
    /// The point's own noise: the stripe's one-sigma along the scan line, px (camera);
    /// along the sensor's z, mm (profiler).
    pub(super) noise_sigma: f64,
    repeatability_mm: f64,
    encoder_sigma_deg: f64,
    flange_rotation_deg: f64,
}

impl UncertaintyModel {
    /// The model of a calibration; errors when the calibration part is asked for and
    /// the file has no covariance, when a figure is negative or not finite, and when the
    /// calibration has no laser plane.
    pub fn new(calibration: &Calibration, opts: &UncertaintyOptions) -> Result<Self> {
        let plane = laser_plane_of(calibration)?;
        check_figures(opts, ("stripe_sigma_px", opts.stripe_sigma_px))?;
        let stripe_sigma_px = match opts.stripe_sigma_px {
            Some(s) => s,
            None => {
                let s = calibration.quality.stripe_rms_px;
                if !(s.is_finite() && s >= 0.0) {
                    return Err(Error::InvalidInput(format!(
                        "the calibration's quality.stripe_rms_px ({s}) cannot serve as the \
                         stripe's noise; give stripe_sigma_px"
                    )));
                }
                s
            }
        };
        let dof = calibration.robot.as_ref().map_or(0, |r| r.dof());
        let selected = select(opts.calibration, calibration.covariance.as_ref(), |n| {
            target_of(n, dof)
        })?;
        // A normal is read normalised: `n' = (n + dn) / |n + dn|`, `dn' = (I - n n^T) dn`.
        let proj = Matrix3::identity() - plane.normal * plane.normal.transpose();
        let direction = match opts.direction {
            StripeDirection::Auto => {
                crate::reconstruct::stripe_direction_from_plane(&calibration.camera, plane)
            }
            d => d,
        };
        let sensor = Sensor::Camera {
            calibration: Box::new(calibration.clone()),
            direction,
        };
        Ok(Self::assemble(
            sensor,
            selected,
            &calibration.hand_cam,
            &proj,
            stripe_sigma_px,
            opts,
        ))
    }

    /// The model of a line profiler's calibration ([`super`] docs, "Profilers"): the
    /// same local vector `eta` with the camera and plane entries unused; the numbers that
    /// move a point are `hand_cam.*` (`T_hand_sensor`) and the DH numbers (`sphere.*`
    /// move none and are left out). The point's own noise is along the sensor's z,
    /// one-sigma `opts.profile_sigma_mm` (default the calibration's
    /// `quality.profile_rms_mm`); `stripe_sigma_px` and `direction` are not read. A
    /// point is addressed by its profile coordinates `(x_mm, z_mm)` where a camera's is
    /// `(u_px, v_px)`. Errors as [`Self::new`] (no laser plane is needed).
    pub fn profiler(calibration: &ProfilerCalibration, opts: &UncertaintyOptions) -> Result<Self> {
        check_figures(opts, ("profile_sigma_mm", opts.profile_sigma_mm))?;
        let sigma_mm = match opts.profile_sigma_mm {
            Some(s) => s,
            None => {
                let s = calibration.quality.profile_rms_mm;
                if !(s.is_finite() && s >= 0.0) {
                    return Err(Error::InvalidInput(format!(
                        "the calibration's quality.profile_rms_mm ({s}) cannot serve as the \
                         profile points' noise; give profile_sigma_mm"
                    )));
                }
                s
            }
        };
        let dof = calibration.robot.as_ref().map_or(0, |r| r.dof());
        let selected =
            select(
                opts.calibration,
                calibration.covariance.as_ref(),
                |n| match target_of(n, dof)? {
                    // A profiler's calibration has no camera or laser plane numbers; should a
                    // covariance name them they move nothing here.
                    Target::Eta(_) => None,
                    t => Some(t),
                },
            )?;
        let sensor = Sensor::Profiler {
            calibration: Box::new(calibration.clone()),
        };
        Ok(Self::assemble(
            sensor,
            selected,
            &calibration.hand_sensor,
            &Matrix3::identity(),
            sigma_mm,
            opts,
        ))
    }

    /// The model from the selected numbers: `M_f`'s frame-independent columns.
    fn assemble(
        sensor: Sensor,
        (names, targets, cov): Selected,
        x: &Iso3,
        proj: &Matrix3<f64>,
        noise_sigma: f64,
        opts: &UncertaintyOptions,
    ) -> Self {
        let rx = x.rotation.to_rotation_matrix().into_inner();
        let jr = right_jacobian(&matrix_to_rotvec(&rx));
        let mut m_fixed = DMatrix::zeros(ETA, names.len());
        for (c, t) in targets.iter().enumerate() {
            match *t {
                Target::Eta(e) if (9..12).contains(&e) => {
                    for r in 0..3 {
                        m_fixed[(9 + r, c)] = proj[(r, e - 9)];
                    }
                }
                Target::Eta(e) => m_fixed[(e, c)] = 1.0,
                Target::XRot(k) => {
                    for r in 0..3 {
                        m_fixed[(13 + r, c)] = jr[(r, k)];
                    }
                }
                Target::XTrans(k) => {
                    for r in 0..3 {
                        m_fixed[(16 + r, c)] = rx[(k, r)];
                    }
                }
                Target::Robot(_) => {}
            }
        }
        UncertaintyModel {
            sensor,
            names,
            targets,
            cov,
            m_fixed,
            rx_t: rx.transpose(),
            tx: x.translation.vector,
            noise_sigma,
            repeatability_mm: opts.repeatability_mm.unwrap_or(0.0),
            encoder_sigma_deg: opts.encoder_sigma_deg.unwrap_or(0.0),
            flange_rotation_deg: opts.flange_rotation_deg.unwrap_or(0.0),
        }
    }

    /// Names of the calibration's numbers in the model (columns of
    /// [`FrameUncertainty::map`]).
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The camera's calibration; `None` for a profiler's model
    /// ([`Self::profiler_calibration`]).
    pub fn calibration(&self) -> Option<&Calibration> {
        match &self.sensor {
            Sensor::Camera { calibration, .. } => Some(calibration),
            Sensor::Profiler { .. } => None,
        }
    }

    /// The profiler's calibration; `None` for a camera's model.
    pub fn profiler_calibration(&self) -> Option<&ProfilerCalibration> {
        match &self.sensor {
            Sensor::Profiler { calibration } => Some(calibration),
            Sensor::Camera { .. } => None,
        }
    }

    /// A profiler's model ([`Self::profiler`]).
    pub fn is_profiler(&self) -> bool {
        matches!(self.sensor, Sensor::Profiler { .. })
    }

    /// The stripe direction (resolved: `Rows` or `Cols`); `Auto` for a profiler's model
    /// (no stripe: its points are measured along the sensor's z).
    pub fn direction(&self) -> StripeDirection {
        match &self.sensor {
            Sensor::Camera { direction, .. } => *direction,
            Sensor::Profiler { .. } => StripeDirection::Auto,
        }
    }

    /// The robot's DH table of the calibration, if any.
    fn robot(&self) -> Option<&Robot> {
        match &self.sensor {
            Sensor::Camera { calibration, .. } => calibration.robot.as_ref(),
            Sensor::Profiler { calibration } => calibration.robot.as_ref(),
        }
    }

    /// `T_hand_cam` (camera) or `T_hand_sensor` (profiler).
    pub(super) fn hand_sensor(&self) -> &Iso3 {
        match &self.sensor {
            Sensor::Camera { calibration, .. } => &calibration.hand_cam,
            Sensor::Profiler { calibration } => &calibration.hand_sensor,
        }
    }

    /// Their covariance (P x P).
    pub fn covariance(&self) -> &DMatrix<f64> {
        &self.cov
    }

    /// The frame taken at `reading`: its pose, the map `M_f` and `Sigma_f`.
    pub fn frame(&self, reading: &RobotReading) -> Result<FrameUncertainty> {
        let robot = self.robot();
        let base_hand = reading.base_hand(robot)?;
        let q = match reading {
            RobotReading::Joints(q) => Some(q.as_slice()),
            RobotReading::FlangePose(_) | RobotReading::Fixed => None,
        };
        let mut map = self.m_fixed.clone();
        let dh: Vec<(usize, DhParam)> = self
            .targets
            .iter()
            .enumerate()
            .filter_map(|(c, t)| match t {
                Target::Robot(p) => Some((c, *p)),
                _ => None,
            })
            .collect();
        if !dh.is_empty() {
            let (Some(robot), Some(q)) = (robot, q) else {
                return Err(Error::InvalidInput(
                    "the calibration's covariance has DH numbers but the frame gives a flange \
                     pose, not joint readings"
                        .into(),
                ));
            };
            let params: Vec<DhParam> = dh.iter().map(|d| d.1).collect();
            for ((c, _), tw) in dh.iter().zip(flange_twists(robot, q, &params)) {
                let (w, v) = self.to_camera(&tw);
                for r in 0..3 {
                    map[(13 + r, *c)] = w[r];
                    map[(16 + r, *c)] = v[r];
                }
            }
        }
        let sigma = &map * &self.cov * map.transpose();
        let mut robot_sigma = Matrix6::zeros();
        if self.encoder_sigma_deg > 0.0 {
            let (Some(robot), Some(q)) = (robot, q) else {
                return Err(Error::InvalidInput(
                    "encoder_sigma_deg needs joint readings and the robot's DH table; the frame \
                     gives a flange pose"
                        .into(),
                ));
            };
            let joints: Vec<DhParam> = (0..robot.dof())
                .map(|joint| DhParam {
                    joint,
                    kind: DhKind::Theta0,
                })
                .collect();
            let s2 = self.encoder_sigma_deg * self.encoder_sigma_deg;
            for tw in flange_twists(robot, q, &joints) {
                let (w, v) = self.to_camera(&tw);
                let g = Vector6::new(w.x, w.y, w.z, v.x, v.y, v.z);
                robot_sigma += g * g.transpose() * s2;
            }
        }
        if self.flange_rotation_deg > 0.0 {
            // The flange turned about each of its axes: a rotation of T_base_cam.
            let s2 = self.flange_rotation_deg.to_radians().powi(2);
            for k in 0..3 {
                let mut tw = [0.0; 6];
                tw[k] = 1.0;
                let (w, v) = self.to_camera(&tw);
                let g = Vector6::new(w.x, w.y, w.z, v.x, v.y, v.z);
                robot_sigma += g * g.transpose() * s2;
            }
        }
        let t2 = self.repeatability_mm * self.repeatability_mm;
        for k in 3..6 {
            robot_sigma[(k, k)] += t2;
        }
        FrameUncertainty::new(self, &base_hand, map, sigma, robot_sigma)
    }

    /// A flange twist (flange frame) as a right perturbation of `T_base_cam`.
    fn to_camera(&self, tw: &[f64; 6]) -> (Vector3<f64>, Vector3<f64>) {
        let wh = Vector3::new(tw[0], tw[1], tw[2]);
        let vh = Vector3::new(tw[3], tw[4], tw[5]);
        (self.rx_t * wh, self.rx_t * (wh.cross(&self.tx) + vh))
    }
}

/// The numbers of a covariance that move a point: names, targets, covariance.
type Selected = (Vec<String>, Vec<Target>, DMatrix<f64>);

/// The figures of `opts` (and `noise`, the sensor's own) are finite and >= 0.
fn check_figures(opts: &UncertaintyOptions, noise: (&str, Option<f64>)) -> Result<()> {
    for (name, v) in [
        noise,
        ("repeatability_mm", opts.repeatability_mm),
        ("encoder_sigma_deg", opts.encoder_sigma_deg),
        ("flange_rotation_deg", opts.flange_rotation_deg),
    ] {
        if let Some(x) = v {
            if !(x.is_finite() && x >= 0.0) {
                return Err(Error::InvalidInput(format!(
                    "uncertainty option {name} = {x} must be finite and >= 0"
                )));
            }
        }
    }
    Ok(())
}

/// The numbers of `named` whose `target` is some (empty when the calibration part is
/// not asked for; an error when it is and there is no covariance).
fn select(
    wanted: bool,
    named: Option<&NamedCovariance>,
    target: impl Fn(&str) -> Option<Target>,
) -> Result<Selected> {
    let (mut names, mut targets, mut idx) = (Vec::new(), Vec::new(), Vec::new());
    if !wanted {
        return Ok((names, targets, DMatrix::zeros(0, 0)));
    }
    let named = named.ok_or_else(|| {
        Error::InvalidInput(
            "the calibration has no covariance (calibration.json without \"covariance\": \
             written before the contract asked for it); recalibrate, or leave the calibration \
             out of the uncertainty"
                .into(),
        )
    })?;
    for (i, n) in named.parameters.iter().enumerate() {
        if let Some(t) = target(n) {
            names.push(n.clone());
            targets.push(t);
            idx.push(i);
        }
    }
    let cov = DMatrix::from_fn(idx.len(), idx.len(), |r, c| named.matrix[(idx[r], idx[c])]);
    if cov.iter().any(|x| !x.is_finite()) {
        return Err(Error::InvalidInput(
            "the calibration's covariance has non-finite entries".into(),
        ));
    }
    Ok((names, targets, cov))
}

/// Where the contract name `n` goes, `None` for numbers that do not move a base point.
fn target_of(n: &str, dof: usize) -> Option<Target> {
    let index = |prefix: &str| -> Option<usize> {
        let k = n.strip_prefix(prefix)?.strip_suffix(']')?;
        k.parse().ok()
    };
    if let Some(k) = index("camera.distortion[") {
        return (k < 5).then_some(Target::Eta(4 + k));
    }
    if let Some(p) = n.strip_prefix("camera.") {
        return PARAM_NAMES[..4]
            .iter()
            .position(|&x| x == p)
            .map(Target::Eta);
    }
    if let Some(k) = index("laser_plane.normal[") {
        return (k < 3).then_some(Target::Eta(9 + k));
    }
    if n == "laser_plane.d_mm" {
        return Some(Target::Eta(12));
    }
    if let Some(k) = index("hand_cam.rotation_vector[") {
        return (k < 3).then_some(Target::XRot(k));
    }
    if let Some(k) = index("hand_cam.translation_mm[") {
        return (k < 3).then_some(Target::XTrans(k));
    }
    DhParam::from_name(n, dof).map(Target::Robot)
}

/// The right Jacobian of SO(3) at rotation vector `r`: `Exp(r + dr) = Exp(r) Exp(J_r dr)`
/// to first order.
pub(crate) fn right_jacobian(r: &Vector3<f64>) -> Matrix3<f64> {
    let th2 = r.norm_squared();
    let th = th2.sqrt();
    let k = r.cross_matrix();
    let (a, b) = if th < 1e-4 {
        (0.5 - th2 / 24.0, 1.0 / 6.0 - th2 / 120.0)
    } else {
        ((1.0 - th.cos()) / th2, (th - th.sin()) / (th2 * th))
    };
    Matrix3::identity() - k * a + k * k * b
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geometry::rotvec_to_matrix;

    #[test]
    fn right_jacobian_matches_finite_differences() {
        for r in [
            Vector3::new(0.3, -1.2, 2.0),
            Vector3::new(1e-6, 2e-6, -1e-6),
            Vector3::new(-0.3087, 0.2362, 3.0369),
        ] {
            let jr = right_jacobian(&r);
            let r0 = rotvec_to_matrix(&r);
            let h = 1e-6;
            for k in 0..3 {
                let mut d = Vector3::zeros();
                d[k] = h;
                let w = (matrix_to_rotvec(&(r0.transpose() * rotvec_to_matrix(&(r + d))))
                    - matrix_to_rotvec(&(r0.transpose() * rotvec_to_matrix(&(r - d)))))
                    / (2.0 * h);
                let e = (w - jr.column(k)).norm();
                assert!(e < 1e-7, "r {r:?} column {k}: {e:.2e}");
            }
        }
    }

    #[test]
    fn names_map_to_their_targets() {
        assert!(matches!(target_of("camera.fu", 6), Some(Target::Eta(0))));
        assert!(matches!(target_of("camera.v0", 6), Some(Target::Eta(3))));
        assert!(matches!(
            target_of("camera.distortion[4]", 6),
            Some(Target::Eta(8))
        ));
        assert!(matches!(
            target_of("laser_plane.normal[2]", 6),
            Some(Target::Eta(11))
        ));
        assert!(matches!(
            target_of("laser_plane.d_mm", 6),
            Some(Target::Eta(12))
        ));
        assert!(matches!(
            target_of("hand_cam.translation_mm[1]", 6),
            Some(Target::XTrans(1))
        ));
        assert!(matches!(
            target_of("robot.joints[2].beta_deg", 6),
            Some(Target::Robot(_))
        ));
        assert!(target_of("robot.joints[6].d_mm", 6).is_none());
        assert!(target_of("base_board.translation_mm[0]", 6).is_none());
        assert!(target_of("board.scale", 6).is_none());
    }
}
