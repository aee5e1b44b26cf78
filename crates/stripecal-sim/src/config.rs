//! Every knob of the twin, as one serialisable configuration.
//!
//! A configuration is plain data (JSON from Python or the CLI): a preset gives all
//! values, and [`SimConfig::with_overrides`] merges a partial JSON object over it, so
//! `{"imaging": {"noise_gray": 2.0}}` changes one knob and keeps the rest. Unknown keys
//! are an error (a misspelt knob must not be silently ignored).
//!
//! Units: mm, degrees (angles in files), radians for rotation vectors, pixels,
//! gray levels of the 8-bit scale for noise (scaled by 257 for 16-bit images).

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use stripecal::model::geometry::{iso_from_rotvec, iso_to_rotvec, Iso3, Plane};
use stripecal::{Board, BoardKind, Camera, DhJoint, DistortionModel, Robot};

use crate::bench::BenchCfg;
use crate::profiler::ProfilerCfg;
use crate::robot_error::RobotErrorCfg;
use crate::verify::VerifyCfg;
use crate::SimError;

/// The camera (true values).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraCfg {
    pub width: u32,
    pub height: u32,
    pub fu: f64,
    pub fv: f64,
    pub u0: f64,
    pub v0: f64,
    /// `radial1`, `radial2` or `opencv5`: the model written to rig.json.
    pub distortion_model: String,
    /// `[k1, k2, p1, p2, k3]`.
    pub distortion: [f64; 5],
}

/// A rigid transform as in the spec's files.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseCfg {
    /// Radians.
    pub rotation_vector: [f64; 3],
    pub translation_mm: [f64; 3],
}

/// The laser plane `n . p = d` in the camera frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneCfg {
    pub normal: [f64; 3],
    pub d_mm: f64,
}

/// One DH row.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DhCfg {
    pub theta0_deg: f64,
    pub alpha_deg: f64,
    pub a_mm: f64,
    pub d_mm: f64,
    /// Hayati's tilt about the new y axis (spec/DATASET.md, "Robot (DH)"); default 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub beta_deg: f64,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// The robot's nominal DH table (written to rig.json).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotCfg {
    pub name: String,
    pub joints: Vec<DhCfg>,
}

/// The target (spec/DATASET.md, "Board" and "Target kinds").
///
/// Which knobs a kind uses:
/// - `circles`: `rows`, `cols`, `pitch_mm`, `circle_diameter_mm`, `markers`,
///   `marker_diameter_mm` (only when `markers` is not empty), `dark_circles`;
/// - `asymmetric_circles`: `rows`, `cols`, `pitch_mm` (between neighbours in a row),
///   `circle_diameter_mm`, `dark_circles`; it has no markers;
/// - `chessboard`: `rows`, `cols` (inner corners) and `square_mm` (`null`: `pitch_mm`);
///   the colours are the contract's (the square outside corner (0, 0) is dark).
///
/// The knobs a kind does not use are ignored, so switching the kind of a preset
/// (`--set board.kind=asymmetric_circles`) needs no other change; rig.json holds only
/// the ones the kind uses.
///
/// `plate_margin_mm` means the same for every kind: how far the plate reaches beyond
/// the OUTER TARGET POINTS (circle centres, a chessboard's outer inner corners) on each
/// side, so the plate is the points' bounding box grown by it. It must cover the
/// printed pattern: at least the largest circle radius for circle grids, and MORE than
/// `square_mm` for a chessboard (whose outer squares reach one square beyond its outer
/// corners); `plate_margin_mm - square_mm` is then the light border around the squares.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoardCfg {
    /// `circles` (default), `asymmetric_circles` or `chessboard`.
    #[serde(default = "default_board_kind")]
    pub kind: String,
    /// Grid rows: circles, or a chessboard's inner corners along board y.
    pub rows: usize,
    /// Grid columns: circles, or a chessboard's inner corners along board x.
    pub cols: usize,
    /// Circle kinds: centre distance between neighbours in a row, mm.
    pub pitch_mm: f64,
    pub circle_diameter_mm: f64,
    pub marker_diameter_mm: f64,
    pub markers: Vec<[usize; 2]>,
    pub dark_circles: bool,
    /// Chessboards: the square side, mm (`null`: `pitch_mm`).
    #[serde(default)]
    pub square_mm: Option<f64>,
    /// Plate beyond the outer target points, mm (each side); see the type's docs.
    pub plate_margin_mm: f64,
    /// Thickness of the plate (or sheet) the target is printed on: the table lies this
    /// far behind the printed surface, a depth step where the plate ends, mm (default
    /// [`crate::dataset::PLATE_THICKNESS_MM`]).
    #[serde(default = "default_plate_thickness")]
    pub plate_thickness_mm: f64,
}

fn default_board_kind() -> String {
    BoardKind::Circles.name().into()
}

fn default_plate_thickness() -> f64 {
    crate::dataset::PLATE_THICKNESS_MM
}

