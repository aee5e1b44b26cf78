//! `stripecal._core.record_keys()`: the keys calibration.json's records are written
//! with, per record (named as `stripecal.types` names its TypedDict), taken from the
//! core's writers on a sample of each record with every optional part present. The
//! Python record types are checked against it (`tests/test_record_types.py`), so the
//! two cannot drift.

use std::collections::BTreeMap;

use pyo3::prelude::*;
use serde_json::{Map, Value};
use stripecal::io::{
    board_scale_to_json, calibration_extra_keys, leave_one_out_to_json, profiler_records_to_json,
    robot_calibration_to_json, robot_pose_noise_to_json, summary_to_json, view_record_to_json,
};
use stripecal::model::camera::{Camera, DistortionModel, Intrinsics};
use stripecal::model::geometry::{Iso3, Plane};
use stripecal::model::kinematics::Robot;
use stripecal::model::{
    AdjustmentSummary, BoardScaleCheck, Calibration, CalibrationRecords, DhCorrection,
    LaserBoardFigure, LeaveOneOut, LooFold, LooView, Mount, RobotCalibration, RobotPoseNoise,
    RobotPoseView, StripeChannel, StripeChannelChoice, StripeExtraction, ViewRecord,
};
use stripecal::model::{
    DiameterCheckRecord, MirrorRecord, ProfilerAdjustmentRecord, ProfilerLooRecord,
    ProfilerLooView, ProfilerRecords, ProfilerViewRecord,
};

/// The keys of a JSON object (none for another value).
fn keys(v: &Value) -> Vec<String> {
    v.as_object()
        .map_or_else(Vec::new, |m: &Map<String, Value>| {
            m.keys().cloned().collect()
        })
}

/// A calibration holding every record, each with its optional parts.
fn sample() -> PyResult<Calibration> {
    let camera = Camera::new(
        64,
        48,
        Intrinsics {
            fu: 100.0,
            fv: 100.0,
            u0: 32.0,
            v0: 24.0,
        },
        DistortionModel::Radial1,
        [0.0; 5],
    )
    .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
    let plane = Plane::new(nalgebra::Vector3::z(), 100.0)
        .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
    let records = CalibrationRecords {
        summary: Some(AdjustmentSummary {
            method: "one-stage".into(),
            centre_model: "conic-exact".into(),
            base_board_orientation: Some("first view".into()),
            stripe_rms_mm: 0.0,
            residual_sigma_px: (0.0, 0.0),
            stripe_off_plane: 0,
        }),
        views: Some(vec![ViewRecord {
            view: 0,
            used: true,
            circles: 0,
            stripe_points: 0,
            stripe_off_plane: 0,
            circle_rms_px: Some(0.0),
            stripe_rms_px: Some(0.0),
            outlier: Some(false),
            note: Some(String::new()),
            stripe_extraction: Some(StripeExtraction::default()),
        }]),
        warnings: vec![String::new()],
        board_scale: Some(BoardScaleCheck {
            scale: 1.0,
            sigma: 0.0,
            declared_mm: 1.0,
            implied_mm: 1.0,
            estimated: false,
            disagrees: false,
            tolerance: 0.01,
        }),
        leave_one_out: Some(sample_leave_one_out(&camera, plane)),
        robot_pose_noise: Some(sample_robot_pose_noise()),
        robot_calibration: Some(RobotCalibration {
            mode: "auto".into(),
            robot: Robot::hp3(),
            estimated: vec![DhCorrection {
                name: String::new(),
                correction: 0.0,
                sigma: 0.0,
            }],
            fixed: vec![(String::new(), String::new())],
        }),
        held_blocks: Some(vec![String::new()]),
        stripe_channel: Some(StripeChannelChoice {
            channel: StripeChannel::Red,
            scores: Some(vec![(StripeChannel::Gray, 0.0)]),
        }),
    };
    Ok(Calibration {
        camera,
        laser_plane: Some(plane),
        mount: Mount::Robot,
        hand_cam: Iso3::identity(),
        base_board: Iso3::identity(),
        robot: Some(Robot::hp3()),
        quality: Default::default(),
        uncertainty: Default::default(),
        covariance: None,
        records,
        extra: Default::default(),
    })
}

/// A leave-one-out record with every optional part.
fn sample_leave_one_out(camera: &Camera, plane: Plane) -> LeaveOneOut {
    LeaveOneOut {
        views: vec![LooView {
            view: 0,
            points: 0,
            board_rms_px: 0.0,
            board_rms_mm: 0.0,
            stripe_points: 0,
            stripe_rms_mm: Some(0.0),
            disagrees: false,
            fold: Some(LooFold {
                camera: camera.clone(),
                plane,
                cam_board: Iso3::identity(),
            }),
        }],
        median_board_rms_px: 0.0,
        median_board_rms_mm: 0.0,
        median_stripe_rms_mm: Some(0.0),
        laser_board: Some(LaserBoardFigure {
            median_mm: 0.0,
            p95_mm: 0.0,
            points: 0,
        }),
    }
}

