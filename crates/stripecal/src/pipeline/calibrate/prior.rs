//! `--from FILE` without `--fix` (DECISIONS 4): the file's camera and laser plane enter
//! with their covariance, so that a few robot views suffice for the hand-eye and the
//! robot-world transforms, and the uncertainty says what the earlier calibration (e.g.
//! the bench's) contributed.
//!
//! ## What is computed
//!
//! The camera and the laser plane (the blocks the file has) are held at the file's values
//! and the adjustment estimates the rest, as with `--fix camera,laser_plane`. Their
//! covariance `C_h` (the file's `covariance` key, with its correlations) is then carried
//! into the estimated numbers `x` to first order: along each principal direction
//! `delta_k = sqrt(lambda_k) e_k` of `C_h`, the calibration is run again from the file
//! moved by `+-delta_k` ([`perturbed_calibration`]), and `g_k = (x(+) - x(-)) / 2`:
//!
//! ```text
//! C_xx = C_xx|h + sum_k g_k g_k^T,     C_xh = sum_k g_k delta_k^T
//! ```
//!
//! (`C_xx|h` the adjustment's covariance with the blocks held). calibration.json's
//! `covariance` holds all of it, the held blocks' part the file's `C_h`, and
//! `uncertainty` the new one-sigmas; extra `prior` names the blocks and the directions.
//!
//! This is a prior of full weight: the new views do not move the camera and the plane
//! (their sigmas stay the file's). It is the limit of the Bayesian update when the
//! earlier calibration knows those blocks much better than the new views do (15 bench
//! views against 3 robot views); a prior the new views could refine is not implemented.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use serde_json::{json, Value};

use super::{CalibrateOptions, CalibrationReport};
use crate::calib::joint::DhParam;
use crate::error::{Error, Result};
use crate::model::calibration_number;
use crate::model::{Calibration, NamedCovariance, QualityCheck};
use crate::reconstruct::uncertainty::perturbed_calibration;

/// Principal directions of `C_h` below this fraction of the largest are not propagated.
const MIN_EIGEN_FRACTION: f64 = 1e-12;

