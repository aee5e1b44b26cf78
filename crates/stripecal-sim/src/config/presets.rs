//! The twin's built-in presets: complete configurations by name.

use stripecal::{Board, BoardKind, Robot};

use super::imaging::{default_laser_colour, default_reflection_offset, default_white};
use super::poses::default_spread;
use super::scan::default_table_offset;
use super::{
    BoardCfg, CameraCfg, DhCfg, ImagingCfg, PlaneCfg, PoseCfg, PosesCfg, RobotCfg, ScanCfg,
    SimConfig,
};
use crate::bench::BenchCfg;
use crate::profiler::ProfilerCfg;
use crate::robot_error::RobotErrorCfg;
use crate::verify::VerifyCfg;
use crate::SimError;

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
                model: None,
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
            model: None,
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
}