/// How calibration poses are chosen.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PosesCfg {
    /// Number of calibration views.
    pub count: usize,
    /// Encoder readings (deg) of the home pose around which poses are sampled.
    pub home_q_deg: Vec<f64>,
    /// Stand-off range: distance from the camera centre to the board plane along the
    /// optical axis, mm.
    pub standoff_mm: [f64; 2],
    /// Largest angle between the optical axis and the board normal, degrees.
    pub max_tilt_deg: f64,
    /// Largest rotation about the optical axis away from the board's upright view, deg.
    pub max_roll_deg: f64,
    /// Largest joint excursion from home, degrees.
    pub max_joint_delta_deg: f64,
    /// Every circle must be at least this far inside the image, px.
    pub margin_px: f64,
    /// Largest angle of incidence of the laser sheet on the board (at the stripe's
    /// middle), degrees: a grazing stripe is wide and faint.
    pub max_laser_incidence_deg: f64,
    /// Explicit encoder readings (deg) per view; when given, no sampling happens.
    pub explicit_q_deg: Option<Vec<Vec<f64>>>,
    /// Poses with the stripe BESIDE the printed pattern: mostly on the plate around it
    /// and crossing the plate's edge onto the table ([`crate::poses::StripeLayout`]),
    /// instead of across the pattern (default `false`).
    #[serde(default)]
    pub stripe_beside_pattern: bool,
    /// One-sigma (degrees) of Gaussian noise added to every joint reading of the
    /// calibration views as views.csv gives them (and [`crate::Twin::exact_observations`]'s
    /// robot poses), drawn per view from the seed; the images are rendered at the true
    /// readings: a robot whose readings are off (repeatability, encoder noise), the
    /// robot-pose noise the calibration estimates. truth.json's `images` then hold the
    /// reported readings too (`q_reading_deg`). The scan's readings stay exact. Default 0.
    #[serde(default)]
    pub reading_noise_deg: f64,
    /// How sampled poses spread: `local` (the default: around the home pose, diverse in
    /// orientation) or `wide` (many feasible candidates over the allowed joint
    /// excursions, then the `count` farthest apart in joint space, each joint's
    /// excursion normalised by `max_joint_delta_deg`: [`crate::poses_wide`]).
    #[serde(default = "default_spread")]
    pub spread: String,
}

fn default_spread() -> String {
    "local".into()
}

/// Image formation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImagingCfg {
    /// 8 or 16.
    pub bit_depth: u8,
    /// Samples per pixel side (>= 4); pixels on a reflectance edge get 4x more per side.
    pub supersample: usize,
    /// Ambient illumination of board images (fraction of full scale on a reflectance-1 surface).
    pub ambient: f64,
    /// Ambient of laser images (dimmed), same unit.
    pub laser_ambient: f64,
    /// One image per view holding both circles and stripe.
    pub single_image: bool,
    /// Ambient of single images.
    pub single_image_ambient: f64,
    pub plate_reflectance: f64,
    pub circle_reflectance: f64,
    pub table_reflectance: f64,
    pub sphere_reflectance: f64,
    /// Relative fall-off at the image corners (0 = none): `1 - v * (r / r_corner)^2`.
    pub vignetting: f64,
    /// Gaussian PSF sigma, px (0 = none).
    pub psf_sigma_px: f64,
    /// Read noise sigma in gray levels of the 8-bit scale (x257 for 16-bit).
    pub noise_gray: f64,
    /// Full-well capacity in electrons for photon (shot) noise; 0 disables it.
    pub full_well_e: f64,
    /// Laser peak radiance on a reflectance-1 surface at normal incidence, fraction of
    /// full scale (> 1 saturates).
    pub laser_peak: f64,
    /// Gaussian sigma of the laser sheet's thickness, mm.
    pub laser_sigma_mm: f64,
    /// Laser emitter position in the camera frame (on the laser plane); `None` puts it
    /// at the foot of the perpendicular from the camera centre to the plane.
    pub laser_emitter_mm: Option<[f64; 3]>,
    /// Speckle contrast (std of the multiplicative factor), 0 = none.
    pub speckle_contrast: f64,
    /// Speckle grain size (Gaussian correlation sigma), px.
    pub speckle_grain_px: f64,
    /// A reflection of the laser line (a shiny part of the scene): a second, weaker
    /// copy of the laser light, this fraction of it (0: none), displaced in the image by
    /// `reflection_offset_px` (whole pixels, x then y). Not part of the stripe's truth.
    #[serde(default)]
    pub reflection_ratio: f64,
    #[serde(default = "default_reflection_offset")]
    pub reflection_offset_px: [i32; 2],
    /// Colour images: the calibration views and the ball scan are rendered as RGB
    /// (written as RGB PNGs) from per-channel reflectances, ambient and laser colour,
    /// with independent noise of `noise_gray` in each channel (default `false`: gray).
    #[serde(default)]
    pub colour: bool,
    /// Colour images: the laser's colour, `"red"`, `"green"` or `"blue"`: its light is
    /// in that channel only, at `laser_peak`.
    #[serde(default = "default_laser_colour")]
    pub laser_colour: String,
    /// Colour images: the ambient light's level per channel (R, G, B), relative to
    /// `ambient`, `laser_ambient` and `single_image_ambient` (`[1, 1, 1]`: white
    /// daylight).
    #[serde(default = "default_white")]
    pub ambient_rgb: [f64; 3],
    /// Colour images: the plate's reflectance per channel; `None`: `plate_reflectance`
    /// in every channel (white).
    #[serde(default)]
    pub plate_rgb: Option<[f64; 3]>,
    /// Colour images: the printed features' (circles', squares') reflectance per
    /// channel; `None`: `circle_reflectance` in every channel (black ink).
    #[serde(default)]
    pub ink_rgb: Option<[f64; 3]>,
}

