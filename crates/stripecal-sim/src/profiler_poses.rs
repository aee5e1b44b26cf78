//! The poses of the profiler mode ([`crate::profiler`]): calibration views around the
//! reference sphere and a straight scan across it.
//!
//! ## Calibration views ([`Twin::profiler_views`])
//!
//! A view is drawn in the SENSOR frame first: the sphere centre as the sensor sees it,
//! `c = (x, y, z)`, with
//! - `z` (the stand-off) uniform in `[standoff_min_mm, standoff_max_mm]`,
//! - `x` (the place along the line) uniform in `+-place_max_mm`,
//! - `y` (the laser plane's offset from the centre) of magnitude uniform in
//!   `[offset_min_frac, offset_max_frac] * R` and sign `+` for even views, `-` for odd
//!   ones (both sides of the plane),
//!
//! and an orientation `R_base_sensor = R_tilt * R_0 * Rz(spin)`: `R_0` the sensor's at
//! the home pose (`poses.home_q_deg`, true robot), `R_tilt` a turn by a uniform angle in
//! `[tilt_min_deg, tilt_max_deg]` about a horizontal (base) axis of uniform azimuth,
//! `spin` uniform in `+-spin_max_deg` about the sensor's own z: the rotation about every
//! sensor axis varies between views. The sensor's origin is then `C - R_base_sensor c`
//! (C the sphere's centre, base frame) and the flange pose
//! `T_base_hand = T_base_sensor * T_hand_sensor^-1`. The joint readings come from the
//! core's damped least squares inverse kinematics on the TRUE robot, started at the
//! home pose; a pose is rejected (and redrawn) when it does not converge, leaves
//! `max_joint_delta_deg` of home, or its noise-free profile holds fewer than
//! [`MIN_SPHERE_POINTS`] sphere points. The view's truth is then recomputed from the
//! readings by forward kinematics (so the truth and the readings agree to rounding).
//!
//! `degenerate` fixes one coordinate of `c` for every view (`same_standoff`: z at the
//! range's middle, `same_place`: x = 0, `same_offset`: y = +(offset_min_frac +
//! offset_max_frac) R / 2), varied only uniformly over `near_degenerate_mm` around that
//! with a non-zero `near_degenerate_mm`. Every draw is made for every view whatever the
//! mode, so the other coordinates are the same as in the non-degenerate set.
//!
//! ## The scan ([`Twin::profiler_scan`])
//!
//! `scan_frames` frames at the home orientation `R_0`, the sphere centre at sensor
//! `(0, y_k, (standoff_min_mm + standoff_max_mm) / 2)` with
//! `y_k = (k - (n - 1) / 2) scan_step_mm`: the laser plane sweeps across the ball along
//! its own normal; each frame's inverse kinematics starts from the last.

use nalgebra::{Rotation3, Unit, UnitQuaternion, Vector3};

use stripecal::model::geometry::Iso3;
use stripecal::model::kinematics::IkOptions;

use crate::profiler::{render_profile, Hit, ProfilerScene};
use crate::rng::Rng;
use crate::{SimError, Twin};

/// The random stream of the profiler poses.
const STREAM: u64 = 0x7072_6f66_706f;
/// Candidate poses per view before giving up.
const MAX_ATTEMPTS: usize = 2000;
/// A view's noise-free profile must hold at least this many sphere points.
pub const MIN_SPHERE_POINTS: usize = 100;

/// One pose of the profiler (a calibration view or a scan frame), as the TRUE robot
/// puts it.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfilerView {
    /// The joint readings, degrees.
    pub q_deg: Vec<f64>,
    /// `T_base_hand(q)` of the true robot.
    pub base_hand: Iso3,
    /// `T_base_sensor = T_base_hand * T_hand_sensor`.
    pub base_sensor: Iso3,
    /// The sphere's centre in the sensor frame, mm.
    pub center_sensor: Vector3<f64>,
    /// Angle between the sensor's z and its z at the home pose, degrees.
    pub tilt_deg: f64,
}

