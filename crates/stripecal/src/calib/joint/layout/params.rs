//! A parameter vector decoded ([`JointParams`]): the camera, the laser plane, `X`, `Z`,
//! the board scale and the per-view blocks' values, and the poses they give each view.

use nalgebra::{Matrix3, Vector3};

use crate::calib::joint::chain;
use crate::model::geometry::{iso_from_parts, Iso3};

/// The values of a parameter vector decoded.
#[derive(Debug, Clone)]
pub(in crate::calib::joint) struct JointParams {
    /// Camera parameters, [`PARAM_NAMES`](crate::model::camera::PARAM_NAMES) order (fixed ones from the base camera).
    pub cam: [f64; 9],
    pub plane_n: Vector3<f64>,
    pub plane_d: f64,
    pub x_rot: Matrix3<f64>,
    pub x_t: Vector3<f64>,
    pub z_rot: Matrix3<f64>,
    pub z_t: Vector3<f64>,
    /// The board's scale.
    pub scale: f64,
    /// Per view used: the robot-pose correction `D_i = (R, t)` (empty when not
    /// estimated: the robot poses are taken as exact).
    pub corrections: Vec<(Matrix3<f64>, Vector3<f64>)>,
    /// Per view used: the image-pose part `e_i` of the correction (rotation rad, then
    /// translation mm; empty when not estimated).
    pub image_pose: Vec<[f64; 6]>,
    /// Per view used, on the bench: the board pose `T_cam_board(i) = (R, t)` (empty
    /// with a robot: the board poses follow from the chain).
    pub board_poses: Vec<(Matrix3<f64>, Vector3<f64>)>,
    /// The DH corrections ([`super::super::robot::RobotBlock::params`]; empty without a robot
    /// block).
    pub robot: Vec<f64>,
}

impl JointParams {
    /// The flange poses the views are imaged from: the robot poses `a` corrected,
    /// `A_i D_i` (as given when the corrections are not estimated).
    pub fn flange_poses(&self, a: &[Iso3]) -> Vec<Iso3> {
        if self.corrections.is_empty() {
            return a.to_vec();
        }
        a.iter()
            .zip(&self.corrections)
            .map(|(a, (r, t))| {
                let ra = a.rotation.to_rotation_matrix().into_inner();
                iso_from_parts(&(ra * r), &(ra * t + a.translation.vector))
            })
            .collect()
    }

    /// `T_cam_board` of each view, `(R, t)`, from the robot poses `a` (corrected,
    /// [`Self::flange_poses`]); on the bench the board poses themselves.
    pub fn view_poses(&self, a: &[Iso3]) -> Vec<([[f64; 3]; 3], [f64; 3])> {
        use crate::numerics::mat3::m3;
        if !self.board_poses.is_empty() {
            return self
                .board_poses
                .iter()
                .map(|(r, t)| (m3(r), [t.x, t.y, t.z]))
                .collect();
        }
        let xr: [[f64; 3]; 3] = m3(&self.x_rot);
        let zr: [[f64; 3]; 3] = m3(&self.z_rot);
        let xt = [self.x_t.x, self.x_t.y, self.x_t.z];
        let zt = [self.z_t.x, self.z_t.y, self.z_t.z];
        self.flange_poses(a)
            .iter()
            .map(|a| chain::cam_board(a, &xr, &xt, &zr, &zt))
            .collect()
    }

    /// The poses the board's points are imaged with: `(R, t / s)` of each
    /// [`Self::view_poses`] (a board `s` times larger at `t` images like rig.json's board
    /// at `t / s`: the central projection is scale-invariant).
    pub fn circle_poses(&self, a: &[Iso3]) -> Vec<([[f64; 3]; 3], [f64; 3])> {
        let k = 1.0 / self.scale;
        self.view_poses(a)
            .into_iter()
            .map(|(r, t)| (r, [t[0] * k, t[1] * k, t[2] * k]))
            .collect()
    }
}
