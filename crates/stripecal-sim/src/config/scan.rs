//! The twin's scan knobs: the ball scan and the table sweep.

use serde::{Deserialize, Serialize};

use super::bad;
use crate::SimError;

/// The ball scan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScanCfg {
    /// Render a scan at all.
    pub enabled: bool,
    pub sphere_diameter_mm: f64,
    /// Sphere position on the table relative to the board centre, along the board's x
    /// and y axes, mm.
    pub sphere_offset_mm: [f64; 2],
    /// Sensor translation between frames, mm.
    pub step_mm: f64,
    /// Extra travel before and after the ball, mm (along the sweep).
    pub margin_mm: f64,
    /// Depth (camera z) of the ball's top at the middle of the sweep, mm.
    pub top_depth_mm: f64,
    /// Cap on the number of frames (0 = no cap): the sweep is shortened symmetrically.
    pub max_frames: usize,
    /// Also render a sweep over the bare table (`scan_table/`, the format of `scan/`),
    /// away from the board and the ball, at poses not used in calibration (default
    /// `false`; [`crate::table_scan`]).
    #[serde(default)]
    pub table: bool,
    /// Where the table sweep's middle lies on the table relative to the board centre,
    /// along the board's x and y axes, mm.
    #[serde(default = "default_table_offset")]
    pub table_offset_mm: [f64; 2],
}

pub(super) fn default_table_offset() -> [f64; 2] {
    crate::table_scan::DEFAULT_TABLE_OFFSET_MM
}

impl ScanCfg {
    /// The sweep's step and the ball, when a scan (of the ball or the table) is rendered.
    pub(super) fn validate(&self) -> Result<(), SimError> {
        if (self.enabled || self.table) && !(self.step_mm > 0.0 && self.sphere_diameter_mm > 0.0) {
            return bad("scan", "step_mm and sphere_diameter_mm must be > 0".into());
        }
        Ok(())
    }
}
