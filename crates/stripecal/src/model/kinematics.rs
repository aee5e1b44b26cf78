//! Robot kinematics: a standard Denavit-Hartenberg chain with encoder offsets.
//!
//! ## Conventions
//!
//! One [`DhJoint`] per revolute joint i = 1..N:
//! `A_i = Rz(theta_i) * Tz(d_i) * Tx(a_i) * Rx(alpha_i) * Ry(beta_i)`,
//! `T_base_hand = A_1 ... A_N`, with `theta_i = q_i - theta0_i` where `q_i` is the
//! encoder reading in degrees (the paper's eq. 8). Angles in degrees, lengths in mm.
//! `beta_i` is Hayati's tilt about the new y axis (0 unless a row carries it): for a
//! joint whose axis is nearly parallel to the previous one, where a small tilt would
//! need a huge change of the standard rows' `d` (the common normal of two nearly
//! parallel axes is far away), the tilt is `beta` instead.

use nalgebra::{
    DMatrix, DVector, Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3, Vector6,
};

use crate::error::{Error, Result};
use crate::model::geometry::{matrix_to_rotvec, Iso3};

/// One row of a DH table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhJoint {
    /// Encoder offset: `theta = q - theta0` (degrees).
    pub theta0_deg: f64,
    /// Link twist (degrees).
    pub alpha_deg: f64,
    /// Link length (mm).
    pub a_mm: f64,
    /// Link offset (mm).
    pub d_mm: f64,
    /// Hayati's tilt about the new y axis (degrees; 0 for a standard DH row).
    pub beta_deg: f64,
}

impl DhJoint {
    /// Rotation and translation of the link transform `A_i` for encoder reading `q_deg`.
    #[inline]
    pub fn rotation_translation(&self, q_deg: f64) -> (Matrix3<f64>, Vector3<f64>) {
        let theta = (q_deg - self.theta0_deg).to_radians();
        let alpha = self.alpha_deg.to_radians();
        let (st, ct) = theta.sin_cos();
        let (sa, ca) = alpha.sin_cos();
        let mut r = Matrix3::new(ct, -st * ca, st * sa, st, ct * ca, -ct * sa, 0.0, sa, ca);
        if self.beta_deg != 0.0 {
            let (sb, cb) = self.beta_deg.to_radians().sin_cos();
            r *= Matrix3::new(cb, 0.0, sb, 0.0, 1.0, 0.0, -sb, 0.0, cb);
        }
        let t = Vector3::new(self.a_mm * ct, self.a_mm * st, self.d_mm);
        (r, t)
    }

    /// The link transform `A_i` for encoder reading `q_deg`.
    #[inline]
    pub fn transform(&self, q_deg: f64) -> Iso3 {
        let (r, t) = self.rotation_translation(q_deg);
        Isometry3::from_parts(
            Translation3::from(t),
            UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(r)),
        )
    }
}

/// A serial robot described by its DH table, with the maker's figures when a user gives
/// them (rig.json `robot.repeatability_mm`, `robot.encoder_sigma_deg`).
#[derive(Debug, Clone, PartialEq)]
pub struct Robot {
    /// A name for reports (e.g. "MOTOMAN HP3").
    pub name: String,
    /// DH rows, base to flange.
    pub joints: Vec<DhJoint>,
    /// The maker's pose repeatability, mm (`None`: not given).
    pub repeatability_mm: Option<f64>,
    /// One-sigma of a joint reading, degrees (`None`: not given).
    pub encoder_sigma_deg: Option<f64>,
}

/// Options of [`Robot::inverse`].
#[derive(Debug, Clone, Copy)]
pub struct IkOptions {
    /// Damping of the damped least squares step (mm-equivalent units).
    pub damping: f64,
    /// Largest joint step per iteration (degrees).
    pub max_step_deg: f64,
    /// Position tolerance (mm).
    pub tol_mm: f64,
    /// Orientation tolerance (radians).
    pub tol_rad: f64,
    /// Iteration limit.
    pub max_iter: usize,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            damping: 1e-3,
            max_step_deg: 10.0,
            tol_mm: 1e-9,
            tol_rad: 1e-11,
            max_iter: 200,
        }
    }
}

