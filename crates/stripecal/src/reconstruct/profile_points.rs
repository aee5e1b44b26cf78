//! The points of a profile scan (a calibrated line profiler, spec/DATASET.md "A profile
//! dataset") as [`ScanPoints`], from profiles and robot readings in memory: what the
//! measurement machinery ([`crate::pipeline::measure_scan_sphere`] and friends, with
//! [`crate::reconstruct::UncertaintyModel::profiler`]) takes.
//!
//! ## Conventions
//!
//! A profile point `(x, z)` mm lies in the sensor frame at `p_s = (x, 0, z)`; in the base
//! frame `p_base = T_base_hand(q) T_hand_sensor p_s`, `T_base_hand` from the joint
//! readings through the calibration's DH table, or the flange pose as given. A scan whose
//! every frame is [`RobotReading::Fixed`] (a fixed profiler) gives the points in the
//! sensor frame with [`ScanPoints::camera_frame`] set, as a fixed camera's scan does;
//! fixed and posed frames do not mix.
//!
//! Per point: `frame` = the frame's index in `frames`, `u_px` / `v_px` = the profile's
//! `x` / `z` in mm (they address the point in its frame's uncertainty chain),
//! `intensity` and `width_px` zero (a profile file's further columns are not read),
//! `flags` zero (a profiler's own extraction is the maker's; its gaps are left out by
//! the reader and counted in [`crate::model::Profile::gaps`]).

use nalgebra::Vector3;

use crate::error::{Error, Result};
use crate::model::{Profile, ProfilerCalibration, RobotReading};

use super::ScanPoints;

/// One frame of a profile scan: its robot reading and its profile.
pub type ProfileFrame = (RobotReading, Profile);

/// The [`ScanPoints`] of a profile scan (module docs). Errors when a reading gives no
/// pose (joints without the calibration's robot, a flange pose not finite), when fixed
/// and posed frames are mixed, and when a profile point is not finite (the frame and
/// point named).
pub fn profile_scan_points(
    frames: &[ProfileFrame],
    calibration: &ProfilerCalibration,
) -> Result<ScanPoints> {
    let fixed = frames.iter().filter(|f| f.0 == RobotReading::Fixed).count();
    if fixed > 0 && fixed < frames.len() {
        return Err(Error::InvalidInput(format!(
            "profile scan: {fixed} of {} frames are fixed (no pose) and the others posed; \
             a scan is either fixed or posed throughout",
            frames.len()
        )));
    }
    let camera_frame = !frames.is_empty() && fixed == frames.len();
    let n: usize = frames.iter().map(|f| f.1.points.len()).sum();
    let mut out = ScanPoints {
        points_mm: Vec::with_capacity(n),
        frame: Vec::with_capacity(n),
        u_px: Vec::with_capacity(n),
        v_px: Vec::with_capacity(n),
        intensity: Vec::with_capacity(n),
        width_px: Vec::with_capacity(n),
        flags: Vec::with_capacity(n),
        camera_frame,
        profiler: true,
        ..Default::default()
    };
    for (i, (reading, profile)) in frames.iter().enumerate() {
        let frame = u32::try_from(i).map_err(|_| {
            Error::InvalidInput(format!("profile scan: {} frames (too many)", frames.len()))
        })?;
        let base_sensor = if camera_frame {
            None
        } else {
            let base_hand = reading
                .base_hand(calibration.robot.as_ref())
                .map_err(|e| super::at_frame(e, i, None))?;
            Some(base_hand * calibration.hand_sensor)
        };
        for (k, &[x, z]) in profile.points.iter().enumerate() {
            if !(x.is_finite() && z.is_finite()) {
                return Err(Error::InvalidInput(format!(
                    "frame {i}: profile point {k} ({x}, {z}) mm is not finite"
                )));
            }
            let p_s = Vector3::new(x, 0.0, z);
            let p = match &base_sensor {
                Some(t) => t.transform_point(&p_s.into()).coords,
                None => p_s,
            };
            out.points_mm.push([p.x, p.y, p.z]);
            out.frame.push(frame);
            out.u_px.push(x);
            out.v_px.push(z);
            out.intensity.push(0.0);
            out.width_px.push(0.0);
            out.flags.push(0);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geometry::iso_from_rotvec;
    use crate::model::kinematics::Robot;
    use crate::model::ProfilerQuality;

    fn calibration() -> ProfilerCalibration {
        ProfilerCalibration {
            hand_sensor: iso_from_rotvec(
                &Vector3::new(0.1, -2.9, 0.2),
                &Vector3::new(10.0, -20.0, 150.0),
            ),
            robot: Some(Robot::hp3()),
            sphere_center_mm: Vector3::zeros(),
            sphere_diameter_mm: 50.0,
            quality: ProfilerQuality::default(),
            uncertainty: Default::default(),
            covariance: None,
            records: Default::default(),
            extra: Default::default(),
        }
    }

    /// Each point is `T_base_hand T_hand_sensor (x, 0, z)`, joints and flange pose alike,
    /// with its frame and profile coordinates.
    #[test]
    fn points_follow_the_pose_chain() {
        let cal = calibration();
        let q = vec![5.0, -15.0, 25.0, 10.0, -80.0, 30.0];
        let bh = cal.robot.as_ref().unwrap().forward(&q).unwrap();
        let prof = Profile {
            points: vec![[-3.0, 101.0], [0.5, 99.0], [4.0, 100.5]],
            gaps: 2,
        };
        let frames = vec![
            (RobotReading::Joints(q), prof.clone()),
            (RobotReading::FlangePose(bh), prof.clone()),
        ];
        let sp = profile_scan_points(&frames, &cal).unwrap();
        assert_eq!(sp.len(), 6);
        assert!(!sp.camera_frame);
        assert_eq!(sp.frame, vec![0, 0, 0, 1, 1, 1]);
        for i in 0..6 {
            let [x, z] = prof.points[i % 3];
            assert_eq!((sp.u_px[i], sp.v_px[i]), (x, z));
            let want = bh * cal.hand_sensor * nalgebra::Point3::new(x, 0.0, z);
            assert!((Vector3::from(sp.points_mm[i]) - want.coords).norm() < 1e-9);
        }
        assert_eq!(sp.intensity.len(), 6);
        assert_eq!(sp.flags, vec![0; 6]);
    }

    #[test]
    fn fixed_scans_and_bad_input() {
        let cal = calibration();
        let prof = Profile {
            points: vec![[1.0, 2.0]],
            gaps: 0,
        };
        let sp = profile_scan_points(&[(RobotReading::Fixed, prof.clone())], &cal).unwrap();
        assert!(sp.camera_frame);
        assert_eq!(sp.points_mm, vec![[1.0, 0.0, 2.0]]);
        let mixed = [
            (RobotReading::Fixed, prof.clone()),
            (RobotReading::Joints(vec![0.0; 6]), prof.clone()),
        ];
        let e = profile_scan_points(&mixed, &cal).unwrap_err().to_string();
        assert!(e.contains("fixed"), "{e}");
        let mut no_robot = cal.clone();
        no_robot.robot = None;
        let e = profile_scan_points(&[(RobotReading::Joints(vec![0.0; 6]), prof)], &no_robot)
            .unwrap_err()
            .to_string();
        assert!(e.contains("frame 0"), "{e}");
        let nan = Profile {
            points: vec![[f64::NAN, 2.0]],
            gaps: 0,
        };
        let e = profile_scan_points(&[(RobotReading::Fixed, nan)], &cal)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not finite"), "{e}");
    }
}
