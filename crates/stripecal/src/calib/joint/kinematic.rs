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
//! their rows of `K`. The robot rows' weighted values `y` (unit variance for the robot's
//! random part) are modelled as `A d + e`, `A` those responses, with independent DH
//! errors of one-sigma `s_a` (angles, deg) and `s_l` (lengths, mm): the part of `y` in the
//! span of `A` has the expected square `s^2 |A|_F^2 + rank A`, white noise alone giving
//! `rank A`. `s_a` comes from the rotation rows (lengths do not turn the flange), `s_l`
//! from the translation rows with the angles' predicted part taken out, each `max(0, |P
//! y|^2 - rank) / |A|_F^2`; a robot whose pose noise is random gives less (the twin with
//! 0.015 deg of reading noise: 0.2-0.3 mm, against 0.52 mm for a link 2 mm off, the RMS
//! over the twelve lengths 0.58 mm). The covariance of the global numbers gains `K_g
//! diag(s_j^2) K_g^T`. A DH number already estimated (`--robot`) is left out
//! (its uncertainty is in the covariance).

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use super::layout::{Block, JointParams, ParamLayout};
use super::residuals::JointProblem;
use super::robot::{candidates, flange_twists, DhKind, DhParam, RobotMode};
use super::JointOptions;
use crate::error::Result;
use crate::model::kinematics::Robot;
use crate::numerics::lm::LmResult;

/// The covariance term of the global numbers and the DH sigmas `(lengths mm, angles
/// deg)`.
pub(super) type KinematicTerm = (DMatrix<f64>, (f64, f64));

/// The covariance term of the global numbers and the DH sigmas (lengths mm, angles deg;
/// module docs); `None` without the robot-pose corrections, a DH table or joint readings
/// for every view.
pub(super) fn term(
    problem: &JointProblem<'_>,
    layout: &ParamLayout,
    res: &LmResult,
    s: &JointParams,
    opts: &JointOptions,
) -> Result<Option<KinematicTerm>> {
    let Some(nominal) = opts.kinematics.as_ref() else {
        return Ok(None);
    };
    if !problem.robot_noise() || res.sigma2.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
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
    let twists = view_twists(&robot, &readings, &s.corrections, &params);
    let Some(g) = problem.flange_response(&res.params, &twists)? else {
        return Ok(None);
    };
    let k = -(&res.covariance / res.sigma2) * g;
    if k.iter().any(|x| !x.is_finite()) {
        return Ok(None);
    }
    let Some((y, resp)) = robot_rows(problem, layout, s, &k, params.len()) else {
        return Ok(None);
    };
    let is_length = |kind: DhKind| matches!(kind, DhKind::D | DhKind::A);
    let (lengths, angles): (Vec<usize>, Vec<usize>) =
        (0..params.len()).partition(|&j| is_length(params[j].kind));
    let cols = |m: &DMatrix<f64>, js: &[usize]| {
        DMatrix::from_fn(m.nrows(), js.len(), |r, c| m[(r, js[c])])
    };
    // The angles from the rotation rows (lengths do not turn the flange); the lengths from
    // the translation rows, the angles' fitted part taken out.
    let (s2_angle, fitted) = moment(&y[0], &cols(&resp[0], &angles));
    let rest = &y[1] - cols(&resp[1], &angles) * fitted;
    let (s2_length, _) = moment(&rest, &cols(&resp[1], &lengths));
    if !(s2_angle.is_finite() && s2_length.is_finite()) || s2_angle + s2_length <= 0.0 {
        return Ok(None);
    }
    let ng = layout.num_global();
    let kg = k.rows(0, ng);
    let d = DMatrix::from_diagonal(&DVector::from_iterator(
        params.len(),
        params.iter().map(|p| {
            if is_length(p.kind) {
                s2_length
            } else {
                s2_angle
            }
        }),
    ));
    let t = kg * d * kg.transpose();
    let t = 0.5 * (&t + t.transpose());
    Ok(t.iter()
        .all(|x| x.is_finite())
        .then(|| (t, (s2_length.sqrt(), s2_angle.sqrt()))))
}

/// Each view's flange motion per DH number of `params` (its joint readings `readings`),
/// in its correction's frame (`corrections`).
fn view_twists(
    robot: &Robot,
    readings: &[Vec<f64>],
    corrections: &[(Matrix3<f64>, Vector3<f64>)],
    params: &[DhParam],
) -> Vec<Vec<[f64; 6]>> {
    readings
        .iter()
        .zip(corrections)
        .map(|(q, (rd, td))| {
            flange_twists(robot, q, params)
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
        .collect()
}

/// The robot rows' weighted values (rotation rows, translation rows) and their responses
/// per DH number (rows x DH numbers).
type RobotRows = ([DVector<f64>; 2], [DMatrix<f64>; 2]);

/// The robot rows' weighted values `y` and their responses per DH number (`np` of
/// them; `k` the solution's response to each), rotation rows and translation rows
/// apart; `None` when a view has no correction columns.
fn robot_rows(
    problem: &JointProblem<'_>,
    layout: &ParamLayout,
    s: &JointParams,
    k: &DMatrix<f64>,
    np: usize,
) -> Option<RobotRows> {
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
    let nv = values.len();
    let mut y = [DVector::zeros(3 * nv), DVector::zeros(3 * nv)];
    let mut resp = [DMatrix::zeros(3 * nv, np), DMatrix::zeros(3 * nv, np)];
    for (i, d) in values.iter().enumerate() {
        let e = s.image_pose.get(i).copied().unwrap_or([0.0; 6]);
        let c = layout.view_columns(Block::RobotPose, i)?;
        let ce = layout.view_columns(Block::ImagePose, i);
        for q in 0..6 {
            let (g, row) = (q / 3, 3 * i + q % 3);
            y[g][row] = wk[q] * (d[q] - e[q]);
            for j in 0..np {
                let de = ce.as_ref().map_or(0.0, |ce| k[(ce.start + q, j)]);
                resp[g][(row, j)] = wk[q] * (k[(c.start + q, j)] - de);
            }
        }
    }
    Some((y, resp))
}

/// The variance per unit of the DH numbers whose responses are the columns of `a` in the
/// unit-weighted rows `y = a d + e` (`e` white, unit variance): `max(0, |P y|^2 - r) /
/// |a|_F^2` (`P` the projection onto `a`'s columns, `r` their rank: what white noise
/// alone puts there), and the least-squares `d` (zero without columns).
fn moment(y: &DVector<f64>, a: &DMatrix<f64>) -> (f64, DVector<f64>) {
    if a.ncols() == 0 || a.nrows() == 0 {
        return (0.0, DVector::zeros(a.ncols()));
    }
    let svd = a.clone().svd(true, true);
    let (Some(u), Some(vt)) = (&svd.u, &svd.v_t) else {
        return (0.0, DVector::zeros(a.ncols()));
    };
    let smax = svd.singular_values.max();
    let mut explained = 0.0;
    let mut rank = 0.0;
    for (k, sv) in svd.singular_values.iter().enumerate() {
        if *sv > 1e-9 * smax {
            explained += u.column(k).dot(y).powi(2);
            rank += 1.0;
        }
    }
    let norm = a.norm_squared();
    let s2 = if norm > 0.0 {
        ((explained - rank) / norm).max(0.0)
    } else {
        0.0
    };
    let mut d = DVector::zeros(a.ncols());
    for (k, sv) in svd.singular_values.iter().enumerate() {
        let c = u.column(k).dot(y);
        d += vt.row(k).transpose() * (c * s2 * sv / (s2 * sv * sv + 1.0));
    }
    (s2, d)
}
