//! Phase 2: the bias the extractor's centroid has on each modelled point, px along the
//! scan line, for the sheet and PSF found and the emitter at a given position.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::points::surfaces;
use super::Pt;
use crate::model::geometry::Plane;
use crate::stripe_model::{board_point_profile, extractor_response, PointProfile, Rig};

/// Every [`EMITTER_KNOT_STEP`]th point of each view's run in `clear` (and its last)
/// for the moved emitters' biases.
pub(super) const EMITTER_KNOT_STEP: usize = 4;

/// [`predicted_biases`] with the emitter at `emitter` instead of the rig's, for the
/// points whose bias at the rig's emitter is `nominal` (`Some`: the points corrected):
/// the change from `nominal` modelled at the knots (every [`EMITTER_KNOT_STEP`]th
/// point of each view's run, and its last; 0 where the moved emitter's model fails) and
/// linear in the point's order between them. The change is smooth along a view's
/// stripe (the emitter moves the sheet's incidence, not the pixel grid), so a quarter of
/// the model runs give the emitter's response; `nominal`'s `None` stay `None`.
pub(super) fn moved_biases(
    rig: &Rig<'_>,
    boards: &[Plane],
    clear: &[&Pt],
    nominal: &[Option<f64>],
    (sigma, psf): (f64, f64),
    emitter: Vector3<f64>,
) -> Vec<Option<f64>> {
    let n = clear.len();
    // the knots: per view's run, every EMITTER_KNOT_STEP-th point and the last
    let mut knots = Vec::new();
    let mut start = 0;
    while start < n {
        let end = (start..n)
            .find(|&i| clear[i].view != clear[start].view)
            .unwrap_or(n);
        knots.extend((start..end).step_by(EMITTER_KNOT_STEP));
        if knots.last() != Some(&(end - 1)) {
            knots.push(end - 1);
        }
        start = end;
    }
    let at: Vec<&Pt> = knots.iter().map(|&i| clear[i]).collect();
    let alt = predicted_biases(rig, boards, &at, sigma, psf, emitter);
    let change: Vec<Option<f64>> = knots
        .iter()
        .zip(&alt)
        .map(|(&i, a)| nominal[i].map(|b| a.map_or(0.0, |a| a - b)))
        .collect();
    let mut out = nominal.to_vec();
    for w in 0..knots.len() {
        let (i0, c0) = (knots[w], change[w]);
        if let (Some(b), Some(c)) = (out[i0], c0) {
            out[i0] = Some(b + c);
        }
        // the points after this knot, up to the next one of the same view
        let Some(&i1) = knots
            .get(w + 1)
            .filter(|&&i1| clear[i1].view == clear[i0].view)
        else {
            continue;
        };
        for (i, o) in out.iter_mut().enumerate().take(i1).skip(i0 + 1) {
            let t = (i - i0) as f64 / (i1 - i0) as f64;
            let c = match (c0, change[w + 1]) {
                (Some(a), Some(b)) => a + t * (b - a),
                (Some(a), None) => a,
                (None, Some(b)) => b,
                (None, None) => 0.0,
            };
            *o = o.map(|b| b + c);
        }
    }
    out
}

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
