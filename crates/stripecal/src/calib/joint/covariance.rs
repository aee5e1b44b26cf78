//! The covariance of the calibration's numbers from the solver's covariance of the
//! parameter vector, under the names of `calibration.json` (the contract's `covariance`
//! key), and the one-sigmas read from its diagonal.
//!
//! The map from the solver's columns to the file's numbers is linear at the solution:
//! the camera's numbers directly; the laser plane's unit normal through its chart
//! (`n = normalize(n0 + a e1 + b e2)`: `dn = (I - n n^T) / |n0 + a e1 + b e2| [e1 e2]`),
//! its offset directly; the transforms' rotation vectors through the inverse right
//! Jacobian of SO(3) (the solver's increment is `R Exp(w)`), their translations
//! directly; the board scale directly. With `J` that map, the file's covariance is
//! `J C J^T`. Held blocks have no rows (their numbers are not estimated).
//!
//! The covariance of the global parameters is the model's widened to the views' own
//! scatter where that is larger ([`crate::calib::clustered`]).

use nalgebra::{DMatrix, Matrix3, Vector3};

use super::layout::{Block, JointParams, ParamLayout};
use super::{JointSigma, TransformSigma};
use crate::model::calibration_number;
use crate::model::camera::PARAM_NAMES;
use crate::model::NamedCovariance;

/// The contract's names of the camera's numbers, [`PARAM_NAMES`] order.
pub(crate) fn camera_name(i: usize) -> String {
    match PARAM_NAMES[i] {
        "k1" => "camera.distortion[0]".into(),
        "k2" => "camera.distortion[1]".into(),
        "p1" => "camera.distortion[2]".into(),
        "p2" => "camera.distortion[3]".into(),
        "k3" => "camera.distortion[4]".into(),
        other => format!("camera.{other}"),
    }
}

/// The covariance of the estimated numbers under the file's names (module docs).
/// `plane_sign` is -1 when the reported plane's normal is the chart's negated (a plane
/// is written with `d >= 0`).
pub(super) fn named_covariance(
    layout: &ParamLayout,
    p: &[f64],
    s: &JointParams,
    cov: &DMatrix<f64>,
    plane_sign: f64,
) -> NamedCovariance {
    let n = layout.num_params();
    let mut names: Vec<String> = Vec::new();
    let mut rows: Vec<Vec<(usize, f64)>> = Vec::new();
    let col = |slot: usize| layout.column(slot);
    for (i, slot) in layout.slots(Block::Camera).enumerate() {
        if let Some(c) = col(slot) {
            names.push(camera_name(i));
            rows.push(vec![(c, 1.0)]);
        }
    }
    let sp = layout.slots(Block::Plane).start;
    if let (Some(ca), Some(cb), Some(cd)) = (col(sp), col(sp + 1), col(sp + 2)) {
        let v = layout.full(p);
        let raw = layout.chart.raw_normal(v[sp], v[sp + 1]);
        let proj = (Matrix3::identity() - s.plane_n * s.plane_n.transpose()) / raw.norm();
        let (de1, de2) = (proj * layout.chart.e1, proj * layout.chart.e2);
        for k in 0..3 {
            names.push(format!("laser_plane.normal[{k}]"));
            rows.push(vec![(ca, plane_sign * de1[k]), (cb, plane_sign * de2[k])]);
        }
        names.push("laser_plane.d_mm".into());
        rows.push(vec![(cd, plane_sign)]);
    }
    for (block, key, rot) in [
        (Block::HandCam, "hand_cam", &s.x_rot),
        (Block::BaseBoard, "base_board", &s.z_rot),
    ] {
        let b = layout.slots(block).start;
        let Some(c0) = col(b) else { continue };
        let jr = inverse_right_jacobian(&crate::model::geometry::matrix_to_rotvec(rot));
        for k in 0..3 {
            names.push(format!("{key}.rotation_vector[{k}]"));
            rows.push((0..3).map(|j| (c0 + j, jr[(k, j)])).collect());
        }
        for k in 0..3 {
            names.push(format!("{key}.translation_mm[{k}]"));
            rows.push(vec![(c0 + 3 + k, 1.0)]);
        }
    }
    if let Some(c) = col(layout.slots(Block::BoardScale).start) {
        names.push("board.scale".into());
        rows.push(vec![(c, 1.0)]);
    }
    for (k, c) in layout.slotless_columns(Block::SphereCentre).enumerate() {
        names.push(format!("sphere.center_mm[{k}]"));
        rows.push(vec![(c, 1.0)]);
    }
    for c in layout.slotless_columns(Block::SphereDiameter) {
        names.push("sphere.diameter_mm".into());
        rows.push(vec![(c, 1.0)]);
    }
    let all = layout.names();
    for c in layout.robot_columns() {
        names.push(all[c].clone());
        rows.push(vec![(c, 1.0)]);
    }
    let mut j = DMatrix::<f64>::zeros(rows.len(), n);
    for (r, entries) in rows.iter().enumerate() {
        for &(c, v) in entries {
            j[(r, c)] = v;
        }
    }
    let matrix = &j * cov * j.transpose();
    NamedCovariance {
        parameters: names,
        matrix,
    }
}

