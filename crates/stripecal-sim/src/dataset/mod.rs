//! The twin as a whole: true parameters, poses, rendering of views and scan frames,
//! and writing datasets in the files of spec/DATASET.md.
//!
//! This file builds the twin and chooses its poses; `render.rs` renders a pose,
//! `records.rs` gives the records (rig, truth, observations, the true calibration) and
//! `write.rs` writes the dataset's folders.

use std::sync::OnceLock;

use nalgebra::{Point3, Vector3};
use serde_json::{json, Value};

use stripecal::io;
use stripecal::model::geometry::{Iso3, Plane};
use stripecal::model::image::{AnyGray, AnyRgb};
use stripecal::model::kinematics::IkOptions;
use stripecal::model::{
    Calibration, Rig, RobotReading, ScanFrame, Sphere, StripeDirection, Truth, View,
};
use stripecal::{Board, Camera, DistortionModel, Robot};

use crate::config::{pose_cfg, pose_model, SimConfig};
use crate::imaging::{form_image, form_rgb, Exposure};
use crate::poses::{PoseInfo, PoseProblem};
use crate::render::{LinearImage, Renderer};
use crate::scene::{ImageScene, Laser, World};
use crate::truth::{stripe_direction, stripe_truth, target_truth, PointTruth, StripePointTruth};
use crate::SimError;

mod records;
mod render;
mod write;

pub use records::noisy_observations;
pub use write::DatasetSummary;

/// Plate thickness: the table lies this far behind the board surface, mm; the default of
/// `board.plate_thickness_mm`.
pub const PLATE_THICKNESS_MM: f64 = 3.0;

/// First random stream of the reading noise (one stream per calibration view).
const READING_NOISE_STREAM: u64 = 0x7265_6164_0000;

/// The digital twin of one rig.
pub struct Twin {
    pub cfg: SimConfig,
    pub camera: Camera,
    pub laser_plane: Plane,
    /// Laser emitter in the camera frame, mm.
    pub emitter: Vector3<f64>,
    /// `T_hand_cam` (true).
    pub hand_cam: Iso3,
    /// `T_base_board` (true).
    pub base_board: Iso3,
    pub robot_nominal: Robot,
    pub robot_true: Robot,
    pub board: Board,
    /// The ball of the scan (base frame), if scans are enabled.
    pub sphere: Option<Sphere>,
    /// The direction the stripe runs in the images.
    pub direction: StripeDirection,
    pub(crate) calib_world: World,
    scan_world: World,
    /// The calibration world with the board frame as the base frame (board-only views
    /// at arbitrary `T_board_cam`).
    board_world: World,
    renderer: OnceLock<Result<Renderer, String>>,
}

/// One rendered view (or scan frame) with its truth.
pub struct ViewRender {
    /// Board image (laser off); in single-image mode the one image. Colour images
    /// (`imaging.colour`): the BT.601 gray of `board_rgb`.
    pub board_image: Option<AnyGray>,
    /// Laser image; `None` in single-image mode (the board image holds the stripe).
    /// Colour images: the BT.601 gray of `laser_rgb`.
    pub laser_image: Option<AnyGray>,
    /// Colour images only: the board image as rendered (RGB).
    pub board_rgb: Option<AnyRgb>,
    /// Colour images only: the laser image as rendered (RGB).
    pub laser_rgb: Option<AnyRgb>,
    /// Imaged target points: circle centres or chessboard corners
    /// ([`crate::truth::target_truth`]; empty for scan frames). The name is historical.
    pub circles: Vec<PointTruth>,
    /// True stripe centre line.
    pub stripe: Vec<StripePointTruth>,
    /// `T_base_cam` of the view.
    pub base_cam: Iso3,
}

