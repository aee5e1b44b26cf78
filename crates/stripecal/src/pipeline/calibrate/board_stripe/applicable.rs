//! Whether the model describes the views' lines: one scan direction, mostly
//! unsaturated, not smoothed along the line (the module docs of [`super`]).

use super::MAX_SATURATED_SHARE;
use crate::calib::ViewObs;
use crate::model::StripeDirection;

/// The views' common scan direction; `Err` with the reason when the model does not
/// describe their lines (no widths recorded, mixed directions, mostly saturated,
/// smoothed along the line for speckle).
pub(super) fn modelled_direction(views: &[ViewObs]) -> Result<StripeDirection, String> {
    let direction = views
        .iter()
        .find_map(|v| v.stripe_shape.as_ref().map(|s| s.direction))
        .ok_or("no stripe widths were recorded")?;
    if direction == StripeDirection::Auto
        || views.iter().any(|v| {
            v.stripe_shape
                .as_ref()
                .is_some_and(|s| s.direction != direction)
        })
    {
        return Err("the views' stripes were extracted in different scan directions".into());
    }
    let shapes = || views.iter().filter_map(|v| v.stripe_shape.as_ref());
    let n_all: usize = shapes().map(|s| s.saturated.len()).sum();
    let n_sat: usize = shapes()
        .map(|s| s.saturated.iter().filter(|x| **x).count())
        .sum();
    if n_all > 0 && n_sat as f64 > MAX_SATURATED_SHARE * n_all as f64 {
        return Err(format!(
            "{:.0} % of the stripe points are saturated (the model is an unsaturated \
             Gaussian sheet; lower the exposure or the laser power to use it)",
            100.0 * n_sat as f64 / n_all as f64
        ));
    }
    let smoothed = shapes().filter(|s| s.along_line > 1).count();
    if smoothed > 0 {
        return Err(format!(
            "the stripes of {smoothed} view(s) were smoothed along the line for speckle \
             (the model describes a single scan line's profile of a clean Gaussian sheet)"
        ));
    }
    Ok(direction)
}
