//! What DH errors the robot-pose noise is consistent with would do to the estimate.
//!
//! With joint readings and rig.json's DH table held (`--robot fixed`), a real arm's DH
//! errors move every view's flange by `G_i d` (`G_i` the flange twists per DH number at
//! the view's readings, [`super::robot::flange_twists`]). The part of that motion that
//! varies over the views is what the robot-pose corrections take up; the part common to
//! every view is taken up by `X` and `Z` without a trace in any residual (a DH table 2 mm
//! off in one link moved the twin's `Z` by 1.7 mm, 200 of the rigid model's sigmas and
//! still 10 of the pose-noise model's). No view can show that part; what can be said is
//! how large DH errors are that would explain the corrections, and what errors of that
//! size do to the estimate. With both robot components at their floors (an exact robot)
//! there is nothing to attribute and no term.
//!
//! The estimate's response to DH errors `d` is `K d`, `K = -N^-1 J^T J_d` (`J_d` the image
//! rows' derivatives along each number's flange motion, through the view's correction
//! columns; `N^-1` the model's unit covariance); the corrections' robot rows respond by
//! their rows of `K`. With independent DH errors of one-sigma `s_a` (angles, deg) and
//! `s_l` (lengths, mm), the robot rows' expected weighted sums of squares are, for the
//! rotation rows, `s_a^2 sum_angles |W dr_j|^2` (lengths do not turn the flange) and, for
//! the translation rows, that of the angles plus `s_l^2 sum_lengths |W dr_j|^2`; `s_a` and
//! `s_l` are set so that they equal the sums the robot rows have (all of the robot's pose
//! noise taken as DH errors: an upper bound, since the repeatability's part has no common
//! motion), and the covariance of the global numbers gains `K_g diag(s_j^2) K_g^T`. A DH number already estimated (`--robot`) is left out
//! (its uncertainty is in the covariance).

use nalgebra::{DMatrix, Vector3};

use super::layout::{Block, JointParams, ParamLayout};
use super::residuals::JointProblem;
use super::robot::{candidates, flange_twists, DhKind, RobotMode};
use super::JointOptions;
use crate::error::Result;
use crate::numerics::lm::LmResult;

/// The covariance term of the global numbers and the DH sigmas (lengths mm, angles deg;
/// module docs); `None` without the robot-pose corrections, a DH table or joint readings
/// for every view.
pub(super) fn term(
    problem: &JointProblem<'_>,
    layout: &ParamLayout,
    res: &LmResult,
    s: &JointParams,
    opts: &JointOptions,
) -> Result<Option<(DMatrix<f64>, (f64, f64))>> {
    let Some(nominal) = opts.kinematics.as_ref() else {
        return Ok(None);
    };
    if !problem.robot_noise() || !(res.sigma2 > 0.0) {
        return Ok(None);
    }
    // Both robot components at their floors: no robot error beyond what the views
    // resolve, nothing to attribute.
    let st = problem.robot_state();
    if st.at_floor.0 && st.at_floor.1 {
        return Ok(None);
    }
    let terms = &problem.terms;
    let Some(readings) = terms
        .q
        .iter()
        .map(|q| q.clone().filter(|q| q.len() == nominal.dof()))
        .collect::<Option<Vec<Vec<f64>>>>()
    else {
        return Ok(None);
    };
    let (robot, estimated) = match &layout.robot {
        Some(rb) => (rb.corrected(&s.robot), rb.params.clone()),
        None => (nominal.clone(), Vec::new()),
    };
    let params: Vec<_> = candidates(&robot, RobotMode::Full)
        .into_iter()
        .filter(|p| !estimated.contains(p))
        .collect();
    if params.is_empty() {
        return Ok(None);
    }
    // Each view's flange motion per DH number, in its correction's frame.
    let twists: Vec<Vec<[f64; 6]>> = readings
        .iter()
        .zip(&s.corrections)
        .map(|(q, (rd, td))| {
            flange_twists(&robot, q, &params)
                .into_iter()
                .map(|c| {
                    let w = Vector3::new(c[0], c[1], c[2]);
                    let v = Vector3::new(c[3], c[4], c[5]);
                    let (wf, vf): (Vector3<f64>, Vector3<f64>) =
                        (rd.transpose() * w, rd.transpose() * (v + w.cross(td)));
                    [wf.x, wf.y, wf.z, vf.x, vf.y, vf.z]
                })
                .collect()
        })
        .collect();
    let Some(g) = problem.flange_response(&res.params, &twists)? else {
        return Ok(None);
    };
    let k = -(&res.covariance / res.sigma2) * g;
    if k.iter().any(|x| !x.is_finite()) {
        return Ok(None);
    }
    // The weights and the robot rows' values at the solution.
    let w = problem.robot_weights();
    let wk = [
        w.rotation,
        w.rotation,
        w.rotation,
        w.translation,
        w.translation,
        w.translation,
    ];
    let values = super::robot_noise::prior_values(s);
    // Per group of robot rows (rotation, translation): their weighted sum of squares,
    // and per DH number their response's.
    let mut num = [0.0; 2];
    for (i, d) in values.iter().enumerate() {
        let e = s.image_pose.get(i).copied().unwrap_or([0.0; 6]);
        for q in 0..6 {
            num[q / 3] += (wk[q] * (d[q] - e[q])).powi(2);
        }
    }
    let is_length = |kind: DhKind| matches!(kind, DhKind::D | DhKind::A);
    // [lengths, angles] x [rotation rows, translation rows]
    let mut den = [[0.0; 2]; 2];
    for i in 0..values.len() {
        let Some(c) = layout.view_columns(Block::RobotPose, i) else {
            continue;
        };
        let ce = layout.view_columns(Block::ImagePose, i);
        for (j, p) in params.iter().enumerate() {
            let kind = usize::from(!is_length(p.kind));
            for q in 0..6 {
                let de = ce.as_ref().map_or(0.0, |ce| k[(ce.start + q, j)]);
                den[kind][q / 3] += (wk[q] * (k[(c.start + q, j)] - de)).powi(2);
            }
        }
    }
    // The angles from the rotation rows (lengths do not turn the flange), the lengths
    // from what the translation rows leave.
    let s2_angle = if den[1][0] > 0.0 {
        num[0] / den[1][0]
    } else {
        0.0
    };
    let s2_length = if den[0][1] > 0.0 {
        ((num[1] - s2_angle * den[1][1]) / den[0][1]).max(0.0)
    } else {
        0.0
    };
    if !(s2_angle.is_finite() && s2_length.is_finite()) || s2_angle + s2_length <= 0.0 {
        return Ok(None);
    }
    let ng = layout.num_global();
    let kg = k.rows(0, ng);
    let d = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
        params.len(),
        params.iter().map(|p| {
            if is_length(p.kind) {
                s2_length
            } else {
                s2_angle
            }
        }),
    ));
    let t = &kg * d * kg.transpose();
    let t = 0.5 * (&t + t.transpose());
    Ok(t.iter()
        .all(|x| x.is_finite())
        .then(|| (t, (s2_length.sqrt(), s2_angle.sqrt()))))
}