fn default_reflection_offset() -> [i32; 2] {
    [40, 0]
}

fn default_laser_colour() -> String {
    "red".into()
}

fn default_white() -> [f64; 3] {
    [1.0; 3]
}

impl ImagingCfg {
    /// The laser colour's channel (0 red, 1 green, 2 blue).
    pub fn laser_channel(&self) -> Result<usize, SimError> {
        match self.laser_colour.as_str() {
            "red" => Ok(0),
            "green" => Ok(1),
            "blue" => Ok(2),
            other => Err(SimError::Config(format!(
                "imaging.laser_colour: {other:?} (expected \"red\", \"green\" or \"blue\")"
            ))),
        }
    }

    /// The reflection's knobs, as truth.json's sim_config leaves them out of twins
    /// without one (so their truth.json is what it was before they existed).
    pub const REFLECTION_KNOBS: [&'static str; 2] = ["reflection_ratio", "reflection_offset_px"];

    /// The knobs of colour images, as truth.json's sim_config leaves them out of gray
    /// twins (so a gray twin's truth.json is what it was before they existed).
    pub const COLOUR_KNOBS: [&'static str; 5] = [
        "colour",
        "laser_colour",
        "ambient_rgb",
        "plate_rgb",
        "ink_rgb",
    ];
}

/// The ball scan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScanCfg {
    /// Render a scan at all.
    pub enabled: bool,
    pub sphere_diameter_mm: f64,
    /// Sphere position on the table relative to the board centre, along the board's x
    /// and y axes, mm.
    pub sphere_offset_mm: [f64; 2],
    /// Sensor translation between frames, mm.
    pub step_mm: f64,
    /// Extra travel before and after the ball, mm (along the sweep).
    pub margin_mm: f64,
    /// Depth (camera z) of the ball's top at the middle of the sweep, mm.
    pub top_depth_mm: f64,
    /// Cap on the number of frames (0 = no cap): the sweep is shortened symmetrically.
    pub max_frames: usize,
    /// Also render a sweep over the bare table (`scan_table/`, the format of `scan/`),
    /// away from the board and the ball, at poses not used in calibration (default
    /// `false`; [`crate::table_scan`]).
    #[serde(default)]
    pub table: bool,
    /// Where the table sweep's middle lies on the table relative to the board centre,
    /// along the board's x and y axes, mm.
    #[serde(default = "default_table_offset")]
    pub table_offset_mm: [f64; 2],
}

fn default_table_offset() -> [f64; 2] {
    crate::table_scan::DEFAULT_TABLE_OFFSET_MM
}

/// Everything the twin needs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    pub preset: String,
    pub seed: u64,
    pub camera: CameraCfg,
    pub laser_plane: PlaneCfg,
    pub hand_cam: PoseCfg,
    /// `T_base_board`; `None` places the board on the table where the home pose sees
    /// it at the middle of the stand-off range.
    pub base_board: Option<PoseCfg>,
    /// Nominal robot (rig.json).
    pub robot: RobotCfg,
    /// True-minus-nominal DH errors per joint `[d_theta0_deg, d_alpha_deg, d_a_mm, d_d_mm]`;
    /// empty = none.
    pub dh_errors: Vec<[f64; 4]>,
    /// One-sigma of random DH errors drawn per joint from the seed and added to the
    /// true robot (on top of `dh_errors`); default none ([`crate::robot_error`]).
    #[serde(default)]
    pub robot_error: RobotErrorCfg,
    pub board: BoardCfg,
    pub poses: PosesCfg,
    pub imaging: ImagingCfg,
    pub scan: ScanCfg,
    /// Stand-offs the rig is meant for (truth.json `working_range_mm`).
    pub working_range_mm: [f64; 2],
    /// rig.json `stripe.direction` hint: `auto`, `rows` or `cols`.
    pub stripe_direction: String,
    /// rig.json `stripe.channel`: `gray`, `red`, `green`, `blue` or `auto`; `None` (the
    /// default): the laser's colour for colour images (`imaging.colour`), gray otherwise.
    #[serde(default)]
    pub stripe_channel: Option<String>,
    /// How views.csv and scan.csv give the robot poses: `None` (the default) writes the
    /// encoder readings `q1..qN`; a pose convention writes the flange pose a controller
    /// would report instead, the NOMINAL robot's forward kinematics of the readings, in
    /// those columns: a shorthand (`ros`, `ur`, `kuka`, `fanuc`, `quaternion`, `rotvec`,
    /// `rotvec_deg`, `matrix`) or a header such as `"qx,qy,qz,qw,x_m,y_m,z_m"`
    /// (`stripecal::io::PoseColumns::from_spec`). rig.json keeps the robot either way.
    #[serde(default)]
    pub pose_columns: Option<String>,
    /// Verification artefacts: ball bar and plate scans with their certificate
    /// (`verify/`, default off; [`crate::verify`]).
    #[serde(default)]
    pub verify: VerifyCfg,
    /// The bench mode: a fixed sensor, the board placed by hand, no robot (default off;
    /// [`crate::bench`]).
    #[serde(default)]
    pub bench: BenchCfg,
    /// The profiler mode: a calibrated line profiler measuring a reference sphere
    /// (default off; [`crate::profiler`]).
    #[serde(default)]
    pub profiler: ProfilerCfg,
}

