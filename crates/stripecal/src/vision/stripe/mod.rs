//! Laser stripe extraction: one sub-pixel stripe point per scan line, reflectance-edge
//! flagging with the board image, and a robust straight-line fit.
//!
//! ## Scan lines
//!
//! [`StripeDirection::Cols`]: the stripe runs roughly along image columns, each ROW is a
//! scan line and gives at most one point `(u, v = row)`. [`StripeDirection::Rows`]: the
//! stripe runs roughly along rows, each COLUMN is a scan line, one point `(u = column, v)`.
//! [`StripeDirection::Auto`] decides from the image (see [`resolve_direction`]).
//!
//! ## Before the scan lines: the survey
//!
//! [`survey`] looks at every 8th row and column: the line's width across, the share of
//! its peaks at full scale, and a speckle index (how much its brightness jumps from a
//! scan line to the next). A line wider than the ridge test's distance allows gets a
//! wider one (`ceil(width / 2) + 3`, with wider widths and longer saturated plateaus
//! accepted: [`StripeOptions::adapt_to_line`]); a saturated or
//! speckled line is smoothed along the line over 5 scan lines first
//! ([`StripeOptions::along_line`]: the centre of a straight line stays where it is, the
//! speckle averages down, a saturated plateau's edges steady). A narrow, unsaturated,
//! clean line is extracted exactly as before the survey existed.
//!
//! ## Per scan line
//!
//! 1. **Peak search (ridge test).** `r(x) = I(x) - max(I(x - d), I(x + d))` with
//!    `d = ridge_px` (or the survey's): positive only on a bright ridge narrower than
//!    `2 d`; a step of the background (a circle's border, the plate's edge, board
//!    texture in single-image views) gives `r <= 0`. Runs of `r >= min_contrast` (runs
//!    less than `d` apart merged: one line) are peak candidates; a scan line keeps its
//!    four strongest. This pass is one read of the scan line with integer arithmetic,
//!    vectorised by the compiler; only the few pixels above the threshold are looked at
//!    further.
//! 2. **One peak or several.** No candidate: no point. A single candidate, or a weaker
//!    one below `second_peak_ratio` of the strongest: the strongest. Two comparable
//!    candidates (a reflection, a second line, a bright edge of the scene) are decided
//!    by the line's continuity ([`chains`]): the one on the heaviest chain of peaks
//!    through the neighbouring scan lines; a scan line that chain cannot decide gives
//!    no point, or both with [`FLAG_AMBIGUOUS`] when [`StripeOptions::keep_ambiguous`]
//!    (the calibration's board-plane consensus then tells which; where one of the two
//!    gives no centre, the other alone, still flagged).
//! 3. **Local background** from two flanks of `flank_px` pixels just outside the centre
//!    window, linear between them (it follows the board texture and shading locally).
//!    Flanks that disagree or are not flat mean a reflectance change under the stripe:
//!    the point is flagged [`FLAG_UNEVEN_BACKGROUND`].
//! 4. **Width** = full width at half maximum along the scan line (`width_px`), peak =
//!    height above the background. Rejected: width outside `[min_width_px,
//!    max_width_px]`, a saturated plateau longer than `max_saturated_px`, a window that
//!    leaves the image.
//! 5. **Sub-pixel centre.** A saturated plateau (2 px or more at full scale): the
//!    middle of its two half-maximum crossings (the clipped top holds no centre; its
//!    edges do, as line profilers take it). Otherwise [`StripeMethod::Centroid`] (the
//!    paper's way): gray centroid of
//!    `I - background` over a window of `+-window_fwhm * width_px` centred on the current
//!    estimate, with fractional weights at the window ends, iterated to a fixed point (so
//!    the window truncation does not pull the centre). [`StripeMethod::Gaussian`]: a
//!    Gauss-Newton fit of `A exp(-(x - c)^2 / 2 s^2)` to the same residuals, started from
//!    the centroid (falls back to it if the fit fails).
//! 6. **Continuity.** Points that do not belong to a chain of at least `min_chain`
//!    neighbouring scan lines (gap <= 2 lines, jump <= `max_jump_px` per line) are dropped:
//!    a real stripe is a curve, noise is not.
//!
//! Points whose support holds a saturated pixel are flagged [`FLAG_SATURATED`]; weak ones
//! (peak < `low_signal_gray`) [`FLAG_LOW_SIGNAL`]; where the stripe crosses the scan line
//! at a shallow angle (slope > `max_slope` from the neighbouring points) [`FLAG_OBLIQUE`]. [`flag_reflectance_edges`] adds
//! [`FLAG_EDGE`] from the board image of the same pose.
//!
//! Gray-level options are on the 8-bit scale and multiplied by 257 for 16-bit images
//! (which use the full range, spec/DATASET.md).
//!
//! Colour laser images: the extractor runs on one channel's image, the signal that
//! `stripe.channel` names ([`colour`]: BT.601 gray, or the laser colour's channel).