/// The one-sigmas of every number from the named covariance (0 for held numbers).
pub(super) fn joint_sigma(named: &NamedCovariance) -> JointSigma {
    let sd = |name: &str| named.sigma(name).unwrap_or(0.0);
    let v3 = |prefix: &str| Vector3::from_fn(|k, _| sd(&format!("{prefix}[{k}]")));
    let pose = |key: &str| TransformSigma {
        rotation_vector: v3(&format!("{key}.rotation_vector")),
        translation_mm: v3(&format!("{key}.translation_mm")),
    };
    JointSigma {
        camera: std::array::from_fn(|i| sd(&camera_name(i))),
        plane_normal: v3("laser_plane.normal"),
        plane_d_mm: sd("laser_plane.d_mm"),
        hand_cam: pose("hand_cam"),
        base_board: pose("base_board"),
        board_scale: sd("board.scale"),
    }
}

/// The value of one of the calibration's numbers by its contract name (`None` for names
/// it does not read: the DH corrections).
fn named_value(r: &super::JointResult, name: &str) -> Option<f64> {
    if name == "board.scale" {
        return Some(r.board_scale);
    }
    calibration_number(
        &r.camera,
        r.plane.as_ref(),
        &r.hand_cam,
        &r.base_board,
        name,
    )
}

impl super::JointResult {
    /// This result's numbers minus `other`'s, under the named covariance's names (0 for
    /// the DH corrections, which [`named_value`] does not read, and for a rotation
    /// vector that jumped to its other form near a half turn).
    pub fn named_difference(&self, other: &super::JointResult) -> nalgebra::DVector<f64> {
        let names = &self.named_covariance.parameters;
        nalgebra::DVector::from_iterator(
            names.len(),
            names
                .iter()
                .map(|n| match (named_value(self, n), named_value(other, n)) {
                    (Some(a), Some(b))
                        if ((a - b).abs() < 0.01 || !n.contains("rotation"))
                            && (a - b).is_finite() =>
                    {
                        a - b
                    }
                    _ => 0.0,
                }),
        )
    }

    /// Adds systematic errors shared by all observations to the covariance of the
    /// calibration's numbers: `sum_k w_k d_k d_k^T`, each `d_k` a change of the numbers
    /// ([`Self::named_difference`]) and `w_k` its variance per unit (e.g. `u^2` for a
    /// correction `D` whose remainder has the standard uncertainty `u` per unit
    /// correction). The one-sigmas follow.
    pub fn add_systematic_terms(&mut self, terms: &[(nalgebra::DVector<f64>, f64)]) {
        for (d, w) in terms {
            self.named_covariance.matrix += d * d.transpose() * *w;
        }
        self.sigma = joint_sigma(&self.named_covariance);
    }
}

/// `d rotvec / d w` for `rotvec(R Exp(w))` at `w = 0`: the inverse right Jacobian of SO(3)
/// at `r`.
pub(super) fn inverse_right_jacobian(r: &Vector3<f64>) -> Matrix3<f64> {
    let th = r.norm();
    let k = r.cross_matrix();
    let c = if th < 1e-6 {
        1.0 / 12.0 + th * th / 720.0
    } else {
        (1.0 / (th * th)) - (1.0 + th.cos()) / (2.0 * th * th.sin())
    };
    Matrix3::identity() + k * 0.5 + k * k * c
}