impl Twin {
    /// A twin from a configuration (validated).
    pub fn new(cfg: SimConfig) -> Result<Twin, SimError> {
        cfg.validate()?;
        let camera = cfg.camera_model()?;
        let laser_plane = cfg.laser_plane_model()?;
        let hand_cam = cfg.hand_cam_model();
        let robot_nominal = cfg.robot_nominal()?;
        let robot_true = cfg.robot_true()?;
        let board = cfg.board_model()?;
        let emitter = match cfg.imaging.laser_emitter_mm {
            Some(e) => {
                let e = Vector3::from(e);
                if laser_plane.signed_distance(&e).abs() > 1e-6 {
                    return Err(SimError::Config(format!(
                        "imaging.laser_emitter_mm {e:?} is not on the laser plane ({:.3} mm off)",
                        laser_plane.signed_distance(&e)
                    )));
                }
                e
            }
            None => laser_plane.normal * laser_plane.d,
        };
        let base_board = match &cfg.base_board {
            Some(p) => pose_model(p),
            None => auto_base_board(&cfg, &robot_true, &hand_cam, &board)?,
        };
        let (plate, circle) = if board.dark_circles {
            (
                cfg.imaging.plate_reflectance,
                cfg.imaging.circle_reflectance,
            )
        } else {
            (
                cfg.imaging.circle_reflectance,
                cfg.imaging.plate_reflectance,
            )
        };
        let calib_world = World {
            board: board.clone(),
            plate_margin_mm: cfg.board.plate_margin_mm,
            base_board,
            plate_thickness_mm: cfg.board.plate_thickness_mm,
            table: true,
            spheres: vec![],
            free_plate: None,
            plate_reflectance: plate,
            circle_reflectance: circle,
            table_reflectance: cfg.imaging.table_reflectance,
            sphere_reflectance: cfg.imaging.sphere_reflectance,
        };
        let sphere = cfg.scan.enabled.then(|| {
            let r = 0.5 * cfg.scan.sphere_diameter_mm;
            let ctr = crate::target::points_center(&board);
            let c_board = Point3::new(
                ctr.x + cfg.scan.sphere_offset_mm[0],
                ctr.y + cfg.scan.sphere_offset_mm[1],
                cfg.board.plate_thickness_mm - r,
            );
            Sphere {
                center_mm: (base_board * c_board).coords,
                diameter_mm: cfg.scan.sphere_diameter_mm,
            }
        });
        let scan_world = World {
            spheres: sphere
                .iter()
                .map(|s| (s.center_mm, 0.5 * s.diameter_mm))
                .collect(),
            ..calib_world.clone()
        };
        let board_world = World {
            base_board: Iso3::identity(),
            ..calib_world.clone()
        };
        let mut twin = Twin {
            cfg,
            camera,
            laser_plane,
            emitter,
            hand_cam,
            base_board,
            robot_nominal,
            robot_true,
            board,
            sphere,
            direction: StripeDirection::Cols,
            calib_world,
            scan_world,
            board_world,
            renderer: OnceLock::new(),
        };
        let mid = 0.5 * (twin.cfg.working_range_mm[0] + twin.cfg.working_range_mm[1]);
        let probe = twin
            .calib_world
            .image_scene(&Iso3::identity(), twin.laser());
        twin.direction = stripe_direction(&probe, &twin.camera, mid);
        Ok(twin)
    }

    /// The laser sheet in the camera frame.
    pub fn laser(&self) -> Laser {
        Laser {
            plane: self.laser_plane,
            emitter: self.emitter,
            sigma_mm: self.cfg.imaging.laser_sigma_mm,
            peak: self.cfg.imaging.laser_peak,
        }
    }

    pub(crate) fn renderer(&self) -> Result<&Renderer, SimError> {
        self.renderer
            .get_or_init(|| {
                Renderer::new(&self.camera, self.cfg.imaging.supersample).map_err(|e| e.to_string())
            })
            .as_ref()
            .map_err(|e| SimError::Render(e.clone()))
    }

    /// `T_base_cam` for encoder readings on the TRUE robot.
    pub fn base_cam(&self, q_deg: &[f64]) -> Result<Iso3, SimError> {
        Ok(self.robot_true.forward(q_deg)? * self.hand_cam)
    }