mod chains;
pub mod colour;
mod edges;
mod extract;
mod gauss;
mod lanes;
mod line;
mod peak;
mod ridge;
mod smooth;
pub mod survey;

pub use crate::model::{RejectCounts, StripeChannel, StripeDirection};
pub use colour::{stripe_signal, stripe_signal_of_file};
pub use edges::{flag_reflectance_edges, EdgeOptions};
pub use extract::{resolve_direction, StripeExtractor};
pub use line::{fit_line, fit_line_with, LineFit, LineFitOptions};

use crate::error::{Error, Result};
use crate::model::image::AnyView;

/// The support of the point holds a saturated pixel (at full scale).
pub const FLAG_SATURATED: u8 = 1;
/// The peak is below `low_signal_gray` above the background (e.g. inside a dark circle):
/// the centre is noisier.
pub const FLAG_LOW_SIGNAL: u8 = 2;
/// The board image shows a reflectance edge (circle border, plate edge) inside the
/// point's support: the centre is biased on a real sensor too ([`flag_reflectance_edges`]).
pub const FLAG_EDGE: u8 = 4;
/// The stripe image's own background changes across the point's support (the two flanks
/// disagree or are not flat): a reflectance or depth edge under the stripe.
pub const FLAG_UNEVEN_BACKGROUND: u8 = 8;
/// The stripe crosses the scan line at a shallow angle here (`|d position / d line| >
/// max_slope`, from the neighbouring points): the scan-line profile runs along the stripe
/// and follows its bends and intensity changes (a sphere's rim), so the centre is biased.
pub const FLAG_OBLIQUE: u8 = 16;
/// The scan line held two comparable peaks that the line's continuity did not decide
/// between, and both were kept ([`StripeOptions::keep_ambiguous`]): one of the two
/// points of the scan line is not the stripe (a calibration's board-plane consensus
/// tells which). Where one of the two gives no centre, the other is kept alone with
/// this flag: it may be the one that is not the stripe.
pub const FLAG_AMBIGUOUS: u8 = 32;
/// Flags that warn of a biased centre: leave such points out of calibration.
pub const FLAG_BIASED: u8 = FLAG_EDGE | FLAG_UNEVEN_BACKGROUND | FLAG_OBLIQUE;

/// How the sub-pixel centre is computed on each scan line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StripeMethod {
    /// Gray centroid over an adaptive window (the paper's way).
    #[default]
    Centroid,
    /// Least-squares Gaussian fit (Steger-like; slower, a little less noisy on weak lines).
    Gaussian,
}

impl StripeMethod {
    /// `centroid` or `gaussian`.
    pub fn name(self) -> &'static str {
        match self {
            StripeMethod::Centroid => "centroid",
            StripeMethod::Gaussian => "gaussian",
        }
    }

    /// Parses `centroid` or `gaussian`.
    pub fn from_name(s: &str) -> Result<Self> {
        match s {
            "centroid" => Ok(StripeMethod::Centroid),
            "gaussian" => Ok(StripeMethod::Gaussian),
            other => Err(Error::InvalidInput(format!(
                "unknown stripe method {other:?}: expected \"centroid\" or \"gaussian\""
            ))),
        }
    }
}

