//! Phase 1: the sheet's and the PSF's Gaussian sigmas from the stripe widths, by linear
//! least squares on `(w / 2.3548)^2 - k / 12 = g^2 sigma^2 + k b^2` (`k = 1 + m^2`).

use nalgebra::{Matrix2, Vector2};

use super::{Pt, MIN_POINTS, WIDTH_POINTS};
use crate::stripe_model::{board_point_scale, BoardSurface, Rig};

/// The sheet's sigma (mm) and the PSF's (px) from the widths of at most
/// [`WIDTH_POINTS`] of the `clear` points (`g` and the slope do not depend on them);
/// `Err` when the widths do not determine them.
pub(super) fn sheet_sigmas(
    rig: &Rig<'_>,
    surfaces: &[Option<BoardSurface<'_>>],
    clear: &[&Pt],
) -> Result<(f64, f64), String> {
    let step = clear.len().div_ceil(WIDTH_POINTS).max(1);
    let sub: Vec<&Pt> = clear.iter().step_by(step).copied().collect();
    let geo: Vec<Option<(f64, f64)>> = sub
        .iter()
        .map(|q| board_point_scale(rig, surfaces[q.view].as_ref()?, q.line, &q.p))
        .collect();
    let (mut a, mut r) = (Matrix2::<f64>::zeros(), Vector2::<f64>::zeros());
    let mut used = 0;
    for (q, g) in sub.iter().zip(&geo) {
        let Some((g, m)) = *g else { continue };
        let k = 1.0 + m * m;
        let y = (q.width / 2.3548).powi(2) - k / 12.0;
        let x = Vector2::new(g * g, k);
        a += x * x.transpose();
        r += x * y;
        used += 1;
    }
    let undetermined = || {
        "the stripe widths do not determine the sheet's thickness (the boards' tilts \
         are too alike)"
            .to_string()
    };
    if used < MIN_POINTS {
        return Err(undetermined());
    }
    let sol = a.lu().solve(&r).ok_or_else(undetermined)?;
    let (s2, b2) = if sol[1] < 0.0 {
        // No PSF term: the sheet alone.
        (r[0] / a[(0, 0)], 0.0)
    } else {
        (sol[0], sol[1])
    };
    if !(s2.is_finite() && s2 > 0.0) {
        return Err(undetermined());
    }
    Ok((s2.sqrt(), b2.sqrt()))
}
