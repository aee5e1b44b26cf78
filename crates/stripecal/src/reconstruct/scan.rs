//! Many frames: in-memory frames in parallel (rayon) and scan folders (scan.csv +
//! images) decoded in parallel chunks with progress reports.

use std::ops::ControlFlow;
use std::path::Path;

use rayon::prelude::*;

use crate::error::{BadFrame, Error, Result};
use crate::model::image::{AnyImage, AnyView};
use crate::model::{Calibration, RobotReading, Scan, ScanFrame, StripeChannel, StripeDirection};
use crate::vision::stripe::colour::{auto_sample, decide_channel_lenient};
use crate::vision::stripe::{stripe_signal_of_file, StripeOptions};

use super::{BadImage, DropCounts, ReconstructOptions, Reconstructor, ScanPoints};

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
    out.camera_frame = !readings.is_empty() && readings.iter().all(|r| *r == RobotReading::Fixed);
    Ok(out)
}

/// Reconstructs a scan folder (scan.csv + images). The robot and camera come from the
/// calibration; `opts.stripe.direction: Auto` takes the scan's rig.json hint when it has
/// one, else the calibration's ([`stripe_direction_from_plane`]). The stripe is found in
/// the signal `opts.channel` names, or (`None`) the scan's rig.json `stripe.channel`
/// (gray without one); `auto` is decided once for the scan from at most
/// [`crate::vision::stripe::colour::AUTO_IMAGES`] of its frames
///. A colour name with a gray frame is an
/// [`Error::Format`] naming the file, whatever `on_bad_image` says. Images are decoded
/// and processed in parallel in chunks.
///
/// `progress(frames_done, frames_total, points_so_far)` is called on the calling thread
/// before the first chunk and after each one; when it returns
/// [`ControlFlow::Break`] the run stops there with [`Error::Cancelled`] (a caller's
/// interrupt: nothing is returned).
///
/// Bad images (see [`BadImage`]): a frame whose image is missing or unreadable, cannot
/// be decoded (truncated, corrupted, not a supported image), is not the calibrated
/// camera's size, or has another bit depth than most of the scan's frames. With
/// [`BadImage::Stop`] (the default) the run stops with [`Error::BadImage`] naming the
/// frame, its scan.csv line, the file and what is wrong: missing files are looked for
/// before any work, undecodable images and wrong sizes stop the run at the first one in
/// frame order, bit depths are compared once every frame is read. With
/// [`BadImage::Skip`] the frame's points are left out and the frame is listed in
/// [`ScanPoints::skipped`] (in frame order, with the reason).
///
/// Other errors (a robot reading that gives no pose...) always stop the run; they name
/// the frame, its scan.csv line and the image file.
///
/// [`stripe_direction_from_plane`]: super::stripe_direction_from_plane
pub fn reconstruct_scan(
    calibration: &Calibration,
    scan: &Scan,
    opts: &ReconstructOptions,
    progress: &mut dyn FnMut(usize, usize, usize) -> ControlFlow<()>,
) -> Result<ScanPoints> {
    let mut opts = opts.clone();
    if opts.stripe.direction == StripeDirection::Auto {
        if let Some(rig) = &scan.rig {
            opts.stripe.direction = rig.stripe_direction;
        }
    }
    if calibration.is_bench() && !scan.is_fixed() {
        return Err(Error::InvalidInput(
            "a bench calibration (no hand_cam: calibrated without a robot) cannot reconstruct \
             a scan with robot poses; calibrate on the robot (e.g. `stripecal calibrate --from \
             BENCH.json DATASET`), or give a scan without pose columns (points in the camera \
             frame)"
                .into(),
        ));
    }
    let proto = Reconstructor::new(calibration, &opts)?;
    let (width, height) = (calibration.camera.width, calibration.camera.height);
    let channel = scan_channel(scan, &opts, (width, height));
    let skip = opts.on_bad_image == BadImage::Skip;
    let bad = |i: usize, f: &ScanFrame, reason: String| BadFrame {
        frame: i,
        line: f.line,
        path: scan.image_path(&f.image),
        reason,
    };
    if !skip {
        // A missing file stops the run before any work.
        for (i, f) in scan.frames.iter().enumerate() {
            if let Err(reason) = check_file(&scan.image_path(&f.image)) {
                return Err(Error::BadImage(bad(i, f, reason)));
            }
        }
    }
    let source = FrameSource {
        scan,
        size: (width, height),
        channel,
        stripe: &opts.stripe,
    };
    let n = scan.frames.len();
    let chunk = (2 * rayon::current_num_threads()).max(2);
    let mut out = ScanPoints::default();
    // The frames reconstructed: index, bit depth, drop counts.
    let mut kept: Vec<(usize, u8, DropCounts)> = Vec::with_capacity(n);
    let mut skipped: Vec<BadFrame> = Vec::new();
    if progress(0, n, 0).is_break() {
        return Err(Error::Cancelled);
    }
    let mut done = 0;
    // One reconstructor (its stripe extractor's buffers) and one points buffer per frame
    // of a chunk, kept from chunk to chunk: the extraction allocates nothing per frame.
    let mut workers: Vec<(Reconstructor, ScanPoints)> = (0..chunk.min(n))
        .map(|_| (proto.clone(), ScanPoints::default()))
        .collect();
    for (c, frames) in scan.frames.chunks(chunk).enumerate() {
        let parts: Vec<Result<FramePart>> = frames
            .par_iter()
            .zip(workers.par_iter_mut())
            .enumerate()
            .map(|(k, (f, (rec, sp)))| frame_points(rec, sp, &source, f, c * chunk + k))
            .collect();
        for (k, part) in parts.into_iter().enumerate() {
            let i = c * chunk + k;
            match part? {
                Ok(depth) => {
                    let sp = &workers[k].1;
                    kept.push((i, depth, sp.dropped));
                    out.append(sp);
                }
                Err(reason) if skip => skipped.push(bad(i, &frames[k], reason)),
                Err(reason) => return Err(Error::BadImage(bad(i, &frames[k], reason))),
            }
        }
        done += frames.len();
        if progress(done, n, out.len()).is_break() {
            return Err(Error::Cancelled);
        }
    }

    let scan_depth = majority_depth(&kept);
    let same = kept.iter().filter(|k| k.1 == scan_depth).count();
    let odd: Vec<(usize, u8)> = kept
        .iter()
        .filter(|k| k.1 != scan_depth)
        .map(|k| (k.0, k.1))
        .collect();
    if !odd.is_empty() {
        let reason = |d: u8| {
            format!(
                "is {d}-bit, but {same} of the scan's {} readable frames are {scan_depth}-bit",
                kept.len()
            )
        };
        if !skip {
            let (i, d) = odd[0];
            return Err(Error::BadImage(bad(i, &scan.frames[i], reason(d))));
        }
        for &(i, d) in &odd {
            skipped.push(bad(i, &scan.frames[i], reason(d)));
        }
        out.retain_frames(|f| odd.binary_search_by_key(&(f as usize), |o| o.0).is_err());
        out.dropped = DropCounts::default();
        for k in kept.iter().filter(|k| k.1 == scan_depth) {
            out.dropped.add(&k.2);
        }
    }
    skipped.sort_by_key(|b| b.frame);
    out.skipped = skipped;
    out.camera_frame = scan.is_fixed();
    Ok(out)
}