/// Options of the stripe extractor. Gray levels on the 8-bit scale (x257 for 16-bit).
#[derive(Debug, Clone, PartialEq)]
pub struct StripeOptions {
    pub direction: StripeDirection,
    pub method: StripeMethod,
    /// Ridge test distance `d`, px: a stripe must be brighter than the pixels `d` away on
    /// both sides. Must exceed the stripe's half width at half maximum.
    pub ridge_px: usize,
    /// Smallest ridge response and peak height above the background, gray.
    pub min_contrast: f32,
    /// A second candidate at least this fraction of the strongest makes the scan line
    /// ambiguous (rejected).
    pub second_peak_ratio: f32,
    /// Accepted stripe width (FWHM along the scan line), px.
    pub min_width_px: f32,
    pub max_width_px: f32,
    /// Centroid window half width, in stripe widths (FWHM).
    pub window_fwhm: f32,
    /// Pixels of each background flank.
    pub flank_px: usize,
    /// Longest saturated plateau still trusted, px.
    pub max_saturated_px: usize,
    /// Peaks below this height above the background get [`FLAG_LOW_SIGNAL`], gray.
    pub low_signal_gray: f32,
    /// Flank disagreement flagged [`FLAG_UNEVEN_BACKGROUND`]: more than
    /// `uneven_gray + uneven_rel * peak`.
    pub uneven_gray: f32,
    pub uneven_rel: f32,
    /// Continuity: shortest chain of neighbouring points kept.
    pub min_chain: usize,
    /// Continuity: largest jump of the centre between neighbouring scan lines, px per line.
    pub max_jump_px: f32,
    /// Points where the stripe's slope against the scan line exceeds this get
    /// [`FLAG_OBLIQUE`].
    pub max_slope: f32,
    /// Adapt to the line's width and saturation ([`survey`]): a line wider than about
    /// `2 * ridge_px - 4` px is found with the ridge distance `ceil(width / 2) + 3`,
    /// widths up to `1.5 * width + 4` are accepted and, on a saturated line, plateaus
    /// as long (`ridge_px`, `max_width_px` and `max_saturated_px` are the
    /// least these become; a narrow, unsaturated line is extracted with them as set).
    pub adapt_to_line: bool,
    /// Scan lines averaged along the line before the centre (1: none; 0: auto, from
    /// the [`survey`]: 5 for a saturated or speckled line, 1 otherwise). At most 31.
    pub along_line: usize,
    /// A scan line with two comparable peaks that the line's continuity does not
    /// decide between (a saturated reflection beside a saturated line) gives both,
    /// flagged [`FLAG_AMBIGUOUS`], after the scan lines' single points (default false:
    /// no point; the calibration keeps both and lets its board-plane consensus decide).
    pub keep_ambiguous: bool,
}

impl Default for StripeOptions {
    fn default() -> Self {
        StripeOptions {
            direction: StripeDirection::Auto,
            method: StripeMethod::Centroid,
            ridge_px: 5,
            min_contrast: 6.0,
            second_peak_ratio: 0.5,
            min_width_px: 1.2,
            max_width_px: 24.0,
            window_fwhm: 1.0,
            flank_px: 3,
            max_saturated_px: 6,
            low_signal_gray: 20.0,
            uneven_gray: 5.0,
            uneven_rel: 0.1,
            min_chain: 3,
            max_jump_px: 4.0,
            max_slope: 1.5,
            adapt_to_line: true,
            along_line: 0,
            keep_ambiguous: false,
        }
    }
}

impl StripeOptions {
    /// Checks the values (finite, positive, ordered).
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::InvalidInput(format!("stripe options: {m}")));
        if self.ridge_px < 1 || self.ridge_px > 64 {
            return bad(format!("ridge_px {} must be in 1..=64", self.ridge_px));
        }
        for (k, v) in [
            ("min_contrast", self.min_contrast),
            ("min_width_px", self.min_width_px),
            ("max_width_px", self.max_width_px),
            ("window_fwhm", self.window_fwhm),
            ("max_jump_px", self.max_jump_px),
            ("max_slope", self.max_slope),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!("{k} = {v} must be finite and > 0"));
            }
        }
        for (k, v) in [
            ("low_signal_gray", self.low_signal_gray),
            ("uneven_gray", self.uneven_gray),
            ("uneven_rel", self.uneven_rel),
            ("second_peak_ratio", self.second_peak_ratio),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{k} = {v} must be finite and >= 0"));
            }
        }
        if self.max_width_px < self.min_width_px || self.max_width_px > 256.0 {
            return bad(format!(
                "max_width_px {} must be >= min_width_px {} and <= 256",
                self.max_width_px, self.min_width_px
            ));
        }
        if self.window_fwhm > 4.0 {
            return bad(format!("window_fwhm {} must be <= 4", self.window_fwhm));
        }
        if self.flank_px < 1 || self.flank_px > 32 {
            return bad(format!("flank_px {} must be in 1..=32", self.flank_px));
        }
        if self.along_line > 31 {
            return bad(format!("along_line {} must be in 0..=31", self.along_line));
        }
        Ok(())
    }
}