    /// What the controller reports for encoder readings `q_deg`, as views.csv and scan.csv
    /// give it: the readings themselves, or with `pose_columns` set the flange pose the
    /// controller computes from them with the NOMINAL robot (rig.json's), not the true one.
    pub fn reading(&self, q_deg: &[f64]) -> Result<RobotReading, SimError> {
        let joints = RobotReading::Joints(q_deg.to_vec());
        Ok(match &self.cfg.pose_columns {
            None => joints,
            Some(_) => RobotReading::FlangePose(joints.base_hand(Some(&self.robot_nominal))?),
        })
    }

    /// The joint readings the robot reports for calibration view `index` at the true
    /// readings `q_deg`: those plus Gaussian noise of `poses.reading_noise_deg` per
    /// joint, drawn from the seed and the view's index (unchanged without noise).
    pub fn reported_q(&self, index: usize, q_deg: &[f64]) -> Vec<f64> {
        let sigma = self.cfg.poses.reading_noise_deg;
        if sigma == 0.0 {
            return q_deg.to_vec();
        }
        let mut rng = crate::rng::Rng::new(
            self.cfg.seed,
            READING_NOISE_STREAM.wrapping_add(index as u64),
        );
        q_deg.iter().map(|q| q + sigma * rng.normal()).collect()
    }

    /// The camera-frame scene of a pose (`with_sphere` for scan frames).
    pub fn scene(&self, q_deg: &[f64], with_sphere: bool) -> Result<ImageScene, SimError> {
        let world = if with_sphere {
            &self.scan_world
        } else {
            &self.calib_world
        };
        Ok(world.image_scene(&self.base_cam(q_deg)?, self.laser()))
    }

