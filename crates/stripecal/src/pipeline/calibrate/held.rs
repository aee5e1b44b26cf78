//! Starting from an earlier calibration (`--from`, DECISIONS 4): the blocks the options
//! hold keep the file's values in the adjustment, and the result carries the file's
//! uncertainty and covariance for them (the estimated blocks' own uncertainty is then
//! conditional on the held values, which the result says in `held_blocks`).

use serde_json::{Map, Value};

use super::CalibrateOptions;
use crate::calib::joint::{FreeBlocks, JointStart};
use crate::error::{Error, Result};
use crate::model::{Calibration, NamedCovariance, Rig};

/// The blocks held from a calibration file.
pub(super) struct Held<'a> {
    pub from: &'a Calibration,
    free: FreeBlocks,
}

/// The held blocks of `opts`: `None` when nothing is held. Errors: blocks held without
/// `--from`, a held laser plane the file does not have, `--from` holding nothing
/// on a bench dataset (priors are [`super::prior`], robot datasets only).
pub(super) fn held(opts: &CalibrateOptions) -> Result<Option<Held<'_>>> {
    let names = held_names(&opts.free);
    match (&opts.from, names.is_empty()) {
        (None, true) => Ok(None),
        (None, false) => Err(Error::InvalidInput(format!(
            "holding {} needs the calibration to take {} from (--from CALIBRATION.json)",
            names.join(", "),
            if names.len() == 1 { "it" } else { "them" }
        ))),
        (Some(_), true) => Err(Error::InvalidInput(
            "--from without --fix on a bench dataset: starting a bench calibration from an \
             earlier one with its covariance as a prior is not available; hold its blocks \
             with --fix camera,laser_plane"
                .into(),
        )),
        (Some(from), false) => {
            if !opts.free.laser_plane && from.laser_plane.is_none() {
                return Err(Error::InvalidInput(
                    "the laser plane is held, but the calibration to start from has none \
                     (\"laser_plane\": null)"
                        .into(),
                ));
            }
            Ok(Some(Held {
                from,
                free: opts.free,
            }))
        }
    }
}

/// `--from`'s calibration must be of this dataset's camera: its image size (the file's
/// `camera.width` x `camera.height`) must be rig.json's. A camera calibrated at another
/// size (another camera, binning, a crop) held or used as a prior would give a confident
/// wrong result (a laser plane at 31 mm instead of 80), so it is refused, naming both
/// sizes, whatever is held (`--fix`, `--laser-only`, or nothing: the prior).
pub(in crate::pipeline) fn check_from_size(rig: &Rig, opts: &CalibrateOptions) -> Result<()> {
    let Some(from) = &opts.from else {
        return Ok(());
    };
    let (fw, fh) = (from.camera.width, from.camera.height);
    if (fw, fh) != (rig.width, rig.height) {
        return Err(Error::InvalidInput(format!(
            "the calibration to start from (--from) is of a {fw} x {fh} camera (its \
             camera.width x camera.height), this dataset's images are {} x {} (rig.json \
             camera.width x camera.height): a camera calibrated at another image size \
             (another camera, binning or a crop) cannot be held or used as a prior here; \
             calibrate this camera without --from, or start from a calibration of it",
            rig.width, rig.height
        )));
    }
    Ok(())
}

/// Whether `opts` hold no block (`--from` alone is then a prior, [`super::prior`]).
pub(super) fn holds_nothing(opts: &CalibrateOptions) -> bool {
    held_names(&opts.free).is_empty()
}

/// The contract's names of the blocks `free` holds.
fn held_names(free: &FreeBlocks) -> Vec<&'static str> {
    [
        ("camera", free.camera),
        ("laser_plane", free.laser_plane),
        ("hand_cam", free.hand_cam),
        ("base_board", free.base_board),
    ]
    .into_iter()
    .filter(|(_, f)| !f)
    .map(|(n, _)| n)
    .collect()
}

impl Held<'_> {
    /// The names of the held blocks.
    pub fn names(&self) -> Vec<&'static str> {
        held_names(&self.free)
    }

    /// Whether the whole chain (camera, `X`, `Z`) is held: the board poses then follow
    /// from the robot, no camera stage is needed.
    pub fn chain_held(&self) -> bool {
        !(self.free.camera || self.free.hand_cam || self.free.base_board)
    }

    /// The start with the held blocks' values from the file.
    pub fn apply(&self, start: &mut JointStart) {
        let f = &self.from;
        if !self.free.camera {
            start.camera = f.camera.clone();
        }
        if !self.free.laser_plane {
            start.plane = f.laser_plane;
        }
        if !self.free.hand_cam {
            start.hand_cam = f.hand_cam;
        }
        if !self.free.base_board {
            start.base_board = f.base_board;
        }
    }

    /// The file's uncertainty entries of the held blocks, added to `u`.
    pub fn add_uncertainty(&self, u: &mut Map<String, Value>) {
        for name in self.names() {
            if let Some(v) = self.from.uncertainty.get(name) {
                u.insert(name.into(), v.clone());
            }
        }
    }

    /// `estimated` with the file's covariance of the held blocks appended (block
    /// diagonal: the adjustment held them, so it has no correlation with them); `None`
    /// when the file has no covariance.
    pub fn covariance(&self, estimated: &NamedCovariance) -> Option<NamedCovariance> {
        let fc = self.from.covariance.as_ref()?;
        let mut names = estimated.parameters.clone();
        let mut blocks = vec![estimated.matrix.clone()];
        for name in self.names() {
            let b = fc.block(&format!("{name}."));
            names.extend(b.parameters);
            blocks.push(b.matrix);
        }
        let n = names.len();
        let mut m = nalgebra::DMatrix::zeros(n, n);
        let mut o = 0;
        for b in blocks {
            let k = b.nrows();
            m.view_mut((o, o), (k, k)).copy_from(&b);
            o += k;
        }
        Some(NamedCovariance {
            parameters: names,
            matrix: m,
        })
    }
}