/// The extractor's sub-pixel estimate on one synthetic scan-line profile: `values[k]` is
/// the (background-free, any positive scale) signal of pixel `k`. The profile is
/// quantised to 16 bits with its maximum at 60000 and handed to the same code as a real
/// scan line (background flanks, width at half maximum, iterated window centroid or
/// Gaussian fit): returns `(centre, width_px, peak)` (centre in pixel indices, peak
/// height in the units of `values`), or `None` where the extractor would reject the scan
/// line. For models of the extractor's response (the
/// curved-surface bias model of [`crate::reconstruct::fit`]).
pub(crate) fn profile_centre(values: &[f64], opts: &StripeOptions) -> Option<(f64, f32, f64)> {
    let (pk, &vmax) = values
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    if !(vmax > 0.0 && vmax.is_finite()) {
        return None;
    }
    let scale = 60000.0 / vmax;
    let seg: Vec<u16> = values
        .iter()
        .map(|&v| (v * scale).round().clamp(0.0, 65535.0) as u16)
        .collect();
    let p = peak::Params::new::<u16>(opts);
    let mut res = Vec::new();
    peak::subpixel(&seg, pk, &p, &mut res)
        .ok()
        .map(|s| (s.c, s.width, s.peak as f64 / scale))
}

/// One stripe point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StripePoint {
    /// Sub-pixel centre, px (pixel centres at integers). One of the two is the scan line
    /// (an integer).
    pub u: f64,
    pub v: f64,
    /// Peak height above the local background, gray levels of the image.
    pub peak: f32,
    /// Width (FWHM) along the scan line, px.
    pub width_px: f32,
    /// Half length of the scan-line segment the centre depends on (window plus background
    /// flanks), px.
    pub support_px: f32,
    /// `FLAG_*` bits.
    pub flags: u8,
}

impl StripePoint {
    /// A reflectance change was seen in the point's support ([`FLAG_EDGE`] or
    /// [`FLAG_UNEVEN_BACKGROUND`]): leave it out of calibration.
    pub fn near_edge(&self) -> bool {
        self.flags & (FLAG_EDGE | FLAG_UNEVEN_BACKGROUND) != 0
    }

    /// The point's support holds a pixel at full scale ([`FLAG_SATURATED`]).
    pub fn saturated(&self) -> bool {
        self.flags & FLAG_SATURATED != 0
    }

    /// No flag warns of a biased centre (none of [`FLAG_BIASED`]; low-signal and saturated
    /// points are noisier, not biased, and count as trusted).
    pub fn trusted(&self) -> bool {
        self.flags & FLAG_BIASED == 0
    }
}

/// The stripe of one image.
#[derive(Debug, Clone, PartialEq)]
pub struct Stripe {
    /// The direction used (never `Auto`).
    pub direction: StripeDirection,
    /// Image size `(width, height)`.
    pub size: (usize, usize),
    /// Points in scan-line order.
    pub points: Vec<StripePoint>,
    /// Scan lines examined.
    pub lines: usize,
    pub rejected: RejectCounts,
    /// What the survey saw of the line ([`survey`]), and the scan lines averaged along
    /// the line before the centres (1: none).
    pub survey: survey::Survey,
    pub along_line: usize,
}

/// Extracts the stripe of one image (see the module docs). An image where no scan line
/// holds a stripe is an error ([`Error::Detection`], "no stripe found ..." with the
/// reasons per scan line); line software
/// that expects empty frames uses [`StripeExtractor::extract_into`], which returns no
/// points instead.
pub fn extract_stripe(img: AnyView<'_>, opts: &StripeOptions) -> Result<Stripe> {
    let mut ex = StripeExtractor::new(opts.clone())?;
    // At most one point per scan line: one allocation, no regrowth.
    let (w0, h0) = img.size();
    let mut points = Vec::with_capacity(w0.max(h0));
    let direction = ex.extract_into(img, &mut points)?;
    let rejected = ex.rejected();
    let (_, along_line) = ex.adapted();
    let (w, h) = img.size();
    let lines = if direction == StripeDirection::Rows {
        w
    } else {
        h
    };
    if points.is_empty() {
        let r = rejected;
        return Err(Error::Detection(format!(
            "no stripe found in any scan line ({lines} {} of a {w} x {h} image: {} without a \
             peak, {} with several peaks, {} saturated, {} of the wrong width or too weak, {} \
             at the border, {} isolated)",
            if direction == StripeDirection::Rows {
                "columns"
            } else {
                "rows"
            },
            r.no_peak,
            r.multiple_peaks,
            r.saturated,
            r.shape,
            r.border,
            r.isolated
        )));
    }
    Ok(Stripe {
        direction,
        size: (w, h),
        points,
        lines,
        rejected,
        survey: ex.survey(),
        along_line,
    })
}
