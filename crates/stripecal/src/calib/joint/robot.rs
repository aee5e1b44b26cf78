//! The robot block: corrections to the DH rows, estimated in the one-stage adjustment
//! from the same images (the paper's future work: "almost eighty-five percent of
//! positioning error is related to the inaccuracy of the robot kinematic model").
//!
//! ## Parameters
//!
//! Per DH row `i` (spec/DATASET.md, "Robot (DH)": `A_i = Rz(q_i - theta0_i) Tz(d_i)
//! Tx(a_i) Rx(alpha_i) Ry(beta_i)`), the candidate corrections are `theta0` (deg), `d`,
//! `a` (mm), `alpha` (deg) and, for a row whose next axis is nearly parallel to its own
//! (nominal `alpha` within [`PARALLEL_DEG`] of 0 or 180 deg, the HP3's joints 2 and 3),
//! Hayati's `beta` (deg). Why `beta`: two parallel axes have no unique common normal;
//! a tilt of the second about the first's `y` axis moves the standard rows' common
//! normal far away (a huge change of `d` for a tiny tilt: the Jacobian column of `d`
//! and the tilt are nearly parallel, the problem ill-conditioned). `beta` is that tilt
//! itself, a small well-conditioned number; `d` of such a row and of the next then act
//! along one direction, which the identifiability rule ([`super::robot_select`]) sees
//! and fixes one of.
//!
//! The values of the block are corrections added to a reference robot (the nominal one
//! of rig.json, or the previous round's refined one); the corrected robot gives each
//! view's flange pose `A_i = FK(q_i)` from its joint readings.
//!
//! ## Jacobian
//!
//! Each correction moves the flange by a twist about (or along) one axis of the chain:
//! `theta0_i` rotates everything after joint `i` about `z_{i-1}` (by `-dtheta0`), `d_i`
//! translates along `z_{i-1}`, `a_i` along `x_i`, `alpha_i` rotates about `x_i` at the
//! origin of frame `i`, `beta_i` about the `y` axis after `alpha_i` there. A rotation by
//! `e` about the unit axis `u` through `c` moves the flange `A = (R, t)` to
//! `(Exp(e u) R, t + e u x (t - c))`; as a perturbation `A (Exp(w), v)` in the flange's
//! own frame (the robot-pose correction's convention, [`super::robot_noise`]):
//! `w = R^T u e`, `v = R^T (u x (t - c)) e`. A translation `e u`: `w = 0`, `v = R^T u e`.
//! With a robot-pose correction `D = (R_D, t_D)` the imaged flange is `F = A D`, and
//! `F`'s own perturbation is `(R_D^T w, R_D^T (v + w x t_D))`.

use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Result};
use crate::model::geometry::Iso3;
use crate::model::kinematics::{DhJoint, Robot};

/// A row gets Hayati's `beta` when its nominal twist is within this many degrees of 0 or
/// 180 (its next joint axis nearly parallel to its own).
pub const PARALLEL_DEG: f64 = 10.0;

/// Which DH corrections the adjustment may estimate (`--robot`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RobotMode {
    /// The robot's DH table is exact (default).
    #[default]
    Fixed,
    /// The encoder offsets `theta0` of every row the data can tell from the rest.
    Offsets,
    /// Every correction the data can tell from the rest (`theta0`, `d`, `a`, `alpha`,
    /// `beta` where it applies), after the identifiability rule.
    Full,
    /// Only the corrections the data show: forward selection of the significant ones
    /// among `full`'s ([`super::robot_select`]).
    Auto,
}

impl RobotMode {
    /// From its CLI name: `fixed`, `offsets`, `full` or `auto`.
    pub fn from_name(name: &str) -> Result<RobotMode> {
        match name {
            "fixed" => Ok(RobotMode::Fixed),
            "offsets" => Ok(RobotMode::Offsets),
            "full" => Ok(RobotMode::Full),
            "auto" => Ok(RobotMode::Auto),
            other => Err(Error::InvalidInput(format!(
                "unknown robot mode {other:?}; expected fixed, offsets, full or auto"
            ))),
        }
    }