impl Twin {
    /// The true `T_hand_sensor` (`profiler.hand_sensor`).
    pub fn hand_sensor(&self) -> Iso3 {
        crate::config::pose_model(&self.cfg.profiler.hand_sensor)
    }

    /// The profiler's world (sphere, stand, table), base frame.
    pub fn profiler_scene(&self) -> ProfilerScene {
        ProfilerScene::of(&self.cfg.profiler)
    }

    /// The sensor's orientation at the home pose (true robot).
    fn home_sensor_rotation(&self) -> Result<UnitQuaternion<f64>, SimError> {
        Ok(self
            .robot_true
            .forward(&self.cfg.poses.home_q_deg)?
            .rotation
            * self.hand_sensor().rotation)
    }

    /// The view of the TRUE robot at readings `q`.
    pub fn profiler_view_at(&self, q_deg: &[f64]) -> Result<ProfilerView, SimError> {
        let base_hand = self.robot_true.forward(q_deg)?;
        let base_sensor = base_hand * self.hand_sensor();
        let z0 = self.home_sensor_rotation()? * Vector3::z();
        let z = base_sensor.rotation * Vector3::z();
        Ok(ProfilerView {
            q_deg: q_deg.to_vec(),
            base_hand,
            base_sensor,
            center_sensor: base_sensor.inverse_transform_vector(
                &(self.profiler_scene().center - base_sensor.translation.vector),
            ),
            tilt_deg: z0.angle(&z).to_degrees(),
        })
    }

    /// Joint readings that put the sensor at `base_sensor` (true robot, from `q0`),
    /// within `max_joint_delta_deg` of home; `None` when there are none.
    fn profiler_solve(&self, base_sensor: &Iso3, q0: &[f64]) -> Option<Vec<f64>> {
        let target = base_sensor * self.hand_sensor().inverse();
        let q = self
            .robot_true
            .inverse(&target, q0, &IkOptions::default())
            .ok()?;
        let lim = self.cfg.profiler.max_joint_delta_deg;
        q.iter()
            .zip(&self.cfg.poses.home_q_deg)
            .all(|(a, h)| (a - h).abs() <= lim)
            .then_some(q)
    }