/// The pipeline with the file's camera and plane as a prior (module docs); `calibrate`
/// runs the pipeline (without its verdict) with the options given, the blocks held.
pub(super) fn calibrate_with_prior(
    opts: &CalibrateOptions,
    from: &Calibration,
    calibrate: impl Fn(&CalibrateOptions) -> Result<(CalibrationReport, Vec<QualityCheck>)>,
) -> Result<(CalibrationReport, Vec<QualityCheck>)> {
    let Some(fc) = from.covariance.as_ref() else {
        return Err(Error::InvalidInput(
            "--from without --fix: the file's camera and laser plane enter with their \
             covariance, but the file has no \"covariance\" key (written before every \
             calibration carried it); hold them instead with --fix camera,laser_plane"
                .into(),
        ));
    };
    let mut held = opts.clone();
    held.free.camera = false;
    let mut blocks = vec!["camera"];
    if from.laser_plane.is_some() {
        held.free.laser_plane = false;
        blocks.push("laser_plane");
    }
    let (mut rep, checks) = calibrate(&held)?;
    // The held blocks' covariance, with its correlations.
    let hidx: Vec<usize> = (0..fc.parameters.len())
        .filter(|&i| {
            blocks
                .iter()
                .any(|b| fc.parameters[i].starts_with(&format!("{b}.")))
        })
        .collect();
    let hnames: Vec<String> = hidx.iter().map(|&i| fc.parameters[i].clone()).collect();
    let chh = DMatrix::from_fn(hidx.len(), hidx.len(), |r, c| fc.matrix[(hidx[r], hidx[c])]);
    let Some(cov) = rep.calibration.covariance.clone() else {
        return Ok((rep, checks));
    };
    let enames: Vec<String> = cov
        .parameters
        .iter()
        .filter(|n| !blocks.iter().any(|b| n.starts_with(&format!("{b}."))))
        .cloned()
        .collect();
    let eig = SymmetricEigen::new(chh.clone());
    let lmax = eig.eigenvalues.iter().fold(0.0f64, |a, &b| a.max(b));
    let quiet = CalibrateOptions {
        leave_one_out: false,
        ..held.clone()
    };
    let mut cee = DMatrix::<f64>::zeros(enames.len(), enames.len());
    let mut ceh = DMatrix::<f64>::zeros(enames.len(), hnames.len());
    let mut directions = 0;
    for (k, &lambda) in eig.eigenvalues.iter().enumerate() {
        if lambda.is_nan() || lambda <= MIN_EIGEN_FRACTION * lmax {
            continue;
        }
        let delta: DVector<f64> = eig.eigenvectors.column(k) * lambda.sqrt();
        let mut x = Vec::with_capacity(2);
        for s in [1.0, -1.0] {
            let d: Vec<f64> = delta.iter().map(|v| s * v).collect();
            let moved = perturbed_calibration(from, &hnames, &d)?;
            let o = CalibrateOptions {
                from: Some(moved),
                ..quiet.clone()
            };
            let (r, _) = calibrate(&o)?;
            x.push(
                enames
                    .iter()
                    .map(|n| named_value(&r.calibration, n))
                    .collect::<Vec<_>>(),
            );
        }
        let g = DVector::from_fn(enames.len(), |i, _| match (x[0][i], x[1][i]) {
            (Some(a), Some(b)) if (a - b).abs() < 0.5 => 0.5 * (a - b),
            _ => 0.0,
        });
        cee += &g * g.transpose();
        ceh += &g * delta.transpose();
        directions += 1;
    }
    // The new covariance: the estimated numbers (with the propagated part), then the
    // held ones, with their cross terms.
    let (ne, nh) = (enames.len(), hnames.len());
    let mut m = DMatrix::<f64>::zeros(ne + nh, ne + nh);
    for (i, a) in enames.iter().enumerate() {
        for (j, b) in enames.iter().enumerate() {
            let old = match (cov.index(a), cov.index(b)) {
                (Some(p), Some(q)) => cov.matrix[(p, q)],
                _ => 0.0,
            };
            m[(i, j)] = old + cee[(i, j)];
        }
    }
    m.view_mut((0, ne), (ne, nh)).copy_from(&ceh);
    m.view_mut((ne, 0), (nh, ne)).copy_from(&ceh.transpose());
    m.view_mut((ne, ne), (nh, nh)).copy_from(&chh);
    let named = NamedCovariance {
        parameters: enames.iter().chain(&hnames).cloned().collect(),
        matrix: m,
    };
    update_uncertainty(&mut rep.calibration.uncertainty, &named, &enames);
    rep.calibration.covariance = Some(named);
    let c = &mut rep.calibration;
    c.records.held_blocks = None;
    c.extra.insert(
        "prior".into(),
        json!({"blocks": blocks, "propagated_directions": directions,
               "mode": "held at the file's values, their covariance propagated"}),
    );
    Ok((rep, checks))
}

/// The one-sigmas of the estimated transforms in calibration.json's `uncertainty` from
/// the new covariance (`hand_cam`, `base_board`; other entries as they are).
fn update_uncertainty(
    u: &mut serde_json::Map<String, Value>,
    cov: &NamedCovariance,
    names: &[String],
) {
    for key in ["hand_cam", "base_board"] {
        let Some(entry) = u.get_mut(key).and_then(Value::as_object_mut) else {
            continue;
        };
        for part in ["rotation_vector", "translation_mm"] {
            let sd: Vec<Value> = (0..3)
                .map(|k| {
                    let n = format!("{key}.{part}[{k}]");
                    let s = names
                        .contains(&n)
                        .then(|| cov.sigma(&n))
                        .flatten()
                        .unwrap_or(0.0);
                    Value::from(s)
                })
                .collect();
            entry.insert(part.into(), Value::Array(sd));
        }
    }
}

/// One of a calibration's numbers by its contract name (`None` when it has no such
/// number).
fn named_value(c: &Calibration, name: &str) -> Option<f64> {
    let n = calibration_number(
        &c.camera,
        c.laser_plane.as_ref(),
        &c.hand_cam,
        &c.base_board,
        name,
    );
    if n.is_some() {
        return n;
    }
    let robot = c.robot.as_ref()?;
    let p = DhParam::from_name(name, robot.dof())?;
    let mut joint = *robot.joints.get(p.joint)?;
    Some(*p.kind.get_mut(&mut joint))
}
