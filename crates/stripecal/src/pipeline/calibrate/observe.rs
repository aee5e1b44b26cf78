//! Step 1: observations of a dataset's views: the target detected in the board image,
//! the stripe extracted from the laser image (in the signal rig.json's `stripe.channel`
//! names, `auto` decided once for the dataset: [`dataset_channel`]; points at
//! reflectance edges dropped) and `T_base_hand` from the robot reading.

use std::borrow::Cow;
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use super::CalibrateOptions;
use crate::calib::{CircleObs, StripeExtraction, StripeShape, ViewObs};
use crate::error::{Error, Result};
use crate::io::{image_size, load_image_info};
use crate::model::image::AnyView;
use crate::model::image::{AnyGray, AnyImage};
use crate::model::{Dataset, RobotReading, StripeChannel, View};
use crate::vision::stripe::colour::{auto_sample, channel_scores, choose_channel};
use crate::vision::stripe::{
    flag_reflectance_edges, stripe_signal_of_file, EdgeOptions, Stripe, StripeDirection,
    StripeExtractor, StripeOptions, StripePoint, FLAG_EDGE, FLAG_OBLIQUE, FLAG_UNEVEN_BACKGROUND,
};
use crate::vision::target::detect_target;

/// The observations of a dataset: the views whose board was found, warnings, and the
/// views left out with the reason.
pub(in crate::pipeline) struct Observed {
    pub obs: Vec<ViewObs>,
    pub warnings: Vec<String>,
    /// `(view, why)` for each view whose board was not found.
    pub left_out: Vec<(usize, String)>,
    /// The signal the stripes were found in (never `Auto`), and for `auto` the scores
    /// it was chosen by (gray, red, green, blue).
    pub channel: (StripeChannel, Option<[f64; 4]>),
}

/// The stripe channel of a dataset: rig.json's `stripe.channel`, `auto` decided once
/// from at most [`crate::vision::stripe::colour::AUTO_IMAGES`] of its laser images
/// (evenly spread over the views), with the summed scores for `auto`.
pub fn dataset_channel(
    ds: &Dataset,
    opts: &StripeOptions,
) -> Result<(StripeChannel, Option<[f64; 4]>)> {
    let ch = ds.rig.stripe_channel;
    if ch != StripeChannel::Auto {
        return Ok((ch, None));
    }
    let lasers: Vec<&std::path::Path> = ds
        .views
        .iter()
        .filter_map(|v| v.laser_image.as_deref())
        .collect();
    let paths: Vec<std::path::PathBuf> = auto_sample(lasers.len())
        .into_iter()
        .map(|i| ds.image_path(lasers[i]))
        .collect();
    decide_channel(&paths, opts)
}