/// A robot-pose-noise record with every optional part.
fn sample_robot_pose_noise() -> RobotPoseNoise {
    let pose_view = RobotPoseView {
        view: 0,
        translation_mm: 0.0,
        rotation_deg: 0.0,
        test: 0.0,
    };
    RobotPoseNoise {
        sigma_translation_mm: 0.0,
        sigma_rotation_deg: 0.0,
        translation_at_floor: false,
        rotation_at_floor: false,
        floor_translation_mm: 0.0,
        floor_rotation_deg: 0.0,
        image_factor: Some(0.0),
        image_factor_at_floor: false,
        kinematic_mm: Some(0.0),
        kinematic_deg: Some(0.0),
        views: vec![pose_view],
        left_out: vec![pose_view],
    }
}

/// A profiler calibration's records, each with its optional parts.
fn profiler_sample(robot_calibration: Option<RobotCalibration>) -> ProfilerRecords {
    ProfilerRecords {
        robot_calibration,
        sphere_diameter_estimated: Some(false),
        adjustment: Some(ProfilerAdjustmentRecord {
            sigma_mm: 0.0,
            points_used: 0,
            iterations: 0,
            view_variance_factor: 1.0,
        }),
        views: Some(vec![ProfilerViewRecord {
            view: 0,
            line: 0,
            profile: String::new(),
            used: true,
            points: 0,
            gaps: 0,
            arc_points: 0,
            sphere_points: 0,
            rejected: 0,
            rms_mm: Some(0.0),
            side: Some(1.0),
            centre_in_sensor_mm: Some([0.0; 3]),
            note: Some(String::new()),
        }]),
        mirror: Some(MirrorRecord {
            ssr_chosen_mm2: 0.0,
            ssr_mirror_mm2: 0.0,
            delta_chi2: 0.0,
            passed: true,
            centre_spread_mm: [0.0; 4],
        }),
        diameter_check: Some(DiameterCheckRecord {
            declared_mm: 0.0,
            estimate_mm: 0.0,
            sigma_mm: 0.0,
            disagrees: false,
        }),
        leave_one_out: Some(ProfilerLooRecord {
            median_rms_mm: 0.0,
            views: vec![ProfilerLooView {
                view: 0,
                points: 0,
                rms_mm: 0.0,
                disagrees: false,
            }],
        }),
        warnings: vec![String::new()],
    }
}

/// `{TypedDict name: [keys]}`: the keys the core writes each calibration.json record
/// with (`CalibrationExtra`: the top-level keys of the records, a subset of the
/// TypedDict's, which also names keys without a typed record).
#[pyfunction]
pub fn record_keys() -> PyResult<BTreeMap<&'static str, Vec<String>>> {
    let c = sample()?;
    let r = &c.records;
    let mut out = BTreeMap::new();
    let extra = Value::Object(calibration_extra_keys(&c));
    out.insert("CalibrationExtra", keys(&extra));
    if let Some(s) = &r.summary {
        out.insert(
            "CalibrationSummary",
            keys(&Value::Object(summary_to_json(s))),
        );
        out.insert(
            "ResidualSigma",
            keys(&summary_to_json(s)["residual_sigma_px"]),
        );
    }
    if let Some(v) = r.views.as_ref().and_then(|v| v.first()) {
        let v = view_record_to_json(v);
        out.insert("CalibrationView", keys(&v));
        let e = &v["stripe_extraction"];
        out.insert("StripeExtraction", keys(e));
        out.insert("StripeLeftOut", keys(&e["left_out"]));
        out.insert(
            "ScanLinesWithoutPoint",
            keys(&e["scan_lines_without_point"]),
        );
    }
    if let Some(b) = &r.board_scale {
        out.insert("BoardScaleCheck", keys(&board_scale_to_json(b)));
    }
    if let Some(l) = &r.leave_one_out {
        let l = leave_one_out_to_json(l);
        out.insert("LeaveOneOut", keys(&l));
        out.insert("LeaveOneOutView", keys(&l["views"][0]));
        out.insert("LeaveOneOutFold", keys(&l["views"][0]["fold"]));
        out.insert("LaserBoardFigure", keys(&l["laser_board"]));
    }
    if let Some(n) = &r.robot_pose_noise {
        let n = robot_pose_noise_to_json(n);
        out.insert("RobotPoseNoise", keys(&n));
        out.insert("RobotPoseAtFloor", keys(&n["at_floor"]));
        out.insert("RobotPoseFloor", keys(&n["floor"]));
        out.insert("RobotPoseNoiseView", keys(&n["views"][0]));
    }
    if let Some(rc) = &r.robot_calibration {
        let rc = robot_calibration_to_json(rc);
        out.insert("RobotCalibration", keys(&rc));
        out.insert("DhCorrection", keys(&rc["estimated"][0]));
        out.insert("DhFixed", keys(&rc["fixed"][0]));
    }
    let p = Value::Object(profiler_records_to_json(&profiler_sample(
        r.robot_calibration.clone(),
    )));
    out.insert("ProfilerExtra", keys(&p));
    out.insert("ProfilerCalibrationAdjustment", keys(&p["adjustment"]));
    out.insert("ProfilerView", keys(&p["views"][0]));
    out.insert("ProfilerMirrorTest", keys(&p["mirror"]));
    out.insert(
        "ProfilerCentreSpread",
        keys(&p["mirror"]["centre_spread_mm"]),
    );
    out.insert("ProfilerDiameterCheck", keys(&p["diameter_check"]));
    out.insert("ProfilerLeaveOneOut", keys(&p["leave_one_out"]));
    out.insert(
        "ProfilerLeaveOneOutView",
        keys(&p["leave_one_out"]["views"][0]),
    );
    Ok(out)
}
