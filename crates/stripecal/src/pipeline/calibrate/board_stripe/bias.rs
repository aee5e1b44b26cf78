//! Phase 2: the bias the extractor's centroid has on each modelled point, px along the
//! scan line, for the sheet and PSF found and the emitter at a given position.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::points::surfaces;
use super::Pt;
use crate::model::geometry::Plane;
use crate::stripe_model::{board_point_profile, extractor_response, PointProfile, Rig};

/// The predicted bias of each of the `clear` points (`None`: a point the model cannot
/// follow) with the emitter at `emitter` (camera frame).
pub(super) fn predicted_biases(
    rig: &Rig<'_>,
    boards: &[Plane],
    clear: &[&Pt],
    sigma: f64,
    psf: f64,
    emitter: Vector3<f64>,
) -> Vec<Option<f64>> {
    let mut r2 = rig.clone();
    r2.emitter = emitter;
    let surf = surfaces(&r2, boards);
    clear
        .par_iter()
        .map_init(
            || (PointProfile::default(), Vec::new()),
            |(prof, buf), q| {
                let s = surf[q.view].as_ref()?;
                if !board_point_profile(&r2, s, q.line, &q.p, sigma, psf, prof) {
                    return None;
                }
                extractor_response(prof, psf, r2.stripe, buf).map(|x| x.0)
            },
        )
        .collect()
}