/// The `auto` choice from the laser images at `paths` (read in parallel), with the
/// summed scores (gray, red, green, blue).
pub(crate) fn decide_channel(
    paths: &[std::path::PathBuf],
    opts: &StripeOptions,
) -> Result<(StripeChannel, Option<[f64; 4]>)> {
    let scores: Vec<[f64; 4]> = paths
        .par_iter()
        .map(|p| channel_scores(&load_image_info(p)?.0, opts))
        .collect::<Result<_>>()?;
    let mut sum = [0.0; 4];
    for s in &scores {
        for k in 0..4 {
            sum[k] += s[k];
        }
    }
    Ok((choose_channel(&scores), Some(sum)))
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
pub(in crate::pipeline) fn observe(ds: &Dataset, opts: &CalibrateOptions) -> Result<Observed> {
    check_image_sizes(ds)?;
    let lossy = AtomicUsize::new(0);
    let mut stripe_opts = opts.stripe.clone();
    stripe_opts.direction = ds.rig.stripe_direction;
    // both peaks of an undecided scan line: the board plane's consensus tells which
    stripe_opts.keep_ambiguous = true;
    let channel = dataset_channel(ds, &stripe_opts)?;
    let results: Vec<Result<std::result::Result<ViewObs, String>>> = ds
        .views
        .par_iter()
        .enumerate()
        .map(|(i, v)| {
            opts.cancel.check()?;
            observe_view(ds, i, v, opts, &stripe_opts, channel.0, &lossy)
        })
        .collect();
    let mut o = Observed {
        obs: Vec::new(),
        warnings: Vec::new(),
        left_out: Vec::new(),
        channel,
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
    o.warnings.extend(extraction_warnings(ds, &o.obs));
    Ok(o)
}

/// Every image's size, read from its header, against rig.json's before any image is
/// decoded: a file of another size (a 30000 x 30000 PNG) is refused without the decoder
/// allocating for its pixels.
fn check_image_sizes(ds: &Dataset) -> Result<()> {
    let want = (ds.rig.width, ds.rig.height);
    for (i, v) in ds.views.iter().enumerate() {
        for rel in std::iter::once(&v.board_image).chain(v.laser_image.as_ref()) {
            let (w, h) = image_size(ds.image_path(rel))?;
            if (w, h) != want {
                // the board image was checked first: a laser image that differs is also
                // one that differs from its board image
                let also = if rel == &v.board_image {
                    String::new()
                } else {
                    format!(
                        "; {} and {} differ in size",
                        rel.display(),
                        v.board_image.display()
                    )
                };
                return Err(Error::InvalidInput(format!(
                    "view {i} (views.csv line {}): {} is {w} x {h}, rig.json says {} x {} \
                     (camera.width, camera.height){also}",
                    v.line,
                    rel.display(),
                    want.0,
                    want.1
                )));
            }
        }
    }
    Ok(())
}

/// A view's stripe points are mostly saturated beyond this share: advice to lower the
/// exposure or the laser power.
pub const SATURATED_ADVICE_SHARE: f64 = 0.5;

/// What the stripe extraction of the views asks the user to know: laser images where no
/// line was found (each named, with the scan lines' reasons), and views whose points
/// are mostly saturated (with advice).
fn extraction_warnings(ds: &Dataset, obs: &[ViewObs]) -> Vec<String> {
    let mut w = Vec::new();
    let mut saturated = Vec::new();
    for v in obs {
        let Some(e) = v.stripe_shape.as_ref().map(|s| &s.extraction) else {
            continue;
        };
        let line = ds.views.get(v.view).map_or(0, |x| x.line);
        if e.found == 0 {
            let r = &e.rejected;
            w.push(format!(
                "view {} (views.csv line {line}): no laser line found in its laser image ({} \
                 scan lines: {} without a peak, {} with several comparable peaks, {} \
                 saturated too long, {} of the wrong width or too weak, {} at the border, {} \
                 isolated); the view serves the camera and the robot only (check the \
                 exposure and rig.json's stripe.direction)",
                v.view,
                e.lines,
                r.no_peak,
                r.multiple_peaks,
                r.saturated,
                r.shape,
                r.border,
                r.isolated
            ));
        } else if e.saturated_share() > SATURATED_ADVICE_SHARE {
            saturated.push((v.view, e.saturated_share()));
        }
    }
    if !saturated.is_empty() {
        let (lo, hi) = saturated
            .iter()
            .fold((1.0f64, 0.0f64), |(a, b), s| (a.min(s.1), b.max(s.1)));
        let names: Vec<String> = saturated.iter().map(|s| s.0.to_string()).collect();
        w.push(format!(
            "the laser line is saturated in {} of {} views (views {}: {:.0}-{:.0} % of their \
             stripe points): their centres come from the saturated plateau's edges, and the \
             stripe-bias model does not apply; lower the exposure or the laser power",
            saturated.len(),
            obs.iter().filter(|v| v.stripe_shape.is_some()).count(),
            names.join(", "),
            100.0 * lo,
            100.0 * hi
        ));
    }
    w
}

/// One view: `Ok(Err(why))` when its board is not found (the view is left out), an
/// error for unreadable or mismatched images and impossible robot readings.
fn observe_view(
    ds: &Dataset,
    i: usize,
    v: &View,
    opts: &CalibrateOptions,
    stripe_opts: &StripeOptions,
    channel: StripeChannel,
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
    let board_path = ds.image_path(&v.board_image);
    let (board_any, info) = load_image_info(&board_path)?;
    let board_img: Cow<'_, AnyGray> = match &board_any {
        AnyImage::Gray(g) => Cow::Borrowed(g),
        AnyImage::Rgb(c) => Cow::Owned(c.to_gray()),
    };
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
        let laser_any;
        let laser_path = ds.image_path(lp);
        let signal = if single {
            if channel == StripeChannel::Gray {
                Cow::Borrowed(board_img.as_ref())
            } else {
                stripe_signal_of_file(&board_path, &board_any, channel, stripe_opts)?
            }
        } else {
            let (img, info) = load_image_info(&laser_path)?;
            if info.lossy {
                lossy.fetch_add(1, Ordering::Relaxed);
            }
            laser_any = img;
            if laser_any.size() != board_img.size() {
                return Err(Error::InvalidInput(format!(
                    "{tag}: {} and {} differ in size",
                    lp.display(),
                    v.board_image.display()
                )));
            }
            stripe_signal_of_file(&laser_path, &laser_any, channel, stripe_opts)?
        };
        let lview = signal.view()?;
        let (s, extraction) = extract_view_stripe(lview, bview, single, stripe_opts, opts)?;
        let kept: Vec<_> = s.iter().filter(|p| p.trusted()).collect();
        stripe = kept.iter().map(|p| [p.u, p.v]).collect();
        shape = Some(StripeShape {
            direction: extraction.1,
            width_px: kept.iter().map(|p| f64::from(p.width_px)).collect(),
            saturated: kept.iter().map(|p| p.saturated()).collect(),
            along_line: extraction.0.along_line,
            extraction: extraction.0,
        });
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

/// The stripe of one laser image with its reflectance edges flagged from the board
/// image, and what the extraction found and left out (an image without a line gives no
/// points and says so in its counts: not an error), with the scan direction used.
fn extract_view_stripe(
    laser: AnyView<'_>,
    board: AnyView<'_>,
    single: bool,
    stripe_opts: &StripeOptions,
    opts: &CalibrateOptions,
) -> Result<(Vec<StripePoint>, (StripeExtraction, StripeDirection))> {
    let mut ex = StripeExtractor::new(stripe_opts.clone())?;
    let (w, h) = laser.size();
    let mut points = Vec::with_capacity(w.max(h));
    let direction = ex.extract_into(laser, &mut points)?;
    let (_, along_line) = ex.adapted();
    let mut s = Stripe {
        direction,
        size: (w, h),
        points,
        lines: if direction == StripeDirection::Rows {
            w
        } else {
            h
        },
        rejected: ex.rejected(),
        survey: ex.survey(),
        along_line,
    };
    let eo = EdgeOptions {
        single_image: single,
        ..opts.edges.clone()
    };
    flag_reflectance_edges(&mut s, board, &eo)?;
    let count = |f: u8| s.points.iter().filter(|p| p.flags & f != 0).count();
    // each point counted under its first reason: edge, uneven, oblique
    let at_edge = count(FLAG_EDGE);
    let uneven = s
        .points
        .iter()
        .filter(|p| p.flags & FLAG_EDGE == 0 && p.flags & FLAG_UNEVEN_BACKGROUND != 0)
        .count();
    let oblique = s
        .points
        .iter()
        .filter(|p| {
            p.flags & (FLAG_EDGE | FLAG_UNEVEN_BACKGROUND) == 0 && p.flags & FLAG_OBLIQUE != 0
        })
        .count();
    let e = StripeExtraction {
        lines: s.lines,
        rejected: s.rejected,
        found: s.points.len(),
        at_edge,
        uneven_background: uneven,
        oblique,
        saturated: s
            .points
            .iter()
            .filter(|p| p.trusted() && p.saturated())
            .count(),
        width_px: s.survey.width_px,
        along_line,
    };
    Ok((s.points, (e, direction)))
}