/// Names of the built-in presets.
pub const PRESETS: [&str; 6] = [
    "hp3-paper",
    "hp3-wide",
    "hp3-chessboard",
    "hp3-asymmetric",
    "hp3-sheet",
    "hp3-profiler",
];

impl SimConfig {
    /// A built-in preset by name.
    pub fn preset(name: &str) -> Result<SimConfig, SimError> {
        match name {
            "hp3-paper" => Ok(Self::hp3_paper()),
            "hp3-wide" => Ok(Self::hp3_wide()),
            "hp3-chessboard" => Ok(Self::hp3_chessboard()),
            "hp3-asymmetric" => Ok(Self::hp3_asymmetric()),
            "hp3-sheet" => Ok(Self::hp3_sheet()),
            "hp3-profiler" => Ok(Self::hp3_profiler()),
            other => Err(SimError::Config(format!(
                "unknown preset {other:?}; presets: {}",
                PRESETS.join(", ")
            ))),
        }
    }

    /// The paper's rig: camera, laser plane and hand-eye X from Table 2 (read as
    /// ERRATA.md says), Table 1's robot, 5 poses, the 8 x 11 board, the 44.8614 mm ball.
    pub fn hp3_paper() -> SimConfig {
        let hp3 = Robot::hp3();
        SimConfig {
            preset: "hp3-paper".into(),
            seed: 0,
            camera: CameraCfg {
                width: 768,
                height: 576,
                fu: 1271.65,
                fv: 1322.52,
                u0: 346.14,
                v0: 262.60,
                distortion_model: "radial1".into(),
                distortion: [0.0002, 0.0, 0.0, 0.0, 0.0],
            },
            laser_plane: PlaneCfg {
                normal: [0.6290, -0.0492, 0.7759],
                d_mm: 79.8728,
            },
            hand_cam: PoseCfg {
                rotation_vector: [-0.3087, 0.2362, 3.0369],
                translation_mm: [29.19, 5.37, 62.64],
            },
            base_board: None,
            robot: RobotCfg {
                name: hp3.name.clone(),
                joints: hp3
                    .joints
                    .iter()
                    .map(|j| DhCfg {
                        theta0_deg: j.theta0_deg,
                        alpha_deg: j.alpha_deg,
                        a_mm: j.a_mm,
                        d_mm: j.d_mm,
                        beta_deg: j.beta_deg,
                    })
                    .collect(),
            },
            dh_errors: vec![],
            robot_error: RobotErrorCfg::default(),
            board: BoardCfg {
                kind: BoardKind::Circles.name().into(),
                rows: 8,
                cols: 11,
                pitch_mm: 5.0,
                circle_diameter_mm: 2.5,
                marker_diameter_mm: 3.5,
                markers: Board::default_markers(),
                dark_circles: true,
                square_mm: None,
                plate_margin_mm: 4.0,
                plate_thickness_mm: crate::dataset::PLATE_THICKNESS_MM,
            },
            poses: PosesCfg {
                count: 5,
                home_q_deg: vec![0.0, 0.0, 0.0, 0.0, -90.0, 0.0],
                standoff_mm: [100.0, 125.0],
                max_tilt_deg: 30.0,
                max_roll_deg: 10.0,
                max_joint_delta_deg: 60.0,
                margin_px: 12.0,
                max_laser_incidence_deg: 65.0,
                explicit_q_deg: None,
                stripe_beside_pattern: false,
                reading_noise_deg: 0.0,
                spread: default_spread(),
            },
            imaging: ImagingCfg {
                bit_depth: 8,
                supersample: 4,
                ambient: 0.8,
                laser_ambient: 0.08,
                single_image: false,
                single_image_ambient: 0.4,
                plate_reflectance: 0.9,
                circle_reflectance: 0.08,
                table_reflectance: 0.35,
                sphere_reflectance: 0.7,
                vignetting: 0.15,
                psf_sigma_px: 0.7,
                noise_gray: 1.0,
                full_well_e: 0.0,
                laser_peak: 0.85,
                laser_sigma_mm: 0.12,
                laser_emitter_mm: None,
                speckle_contrast: 0.0,
                speckle_grain_px: 1.0,
                reflection_ratio: 0.0,
                reflection_offset_px: default_reflection_offset(),
                colour: false,
                laser_colour: default_laser_colour(),
                ambient_rgb: default_white(),
                plate_rgb: None,
                ink_rgb: None,
            },
            scan: ScanCfg {
                enabled: true,
                sphere_diameter_mm: 44.8614,
                sphere_offset_mm: [0.0, 90.0],
                step_mm: 0.5,
                margin_mm: 3.0,
                top_depth_mm: 88.0,
                max_frames: 0,
                table: false,
                table_offset_mm: default_table_offset(),
            },
            working_range_mm: [80.0, 130.0],
            stripe_direction: "auto".into(),
            stripe_channel: None,
            pose_columns: None,
            verify: VerifyCfg::default(),
            bench: BenchCfg::default(),
            profiler: ProfilerCfg::default(),
        }
    }