    fn pose_problem<'a>(
        &'a self,
        scene: &'a (dyn Fn(&Iso3) -> ImageScene + Sync),
    ) -> PoseProblem<'a> {
        let p = &self.cfg.poses;
        PoseProblem {
            robot: &self.robot_true,
            camera: &self.camera,
            hand_cam: &self.hand_cam,
            base_board: &self.base_board,
            home_q: &p.home_q_deg,
            standoff: p.standoff_mm,
            max_tilt_deg: p.max_tilt_deg,
            max_roll_deg: p.max_roll_deg,
            max_joint_delta_deg: p.max_joint_delta_deg,
            margin_px: p.margin_px,
            max_laser_incidence_deg: p.max_laser_incidence_deg,
            stripe_beside_pattern: p.stripe_beside_pattern,
            scene,
        }
    }

    /// The calibration poses: explicit ones (checked) or sampled by seed.
    pub fn calibration_poses(&self) -> Result<Vec<PoseInfo>, SimError> {
        let laser = self.laser();
        let scene_fn = move |t: &Iso3| self.calib_world.image_scene(t, laser);
        let problem = self.pose_problem(&scene_fn);
        match &self.cfg.poses.explicit_q_deg {
            Some(list) => list
                .iter()
                .enumerate()
                .map(|(i, q)| {
                    problem
                        .check(q)
                        .map_err(|e| SimError::Poses(format!("poses.explicit_q_deg[{i}]: {e}")))
                })
                .collect(),
            None if self.cfg.poses.spread == "wide" => {
                problem.sample_wide(self.cfg.poses.count, self.cfg.seed)
            }
            None => problem.sample(self.cfg.poses.count, self.cfg.seed),
        }
    }

    /// Encoder readings of the scan: a straight sweep of the sensor over the ball.
    pub fn scan_poses(&self) -> Result<Vec<Vec<f64>>, SimError> {
        let Some(sphere) = self.sphere else {
            return Ok(vec![]);
        };
        let sc = &self.cfg.scan;
        let home = &self.cfg.poses.home_q_deg;
        let home_cam = self.base_cam(home)?;
        let rot = home_cam.rotation;
        let r = 0.5 * sphere.diameter_mm;
        let up = self.base_board.rotation * -Vector3::z();
        let top = sphere.center_mm + up * r;
        let (sweep, rate) = self.table_sweep(&rot, &up)?;
        let origin = crate::poses::scan_origin(
            &rot,
            &self.laser_plane.normal,
            self.laser_plane.d,
            &sphere.center_mm,
            &top,
            sc.top_depth_mm,
            &sweep,
        )
        .ok_or_else(|| {
            SimError::Poses("cannot place the scan sweep (degenerate geometry)".into())
        })?;
        self.sweep_poses(&origin, &sweep, &rot, rate, "scan")
    }

    /// The direction a sweep at camera orientation `rot` moves along the table (normal
    /// `up`): the laser plane's normal (base frame) with its `up` part removed, unit;
    /// and the rate the plane moves along its normal per mm of travel.
    pub(crate) fn table_sweep(
        &self,
        rot: &nalgebra::UnitQuaternion<f64>,
        up: &Vector3<f64>,
    ) -> Result<(Vector3<f64>, f64), SimError> {
        let n_base = rot * self.laser_plane.normal;
        let sweep = n_base - up * n_base.dot(up);
        if sweep.norm() < 1e-6 {
            return Err(SimError::Poses(
                "the laser plane is parallel to the table: no sweep direction".into(),
            ));
        }
        let sweep = sweep.normalize();
        Ok((sweep, n_base.dot(&sweep).abs()))
    }

    /// Encoder readings of a straight sweep of the camera at orientation `rot` from
    /// `origin` along `sweep` (base frame), centred: long enough for the laser plane,
    /// moving at `rate` mm per mm of travel, to cross the ball's diameter plus
    /// `scan.margin_mm` each side, in `scan.step_mm` steps (at most `scan.max_frames`
    /// frames); each frame's inverse kinematics on the TRUE robot starts from the last.
    /// `what` names the scan in errors.
    pub(crate) fn sweep_poses(
        &self,
        origin: &Vector3<f64>,
        sweep: &Vector3<f64>,
        rot: &nalgebra::UnitQuaternion<f64>,
        rate: f64,
        what: &str,
    ) -> Result<Vec<Vec<f64>>, SimError> {
        let sc = &self.cfg.scan;
        let half = (0.5 * sc.sphere_diameter_mm + sc.margin_mm) / rate;
        let mut n = (2.0 * half / sc.step_mm).floor() as usize + 1;
        if sc.max_frames > 0 && n > sc.max_frames {
            n = sc.max_frames;
        }
        let start = -0.5 * (n - 1) as f64 * sc.step_mm;
        let x_inv = self.hand_cam.inverse();
        let mut q = self.cfg.poses.home_q_deg.clone();
        let mut out = Vec::with_capacity(n);
        for k in 0..n {
            let t = start + k as f64 * sc.step_mm;
            let cam = Iso3::from_parts((origin + sweep * t).into(), *rot);
            q = self
                .robot_true
                .inverse(&(cam * x_inv), &q, &IkOptions::default())
                .map_err(|e| {
                    SimError::Poses(format!(
                        "{what} frame {k}: the robot cannot reach the sweep: {e}"
                    ))
                })?;
            out.push(q.clone());
        }
        Ok(out)
    }
}

/// Places the board flat on the table where the home pose sees its centre at the
/// middle of the stand-off range, upright in the image.
fn auto_base_board(
    cfg: &SimConfig,
    robot: &Robot,
    hand_cam: &Iso3,
    board: &Board,
) -> Result<Iso3, SimError> {
    let cam = robot.forward(&cfg.poses.home_q_deg)? * hand_cam;
    let a = cam.rotation * Vector3::z();
    let o = cam.translation.vector;
    let s = 0.5 * (cfg.poses.standoff_mm[0] + cfg.poses.standoff_mm[1]);
    // table is horizontal (normal +z in base); the camera must look down
    if a.z > -0.2 {
        return Err(SimError::Config(
            "the camera does not look down at the home pose; give base_board explicitly".into(),
        ));
    }
    let zb = -Vector3::z();
    // distance along the axis to the horizontal plane is s
    let target = o + a * s;
    let xc = cam.rotation * Vector3::x();
    let xb = (xc - zb * xc.dot(&zb)).normalize();
    let yb = zb.cross(&xb);
    let r = nalgebra::Matrix3::from_columns(&[xb, yb, zb]);
    let c_board = crate::target::points_center(board);
    let t = target - r * c_board;
    Ok(stripecal::model::geometry::iso_from_parts(&r, &t))
}
