//! On the bench: views of a board that is not flat (a paper board held by hand) named with
//! their flatness figure ([`crate::calib::flatness`]: the sag of the best-fitting
//! cylinder, docs/flatness.md) and left out, never absorbed into the lens distortion.
//!
//! After the camera stage, every view's sag is measured from its own circles with that
//! camera and its pose. A view is BENT when `|sag| > 3 sigma` (not noise) and `|sag| >`
//! [`super::CalibrateOptions::max_board_sag_mm`] (default 0.02 mm: twice the laser
//! plane's 0.01 mm target; a bent view's stripe points lie up to the sag off the flat
//! board plane). Bent views are left out and the camera stage is run again without
//! them; the figures of every view go into calibration.json's extra `board_flatness`.
//! On a robot dataset the board is one fixed object seen in every view, so a bend would
//! be the same in all of them: the check is the bench's.

use super::stages::camera_stage;
use super::{CalibrateOptions, ViewStatus};
use crate::calib::camera::CameraCalibration;
use crate::calib::flatness::{view_flatness, Flatness, FlatnessOptions};
use crate::calib::ViewObs;
use crate::error::Result;
use crate::model::Rig;

/// One view's flatness figure.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewFlatness {
    /// `ViewObs::view`.
    pub view: usize,
    pub flatness: Flatness,
    /// Left out for it.
    pub bent: bool,
}

/// Every used view's figure with the camera stage `camcal`.
fn figures(
    views: &[ViewObs],
    camcal: &CameraCalibration,
    rig: &Rig,
    limit: f64,
) -> Vec<ViewFlatness> {
    let mut out = Vec::new();
    for (view, cb) in &camcal.poses {
        let Some(v) = views.iter().find(|v| v.view == *view) else {
            continue;
        };
        let Ok(f) = view_flatness(
            &camcal.camera,
            &rig.board,
            &v.circles,
            cb,
            &FlatnessOptions::default(),
        ) else {
            continue;
        };
        let bent = f.significance() > 3.0 && f.sag_mm.abs() > limit;
        out.push(ViewFlatness {
            view: *view,
            flatness: f,
            bent,
        });
    }
    out
}

/// The views with the bent ones left out, the camera stage on them, and every view's
/// figure (module docs). A bent view also bends the camera stage's camera, which makes
/// flat views look bent: the most bent view is left out first, the camera stage run
/// again and the figures measured again, until none is bent (at most half the views
/// are left out). `status` and `warnings` name the bent views.
pub(super) fn leave_out_bent(
    views: &[ViewObs],
    mut camcal: CameraCalibration,
    rig: &Rig,
    opts: &CalibrateOptions,
    status: &mut [ViewStatus],
    warnings: &mut Vec<String>,
) -> Result<(Vec<ViewObs>, CameraCalibration, Vec<ViewFlatness>)> {
    let limit = opts.max_board_sag_mm;
    let mut kept: Vec<ViewObs> = views.to_vec();
    let mut left_out: Vec<ViewFlatness> = Vec::new();
    loop {
        let figs = figures(&kept, &camcal, rig, limit);
        let worst = figs
            .iter()
            .filter(|f| f.bent)
            .max_by(|a, b| a.flatness.sag_mm.abs().total_cmp(&b.flatness.sag_mm.abs()));
        let Some(worst) = worst.filter(|_| 2 * (left_out.len() + 1) <= views.len()) else {
            // The figures of the views kept (none bent, or too many to leave out), then
            // those left out as they were measured.
            // (those left out measured again with the final camera, from their own
            // bent fit's pose)
            let mut all = figs;
            for lo in left_out {
                let again = views.iter().find(|v| v.view == lo.view).and_then(|v| {
                    view_flatness(
                        &camcal.camera,
                        &rig.board,
                        &v.circles,
                        &lo.flatness.cam_board,
                        &FlatnessOptions::default(),
                    )
                    .ok()
                });
                let lo = ViewFlatness {
                    flatness: again.unwrap_or(lo.flatness),
                    ..lo
                };
                let f = &lo.flatness;
                let note = format!(
                    "view {}: left out: the board is not flat: sag {:+.3} +- {:.3} mm over \
                     {:.1} mm (best-fitting cylinder, axis {:.0} deg from board x; limit {} mm)",
                    lo.view, f.sag_mm, f.sigma_mm, f.width_mm, f.axis_deg, limit
                );
                warnings.push(note.clone());
                if let Some(s) = status.iter_mut().find(|s| s.view == lo.view) {
                    s.note = Some(note);
                }
                all.push(lo);
            }
            all.sort_by_key(|f| f.view);
            return Ok((kept, camcal, all));
        };
        let gone = worst.view;
        left_out.push(worst.clone());
        kept.retain(|v| v.view != gone);
        camcal = camera_stage(&kept, rig, opts)?;
    }
}

/// calibration.json's extra `board_flatness`: per view, its sag, sigma, axis, width and
/// whether it was left out.
pub(super) fn flatness_extra(figures: &[ViewFlatness]) -> serde_json::Value {
    serde_json::Value::Array(
        figures
            .iter()
            .map(|f| {
                serde_json::json!({
                    "view": f.view,
                    "sag_mm": f.flatness.sag_mm,
                    "sigma_mm": f.flatness.sigma_mm,
                    "axis_deg": f.flatness.axis_deg,
                    "width_mm": f.flatness.width_mm,
                    "left_out": f.bent,
                })
            })
            .collect(),
    )
}
