//! Phase 3: the views with their modelled stripe points moved by predicted biases, the
//! points the model cannot follow left out.

use super::Pt;
use crate::calib::{kept, ViewObs};

/// `views` with every kept point of `clear` moved by its bias `d[k]` along the scan
/// line (coordinate `along`), the points not kept (`keep`) or without a bias left out.
pub(super) fn moved_views(
    views: &[ViewObs],
    clear: &[&Pt],
    keep: &[bool],
    d: &[Option<f64>],
    along: usize,
) -> Vec<ViewObs> {
    let mut out: Vec<ViewObs> = views.to_vec();
    let mut kept_pts: Vec<Vec<bool>> = views.iter().map(|v| vec![true; v.stripe.len()]).collect();
    for ((q, k), dk) in clear.iter().zip(keep).zip(d) {
        match (k, dk) {
            (true, Some(dk)) => out[q.view].stripe[q.idx][along] = q.a - dk,
            _ => kept_pts[q.view][q.idx] = false,
        }
    }
    for (v, k) in out.iter_mut().zip(&kept_pts) {
        if k.iter().all(|x| *x) {
            continue;
        }
        v.stripe = kept(&v.stripe, k);
        if let Some(sh) = v.stripe_shape.as_mut() {
            *sh = sh.subset(k);
        }
    }
    out
}