    /// The CLI name.
    pub fn name(self) -> &'static str {
        match self {
            RobotMode::Fixed => "fixed",
            RobotMode::Offsets => "offsets",
            RobotMode::Full => "full",
            RobotMode::Auto => "auto",
        }
    }
}

/// One quantity of a DH row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum DhKind {
    Theta0,
    D,
    A,
    Alpha,
    Beta,
}

impl DhKind {
    /// The key of the quantity in a DH row (calibration.json).
    pub fn key(self) -> &'static str {
        match self {
            DhKind::Theta0 => "theta0_deg",
            DhKind::D => "d_mm",
            DhKind::A => "a_mm",
            DhKind::Alpha => "alpha_deg",
            DhKind::Beta => "beta_deg",
        }
    }

    pub(crate) fn get_mut(self, j: &mut DhJoint) -> &mut f64 {
        match self {
            DhKind::Theta0 => &mut j.theta0_deg,
            DhKind::D => &mut j.d_mm,
            DhKind::A => &mut j.a_mm,
            DhKind::Alpha => &mut j.alpha_deg,
            DhKind::Beta => &mut j.beta_deg,
        }
    }
}

/// One correction: a quantity of a row (0-based).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct DhParam {
    pub joint: usize,
    pub kind: DhKind,
}

impl DhParam {
    /// calibration.json's name: `robot.joints[i].theta0_deg`.
    pub fn name(&self) -> String {
        format!("robot.joints[{}].{}", self.joint, self.kind.key())
    }

    /// The correction [`DhParam::name`] names, for a robot of `dof` rows (`None` for
    /// another name or a row beyond the table).
    pub fn from_name(name: &str, dof: usize) -> Option<DhParam> {
        let rest = name.strip_prefix("robot.joints[")?;
        let (i, key) = rest.split_once("].")?;
        let joint: usize = i.parse().ok()?;
        let kind = [
            DhKind::Theta0,
            DhKind::D,
            DhKind::A,
            DhKind::Alpha,
            DhKind::Beta,
        ]
        .into_iter()
        .find(|k| k.key() == key)?;
        (joint < dof).then_some(DhParam { joint, kind })
    }
}

/// The candidate corrections of `mode` for `robot` (module docs), in row order.
pub fn candidates(robot: &Robot, mode: RobotMode) -> Vec<DhParam> {
    let mut out = Vec::new();
    for (joint, j) in robot.joints.iter().enumerate() {
        let mut kinds = vec![DhKind::Theta0];
        if mode != RobotMode::Offsets {
            kinds.extend([DhKind::D, DhKind::A, DhKind::Alpha]);
            let s = j.alpha_deg.to_radians().sin().abs();
            if s < PARALLEL_DEG.to_radians().sin() {
                kinds.push(DhKind::Beta);
            }
        }
        if mode == RobotMode::Fixed {
            kinds.clear();
        }
        out.extend(kinds.into_iter().map(|kind| DhParam { joint, kind }));
    }
    out
}

/// The robot block of one adjustment: a reference robot, the corrections estimated and
/// every used view's joint readings.
#[derive(Debug, Clone)]
pub struct RobotBlock {
    pub reference: Robot,
    pub params: Vec<DhParam>,
    /// Joint readings (deg) of each used view.
    pub readings: Vec<Vec<f64>>,
}

impl RobotBlock {
    /// The reference robot with the corrections `values` (one per [`Self::params`]).
    pub fn corrected(&self, values: &[f64]) -> Robot {
        let mut r = self.reference.clone();
        for (p, v) in self.params.iter().zip(values) {
            *p.kind.get_mut(&mut r.joints[p.joint]) += v;
        }
        r
    }

    /// Every used view's flange pose `T_base_hand` for the corrections `values`.
    pub fn flanges(&self, values: &[f64]) -> Vec<Iso3> {
        let robot = self.corrected(values);
        self.readings
            .iter()
            .map(|q| robot.forward_unchecked(q))
            .collect()
    }