/// Length scale (mm) that weights orientation errors against position errors in IK.
const IK_ROT_SCALE_MM: f64 = 100.0;

impl Robot {
    /// A robot from DH rows; at least one row, all values finite.
    pub fn new(name: impl Into<String>, joints: Vec<DhJoint>) -> Result<Robot> {
        let r = Robot {
            name: name.into(),
            joints,
            repeatability_mm: None,
            encoder_sigma_deg: None,
        };
        r.validate()?;
        Ok(r)
    }

    /// The same robot with the maker's figures (see [`Robot::pose_noise_floor`]).
    pub fn with_figures(
        mut self,
        repeatability_mm: Option<f64>,
        encoder_sigma_deg: Option<f64>,
    ) -> Result<Robot> {
        self.repeatability_mm = repeatability_mm;
        self.encoder_sigma_deg = encoder_sigma_deg;
        self.validate()?;
        Ok(self)
    }

    /// The lower bounds the maker's figures put on the robot-pose noise of one flange
    /// pose, as one-sigmas per component: `(translation mm, rotation deg)`.
    ///
    /// - Translation: `repeatability_mm` itself (a conservative reading: makers quote
    ///   the repeatability as the radius that holds nearly every repeated pose).
    /// - Rotation: the flange rotation that independent joint readings of one-sigma
    ///   `encoder_sigma_deg` give: each joint turns the flange about its own unit axis,
    ///   so the rotation vector's covariance is `sigma_q^2 sum_i z_i z_i^T`, whose trace
    ///   is `N sigma_q^2` whatever the pose; per component `sigma_q sqrt(N / 3)` for N
    ///   joints. (The translation the readings cause depends on the pose's lever arms
    ///   and is left to the estimate.)
    pub fn pose_noise_floor(&self) -> (Option<f64>, Option<f64>) {
        let n = self.joints.len() as f64;
        (
            self.repeatability_mm,
            self.encoder_sigma_deg.map(|s| s * (n / 3.0).sqrt()),
        )
    }

    /// Checks the table (non-empty, finite) and the figures (finite, >= 0).
    pub fn validate(&self) -> Result<()> {
        if self.joints.is_empty() {
            return Err(Error::InvalidInput("robot has no joints".into()));
        }
        for (name, v) in [
            ("repeatability_mm", self.repeatability_mm),
            ("encoder_sigma_deg", self.encoder_sigma_deg),
        ] {
            if let Some(x) = v {
                if !(x.is_finite() && x >= 0.0) {
                    return Err(Error::InvalidInput(format!(
                        "robot {name} {x} must be finite and >= 0"
                    )));
                }
            }
        }
        for (i, j) in self.joints.iter().enumerate() {
            if ![j.theta0_deg, j.alpha_deg, j.a_mm, j.d_mm, j.beta_deg]
                .iter()
                .all(|x| x.is_finite())
            {
                return Err(Error::InvalidInput(format!(
                    "robot joint {} has a non-finite DH value",
                    i + 1
                )));
            }
        }
        Ok(())
    }

