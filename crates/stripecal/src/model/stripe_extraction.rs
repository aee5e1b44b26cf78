//! What a stripe extraction found and left out: per scan line the reasons it gave no
//! point, and per view the points found, left out as biased and saturated (the
//! extractor is `crate::vision::stripe`; the records live here, where calibration
//! results can hold them).

/// Why scan lines gave no point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RejectCounts {
    /// No ridge above `min_contrast`.
    pub no_peak: usize,
    /// Two or more comparable peaks.
    pub multiple_peaks: usize,
    /// A saturated plateau longer than `max_saturated_px`.
    pub saturated: usize,
    /// Width outside the accepted range, or a peak too weak after background removal.
    pub shape: usize,
    /// The window or its flanks leave the image.
    pub border: usize,
    /// Not part of a chain of neighbouring points (continuity).
    pub isolated: usize,
    /// Scan lines that DID give a point, from the peak that continues the line, while
    /// holding another peak of comparable strength (a reflection, a second line) that
    /// was left out.
    pub reflections: usize,
    /// Scan lines whose only peak continues a reflection (a chain that lost to a
    /// heavier line where both were seen).
    pub reflection_only: usize,
    /// Scan lines that gave two points (`keep_ambiguous`): two comparable peaks that
    /// the line's continuity did not decide between.
    pub ambiguous: usize,
}

/// What the stripe extraction of one view found and left out, before the calibration
/// selects its points (per view in calibration.json and the CLI's table).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StripeExtraction {
    /// Scan lines searched.
    pub lines: usize,
    /// Scan lines without a point, by reason.
    pub rejected: RejectCounts,
    /// Points the extractor found.
    pub found: usize,
    /// Of them left out as biased: a reflectance edge of the board image in their
    /// support, an uneven background in the stripe image, a shallow crossing of the
    /// scan line.
    pub at_edge: usize,
    pub uneven_background: usize,
    pub oblique: usize,
    /// Of the points kept, those whose profile holds a saturated pixel.
    pub saturated: usize,
    /// The line's width across (the survey's, px) and the scan lines averaged along
    /// the line (1: none).
    pub width_px: f64,
    pub along_line: usize,
}

impl StripeExtraction {
    /// Of the points found, the share whose profile holds a saturated pixel (0 with
    /// none kept).
    pub fn saturated_share(&self) -> f64 {
        let kept = self
            .found
            .saturating_sub(self.at_edge + self.uneven_background + self.oblique);
        if kept == 0 {
            0.0
        } else {
            self.saturated as f64 / kept as f64
        }
    }
}
