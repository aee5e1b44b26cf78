//! Phase 3 of a plan: the predicted covariance's figures: the one-sigma of every number
//! of calibration.json and of every adjusted parameter, and the covariance matrix.

use super::SigmaEntry;
use crate::calib::joint::Prediction;

/// The one-sigmas of calibration.json's numbers, their covariance (rows), and the
/// one-sigmas of the adjustment's parameters.
pub(super) fn parameter_figures(
    pred: &Prediction,
) -> (Vec<SigmaEntry>, Vec<Vec<f64>>, Vec<SigmaEntry>) {
    let named = &pred.named_covariance;
    let parameters = named
        .parameters
        .iter()
        .enumerate()
        .map(|(i, n)| SigmaEntry {
            name: n.clone(),
            sigma: named.matrix[(i, i)].max(0.0).sqrt(),
        })
        .collect();
    let covariance = (0..named.matrix.nrows())
        .map(|r| named.matrix.row(r).iter().copied().collect())
        .collect();
    let state = pred
        .param_names
        .iter()
        .enumerate()
        .map(|(i, n)| SigmaEntry {
            name: n.clone(),
            sigma: pred.covariance[(i, i)].max(0.0).sqrt(),
        })
        .collect();
    (parameters, covariance, state)
}