    /// The same robot with a wider-angle, more distorted camera and 15 poses: a
    /// different lens for tests that must not be tuned to the paper's camera.
    pub fn hp3_wide() -> SimConfig {
        let mut c = Self::hp3_paper();
        c.preset = "hp3-wide".into();
        c.camera = CameraCfg {
            width: 1024,
            height: 768,
            fu: 900.0,
            fv: 900.5,
            u0: 515.3,
            v0: 380.8,
            distortion_model: "radial2".into(),
            distortion: [-0.25, 0.12, 0.0, 0.0, 0.0],
        };
        c.poses.count = 15;
        c.poses.standoff_mm = [95.0, 125.0];
        c
    }

    /// The paper's rig (`hp3-paper`: camera, robot, poses, laser, scan) with a
    /// chessboard of 7 x 10 inner corners and 4.8 mm squares. Its printed pattern (11 x
    /// 8 squares, 52.8 x 38.4 mm) is the size of the paper board's (53.5 x 38.5 mm over
    /// the outer circles' edges), so the same poses see it as fully; a square is ~54 px
    /// at the nominal stand-off. rows + cols is odd, so the colours fix the board's
    /// orientation. The plate reaches 10 mm beyond the outer corners: a 5.2 mm light
    /// border (more than a square) around the squares.
    pub fn hp3_chessboard() -> SimConfig {
        let mut c = Self::hp3_paper();
        c.preset = "hp3-chessboard".into();
        c.board = BoardCfg {
            kind: BoardKind::Chessboard.name().into(),
            rows: 7,
            cols: 10,
            pitch_mm: 4.8,
            circle_diameter_mm: 0.0,
            marker_diameter_mm: 0.0,
            markers: vec![],
            dark_circles: true,
            square_mm: Some(4.8),
            plate_margin_mm: 10.0,
            plate_thickness_mm: crate::dataset::PLATE_THICKNESS_MM,
        };
        c
    }

    /// The paper's rig with an asymmetric circle grid: 11 rows of 8 circles (88, like
    /// the paper board), pitch 7 mm along a row (neighbours 4.95 mm apart), circles of
    /// 2.5 mm (~28 px across at the nominal stand-off, ~19 px at 1.5x it). The centres
    /// span 52.5 x 35 mm (the paper board's: 50 x 35 mm), the aspect of the 4:3 image.
    /// An odd number of rows: the grid fixes its own orientation (an even one is the same
    /// after a half turn).
    pub fn hp3_asymmetric() -> SimConfig {
        let mut c = Self::hp3_paper();
        c.preset = "hp3-asymmetric".into();
        c.board = BoardCfg {
            kind: BoardKind::AsymmetricCircles.name().into(),
            rows: 11,
            cols: 8,
            pitch_mm: 7.0,
            circle_diameter_mm: 2.5,
            marker_diameter_mm: 2.5,
            markers: vec![],
            dark_circles: true,
            square_mm: None,
            plate_margin_mm: 4.0,
            plate_thickness_mm: crate::dataset::PLATE_THICKNESS_MM,
        };
        c
    }

