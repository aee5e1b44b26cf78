//! Many frames: in-memory frames in parallel (rayon) and scan folders (scan.csv +
//! images) decoded in parallel chunks with progress reports.

use std::path::Path;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::model::image::AnyView;
use crate::model::{Calibration, RobotReading, Scan, StripeDirection};

use super::{at_frame, ReconstructOptions, Reconstructor, ScanPoints};

/// Reconstructs many in-memory frames in parallel (rayon). `readings[i]` belongs to
/// `images[i]`; points come out in frame order, tagged with the frame index. The first
/// failing frame (by index) is the error, naming it; nothing is returned then.
pub fn reconstruct_frames(
    calibration: &Calibration,
    images: &[AnyView<'_>],
    readings: &[RobotReading],
    opts: &ReconstructOptions,
) -> Result<ScanPoints> {
    if images.len() != readings.len() {
        return Err(Error::InvalidInput(format!(
            "{} images but {} robot readings",
            images.len(),
            readings.len()
        )));
    }
    let proto = Reconstructor::new(calibration, opts)?;
    let parts: Vec<Result<ScanPoints>> = images
        .par_iter()
        .zip(readings.par_iter())
        .enumerate()
        .map_init(
            || proto.clone(),
            |rec, (i, (img, reading))| {
                let mut sp = ScanPoints::default();
                rec.frame_reading(*img, reading, i as u32, &mut sp)?;
                Ok(sp)
            },
        )
        .collect();
    let mut out = ScanPoints::default();
    for p in parts {
        out.append(&p?);
    }
    Ok(out)
}

/// Reconstructs a scan folder (scan.csv + images). The robot and camera come from the
/// calibration; `opts.stripe.direction: Auto` takes the scan's rig.json hint when it has
/// one, else the calibration's ([`stripe_direction_from_plane`]). Images are decoded and
/// processed in parallel in chunks; `progress(frames_done, frames_total, points_so_far)`
/// is called on the calling thread after each chunk. Errors name the frame, its scan.csv
/// line and the image file.
pub fn reconstruct_scan(
    calibration: &Calibration,
    scan: &Scan,
    opts: &ReconstructOptions,
    progress: &mut dyn FnMut(usize, usize, usize),
) -> Result<ScanPoints> {
    let mut opts = opts.clone();
    if opts.stripe.direction == StripeDirection::Auto {
        if let Some(rig) = &scan.rig {
            opts.stripe.direction = rig.stripe_direction;
        }
    }
    let proto = Reconstructor::new(calibration, &opts)?;
    let n = scan.frames.len();
    let chunk = (2 * rayon::current_num_threads()).max(2);
    let mut out = ScanPoints::default();
    progress(0, n, 0);
    let mut done = 0;
    for (c, frames) in scan.frames.chunks(chunk).enumerate() {
        let parts: Vec<Result<ScanPoints>> = frames
            .par_iter()
            .enumerate()
            .map_init(
                || proto.clone(),
                |rec, (k, f)| {
                    let i = c * chunk + k;
                    let path = scan.image_path(&f.image);
                    let img =
                        crate::io::load_gray(&path).map_err(|e| at_frame(e, i, Some(f.line)))?;
                    let view = img.view().map_err(|e| at_frame(e, i, Some(f.line)))?;
                    let mut sp = ScanPoints::default();
                    rec.frame_reading(view, &f.reading, i as u32, &mut sp)
                        .map_err(|e| match e {
                            Error::InvalidInput(m) => Error::InvalidInput(format!(
                                "{m} (scan.csv line {}, image {})",
                                f.line,
                                path.display()
                            )),
                            other => other,
                        })?;
                    Ok(sp)
                },
            )
            .collect();
        for p in parts {
            out.append(&p?);
        }
        done += frames.len();
        progress(done, n, out.len());
    }
    Ok(out)
}

/// Loads a scan folder for a calibration (checks joint counts against its robot).
pub fn load_scan(root: impl AsRef<Path>, calibration: &Calibration) -> Result<Scan> {
    Scan::load(root, calibration.robot.as_ref())
}
