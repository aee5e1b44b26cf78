//! The robot block's rounds: select the DH corrections the data determine
//! ([`super::robot_select`]) and, for `auto`, adjust with them and select again from
//! there until nothing is added. The caller solves with the final block (for `full` and
//! `offsets` its only solve with the corrections) and reports.

use super::layout::ParamLayout;
use super::residuals::{JointProblem, Terms, GROUPS};
use super::robot::{candidates, DhParam, RobotBlock, RobotMode};
use super::robot_select::{information, select};
use super::{solve, FreeBlocks, JointOptions, JointStart};
use crate::error::{Error, Result};
use crate::model::kinematics::Robot;
use crate::model::{DhCorrection, RobotCalibration};
use nalgebra::DMatrix;

/// Rounds of `auto`'s selection at most (each adds at least one correction).
const MAX_ROUNDS: usize = 4;

/// The robot to calibrate and how (`--robot`).
#[derive(Debug, Clone, PartialEq)]
pub struct RobotOptions {
    /// rig.json's robot: the corrections are relative to it.
    pub nominal: Robot,
    pub mode: RobotMode,
}

/// What the rounds settled on.
pub(super) struct RobotOutcome {
    /// The final block: the reference robot (the corrections of the rounds folded in)
    /// and the corrections chosen (`None`: none chosen).
    pub block: Option<RobotBlock>,
    pub nominal: Robot,
    pub mode: RobotMode,
    /// The candidates left fixed, with why.
    pub fixed: Vec<(DhParam, String)>,
    /// Where the final solve starts (in `layout`'s terms) and its image weights.
    pub layout: ParamLayout,
    pub p: Vec<f64>,
    pub weights: [f64; GROUPS],
}

/// `p` of layout `from` carried over to layout `to` by parameter name; the robot's
/// corrections start at zero (the rounds fold them into the reference robot).
pub(super) fn transfer(from: &ParamLayout, p: &[f64], to: &ParamLayout) -> Vec<f64> {
    let mut out = to.encode();
    let names_from = from.names();
    let names_to = to.names();
    for (i, name) in names_to.iter().enumerate() {
        if name.starts_with("robot.joints") {
            continue;
        }
        if let Some(j) = names_from.iter().position(|n| n == name) {
            out[i] = p[j];
        }
    }
    out
}

/// The rounds (module docs) from the robot-held solution `p0` of `layout0`; `None`
/// when the robot is not calibrated.
pub(super) fn robot_rounds(
    start: &JointStart,
    free: &FreeBlocks,
    opts: &JointOptions,
    terms: &Terms,
    layout0: &ParamLayout,
    p0: &[f64],
    weights0: [f64; GROUPS],
) -> Result<Option<RobotOutcome>> {
    let Some(ro) = opts.robot.as_ref() else {
        return Ok(None);
    };
    if ro.mode == RobotMode::Fixed {
        return Ok(None);
    }
    let readings = readings(terms, ro)?;
    let cands = candidates(&ro.nominal, ro.mode);
    let mut reference = ro.nominal.clone();
    let mut chosen: Vec<usize> = Vec::new();
    let mut fixed = Vec::new();
    let mut layout = layout0.clone();
    let mut p = p0.to_vec();
    let mut weights = weights0;
    let rounds = if ro.mode == RobotMode::Auto {
        MAX_ROUNDS
    } else {
        1
    };
    let block_of = |reference: &Robot, params: Vec<DhParam>| RobotBlock {
        reference: reference.clone(),
        params,
        readings: readings.clone(),
    };
    for _ in 0..rounds {
        let lc = ParamLayout::of(
            start,
            free,
            opts,
            &terms.used,
            Some(block_of(&reference, cands.clone())),
        );
        let pc = transfer(&layout, &p, &lc);
        let mut prob = JointProblem::new(&start.camera, &lc, terms.clone(), opts);
        prob.set_all_weights(&weights);
        prob.prepare_solve(opts.centre_model, opts.centre_model);
        let info = information(&prob, &pc)?;
        let sel = select(&info, &lc, &cands, ro.mode, &chosen)?;
        let added = sel.chosen.len() > chosen.len();
        chosen = sel.chosen;
        fixed = sel.fixed;
        // Without another round to follow (`full`, `offsets`, or nothing added), the
        // caller's final solve is the one with these corrections.
        if !added || rounds == 1 {
            break;
        }
        let block = block_of(&reference, chosen.iter().map(|&i| cands[i]).collect());
        let lk = ParamLayout::of(start, free, opts, &terms.used, Some(block.clone()));
        let pk = transfer(&layout, &p, &lk);
        let mut prob = JointProblem::new(&start.camera, &lk, terms.clone(), opts);
        prob.set_all_weights(&weights);
        let (res, _) = solve(&mut prob, pk, opts, false)?;
        weights = prob.all_weights();
        reference = block.corrected(&res.params[lk.robot_columns()]);
        p = res.params;
        layout = lk;
    }
    let block = (!chosen.is_empty())
        .then(|| block_of(&reference, chosen.iter().map(|&i| cands[i]).collect()));
    Ok(Some(RobotOutcome {
        block,
        nominal: ro.nominal.clone(),
        mode: ro.mode,
        fixed: fixed.into_iter().map(|(i, why)| (cands[i], why)).collect(),
        layout,
        p,
        weights,
    }))
}