    /// The calibration views of the profiler mode (module docs), deterministic per seed.
    pub fn profiler_views(&self) -> Result<Vec<ProfilerView>, SimError> {
        let pc = &self.cfg.profiler;
        pc.validate()?;
        let scene = self.profiler_scene();
        let r0 = self.home_sensor_rotation()?;
        let r = pc.radius();
        let home = self.cfg.poses.home_q_deg.clone();
        let mut rng = Rng::new(self.cfg.seed, STREAM);
        let mut out = Vec::with_capacity(pc.views);
        let near = pc.near_degenerate_mm;
        for i in 0..pc.views {
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            let mut found = None;
            for _ in 0..MAX_ATTEMPTS {
                let u: [f64; 8] = std::array::from_fn(|_| rng.uniform());
                let mut c = Vector3::new(
                    pc.place_max_mm * (2.0 * u[0] - 1.0),
                    sign * r
                        * (pc.offset_min_frac + (pc.offset_max_frac - pc.offset_min_frac) * u[1]),
                    pc.standoff_min_mm + (pc.standoff_max_mm - pc.standoff_min_mm) * u[2],
                );
                let jitter = near * (u[7] - 0.5);
                match pc.degenerate.as_str() {
                    "same_standoff" => {
                        c.z = 0.5 * (pc.standoff_min_mm + pc.standoff_max_mm) + jitter
                    }
                    "same_place" => c.x = jitter,
                    "same_offset" => {
                        c.y = 0.5 * (pc.offset_min_frac + pc.offset_max_frac) * r + jitter
                    }
                    _ => {}
                }
                let tilt =
                    (pc.tilt_min_deg + (pc.tilt_max_deg - pc.tilt_min_deg) * u[3]).to_radians();
                let az = std::f64::consts::TAU * u[4];
                let spin = (pc.spin_max_deg * (2.0 * u[5] - 1.0)).to_radians();
                let axis = Unit::new_normalize(Vector3::new(az.cos(), az.sin(), 0.0));
                let rot = UnitQuaternion::from_axis_angle(&axis, tilt)
                    * r0
                    * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), spin);
                let origin = scene.center - rot * c;
                let base_sensor = Iso3::from_parts(origin.into(), rot);
                let Some(q) = self.profiler_solve(&base_sensor, &home) else {
                    continue;
                };
                let v = self.profiler_view_at(&q)?;
                let sphere = render_profile(pc, &scene, &v.base_sensor, None)
                    .iter()
                    .filter(|s| matches!(s.truth, Some((_, Hit::Sphere))))
                    .count();
                if sphere >= MIN_SPHERE_POINTS {
                    found = Some(v);
                    break;
                }
            }
            out.push(found.ok_or_else(|| {
                SimError::Poses(format!(
                    "profiler view {i}: no reachable pose in {MAX_ATTEMPTS} attempts; move \
                     profiler.sphere_center_mm, narrow the tilts or raise max_joint_delta_deg"
                ))
            })?);
        }
        Ok(out)
    }

    /// The scan frames of the profiler mode (module docs); empty with `scan_frames = 0`.
    pub fn profiler_scan(&self) -> Result<Vec<ProfilerView>, SimError> {
        let pc = &self.cfg.profiler;
        let scene = self.profiler_scene();
        let rot = self.home_sensor_rotation()?;
        let n = pc.scan_frames;
        let z = 0.5 * (pc.standoff_min_mm + pc.standoff_max_mm);
        let mut q = self.cfg.poses.home_q_deg.clone();
        let mut out = Vec::with_capacity(n);
        for k in 0..n {
            let y = (k as f64 - 0.5 * (n as f64 - 1.0)) * pc.scan_step_mm;
            let c = Vector3::new(0.0, y, z);
            let base_sensor = Iso3::from_parts((scene.center - rot * c).into(), rot);
            q = self.profiler_solve(&base_sensor, &q).ok_or_else(|| {
                SimError::Poses(format!(
                    "profiler scan frame {k}: the robot cannot reach the sweep"
                ))
            })?;
            out.push(self.profiler_view_at(&q)?);
        }
        Ok(out)
    }
}