    /// The paper's robot, camera and laser with the target of many real cells: a
    /// chessboard (8 x 9 inner corners, 10 x 9 squares of 4 mm: 40 x 36 mm) printed on a
    /// white sheet much larger than the pattern (it reaches 5 pitches, 20 mm, beyond the
    /// outer corners: a 16 mm white border around the squares) lying 4 mm above the table
    /// (a visible depth step where the sheet ends), the laser in the same image as the
    /// board (`imaging.single_image`), and 15 poses with the stripe BESIDE the pattern:
    /// mostly on the sheet, crossing the sheet's edge onto the table
    /// (`poses.stripe_beside_pattern`). The pattern then fills only part of each image, so
    /// the poses tilt up to 40 deg and turn up to 90 deg about the optical axis to keep the
    /// camera (and through it the plane and hand-eye) as well determined as the other
    /// presets'. rows + cols is odd: the colours fix the board's orientation. No scan.
    pub fn hp3_sheet() -> SimConfig {
        let mut c = Self::hp3_paper();
        c.preset = "hp3-sheet".into();
        c.board = BoardCfg {
            kind: BoardKind::Chessboard.name().into(),
            rows: 8,
            cols: 9,
            pitch_mm: 4.0,
            circle_diameter_mm: 0.0,
            marker_diameter_mm: 0.0,
            markers: vec![],
            dark_circles: true,
            square_mm: Some(4.0),
            plate_margin_mm: 20.0,
            plate_thickness_mm: 4.0,
        };
        c.imaging.single_image = true;
        c.poses.count = 15;
        c.poses.stripe_beside_pattern = true;
        c.poses.max_tilt_deg = 40.0;
        c.poses.max_roll_deg = 90.0;
        c.scan.enabled = false;
        // As a real rig says (the sheet's edge and the table give a second stripe beside
        // the first on some rows, which can mislead the automatic choice).
        c.stripe_direction = "cols".into();
        c
    }

    /// The HP3 robot carrying a calibrated line PROFILER (issue 18; [`crate::profiler`]):
    /// 15 views of an 80 mm sphere on a 20 mm stand 60 mm above the table, a 90 mm line of
    /// 3000 samples, measuring range 150..350 mm, 0.01 mm noise, 2 % dropouts, 1 % spikes,
    /// joint readings in views.csv, a 60-frame scan. The camera, board and ball scan of
    /// the paper's rig are unused (the scan is off).
    pub fn hp3_profiler() -> SimConfig {
        let mut c = Self::hp3_paper();
        c.preset = "hp3-profiler".into();
        c.scan.enabled = false;
        c.profiler = ProfilerCfg {
            enabled: true,
            ..ProfilerCfg::default()
        };
        c
    }