/// `(name, why)` of the DH corrections held.
pub(super) type Held = Vec<(String, String)>;

/// For pose planning (no observations yet): the corrections the identifiability rule
/// keeps at `start` (`full`'s structural rule for `full` and `auto`, whose significance
/// needs data; `offsets`' for `offsets`) and the candidates it fixes, with why.
pub(super) fn structural_block(
    start: &JointStart,
    free: &FreeBlocks,
    opts: &JointOptions,
    terms: &Terms,
) -> Result<(Option<RobotBlock>, Held)> {
    let Some(ro) = opts.robot.as_ref().filter(|r| r.mode != RobotMode::Fixed) else {
        return Ok((None, Vec::new()));
    };
    let mode = if ro.mode == RobotMode::Auto {
        RobotMode::Full
    } else {
        ro.mode
    };
    let cands = candidates(&ro.nominal, mode);
    let all = RobotBlock {
        reference: ro.nominal.clone(),
        params: cands.clone(),
        readings: readings(terms, ro)?,
    };
    let lc = ParamLayout::of(start, free, opts, &terms.used, Some(all.clone()));
    let mut prob = JointProblem::new(&start.camera, &lc, terms.clone(), opts);
    prob.prepare_solve(opts.centre_model, opts.centre_model);
    let info = information(&prob, &lc.encode())?;
    let sel = select(&info, &lc, &cands, mode, &[])?;
    let fixed = sel
        .fixed
        .iter()
        .map(|(i, why)| (cands[*i].name(), why.clone()))
        .collect();
    let block = (!sel.chosen.is_empty()).then(|| RobotBlock {
        params: sel.chosen.iter().map(|&i| cands[i]).collect(),
        ..all
    });
    Ok((block, fixed))
}

/// Every used view's joint readings (errors name a view without them).
fn readings(terms: &Terms, ro: &RobotOptions) -> Result<Vec<Vec<f64>>> {
    terms
        .q
        .iter()
        .zip(&terms.used)
        .map(|(q, view)| {
            let q = q.clone().ok_or_else(|| {
                Error::InvalidInput(format!(
                    "view {view}: robot calibration (--robot {}) needs joint readings; the \
                     view gives a flange pose",
                    ro.mode.name()
                ))
            })?;
            if q.len() != ro.nominal.dof() {
                return Err(Error::InvalidInput(format!(
                    "view {view}: {} joint readings for a robot with {} DH rows",
                    q.len(),
                    ro.nominal.dof()
                )));
            }
            Ok(q)
        })
        .collect::<Result<Vec<_>>>()
}

/// The report of the rounds' outcome at the final solution `p` of `layout` (whose robot
/// block, if any, is `out.block`), its covariance `cov`.
pub(super) fn report(
    out: &RobotOutcome,
    layout: &ParamLayout,
    p: &[f64],
    cov: &DMatrix<f64>,
) -> RobotCalibration {
    let rc = layout.robot_columns();
    let (robot, estimated) = match &layout.robot {
        Some(block) if !rc.is_empty() => {
            let values = &p[rc.clone()];
            let robot = block.corrected(values);
            let est = block
                .params
                .iter()
                .enumerate()
                .map(|(k, prm)| {
                    let get = |r: &Robot| {
                        let j = &r.joints[prm.joint];
                        match prm.kind {
                            super::robot::DhKind::Theta0 => j.theta0_deg,
                            super::robot::DhKind::D => j.d_mm,
                            super::robot::DhKind::A => j.a_mm,
                            super::robot::DhKind::Alpha => j.alpha_deg,
                            super::robot::DhKind::Beta => j.beta_deg,
                        }
                    };
                    let c = rc.start + k;
                    DhCorrection {
                        name: prm.name(),
                        correction: get(&robot) - get(&out.nominal),
                        sigma: cov[(c, c)].max(0.0).sqrt(),
                    }
                })
                .collect();
            (robot, est)
        }
        _ => (out.nominal.clone(), Vec::new()),
    };
    RobotCalibration {
        mode: out.mode.name().into(),
        robot,
        estimated,
        fixed: out
            .fixed
            .iter()
            .map(|(p, why)| (p.name(), why.clone()))
            .collect(),
    }
}