/// The rotation angle (degrees) of `a^-1 b`, for spread checks.
pub fn relative_angle_deg(a: &Iso3, b: &Iso3) -> f64 {
    Rotation3::from(a.rotation.inverse() * b.rotation)
        .angle()
        .to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SimConfig;

    fn twin(over: serde_json::Value) -> Twin {
        let c = SimConfig::preset("hp3-profiler")
            .unwrap()
            .with_overrides(&serde_json::json!({ "profiler": over }))
            .unwrap();
        Twin::new(c).unwrap()
    }

    #[test]
    fn views_keep_the_pose_set_constraints() {
        let t = twin(serde_json::json!({}));
        let pc = &t.cfg.profiler;
        let r = pc.radius();
        let vs = t.profiler_views().unwrap();
        assert_eq!(vs.len(), 15);
        let tol = 1e-6;
        let (mut pos, mut neg) = (0, 0);
        for (i, v) in vs.iter().enumerate() {
            let c = v.center_sensor;
            assert!(
                c.z >= pc.standoff_min_mm - tol && c.z <= pc.standoff_max_mm + tol,
                "{i}: {c:?}"
            );
            assert!(c.x.abs() <= pc.place_max_mm + tol, "{i}: {c:?}");
            assert!(c.y.abs() <= pc.offset_max_frac * r + tol, "{i}: {c:?}");
            assert!(c.y.abs() >= pc.offset_min_frac * r - tol, "{i}: {c:?}");
            if c.y > 0.0 {
                pos += 1
            } else {
                neg += 1
            }
            assert!(
                v.tilt_deg <= pc.tilt_max_deg + 1e-6,
                "{i}: tilt {}",
                v.tilt_deg
            );
            // the readings reproduce the truth (the TRUE robot)
            let fk = t.robot_true.forward(&v.q_deg).unwrap() * t.hand_sensor();
            assert!((fk.translation.vector - v.base_sensor.translation.vector).norm() < 1e-9);
            for (q, h) in v.q_deg.iter().zip(&t.cfg.poses.home_q_deg) {
                assert!((q - h).abs() <= pc.max_joint_delta_deg);
            }
        }
        assert_eq!((pos, neg), (8, 7), "both sides of the laser plane");
        // the ranges are used, not only respected
        let zs: Vec<f64> = vs.iter().map(|v| v.center_sensor.z).collect();
        let span = zs.iter().cloned().fold(f64::MIN, f64::max)
            - zs.iter().cloned().fold(f64::MAX, f64::min);
        assert!(span > 25.0, "stand-off span {span}");
        // the orientation varies about every sensor axis: relative rotations' axes in
        // the sensor frame have components on x, y and z
        let mut axis_abs = Vector3::zeros();
        for w in vs.windows(2) {
            let rel = w[0].base_sensor.rotation.inverse() * w[1].base_sensor.rotation;
            if let Some(ax) = rel.axis() {
                axis_abs += ax.into_inner().abs() * rel.angle();
            }
        }
        assert!(
            axis_abs.min() > 0.5,
            "rotation about each sensor axis: {axis_abs:?}"
        );
        assert!(relative_angle_deg(&vs[0].base_sensor, &vs[1].base_sensor) > 1.0);
        // deterministic
        assert_eq!(t.profiler_views().unwrap(), vs);
    }

    #[test]
    fn degenerate_modes_keep_their_coordinate() {
        for (mode, k) in [("same_standoff", 2), ("same_place", 0), ("same_offset", 1)] {
            let vs = twin(serde_json::json!({"degenerate": mode}))
                .profiler_views()
                .unwrap();
            let vals: Vec<f64> = vs.iter().map(|v| v.center_sensor[k]).collect();
            let span = |v: &[f64]| {
                v.iter().cloned().fold(f64::MIN, f64::max)
                    - v.iter().cloned().fold(f64::MAX, f64::min)
            };
            assert!(span(&vals) < 1e-6, "{mode}: {vals:?}");
            // the others still vary
            for j in (0..3).filter(|&j| j != k) {
                let o: Vec<f64> = vs.iter().map(|v| v.center_sensor[j]).collect();
                assert!(span(&o) > 5.0, "{mode}: coordinate {j} {o:?}");
            }
            let near = twin(serde_json::json!({"degenerate": mode, "near_degenerate_mm": 0.5}))
                .profiler_views()
                .unwrap();
            let vals: Vec<f64> = near.iter().map(|v| v.center_sensor[k]).collect();
            let s = span(&vals);
            assert!(s > 0.1 && s <= 0.5 + 1e-6, "{mode} near: span {s}");
        }
    }

    #[test]
    fn forty_views_with_robot_errors_and_a_scan() {
        let c = SimConfig::preset("hp3-profiler")
            .unwrap()
            .with_overrides(&serde_json::json!({
                "seed": 4,
                "profiler": {"views": 40},
                "robot_error": {"theta0_deg": 0.05, "a_mm": 0.3, "d_mm": 0.3, "alpha_deg": 0.02}
            }))
            .unwrap();
        let t = Twin::new(c).unwrap();
        assert_ne!(t.robot_true, t.robot_nominal);
        let vs = t.profiler_views().unwrap();
        assert_eq!(vs.len(), 40);
        let scan = t.profiler_scan().unwrap();
        assert_eq!(scan.len(), 60);
        let step = t.cfg.profiler.scan_step_mm;
        for w in scan.windows(2) {
            let dy = w[1].center_sensor.y - w[0].center_sensor.y;
            assert!((dy - step).abs() < 1e-6, "{dy}");
            assert!((w[1].center_sensor.z - w[0].center_sensor.z).abs() < 1e-6);
        }
    }
}