    /// Every used view's flange perturbation per correction (module docs): for view
    /// `i`, `out[i][k] = (w, v)` of correction `k` (per degree or mm), for the
    /// corrections `values` and the robot-pose corrections `d` (`None`: identity).
    pub fn flange_jacobians(
        &self,
        values: &[f64],
        d: &[(Matrix3<f64>, Vector3<f64>)],
    ) -> Vec<Vec<[f64; 6]>> {
        let robot = self.corrected(values);
        self.readings
            .iter()
            .enumerate()
            .map(|(i, q)| {
                let cols = flange_twists(&robot, q, &self.params);
                match d.get(i) {
                    None => cols,
                    Some((rd, td)) => cols
                        .into_iter()
                        .map(|c| {
                            let w = Vector3::new(c[0], c[1], c[2]);
                            let v = Vector3::new(c[3], c[4], c[5]);
                            let wf = rd.transpose() * w;
                            let vf = rd.transpose() * (v + w.cross(td));
                            [wf.x, wf.y, wf.z, vf.x, vf.y, vf.z]
                        })
                        .collect(),
                }
            })
            .collect()
    }
}

/// An axis of the chain: `(u, Some(c))` a rotation about `u` through `c`, `(u, None)`
/// a translation along `u`.
type Axis = (Vector3<f64>, Option<Vector3<f64>>);

/// The flange's own perturbation `(w, v)` per unit of each correction in `params` at
/// readings `q` (module docs).
pub fn flange_twists(robot: &Robot, q: &[f64], params: &[DhParam]) -> Vec<[f64; 6]> {
    let deg = std::f64::consts::PI / 180.0;
    let end = robot.forward_unchecked(q);
    let re = end.rotation.to_rotation_matrix().into_inner();
    let te = end.translation.vector;
    // Per row: the axes and points of its quantities, in the base frame.
    let mut axes: Vec<[Axis; 5]> = Vec::new();
    let mut r = Matrix3::identity();
    let mut o = Vector3::zeros();
    for (j, &qi) in robot.joints.iter().zip(q) {
        let z = r.column(2).into_owned();
        let theta = (qi - j.theta0_deg).to_radians();
        let rz = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), theta).into_inner();
        let r1 = r * rz;
        let o1 = o + z * j.d_mm;
        let x = r1.column(0).into_owned();
        let o2 = o1 + x * j.a_mm;
        let rx = nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), j.alpha_deg.to_radians())
            .into_inner();
        let r2 = r1 * rx;
        let y = r2.column(1).into_owned();
        let ry = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), j.beta_deg.to_radians())
            .into_inner();
        // (axis, Some(point)) for a rotation, (axis, None) for a translation.
        axes.push([
            (-z, Some(o)),
            (z, None),
            (x, None),
            (x, Some(o2)),
            (y, Some(o2)),
        ]);
        r = r2 * ry;
        o = o2;
    }
    params
        .iter()
        .map(|p| {
            let k = match p.kind {
                DhKind::Theta0 => 0,
                DhKind::D => 1,
                DhKind::A => 2,
                DhKind::Alpha => 3,
                DhKind::Beta => 4,
            };
            let (u, c) = axes[p.joint][k];
            let (w, v) = match c {
                Some(c) => (
                    re.transpose() * u * deg,
                    re.transpose() * u.cross(&(te - c)) * deg,
                ),
                None => (Vector3::zeros(), re.transpose() * u),
            };
            [w.x, w.y, w.z, v.x, v.y, v.z]
        })
        .collect()
}

