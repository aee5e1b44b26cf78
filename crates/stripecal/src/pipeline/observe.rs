//! Step 1: observations of a dataset's views: the target detected in the board image,
//! the stripe extracted from the laser image (points at reflectance edges dropped) and
//! `T_base_hand` from the robot reading.

use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use super::CalibrateOptions;
use crate::calib::{CircleObs, StripeShape, ViewObs};
use crate::error::{Error, Result};
use crate::io::load_gray_info;
use crate::model::{Dataset, RobotReading, View};
use crate::vision::stripe::{extract_stripe, flag_reflectance_edges, EdgeOptions, StripeOptions};
use crate::vision::target::detect_target;

/// The observations of a dataset: the views whose board was found, warnings, and the
/// views left out with the reason.
pub(super) struct Observed {
    pub obs: Vec<ViewObs>,
    pub warnings: Vec<String>,
    /// `(view, why)` for each view whose board was not found.
    pub left_out: Vec<(usize, String)>,
}

/// Detects circles and stripes of every view of a dataset (in parallel over views).
///
/// Returns the observations of the views whose board was found, and warnings naming the
/// others. Image files that cannot be read are errors (naming the file).
pub fn observe_dataset(
    ds: &Dataset,
    opts: &CalibrateOptions,
) -> Result<(Vec<ViewObs>, Vec<String>)> {
    let o = observe(ds, opts)?;
    Ok((o.obs, o.warnings))
}

/// [`observe_dataset`] with the left-out views kept apart.
pub(super) fn observe(ds: &Dataset, opts: &CalibrateOptions) -> Result<Observed> {
    let lossy = AtomicUsize::new(0);
    let mut stripe_opts = opts.stripe.clone();
    stripe_opts.direction = ds.rig.stripe_direction;
    let results: Vec<Result<std::result::Result<ViewObs, String>>> = ds
        .views
        .par_iter()
        .enumerate()
        .map(|(i, v)| observe_view(ds, i, v, opts, &stripe_opts, &lossy))
        .collect();
    let mut o = Observed {
        obs: Vec::new(),
        warnings: Vec::new(),
        left_out: Vec::new(),
    };
    let lossy = lossy.into_inner();
    if lossy > 0 {
        o.warnings.push(format!(
            "{lossy} image(s) are JPEG: lossy compression costs accuracy (accepted; PNG, TIFF \
             or BMP keep every grey level)"
        ));
    }
    for (i, r) in results.into_iter().enumerate() {
        match r? {
            Ok(v) => o.obs.push(v),
            Err(w) => {
                o.warnings.push(w.clone());
                o.left_out.push((i, w));
            }
        }
    }
    Ok(o)
}

/// One view: `Ok(Err(why))` when its board is not found (the view is left out), an
/// error for unreadable or mismatched images and impossible robot readings.
fn observe_view(
    ds: &Dataset,
    i: usize,
    v: &View,
    opts: &CalibrateOptions,
    stripe_opts: &StripeOptions,
    lossy: &AtomicUsize,
) -> Result<std::result::Result<ViewObs, String>> {
    let rig = &ds.rig;
    let tag = format!("view {i} (views.csv line {})", v.line);
    // A bench view (no pose columns) has no robot pose: its board pose is free.
    let base_hand = match v.reading {
        RobotReading::Fixed => None,
        _ => Some(
            v.reading
                .base_hand(rig.robot.as_ref())
                .map_err(|e| Error::InvalidInput(format!("{tag}: robot pose: {e}")))?,
        ),
    };
    let (board_img, info) = load_gray_info(ds.image_path(&v.board_image))?;
    if board_img.size() != (rig.width as usize, rig.height as usize) {
        return Err(Error::InvalidInput(format!(
            "{tag}: {} is {} x {}, rig.json says {} x {}",
            v.board_image.display(),
            board_img.size().0,
            board_img.size().1,
            rig.width,
            rig.height
        )));
    }
    if info.lossy {
        lossy.fetch_add(1, Ordering::Relaxed);
    }
    let bview = board_img.view()?;
    let det = match detect_target(bview, &rig.board, &opts.target) {
        Ok(g) => g,
        Err(e) => return Ok(Err(format!("{tag}: left out, board not found: {e}"))),
    };
    let circles = det
        .points
        .iter()
        .map(|c| CircleObs {
            row: c.row,
            col: c.col,
            u: c.u,
            v: c.v,
        })
        .collect();
    let mut stripe = Vec::new();
    let mut shape = None;
    if let Some(lp) = &v.laser_image {
        let single = lp == &v.board_image;
        let laser_img;
        let lview = if single {
            bview
        } else {
            let (img, info) = load_gray_info(ds.image_path(lp))?;
            if info.lossy {
                lossy.fetch_add(1, Ordering::Relaxed);
            }
            laser_img = img;
            if laser_img.size() != board_img.size() {
                return Err(Error::InvalidInput(format!(
                    "{tag}: {} and {} differ in size",
                    lp.display(),
                    v.board_image.display()
                )));
            }
            laser_img.view()?
        };
        match extract_stripe(lview, stripe_opts) {
            Ok(mut s) => {
                let eo = EdgeOptions {
                    single_image: single,
                    ..opts.edges.clone()
                };
                flag_reflectance_edges(&mut s, bview, &eo)?;
                let kept: Vec<_> = s.points.iter().filter(|p| p.trusted()).collect();
                stripe = kept.iter().map(|p| [p.u, p.v]).collect();
                shape = Some(StripeShape {
                    direction: s.direction,
                    width_px: kept.iter().map(|p| f64::from(p.width_px)).collect(),
                });
            }
            Err(Error::Detection(_)) => {}
            Err(e) => return Err(e),
        }
    }
    Ok(Ok(ViewObs {
        view: i,
        circles,
        stripe,
        reading: Some(v.reading.clone()),
        base_hand,
        alternatives: det.alternatives,
        stripe_shape: shape,
    }))
}
