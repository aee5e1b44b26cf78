//! A calibration (a camera's or a profiler's) moved by deltas of its named numbers (contract names): what the finite
//! difference and Monte Carlo checks of the propagation draw.

use nalgebra::Vector3;

use crate::calib::joint::DhParam;
use crate::error::{Error, Result};
use crate::model::camera::PARAM_NAMES;
use crate::model::geometry::{iso_from_rotvec, matrix_to_rotvec, Plane};
use crate::model::{Calibration, ProfilerCalibration};

/// One delta per name.
fn same_length(names: &[String], deltas: &[f64]) -> Result<()> {
    if names.len() != deltas.len() {
        return Err(Error::InvalidInput(format!(
            "{} names but {} deltas",
            names.len(),
            deltas.len()
        )));
    }
    Ok(())
}

/// The `k` of a name `{prefix}{k}]` (`prefix` ends with `[`).
fn index(name: &str, prefix: &str) -> Option<usize> {
    name.strip_prefix(prefix)?.strip_suffix(']')?.parse().ok()
}

/// `calibration` with `deltas[i]` added to the number named `names[i]` (the names of
/// calibration.json's `covariance`): camera numbers and DH values directly; the laser
/// plane's normal component-wise, then renormalised (its offset directly); `hand_cam` /
/// `base_board` rotation vectors and translations component-wise. An unknown name is an
/// error.
pub fn perturbed_calibration(
    calibration: &Calibration,
    names: &[String],
    deltas: &[f64],
) -> Result<Calibration> {
    same_length(names, deltas)?;
    let mut c = calibration.clone();
    let mut cam = c.camera.params();
    let (mut n, mut d) = match &c.laser_plane {
        Some(p) => (p.normal, p.d),
        None => (Vector3::z(), 1.0),
    };
    let mut poses = [
        (
            matrix_to_rotvec(&c.hand_cam.rotation.to_rotation_matrix().into_inner()),
            c.hand_cam.translation.vector,
        ),
        (
            matrix_to_rotvec(&c.base_board.rotation.to_rotation_matrix().into_inner()),
            c.base_board.translation.vector,
        ),
    ];
    let dof = c.robot.as_ref().map_or(0, |r| r.dof());
    for (name, &delta) in names.iter().zip(deltas) {
        let name = name.as_str();
        if let Some(k) = index(name, "camera.distortion[").filter(|&k| k < 5) {
            cam[4 + k] += delta;
        } else if let Some(k) = name
            .strip_prefix("camera.")
            .and_then(|p| PARAM_NAMES[..4].iter().position(|&x| x == p))
        {
            cam[k] += delta;
        } else if let Some(k) = index(name, "laser_plane.normal[").filter(|&k| k < 3) {
            n[k] += delta;
        } else if name == "laser_plane.d_mm" {
            d += delta;
        } else if let Some(p) = DhParam::from_name(name, dof) {
            let robot = c.robot.as_mut().expect("dof > 0 means a robot");
            *p.kind.get_mut(&mut robot.joints[p.joint]) += delta;
        } else if name == "board.scale" {
            // Moves no reconstructed point; the calibration has no field for it.
        } else {
            let mut done = false;
            for (key, pose) in ["hand_cam", "base_board"].iter().zip(poses.iter_mut()) {
                if let Some(k) = index(name, &format!("{key}.rotation_vector[")) {
                    if k < 3 {
                        pose.0[k] += delta;
                        done = true;
                    }
                } else if let Some(k) = index(name, &format!("{key}.translation_mm[")) {
                    if k < 3 {
                        pose.1[k] += delta;
                        done = true;
                    }
                }
            }
            if !done {
                return Err(Error::InvalidInput(format!(
                    "unknown calibration number {name:?}"
                )));
            }
        }
    }
    c.camera = c.camera.with_params(&cam);
    if c.laser_plane.is_some() {
        let norm = n.norm();
        c.laser_plane = Some(Plane::new(n / norm, d)?);
    }
    c.hand_cam = iso_from_rotvec(&poses[0].0, &poses[0].1);
    c.base_board = iso_from_rotvec(&poses[1].0, &poses[1].1);
    Ok(c)
}

/// A profiler's `calibration` with `deltas[i]` added to the number named `names[i]`:
/// `hand_cam` (= `T_hand_sensor`) rotation vector and translation component-wise, DH
/// values directly, `sphere.center_mm[k]` and `sphere.diameter_mm` directly. An unknown
/// name is an error.
pub fn perturbed_profiler_calibration(
    calibration: &ProfilerCalibration,
    names: &[String],
    deltas: &[f64],
) -> Result<ProfilerCalibration> {
    same_length(names, deltas)?;
    let mut c = calibration.clone();
    let mut r = matrix_to_rotvec(&c.hand_sensor.rotation.to_rotation_matrix().into_inner());
    let mut t = c.hand_sensor.translation.vector;
    let dof = c.robot.as_ref().map_or(0, |r| r.dof());
    for (name, &delta) in names.iter().zip(deltas) {
        let name = name.as_str();
        if let Some(k) = index(name, "hand_cam.rotation_vector[").filter(|&k| k < 3) {
            r[k] += delta;
        } else if let Some(k) = index(name, "hand_cam.translation_mm[").filter(|&k| k < 3) {
            t[k] += delta;
        } else if let Some(k) = index(name, "sphere.center_mm[").filter(|&k| k < 3) {
            c.sphere_center_mm[k] += delta;
        } else if name == "sphere.diameter_mm" {
            c.sphere_diameter_mm += delta;
        } else if let (Some(p), Some(robot)) = (DhParam::from_name(name, dof), c.robot.as_mut()) {
            *p.kind.get_mut(&mut robot.joints[p.joint]) += delta;
        } else {
            return Err(Error::InvalidInput(format!(
                "unknown profiler calibration number {name:?}"
            )));
        }
    }
    c.hand_sensor = iso_from_rotvec(&r, &t);
    Ok(c)
}