    /// Merges a partial JSON object over this configuration (nested objects merge,
    /// everything else replaces); unknown keys are an error.
    pub fn with_overrides(&self, overrides: &serde_json::Value) -> Result<SimConfig, SimError> {
        let mut base = serde_json::to_value(self).map_err(|e| SimError::Config(e.to_string()))?;
        merge(&mut base, overrides, "")?;
        let cfg: SimConfig = serde_json::from_value(base)
            .map_err(|e| SimError::Config(format!("invalid configuration: {e}")))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Checks every value; the message names the knob.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |k: &str, m: String| Err(SimError::Config(format!("{k}: {m}")));
        self.camera_model()?;
        self.board_model()?;
        self.robot_nominal()?;
        self.laser_plane_model()?;
        if !self.dh_errors.is_empty() && self.dh_errors.len() != self.robot.joints.len() {
            return bad(
                "dh_errors",
                format!(
                    "{} rows given, robot has {} joints",
                    self.dh_errors.len(),
                    self.robot.joints.len()
                ),
            );
        }
        if self.poses.home_q_deg.len() != self.robot.joints.len() {
            return bad(
                "poses.home_q_deg",
                format!(
                    "{} values given, robot has {} joints",
                    self.poses.home_q_deg.len(),
                    self.robot.joints.len()
                ),
            );
        }
        if let Some(ex) = &self.poses.explicit_q_deg {
            if let Some((i, q)) = ex
                .iter()
                .enumerate()
                .find(|(_, q)| q.len() != self.robot.joints.len())
            {
                return bad(
                    "poses.explicit_q_deg",
                    format!(
                        "view {i} has {} values, robot has {} joints",
                        q.len(),
                        self.robot.joints.len()
                    ),
                );
            }
        } else if self.poses.count < 1 {
            return bad("poses.count", "must be at least 1".into());
        }
        let rn = self.poses.reading_noise_deg;
        if !(rn.is_finite() && rn >= 0.0) {
            return bad(
                "poses.reading_noise_deg",
                format!("{rn} must be finite and >= 0"),
            );
        }
        if !matches!(self.poses.spread.as_str(), "local" | "wide") {
            return bad(
                "poses.spread",
                format!("{:?} (expected \"local\" or \"wide\")", self.poses.spread),
            );
        }
        self.robot_error.validate()?;
        let [a, b] = self.poses.standoff_mm;
        if !(a > 0.0 && b >= a) {
            return bad(
                "poses.standoff_mm",
                format!("[{a}, {b}] is not a range of positive distances"),
            );
        }
        let im = &self.imaging;
        if im.bit_depth != 8 && im.bit_depth != 16 {
            return bad(
                "imaging.bit_depth",
                format!("{} (expected 8 or 16)", im.bit_depth),
            );
        }
        if im.supersample < 4 || im.supersample > 32 {
            return bad(
                "imaging.supersample",
                format!("{} (expected 4..=32)", im.supersample),
            );
        }
        for (k, v) in [
            ("imaging.psf_sigma_px", im.psf_sigma_px),
            ("imaging.noise_gray", im.noise_gray),
            ("imaging.full_well_e", im.full_well_e),
            ("imaging.speckle_contrast", im.speckle_contrast),
            ("imaging.ambient", im.ambient),
            ("imaging.laser_ambient", im.laser_ambient),
            ("imaging.laser_peak", im.laser_peak),
            ("imaging.vignetting", im.vignetting),
            ("imaging.reflection_ratio", im.reflection_ratio),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(k, format!("{v} must be finite and >= 0"));
            }
        }
        if im.laser_sigma_mm.is_nan()
            || im.laser_sigma_mm <= 0.0
            || im.speckle_grain_px.is_nan()
            || im.speckle_grain_px <= 0.0
        {
            return bad(
                "imaging.laser_sigma_mm",
                "laser sigma and speckle grain must be > 0".into(),
            );
        }
        if im.vignetting >= 1.0 {
            return bad(
                "imaging.vignetting",
                format!("{} must be < 1", im.vignetting),
            );
        }
        let t = self.board.plate_thickness_mm;
        if !(t.is_finite() && t >= 0.0) {
            return bad(
                "board.plate_thickness_mm",
                format!("{t} must be finite and >= 0"),
            );
        }
        if (self.scan.enabled || self.scan.table)
            && !(self.scan.step_mm > 0.0 && self.scan.sphere_diameter_mm > 0.0)
        {
            return bad("scan", "step_mm and sphere_diameter_mm must be > 0".into());
        }
        stripecal::model::StripeDirection::from_name(&self.stripe_direction)
            .map_err(|e| SimError::Config(format!("stripe_direction: {e}")))?;
        self.stripe_channel_model()?;
        im.laser_channel()?;
        for (k, v) in [
            ("imaging.ambient_rgb", Some(im.ambient_rgb)),
            ("imaging.plate_rgb", im.plate_rgb),
            ("imaging.ink_rgb", im.ink_rgb),
        ] {
            if let Some(v) = v {
                if v.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
                    return bad(k, format!("{v:?} must be finite and >= 0"));
                }
            }
        }
        self.pose_columns_model()?;
        self.verify.validate()?;
        self.bench.validate()?;
        if self.profiler.enabled {
            if self.bench.enabled {
                return bad(
                    "profiler.enabled",
                    "the profiler and bench modes exclude each other".into(),
                );
            }
            self.profiler.validate()?;
        }
        Ok(())
    }

    /// rig.json's `stripe.channel` (see [`SimConfig::stripe_channel`]).
    pub fn stripe_channel_model(&self) -> Result<stripecal::model::StripeChannel, SimError> {
        use stripecal::model::StripeChannel;
        match &self.stripe_channel {
            Some(name) => StripeChannel::from_name(name)
                .map_err(|e| SimError::Config(format!("stripe_channel: {e}"))),
            None if self.imaging.colour => {
                Ok(StripeChannel::ALL[1 + self.imaging.laser_channel()?])
            }
            None => Ok(StripeChannel::Gray),
        }
    }

    /// The flange-pose columns of views.csv and scan.csv, `None` for joint readings.
    pub fn pose_columns_model(&self) -> Result<Option<stripecal::io::PoseColumns>, SimError> {
        self.pose_columns
            .as_deref()
            .map(|spec| {
                stripecal::io::PoseColumns::from_spec(&[spec])
                    .map_err(|e| SimError::Config(format!("pose_columns: {e}")))
            })
            .transpose()
    }

    /// The true camera.
    pub fn camera_model(&self) -> Result<Camera, SimError> {
        let c = &self.camera;
        let model = DistortionModel::from_name(&c.distortion_model)
            .map_err(|e| SimError::Config(format!("camera.distortion_model: {e}")))?;
        Camera::new(
            c.width,
            c.height,
            c.fu,
            c.fv,
            c.u0,
            c.v0,
            model,
            c.distortion,
        )
        .map_err(|e| SimError::Config(format!("camera: {e}")))
    }

    /// The true laser plane (camera frame).
    pub fn laser_plane_model(&self) -> Result<Plane, SimError> {
        let p = &self.laser_plane;
        Plane::new(Vector3::from(p.normal), p.d_mm)
            .map_err(|e| SimError::Config(format!("laser_plane: {e}")))
    }

    /// The true hand-eye `T_hand_cam`.
    pub fn hand_cam_model(&self) -> Iso3 {
        pose_model(&self.hand_cam)
    }

    /// The board of `board.kind` (see [`BoardCfg`] for the knobs each kind uses), with
    /// its plate margin checked.
    pub fn board_model(&self) -> Result<Board, SimError> {
        let b = &self.board;
        let kind = BoardKind::from_name(&b.kind)
            .map_err(|e| SimError::Config(format!("board.kind: {e}")))?;
        let board = match kind {
            BoardKind::Circles => Board {
                kind,
                rows: b.rows,
                cols: b.cols,
                pitch_mm: b.pitch_mm,
                circle_diameter_mm: b.circle_diameter_mm,
                marker_diameter_mm: b.marker_diameter_mm,
                markers: b.markers.clone(),
                dark_circles: b.dark_circles,
                square_mm: None,
            },
            BoardKind::AsymmetricCircles => Board {
                dark_circles: b.dark_circles,
                ..Board::asymmetric_circles(b.rows, b.cols, b.pitch_mm, b.circle_diameter_mm)
                    .map_err(|e| SimError::Config(format!("board: {e}")))?
            },
            BoardKind::Chessboard => {
                Board::chessboard(b.rows, b.cols, b.square_mm.unwrap_or(b.pitch_mm))
                    .map_err(|e| SimError::Config(format!("board: {e}")))?
            }
        };
        board
            .validate()
            .map_err(|e| SimError::Config(format!("board: {e}")))?;
        crate::target::check_plate_margin(&board, b.plate_margin_mm)
            .map_err(|m| SimError::Config(format!("board.plate_margin_mm: {m}")))?;
        Ok(board)
    }

    /// The nominal robot (rig.json).
    pub fn robot_nominal(&self) -> Result<Robot, SimError> {
        let joints = self
            .robot
            .joints
            .iter()
            .map(|j| DhJoint {
                theta0_deg: j.theta0_deg,
                alpha_deg: j.alpha_deg,
                a_mm: j.a_mm,
                d_mm: j.d_mm,
                beta_deg: j.beta_deg,
            })
            .collect();
        Robot::new(self.robot.name.clone(), joints)
            .map_err(|e| SimError::Config(format!("robot: {e}")))
    }

    /// The true robot: nominal plus `dh_errors` plus the random errors of
    /// `robot_error` drawn from the seed ([`crate::robot_error::draw`]).
    pub fn robot_true(&self) -> Result<Robot, SimError> {
        let mut r = self.robot_nominal()?;
        for (j, e) in r.joints.iter_mut().zip(&self.dh_errors) {
            j.theta0_deg += e[0];
            j.alpha_deg += e[1];
            j.a_mm += e[2];
            j.d_mm += e[3];
        }
        if !self.robot_error.is_zero() {
            let nominal = self.robot_nominal()?;
            let draws = crate::robot_error::draw(&self.robot_error, &nominal, self.seed);
            for (j, e) in r.joints.iter_mut().zip(&draws) {
                j.theta0_deg += e.theta0_deg;
                j.alpha_deg += e.alpha_deg;
                j.a_mm += e.a_mm;
                j.d_mm += e.d_mm;
                j.beta_deg += e.beta_deg;
            }
            Robot::new(r.name.clone(), r.joints.clone())
                .map_err(|e| SimError::Config(format!("robot_error: {e}")))?;
        }
        Ok(r)
    }
}