    /// The MOTOMAN HP3 of the paper's Table 1 (read as ERRATA.md says).
    pub fn hp3() -> Robot {
        let row = |theta0_deg, alpha_deg, a_mm, d_mm| DhJoint {
            theta0_deg,
            alpha_deg,
            a_mm,
            d_mm,
            beta_deg: 0.0,
        };
        Robot {
            repeatability_mm: None,
            encoder_sigma_deg: None,
            name: "MOTOMAN HP3".into(),
            joints: vec![
                row(0.0, -90.0, 100.0, 0.0),
                row(90.0, 180.0, 370.0, 0.0),
                row(0.0, -90.0, 85.0, 0.0),
                row(0.0, 90.0, 0.0, -380.0),
                row(-180.0, 90.0, 0.0, 0.0),
                row(-180.0, 180.0, 0.0, -90.0),
            ],
        }
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    fn check_q(&self, q_deg: &[f64]) -> Result<()> {
        if q_deg.len() != self.joints.len() {
            return Err(Error::InvalidInput(format!(
                "{} joint readings given, robot {:?} has {} joints",
                q_deg.len(),
                self.name,
                self.joints.len()
            )));
        }
        if let Some(i) = q_deg.iter().position(|x| !x.is_finite()) {
            return Err(Error::InvalidInput(format!(
                "joint reading q{} is not finite",
                i + 1
            )));
        }
        Ok(())
    }

    /// Forward kinematics `T_base_hand(q)` for encoder readings in degrees.
    pub fn forward(&self, q_deg: &[f64]) -> Result<Iso3> {
        self.check_q(q_deg)?;
        Ok(self.forward_unchecked(q_deg))
    }

    /// Forward kinematics without argument checks (`q_deg.len()` must equal `dof()`).
    pub fn forward_unchecked(&self, q_deg: &[f64]) -> Iso3 {
        // Chain 3x3 rotations and translations (cheaper than a quaternion per joint),
        // then convert once.
        let mut r = Matrix3::identity();
        let mut t = Vector3::zeros();
        for (j, &q) in self.joints.iter().zip(q_deg) {
            let (rj, tj) = j.rotation_translation(q);
            t += r * tj;
            r *= rj;
        }
        crate::model::geometry::iso_from_parts(&r, &t)
    }

    /// The geometric Jacobian (6 x N) at `q`: rows `[v; w]` (mm/rad and rad/rad) of the
    /// flange origin, columns per joint in radians of encoder reading.
    pub fn jacobian(&self, q_deg: &[f64]) -> Result<DMatrix<f64>> {
        self.check_q(q_deg)?;
        let n = self.dof();
        let mut frames = Vec::with_capacity(n + 1);
        let mut t = Iso3::identity();
        frames.push(t);
        for (j, &q) in self.joints.iter().zip(q_deg) {
            t *= j.transform(q);
            frames.push(t);
        }
        let p_end = t.translation.vector;
        let mut jac = DMatrix::zeros(6, n);
        for i in 0..n {
            let z = frames[i].rotation * Vector3::z();
            let o = frames[i].translation.vector;
            let v = z.cross(&(p_end - o));
            for k in 0..3 {
                jac[(k, i)] = v[k];
                jac[(3 + k, i)] = z[k];
            }
        }
        Ok(jac)
    }

    /// Damped-least-squares inverse kinematics: encoder readings (degrees) that put the
    /// flange at `target`, starting from `q0_deg` and staying on its branch.
    pub fn inverse(&self, target: &Iso3, q0_deg: &[f64], opts: &IkOptions) -> Result<Vec<f64>> {
        self.check_q(q0_deg)?;
        let mut q: Vec<f64> = q0_deg.to_vec();
        let n = self.dof();
        let mut last_err = f64::INFINITY;
        for _ in 0..opts.max_iter {
            let cur = self.forward_unchecked(&q);
            let dp = target.translation.vector - cur.translation.vector;
            let r_err = (target.rotation * cur.rotation.inverse()).to_rotation_matrix();
            let dw = matrix_to_rotvec(r_err.matrix());
            if dp.norm() < opts.tol_mm && dw.norm() < opts.tol_rad {
                return Ok(q);
            }
            last_err = dp.norm() + dw.norm() * IK_ROT_SCALE_MM;
            let mut jac = self.jacobian(&q)?;
            let mut e = Vector6::zeros();
            for k in 0..3 {
                e[k] = dp[k];
                e[3 + k] = dw[k] * IK_ROT_SCALE_MM;
                for i in 0..n {
                    jac[(3 + k, i)] *= IK_ROT_SCALE_MM;
                }
            }
            let jjt = &jac * jac.transpose() + DMatrix::identity(6, 6) * opts.damping.powi(2);
            let Some(chol) = jjt.cholesky() else {
                return Err(Error::Degenerate(
                    "IK normal matrix is not positive definite".into(),
                ));
            };
            let ev = DVector::from_column_slice(e.as_slice());
            let step = jac.transpose() * chol.solve(&ev);
            let max = step.amax().to_degrees();
            let scale = if max > opts.max_step_deg {
                opts.max_step_deg / max
            } else {
                1.0
            };
            for i in 0..n {
                q[i] += step[i].to_degrees() * scale;
            }
        }
        Err(Error::NotConverged {
            what: "inverse kinematics",
            iterations: opts.max_iter,
            residual: last_err,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beta_is_a_tilt_about_the_new_y_axis() {
        let mut row = DhJoint {
            theta0_deg: 10.0,
            alpha_deg: 180.0,
            a_mm: 370.0,
            d_mm: 2.0,
            beta_deg: 0.0,
        };
        let (r0, t0) = row.rotation_translation(35.0);
        row.beta_deg = 0.3;
        let (r1, t1) = row.rotation_translation(35.0);
        let b = 0.3f64.to_radians();
        let ry = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), b).into_inner();
        assert!((r1 - r0 * ry).abs().max() < 1e-15);
        assert_eq!(t0, t1, "the tilt does not move the row's origin");
        // The joint Jacobian follows the tilted axes: finite differences of forward.
        let mut robot = Robot::hp3();
        robot.joints[1].beta_deg = 0.5;
        let q = [5.0, -20.0, 30.0, 10.0, -80.0, 15.0];
        let jac = robot.jacobian(&q).unwrap();
        let h = 1e-6;
        let mut qp = q;
        qp[2] += h;
        let p0 = robot.forward(&q).unwrap().translation.vector;
        let p1 = robot.forward(&qp).unwrap().translation.vector;
        let fd = (p1 - p0) / h.to_radians();
        for k in 0..3 {
            assert!(
                (fd[k] - jac[(k, 2)]).abs() < 1e-4,
                "{fd:?} vs {}",
                jac.column(2)
            );
        }
    }

    #[test]
    fn hp3_home_pose_matches_the_errata() {
        let r = Robot::hp3();
        let t = r.forward(&[0.0, 0.0, 0.0, 0.0, -90.0, 0.0]).unwrap();
        let p = t.translation.vector;
        assert!((p - Vector3::new(480.0, 0.0, 365.0)).norm() < 1e-9, "{p:?}");
        let z = t.rotation * Vector3::z();
        assert!((z - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12, "{z:?}");
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let r = Robot::hp3();
        let q = [5.0, -10.0, 12.0, 20.0, -80.0, 30.0];
        let j = r.jacobian(&q).unwrap();
        let h: f64 = 1e-6;
        for i in 0..6 {
            let (mut a, mut b) = (q, q);
            a[i] += h.to_degrees();
            b[i] -= h.to_degrees();
            let ta = r.forward(&a).unwrap();
            let tb = r.forward(&b).unwrap();
            let dv = (ta.translation.vector - tb.translation.vector) / (2.0 * h);
            let dw = matrix_to_rotvec(
                (ta.rotation * tb.rotation.inverse())
                    .to_rotation_matrix()
                    .matrix(),
            ) / (2.0 * h);
            for k in 0..3 {
                assert!(
                    (dv[k] - j[(k, i)]).abs() < 1e-5 * (1.0 + dv.norm()),
                    "v {k} {i}"
                );
                assert!((dw[k] - j[(3 + k, i)]).abs() < 1e-6, "w {k} {i}");
            }
        }
    }

    #[test]
    fn ik_recovers_a_nearby_pose() {
        let r = Robot::hp3();
        let home = [0.0, 0.0, 0.0, 0.0, -90.0, 0.0];
        let q_true = [4.0, 6.0, -5.0, 12.0, -80.0, -20.0];
        let target = r.forward(&q_true).unwrap();
        let q = r.inverse(&target, &home, &IkOptions::default()).unwrap();
        let t = r.forward(&q).unwrap();
        assert!((t.translation.vector - target.translation.vector).norm() < 1e-8);
        assert!(t.rotation.angle_to(&target.rotation) < 1e-10);
    }

    #[test]
    fn wrong_length_and_nan_are_errors() {
        let r = Robot::hp3();
        assert!(r.forward(&[0.0; 5]).is_err());
        assert!(r.forward(&[0.0, 0.0, f64::NAN, 0.0, 0.0, 0.0]).is_err());
    }
}