/// The signal a scan's stripes are found in: `opts.channel`, else the scan's rig.json
/// `stripe.channel` (gray without one); `auto` decided from at most
/// [`crate::vision::stripe::colour::AUTO_IMAGES`] of its frames.
fn scan_channel(
    scan: &Scan,
    opts: &ReconstructOptions,
    (width, height): (u32, u32),
) -> StripeChannel {
    let mut channel = opts
        .channel
        .or_else(|| scan.rig.as_ref().map(|r| r.stripe_channel))
        .unwrap_or_default();
    if channel == StripeChannel::Auto {
        // decided from frames that can be read and are the camera's size by their
        // header (never decoding a huge one; a bad frame is reported below)
        let readable: Vec<std::path::PathBuf> = scan
            .frames
            .iter()
            .map(|f| scan.image_path(&f.image))
            .filter(|p| p.is_file() && crate::io::image_size(p).ok() == Some((width, height)))
            .collect();
        let paths: Vec<std::path::PathBuf> = auto_sample(readable.len())
            .into_iter()
            .map(|i| readable[i].clone())
            .collect();
        let load = |p: &Path| Some(crate::io::load_image_info(p).ok()?.0);
        channel = decide_channel_lenient(&paths, load, &opts.stripe);
    }
    channel
}

/// What every frame of a scan is read with: the scan, the camera's size, the stripe's
/// signal and the extractor's options.
struct FrameSource<'a> {
    scan: &'a Scan,
    size: (u32, u32),
    channel: StripeChannel,
    stripe: &'a StripeOptions,
}