/// A pose from its file form.
pub fn pose_model(p: &PoseCfg) -> Iso3 {
    iso_from_rotvec(
        &Vector3::from(p.rotation_vector),
        &Vector3::from(p.translation_mm),
    )
}

/// The file form of a pose.
pub fn pose_cfg(t: &Iso3) -> PoseCfg {
    let (r, tr) = iso_to_rotvec(t);
    PoseCfg {
        rotation_vector: [r.x, r.y, r.z],
        translation_mm: [tr.x, tr.y, tr.z],
    }
}

fn merge(
    base: &mut serde_json::Value,
    over: &serde_json::Value,
    path: &str,
) -> Result<(), SimError> {
    match (base, over) {
        (serde_json::Value::Object(b), serde_json::Value::Object(o)) => {
            for (k, v) in o {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                match b.get_mut(k) {
                    Some(slot) if slot.is_object() && v.is_object() => merge(slot, v, &p)?,
                    Some(slot) => *slot = v.clone(),
                    None => {
                        return Err(SimError::Config(format!(
                            "unknown knob `{p}`; known keys here: {}",
                            b.keys().cloned().collect::<Vec<_>>().join(", ")
                        )))
                    }
                }
            }
            Ok(())
        }
        (_, _) => Err(SimError::Config(format!(
            "overrides must be a JSON object{}",
            if path.is_empty() {
                String::new()
            } else {
                format!(" at `{path}`")
            }
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_validate_and_overrides_merge() {
        for p in PRESETS {
            SimConfig::preset(p).unwrap().validate().unwrap();
        }
        let c = SimConfig::hp3_paper()
            .with_overrides(&serde_json::json!({"imaging": {"noise_gray": 2.5}, "seed": 9}))
            .unwrap();
        assert_eq!(c.imaging.noise_gray, 2.5);
        assert_eq!(c.seed, 9);
        assert_eq!(c.imaging.psf_sigma_px, 0.7);
        let e = SimConfig::hp3_paper()
            .with_overrides(&serde_json::json!({"imaging": {"nosie": 1}}))
            .unwrap_err();
        assert!(e.to_string().contains("imaging.nosie"), "{e}");
        let e = SimConfig::hp3_paper()
            .with_overrides(&serde_json::json!({"imaging": {"bit_depth": 12}}))
            .unwrap_err();
        assert!(e.to_string().contains("bit_depth"), "{e}");
    }
}
