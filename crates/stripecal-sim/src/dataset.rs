//! The twin as a whole: true parameters, poses, rendering of views and scan frames,
//! and writing datasets in the files of spec/DATASET.md.

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

mod write;

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

    /// Linear radiance of a pose (for fidelity tests): `(image, scene)`.
    pub fn render_linear(
        &self,
        q_deg: &[f64],
        with_sphere: bool,
    ) -> Result<(LinearImage, ImageScene), SimError> {
        let scene = self.scene(q_deg, with_sphere)?;
        Ok((self.renderer()?.render(&scene), scene))
    }

    /// The world of `base` with colour channel `c`'s reflectances (`imaging.plate_rgb`,
    /// `imaging.ink_rgb`, swapped like the gray ones for light circles); `None` when
    /// they are the gray ones (the gray render serves the channel).
    fn channel_world(&self, base: &World, c: usize) -> Option<World> {
        let im = &self.cfg.imaging;
        let plate = im.plate_rgb.map_or(im.plate_reflectance, |v| v[c]);
        let ink = im.ink_rgb.map_or(im.circle_reflectance, |v| v[c]);
        if plate == im.plate_reflectance && ink == im.circle_reflectance {
            return None;
        }
        let (plate, circle) = if self.board.dark_circles {
            (plate, ink)
        } else {
            (ink, plate)
        };
        Some(World {
            plate_reflectance: plate,
            circle_reflectance: circle,
            ..base.clone()
        })
    }

    /// The linear images of a pose per colour channel: `lin` (the gray render) where
    /// the channel's reflectances are the gray ones, a render with its own otherwise.
    fn linear_rgb(
        &self,
        q_deg: &[f64],
        with_sphere: bool,
        lin: LinearImage,
    ) -> Result<[std::sync::Arc<LinearImage>; 3], SimError> {
        let base = if with_sphere {
            &self.scan_world
        } else {
            &self.calib_world
        };
        let base_cam = self.base_cam(q_deg)?;
        self.channel_renders(base, lin, |w| w.image_scene(&base_cam, self.laser()))
    }

    /// The linear images per colour channel of the scene `scene_of(world)`: `lin` (the
    /// gray render of `base`) where the channel's reflectances are the gray ones, a
    /// render of the channel's own world otherwise.
    pub(crate) fn channel_renders(
        &self,
        base: &World,
        lin: LinearImage,
        scene_of: impl Fn(&World) -> ImageScene,
    ) -> Result<[std::sync::Arc<LinearImage>; 3], SimError> {
        let gray = std::sync::Arc::new(lin);
        let mut out = [gray.clone(), gray.clone(), gray];
        for (c, slot) in out.iter_mut().enumerate() {
            if let Some(w) = self.channel_world(base, c) {
                *slot = std::sync::Arc::new(self.renderer()?.render(&scene_of(&w)));
            }
        }
        Ok(out)
    }

    /// The image of one exposure: gray, or with `imaging.colour` the RGB image and its
    /// BT.601 gray.
    pub(crate) fn expose(
        &self,
        lin: &LinearImage,
        rgb: Option<&[std::sync::Arc<LinearImage>; 3]>,
        exposure: Exposure,
        stream: u64,
    ) -> Result<(AnyGray, Option<AnyRgb>), SimError> {
        let im = &self.cfg.imaging;
        let seed = self.cfg.seed;
        Ok(match rgb {
            None => (
                form_image(lin, &self.camera, im, exposure, seed, stream),
                None,
            ),
            Some(l) => {
                let c = form_rgb(
                    [&l[0], &l[1], &l[2]],
                    &self.camera,
                    im,
                    exposure,
                    seed,
                    stream,
                )?;
                (c.to_gray(), Some(c))
            }
        })
    }

    /// Renders calibration view `index` at `q_deg`: board (and laser) image with truth.
    pub fn render_view(&self, q_deg: &[f64], index: usize) -> Result<ViewRender, SimError> {
        let (lin, scene) = self.render_linear(q_deg, false)?;
        if self.cfg.imaging.colour {
            return self.render_view_rgb(q_deg, index, lin, scene);
        }
        let im = &self.cfg.imaging;
        let seed = self.cfg.seed;
        let (board_image, laser_image) = if im.single_image {
            (
                form_image(
                    &lin,
                    &self.camera,
                    im,
                    Exposure::Single,
                    seed,
                    3 * index as u64,
                ),
                None,
            )
        } else {
            (
                form_image(
                    &lin,
                    &self.camera,
                    im,
                    Exposure::Board,
                    seed,
                    3 * index as u64,
                ),
                Some(form_image(
                    &lin,
                    &self.camera,
                    im,
                    Exposure::Laser,
                    seed,
                    3 * index as u64 + 1,
                )),
            )
        };
        Ok(ViewRender {
            board_image: Some(board_image),
            laser_image,
            board_rgb: None,
            laser_rgb: None,
            circles: target_truth(&scene, &self.camera, 0.0),
            stripe: stripe_truth(&scene, &self.camera, self.direction),
            base_cam: self.base_cam(q_deg)?,
        })
    }

    /// [`Self::render_view`] of colour images.
    fn render_view_rgb(
        &self,
        q_deg: &[f64],
        index: usize,
        lin: LinearImage,
        scene: ImageScene,
    ) -> Result<ViewRender, SimError> {
        let rgb = self.linear_rgb(q_deg, false, lin)?;
        let s = 3 * index as u64;
        let (board_image, board_rgb, laser_image, laser_rgb) = if self.cfg.imaging.single_image {
            let (g, c) = self.expose(&rgb[0], Some(&rgb), Exposure::Single, s)?;
            (g, c, None, None)
        } else {
            let (g, c) = self.expose(&rgb[0], Some(&rgb), Exposure::Board, s)?;
            let (lg, lc) = self.expose(&rgb[0], Some(&rgb), Exposure::Laser, s + 1)?;
            (g, c, Some(lg), lc)
        };
        Ok(ViewRender {
            board_image: Some(board_image),
            laser_image,
            board_rgb,
            laser_rgb,
            circles: target_truth(&scene, &self.camera, 0.0),
            stripe: stripe_truth(&scene, &self.camera, self.direction),
            base_cam: self.base_cam(q_deg)?,
        })
    }

    /// The calibration scene (the plate on its table, no sphere) with the laser off,
    /// seen from `T_board_cam` (the camera pose in the board frame, not through the
    /// robot): the scene of the board-only views of [`crate::views`].
    pub fn board_scene(&self, board_cam: &Iso3) -> ImageScene {
        let mut laser = self.laser();
        laser.peak = 0.0;
        self.board_world.image_scene(board_cam, laser)
    }

    /// Linear radiance of the board-only scene from `T_board_cam` (for fidelity tests):
    /// `(image, scene)`.
    pub fn render_board_linear(
        &self,
        board_cam: &Iso3,
    ) -> Result<(LinearImage, ImageScene), SimError> {
        let scene = self.board_scene(board_cam);
        Ok((self.renderer()?.render(&scene), scene))
    }

    /// A board image (board lit, laser off) from `T_board_cam`: the cheapest render of
    /// the twin (no laser: every pixel off an edge is one sample). `stream` selects the
    /// noise (the twin's seed, stream `stream`).
    pub fn render_board_image(&self, board_cam: &Iso3, stream: u64) -> Result<AnyGray, SimError> {
        let (lin, _) = self.render_board_linear(board_cam)?;
        Ok(form_image(
            &lin,
            &self.camera,
            &self.cfg.imaging,
            Exposure::Board,
            self.cfg.seed,
            stream,
        ))
    }

    /// Renders scan frame `index` at `q_deg` (stripe image only) with its truth.
    pub fn render_scan_frame(&self, q_deg: &[f64], index: usize) -> Result<ViewRender, SimError> {
        let (lin, scene) = self.render_linear(q_deg, true)?;
        let stream = 1_000_000 + index as u64;
        let (img, rgb) = if self.cfg.imaging.colour {
            let l = self.linear_rgb(q_deg, true, lin)?;
            self.expose(&l[0], Some(&l), Exposure::Laser, stream)?
        } else {
            self.expose(&lin, None, Exposure::Laser, stream)?
        };
        Ok(ViewRender {
            board_image: None,
            laser_image: Some(img),
            board_rgb: None,
            laser_rgb: rgb,
            circles: vec![],
            stripe: stripe_truth(&scene, &self.camera, self.direction),
            base_cam: self.base_cam(q_deg)?,
        })
    }

    /// The rig description written to rig.json (nominal robot).
    pub fn rig(&self) -> Result<Rig, SimError> {
        Ok(Rig {
            width: self.camera.width,
            height: self.camera.height,
            distortion_model: DistortionModel::from_name(&self.cfg.camera.distortion_model)?,
            board: self.board.clone(),
            robot: Some(self.robot_nominal.clone()),
            stripe_direction: StripeDirection::from_name(&self.cfg.stripe_direction)?,
            stripe_channel: self.cfg.stripe_channel_model()?,
        })
    }

    /// The true parameters as a Truth (no per-image keys).
    pub fn truth(&self, with_sphere: bool) -> Truth {
        let mut extra = serde_json::Map::new();
        extra.insert(
            "laser_emitter_mm".into(),
            json!([self.emitter.x, self.emitter.y, self.emitter.z]),
        );
        extra.insert("stripe_direction".into(), json!(self.direction.name()));
        extra.insert("table".into(), self.table_plane().to_json());
        extra.insert("plate".into(), self.plate_json());
        let mut cfg = serde_json::to_value(&self.cfg).unwrap_or(Value::Null);
        if !self.cfg.verify.enabled {
            // off: truth.json as before the knobs existed
            if let Some(m) = cfg.as_object_mut() {
                m.remove("verify");
            }
        }
        if !self.cfg.bench.enabled {
            // off: truth.json as before the bench mode existed
            if let Some(m) = cfg.as_object_mut() {
                m.remove("bench");
            }
        }
        if !self.cfg.profiler.enabled {
            // off: truth.json as before the profiler mode existed
            if let Some(m) = cfg.as_object_mut() {
                m.remove("profiler");
            }
        }
        if self.cfg.imaging.reflection_ratio == 0.0 {
            // no reflection: truth.json as before the knob existed
            if let Some(im) = cfg
                .as_object_mut()
                .and_then(|m| m.get_mut("imaging"))
                .and_then(|v| v.as_object_mut())
            {
                for k in crate::config::ImagingCfg::REFLECTION_KNOBS {
                    im.remove(k);
                }
            }
        }
        if !self.cfg.imaging.colour && self.cfg.stripe_channel.is_none() {
            // gray: truth.json as before the colour knobs existed
            if let Some(m) = cfg.as_object_mut() {
                m.remove("stripe_channel");
                if let Some(im) = m.get_mut("imaging").and_then(|v| v.as_object_mut()) {
                    for k in crate::config::ImagingCfg::COLOUR_KNOBS {
                        im.remove(k);
                    }
                }
            }
        }
        extra.insert("sim_config".into(), cfg);
        Truth {
            camera: self.camera.clone(),
            laser_plane: self.laser_plane,
            hand_cam: self.hand_cam,
            base_board: self.base_board,
            robot: Some(self.robot_true.clone()),
            sphere: if with_sphere { self.sphere } else { None },
            working_range_mm: Some(self.cfg.working_range_mm),
            extra,
        }
    }

    /// The exact observations of the calibration poses, as a detector would report them
    /// with no error: imaged-circle centres (area centroids of the projected outlines),
    /// stripe points on the board, and `T_base_hand` of the TRUE robot at the reported
    /// readings ([`Self::reported_q`]: the true ones unless `poses.reading_noise_deg`).
    /// For tests and benchmarks of the calibration from points.
    pub fn exact_observations(&self) -> Result<Vec<stripecal::calib::ViewObs>, SimError> {
        use stripecal::calib::{CircleObs, ViewObs};
        let mut out = Vec::new();
        for (i, p) in self.calibration_poses()?.iter().enumerate() {
            let scene = self.scene(&p.q_deg, false)?;
            let circles = target_truth(&scene, &self.camera, 0.0)
                .iter()
                .map(|c| CircleObs {
                    row: c.row,
                    col: c.col,
                    u: c.u,
                    v: c.v,
                })
                .collect();
            let stripe = stripe_truth(&scene, &self.camera, self.direction)
                .into_iter()
                .filter(|s| s.surface == "board")
                .map(|s| [s.u, s.v])
                .collect();
            out.push(ViewObs {
                view: i,
                circles,
                stripe,
                reading: Some(RobotReading::Joints(self.reported_q(i, &p.q_deg))),
                base_hand: Some(self.robot_true.forward(&self.reported_q(i, &p.q_deg))?),
                alternatives: Vec::new(),
                stripe_shape: None,
            });
        }
        Ok(out)
    }

    /// A calibration holding the TRUE parameters (for tests that reconstruct with truth).
    pub fn true_calibration(&self) -> Calibration {
        Calibration {
            camera: self.camera.clone(),
            laser_plane: Some(self.laser_plane),
            mount: stripecal::model::Mount::Robot,
            hand_cam: self.hand_cam,
            base_board: self.base_board,
            robot: Some(self.robot_true.clone()),
            quality: Default::default(),
            uncertainty: Default::default(),
            covariance: None,
            records: Default::default(),
            extra: Default::default(),
        }
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

/// `views` with Gaussian noise of `circle_px` added to each circle-centre coordinate and
/// `stripe_px` to each stripe-point coordinate, drawn from `rng` view by view (circles,
/// then stripe points; a zero sigma draws nothing). For tests and benchmarks of the
/// calibration from points (with [`Twin::exact_observations`]).
pub fn noisy_observations(
    views: &[stripecal::calib::ViewObs],
    circle_px: f64,
    stripe_px: f64,
    rng: &mut crate::rng::Rng,
) -> Vec<stripecal::calib::ViewObs> {
    use stripecal::calib::{CircleObs, ViewObs};
    views
        .iter()
        .map(|v| {
            let circles = if circle_px == 0.0 {
                v.circles.clone()
            } else {
                v.circles
                    .iter()
                    .map(|c| CircleObs {
                        u: c.u + circle_px * rng.normal(),
                        v: c.v + circle_px * rng.normal(),
                        ..*c
                    })
                    .collect()
            };
            let stripe = if stripe_px == 0.0 {
                v.stripe.clone()
            } else {
                v.stripe
                    .iter()
                    .map(|p| {
                        [
                            p[0] + stripe_px * rng.normal(),
                            p[1] + stripe_px * rng.normal(),
                        ]
                    })
                    .collect()
            };
            ViewObs {
                circles,
                stripe,
                ..v.clone()
            }
        })
        .collect()
}