/// A frame's image's bit depth (its points in the worker's buffer), or why its image
/// cannot be used.
type FramePart = std::result::Result<u8, String>;

/// Frame `i` (`f`) reconstructed with `rec` into `sp` (cleared first): its bit depth, or
/// why its image cannot be used; errors (naming the frame's scan.csv line and image)
/// stop the run.
fn frame_points(
    rec: &mut Reconstructor,
    sp: &mut ScanPoints,
    source: &FrameSource<'_>,
    f: &ScanFrame,
    i: usize,
) -> Result<FramePart> {
    let path = source.scan.image_path(&f.image);
    let img = match frame_image(&path, source.size.0, source.size.1) {
        Ok(img) => img,
        Err(reason) => return Ok(Err(reason)),
    };
    let signal = stripe_signal_of_file(&path, &img, source.channel, source.stripe)?;
    let view = match signal.view() {
        Ok(v) => v,
        Err(e) => return Ok(Err(e.to_string())),
    };
    sp.clear();
    rec.frame_reading(view, &f.reading, i as u32, sp)
        .map_err(|e| match e {
            Error::InvalidInput(m) => Error::InvalidInput(format!(
                "{m} (scan.csv line {}, image {})",
                f.line,
                path.display()
            )),
            other => other,
        })?;
    Ok(Ok(img.bit_depth()))
}

/// The bit depth most of the `kept` frames `(index, depth, drops)` have (a tie: the first
/// frame's).
fn majority_depth(kept: &[(usize, u8, DropCounts)]) -> u8 {
    let deep = kept.iter().filter(|k| k.1 == 16).count();
    match (2 * deep).cmp(&kept.len()) {
        std::cmp::Ordering::Greater => 16,
        std::cmp::Ordering::Less => 8,
        std::cmp::Ordering::Equal => kept.first().map_or(8, |k| k.1),
    }
}

/// Why a frame's image file cannot be opened, if it cannot: it is missing, a folder, a
/// FIFO, a device or a broken symbolic link ([`crate::io::file_problem`]).
fn check_file(path: &Path) -> std::result::Result<(), String> {
    match crate::io::file_problem(path) {
        None => Ok(()),
        Some((_, why)) => Err(why),
    }
}

/// A frame's image, decoded and checked against the calibrated camera's size, or what is
/// wrong with it.
fn frame_image(path: &Path, width: u32, height: u32) -> std::result::Result<AnyImage, String> {
    check_file(path)?;
    let why = |e: Error| match e {
        Error::Io { source, .. } => format!("cannot be read: {source}"),
        Error::Image { message, .. } => format!("cannot be decoded: {message}"),
        other => other.to_string(),
    };
    // the size from the header first: a huge file is refused before it is decoded
    let (w, h) = crate::io::image_size(path).map_err(why)?;
    if (w, h) != (width, height) {
        return Err(format!(
            "is {w} x {h} pixels, the calibrated camera is {width} x {height}"
        ));
    }
    let img = crate::io::load_image(path).map_err(why)?;
    let (w, h) = img.size();
    if (w, h) != (width as usize, height as usize) {
        return Err(format!(
            "is {w} x {h} pixels, the calibrated camera is {width} x {height}"
        ));
    }
    Ok(img)
}

/// Loads a scan folder for a calibration (checks joint counts against its robot). The
/// images are not looked at: [`reconstruct_scan`] checks each one.
pub fn load_scan(root: impl AsRef<Path>, calibration: &Calibration) -> Result<Scan> {
    Scan::read(root, calibration.robot.as_ref())
}