/// The derivative of a base-frame point `A(q) p_f` (`p_f` in the flange frame) per
/// DH correction named `robot.joints[i].<key>` in `names` (others skipped): `R_A (w x
/// p_f + v)` of the flange's perturbation `(w, v)`.
pub fn point_gradients(
    robot: &Robot,
    q: &[f64],
    names: &[String],
    p_f: &Vector3<f64>,
) -> Vec<(String, Vector3<f64>)> {
    let found: Vec<(String, DhParam)> = names
        .iter()
        .filter_map(|n| DhParam::from_name(n, robot.dof()).map(|p| (n.clone(), p)))
        .collect();
    if found.is_empty() || q.len() != robot.dof() {
        return Vec::new();
    }
    let params: Vec<DhParam> = found.iter().map(|f| f.1).collect();
    let ra = robot.forward_unchecked(q).rotation;
    found
        .into_iter()
        .zip(flange_twists(robot, q, &params))
        .map(|((n, _), t)| {
            let w = Vector3::new(t[0], t[1], t[2]);
            let v = Vector3::new(t[3], t[4], t[5]);
            (n, ra * (w.cross(p_f) + v))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geometry::matrix_to_rotvec;

    #[test]
    fn flange_twists_match_finite_differences() {
        let mut robot = Robot::hp3();
        robot.joints[1].beta_deg = 0.2;
        robot.joints[3].alpha_deg += 0.3;
        let q = [12.0, -25.0, 35.0, 20.0, -70.0, 40.0];
        let params = candidates(&robot, RobotMode::Full);
        assert!(params.contains(&DhParam {
            joint: 1,
            kind: DhKind::Beta
        }));
        assert!(!params.contains(&DhParam {
            joint: 0,
            kind: DhKind::Beta
        }));
        let twists = flange_twists(&robot, &q, &params);
        let a0 = robot.forward_unchecked(&q);
        let r0 = a0.rotation.to_rotation_matrix().into_inner();
        let h = 1e-6;
        for (p, tw) in params.iter().zip(&twists) {
            let block = RobotBlock {
                reference: robot.clone(),
                params: vec![*p],
                readings: vec![q.to_vec()],
            };
            let a1 = block.flanges(&[h])[0];
            let r1 = a1.rotation.to_rotation_matrix().into_inner();
            let w = matrix_to_rotvec(&(r0.transpose() * r1)) / h;
            let v = r0.transpose() * (a1.translation.vector - a0.translation.vector) / h;
            let fd = [w.x, w.y, w.z, v.x, v.y, v.z];
            for k in 0..6 {
                let tol = 1e-4 * (1.0 + tw[k].abs());
                assert!(
                    (fd[k] - tw[k]).abs() < tol,
                    "{}: component {k}: analytic {} vs finite differences {}",
                    p.name(),
                    tw[k],
                    fd[k]
                );
            }
        }
    }

    #[test]
    fn point_gradients_match_finite_differences() {
        let robot = Robot::hp3();
        let q = [5.0, -15.0, 25.0, 10.0, -80.0, 30.0];
        let params = candidates(&robot, RobotMode::Full);
        let names: Vec<String> = params.iter().map(|p| p.name()).collect();
        let p_f = Vector3::new(30.0, -10.0, 160.0);
        let g = point_gradients(&robot, &q, &names, &p_f);
        assert_eq!(g.len(), params.len());
        let h = 1e-5;
        for ((name, grad), p) in g.iter().zip(&params) {
            let block = RobotBlock {
                reference: robot.clone(),
                params: vec![*p],
                readings: vec![q.to_vec()],
            };
            let at = |e: f64| block.flanges(&[e])[0] * nalgebra::Point3::from(p_f);
            let fd = (at(h) - at(-h)) / (2.0 * h);
            assert!(
                (fd - grad).norm() < 1e-5 * (1.0 + grad.norm()),
                "{name}: {grad:?} vs {fd:?}"
            );
        }
    }

    #[test]
    fn modes_choose_their_candidates() {
        let r = Robot::hp3();
        assert!(candidates(&r, RobotMode::Fixed).is_empty());
        let off = candidates(&r, RobotMode::Offsets);
        assert_eq!(off.len(), 6);
        assert!(off.iter().all(|p| p.kind == DhKind::Theta0));
        // HP3: rows 2 and 6 (alpha 180) carry beta.
        let full = candidates(&r, RobotMode::Full);
        assert_eq!(full.len(), 6 * 4 + 2);
        assert_eq!(full[0].name(), "robot.joints[0].theta0_deg");
        assert_eq!(RobotMode::from_name("auto").unwrap(), RobotMode::Auto);
        assert!(RobotMode::from_name("all").is_err());
    }
}
