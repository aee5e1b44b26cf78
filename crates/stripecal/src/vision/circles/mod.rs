//! Circle-grid detection (symmetric grids with any number of markers, and asymmetric
//! grids): find the board's circles in an image, index them by `(row, col)` and measure
//! their centres to sub-pixel accuracy.
//!
//! [`detect_circles`] runs four stages:
//!
//! 1. Blobs (`blobs`): adaptive threshold against a local mean over a window that is a
//!    fraction of the image, run-length connected components, filters on area (relative
//!    to the image), fill ratio and axis ratio of the moment ellipse, and a darker-than-
//!    its-surroundings test that tolerates a close neighbour. Components touching the
//!    image border are cut circles: kept aside, only to tell a cut marker by its size.
//! 2. Lattice (`lattice`): lattice coordinates grown from neighbourhood topology (for
//!    an asymmetric grid the 45-degree lattice of its nearest neighbours), checked
//!    leave-one-out; a grid larger than the board, or a second board, is an error.
//! 3. Labels (`labels`): board indices from what the image shows: marker circles by
//!    their relative size (cut ones by the visible part), every rotation and shift of
//!    the lattice that puts the grid on the board with the markers on markers, mirror
//!    images rejected. One placement is the labelling; placements related by the
//!    board's own symmetries are returned as alternatives
//!    ([`CircleGrid::alternatives`]) for the calibration to decide from the robot poses;
//!    any other ambiguity (a part of a board without markers) is an
//!    [`Error::Detection`] saying so, never a guess. So is a grid that ends inside the
//!    image where the board of rig.json would go on.
//! 4. Centres (`centre`): the gravity method (background-corrected intensity centroid
//!    over the blob and its blurred edge) or the centre of an ellipse fitted to
//!    sub-pixel edge points; see [`CentreMethod`]. Every circle also carries the RMS
//!    residual of the ellipse fit as its quality figure.
//!
//! ## Accuracy (digital twin, `hp3-paper`: 768 x 576, noise 1 gray level, PSF 0.7 px)
//!
//! Measured against the true centres (area centroids of the exactly projected
//! outlines) by `crates/stripecal/tests/it/vision_circles.rs`; the figures are in
//! BENCHMARKS.md ("Vision: circles"). The gravity method is the default because it
//! measured best there.
//!
//! ## Single-image views (board lit and stripe on)
//!
//! A laser stripe crossing a circle's window biases both centre methods (it adds light
//! to part of the circle and its edge). Such circles are found (bright outliers in the
//! background ring, see `centre`) and **dropped** from [`CircleGrid::circles`]; they
//! are listed in [`CircleGrid::dropped`] with the reason. Masking the stripe out of the
//! centroid was rejected: it removes an asymmetric part of the circle and biases the
//! centroid just as much. With [`CircleOptions::drop_stripe_crossed`] `false` they are
//! kept and flagged instead.
//!
//! ## Conventions
//!
//! Pixel centres at integer coordinates (spec/DATASET.md): `u` along columns, `v` along
//! rows, the top-left pixel's centre is `(0, 0)`.

mod blobs;
mod centre;
mod labels;
mod lattice;

use crate::error::{Error, Result};
use crate::model::board::Board;
use crate::model::image::{AnyView, Pixel};

use blobs::Img;

/// How circle centres are measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CentreMethod {
    /// Background-corrected intensity centroid over the blob and its edge (the paper's
    /// gravity method).
    #[default]
    Gravity,
    /// Centre of an ellipse fitted to sub-pixel edge points.
    Ellipse,
}

impl CentreMethod {
    /// `gravity` or `ellipse`.
    pub fn name(self) -> &'static str {
        match self {
            CentreMethod::Gravity => "gravity",
            CentreMethod::Ellipse => "ellipse",
        }
    }

    /// Parses `gravity` / `ellipse`.
    pub fn from_name(s: &str) -> Result<Self> {
        match s {
            "gravity" => Ok(CentreMethod::Gravity),
            "ellipse" => Ok(CentreMethod::Ellipse),
            other => Err(Error::InvalidInput(format!(
                "unknown centre method {other:?}: expected \"gravity\" or \"ellipse\""
            ))),
        }
    }
}

/// Options of [`detect_circles`]. The defaults suit the `hp3-paper` rig and images
/// where the board's circles are 8 px or more across.
#[derive(Debug, Clone, PartialEq)]
pub struct CircleOptions {
    /// Centre method.
    pub method: CentreMethod,
    /// Threshold window side as a fraction of the shorter image side (default 1/6).
    pub window_frac: f64,
    /// A pixel is a blob pixel when its darkness is below this fraction of the window
    /// mean (default 0.75; for light circles the image is inverted first).
    pub threshold_ratio: f64,
    /// Smallest blob, px^2 (default 12: the centre methods need a few pixels).
    pub min_area_px: f64,
    /// Smallest minor / major axis ratio of a blob (default 0.2: tilts up to ~78 deg).
    pub min_axis_ratio: f64,
    /// Blur allowance around each blob's edge, px (default 3: PSF sigma up to ~1 px);
    /// the integration window is the blob grown by this plus 10 % of its minor semi-axis.
    pub edge_margin_px: f64,
    /// Drop circles crossed by a bright stripe (default `true`); when `false` they are
    /// kept with [`DetectedCircle::stripe_crossed`] set.
    pub drop_stripe_crossed: bool,
}

impl Default for CircleOptions {
    fn default() -> Self {
        CircleOptions {
            method: CentreMethod::Gravity,
            window_frac: 1.0 / 6.0,
            threshold_ratio: 0.75,
            min_area_px: 12.0,
            min_axis_ratio: 0.2,
            edge_margin_px: 3.0,
            drop_stripe_crossed: true,
        }
    }
}

impl CircleOptions {
    fn validate(&self) -> Result<()> {
        let bad = |what: &str, v: f64| {
            Err(Error::InvalidInput(format!(
                "CircleOptions.{what} = {v} is out of range"
            )))
        };
        if !(self.window_frac > 0.0 && self.window_frac <= 1.0) {
            return bad("window_frac", self.window_frac);
        }
        if !(self.threshold_ratio > 0.0 && self.threshold_ratio < 1.0) {
            return bad("threshold_ratio", self.threshold_ratio);
        }
        if !(self.min_area_px >= 4.0 && self.min_area_px.is_finite()) {
            return bad("min_area_px", self.min_area_px);
        }
        if !(self.min_axis_ratio > 0.0 && self.min_axis_ratio <= 1.0) {
            return bad("min_axis_ratio", self.min_axis_ratio);
        }
        if !(self.edge_margin_px >= 0.5 && self.edge_margin_px <= 50.0) {
            return bad("edge_margin_px", self.edge_margin_px);
        }
        Ok(())
    }
}

/// One detected circle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectedCircle {
    /// Board row and column.
    pub row: usize,
    pub col: usize,
    /// Centre by the chosen method, px.
    pub u: f64,
    pub v: f64,
    /// RMS geometric residual of the ellipse fitted to the edge points, px (NaN when
    /// the edge could not be fitted).
    pub quality_px: f64,
    /// Area from the background-corrected intensity, px^2.
    pub area_px: f64,
    /// Semi-axes (major, minor) of the fitted ellipse, px (NaN when not fitted).
    pub axes_px: [f64; 2],
    /// Angle of the major axis from +u towards +v, radians (NaN when not fitted).
    pub angle_rad: f64,
    /// A bright stripe crosses the circle's window (only when kept, see
    /// [`CircleOptions::drop_stripe_crossed`]).
    pub stripe_crossed: bool,
}

/// A circle of the grid that was indexed but left out of the result (its rough position
/// is the blob's pixel centroid).
pub type DroppedCircle = crate::vision::target::DroppedPoint;

/// The result of [`detect_circles`].
#[derive(Debug, Clone, PartialEq)]
pub struct CircleGrid {
    /// Detected circles sorted by `(row, col)`.
    pub circles: Vec<DetectedCircle>,
    /// Indexed circles left out (stripe, window outside the image, failed fit).
    pub dropped: Vec<DroppedCircle>,
    /// Blobs that passed the shape filters.
    pub blobs: usize,
    /// Lattice nodes grown, and those removed by the consistency check.
    pub nodes_grown: usize,
    pub nodes_inconsistent: usize,
    /// RMS and largest residual of a board-to-image homography fitted to the circles'
    /// centres, px (lens distortion shows here as well; a diagnostic).
    pub homography_rms_px: f64,
    pub homography_max_px: f64,
    /// The method used for `u, v`.
    pub method: CentreMethod,
    /// Marker circles seen (measured or cut by the image border).
    pub markers_seen: usize,
    /// Board symmetries the view cannot decide (see
    /// [`crate::vision::target::TargetDetection::alternatives`]).
    pub alternatives: Vec<crate::model::board::Symmetry>,
}

/// Smallest image side accepted.
pub const MIN_IMAGE_SIDE: usize = 16;

/// Detects the circles of `board` in `img` (8- or 16-bit gray).
///
/// Errors: [`Error::InvalidInput`] for a board that is not a circle board or whose
/// markers cannot fix the grid, an image smaller than 16 x 16 or bad options;
/// [`Error::Detection`] when no grid is found or it cannot be indexed without guessing
/// (the message says how many blobs, lattice nodes and markers were found).
pub fn detect_circles(img: AnyView<'_>, board: &Board, opts: &CircleOptions) -> Result<CircleGrid> {
    board.validate()?;
    opts.validate()?;
    if !board.kind.is_circles() {
        return Err(Error::InvalidInput(format!(
            "detect_circles needs a circle board (kind \"circles\" or \"asymmetric_circles\"), \
             not a \"{}\"",
            board.kind.name()
        )));
    }
    let (w, h) = img.size();
    if w < MIN_IMAGE_SIDE || h < MIN_IMAGE_SIDE {
        return Err(Error::InvalidInput(format!(
            "image is {w} x {h} pixels; at least {MIN_IMAGE_SIDE} x {MIN_IMAGE_SIDE} is needed"
        )));
    }
    match img {
        AnyView::U8(v) => detect_in(Img::new(v), board, opts),
        AnyView::U16(v) => detect_in(Img::new(v), board, opts),
    }
}

fn detect_in<T: Pixel>(im: Img<'_, T>, board: &Board, opts: &CircleOptions) -> Result<CircleGrid> {
    let (lo, hi) = im.range();
    if hi - lo < im.max / 64.0 {
        return Err(Error::Detection(format!(
            "no circle grid: the image has no contrast (all pixels between {lo} and {hi})"
        )));
    }
    let dark = board.dark_circles;
    let found = blobs::find_blobs(&im, dark, opts);
    let (blobs, stats) = (&found.blobs, found.stats);
    let summary = || {
        format!(
            "{} blobs passed the filters ({} components: {} touching the border, {} too small, {} \
             too large, {} not elliptical, {} not surrounded by background)",
            blobs.len(),
            stats.components,
            stats.touching_border,
            stats.too_small,
            stats.too_large,
            stats.bad_shape,
            stats.not_surrounded
        )
    };
    let grid = lattice::build(blobs, board, &summary)?;
    let g = labels::label(&grid, blobs, &found.cut, board, (im.w, im.h), &summary)?;

    let shapes: Vec<centre::Shape> = blobs
        .iter()
        .map(|b| centre::Shape::of(b, opts.edge_margin_px))
        .collect();
    let mut circles = Vec::with_capacity(g.nodes.len());
    let mut dropped = Vec::new();
    let mut near: Vec<centre::Shape> = Vec::new();
    for &(bi, row, col) in &g.nodes {
        let b = &blobs[bi];
        let drop = |reason: &'static str| DroppedCircle {
            row,
            col,
            u: b.cx,
            v: b.cy,
            reason,
        };
        // Blobs whose grown ellipse can reach this blob's background ring.
        let reach = 2.0 * shapes[bi].reach() + 1.0;
        near.clear();
        near.extend(shapes.iter().enumerate().filter_map(|(k, s)| {
            let d2 = (s.cx() - b.cx).powi(2) + (s.cy() - b.cy).powi(2);
            (k != bi && d2 < (reach + s.reach()).powi(2)).then_some(*s)
        }));
        let ellipse_centre = opts.method == CentreMethod::Ellipse;
        let m = match centre::measure(&im, b, dark, opts.edge_margin_px, &near, ellipse_centre) {
            Ok(m) => m,
            Err(f) => {
                dropped.push(drop(f.reason()));
                continue;
            }
        };
        let stripe = m.stripe_px >= 2;
        if stripe && opts.drop_stripe_crossed {
            dropped.push(drop("crossed by a bright stripe"));
            continue;
        }
        let (u, v) = match opts.method {
            CentreMethod::Gravity => (m.gravity[0], m.gravity[1]),
            CentreMethod::Ellipse => match &m.ellipse {
                Some(e) => (e.centre[0], e.centre[1]),
                None => {
                    dropped.push(drop("no ellipse could be fitted to its edge"));
                    continue;
                }
            },
        };
        let (quality_px, axes_px, angle_rad) = match &m.ellipse {
            Some(e) => (e.rms, e.axes, e.angle),
            None => (f64::NAN, [f64::NAN; 2], f64::NAN),
        };
        circles.push(DetectedCircle {
            row,
            col,
            u,
            v,
            quality_px,
            area_px: m.area_px,
            axes_px,
            angle_rad,
            stripe_crossed: stripe,
        });
    }
    let pts: Vec<(usize, usize, f64, f64)> =
        circles.iter().map(|c| (c.row, c.col, c.u, c.v)).collect();
    let (homography_rms_px, homography_max_px) =
        crate::vision::target::homography_residuals(board, &pts);
    Ok(CircleGrid {
        circles,
        dropped,
        blobs: blobs.len(),
        nodes_grown: grid.grown,
        nodes_inconsistent: grid.outliers,
        homography_rms_px,
        homography_max_px,
        method: opts.method,
        alternatives: g.alternatives,
        markers_seen: g.markers_seen,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::board::BoardKind;
    use crate::model::image::ImageView;

    fn detect(data: &[u8], w: usize, h: usize) -> Result<CircleGrid> {
        let v = ImageView::from_slice(data, w, h)?;
        detect_circles(
            AnyView::U8(v),
            &Board::hp3_paper(),
            &CircleOptions::default(),
        )
    }

    /// A synthetic fronto-parallel board, anti-aliased by 8x8 supersampling.
    fn synthetic(w: usize, h: usize, pitch_px: f64, rot: f64, origin: (f64, f64)) -> Vec<u8> {
        synthetic_boards(w, h, &[(Board::hp3_paper(), pitch_px, rot, origin)])
    }

    /// Several boards `(board, pitch px, rotation, image position of point (0, 0))` on
    /// one light plate.
    fn synthetic_boards(w: usize, h: usize, boards: &[(Board, f64, f64, (f64, f64))]) -> Vec<u8> {
        let mut out = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0f64;
                for sy in 0..8 {
                    for sx in 0..8 {
                        let ink = boards.iter().any(|(b, pitch_px, rot, origin)| {
                            let s = pitch_px / b.pitch_mm;
                            let (c, sn) = (rot.cos(), rot.sin());
                            let u = x as f64 - 0.5 + (sx as f64 + 0.5) / 8.0 - origin.0;
                            let v = y as f64 - 0.5 + (sy as f64 + 0.5) / 8.0 - origin.1;
                            // image -> board (inverse rotation, scale)
                            let bx = (c * u + sn * v) / s;
                            let by = (-sn * u + c * v) / s;
                            b.circle_at(bx, by).is_some()
                        });
                        acc += if ink { 0.1 } else { 0.8 };
                    }
                }
                out[y * w + x] = (acc / 64.0 * 255.0).round() as u8;
            }
        }
        out
    }

    fn detect_as(data: &[u8], w: usize, h: usize, board: &Board) -> Result<CircleGrid> {
        let v = ImageView::from_slice(data, w, h)?;
        detect_circles(AnyView::U8(v), board, &CircleOptions::default())
    }

    /// The image shows the 8 x 11 board whole; rig.json says another size: a typed
    /// detection error saying so, in both directions.
    #[test]
    fn wrong_board_size_is_a_detection_error() {
        let (w, h) = (320, 240);
        let img = synthetic(w, h, 16.0, 0.2, (90.0, 40.0));
        assert_eq!(detect(&img, w, h).unwrap().circles.len(), 88);
        for (rows, cols, what) in [
            (8, 10, "larger"),
            (7, 11, "larger"),
            (9, 11, "ends inside"),
            (8, 12, "ends inside"),
            // far larger than the print: most of the next line is outside the image,
            // but the points beside the grid are inside (issue 39, fault 10)
            (20, 20, "ends inside"),
            (1000, 1000, "ends inside"),
            (8, 40, "ends inside"),
        ] {
            let mut b = Board::hp3_paper();
            (b.rows, b.cols) = (rows, cols);
            let e = detect_as(&img, w, h, &b).unwrap_err();
            assert!(matches!(e, Error::Detection(_)), "{rows} x {cols}: {e}");
            assert!(e.to_string().contains(what), "{rows} x {cols}: {e}");
        }
    }

    /// Two boards in the image: which is the target cannot be told.
    #[test]
    fn two_boards_are_a_detection_error() {
        let (w, h) = (480, 240);
        let b = Board::hp3_paper();
        let img = synthetic_boards(
            w,
            h,
            &[
                (b.clone(), 12.0, 0.1, (20.0, 40.0)),
                (b, 12.0, -0.2, (300.0, 80.0)),
            ],
        );
        let e = detect(&img, w, h).unwrap_err();
        assert!(matches!(e, Error::Detection(_)), "{e}");
        assert!(e.to_string().contains("two boards"), "{e}");
    }

    /// A grid without markers: the half turn is returned as the alternative, and the
    /// labelling is one of the two.
    #[test]
    fn no_markers_gives_the_half_turn_as_alternative() {
        let (w, h) = (320, 240);
        let img = synthetic(w, h, 16.0, 0.4, (100.0, 30.0));
        let mut b = Board::hp3_paper();
        b.markers.clear();
        let g = detect_as(&img, w, h, &b).unwrap();
        assert_eq!(g.circles.len(), 88);
        assert_eq!(g.alternatives, b.symmetries());
        // a part of it (the right third out of the image): where on the board is unknown
        let img = synthetic(w, h, 16.0, 0.0, (170.0, 60.0));
        let e = detect_as(&img, w, h, &b).unwrap_err();
        assert!(
            e.to_string().contains("cannot tell where on the board"),
            "{e}"
        );
        // with the marker L it is indexed
        let g = detect(&img, w, h).unwrap();
        assert!(g.circles.len() > 40 && g.circles.iter().all(|c| c.col < 10));
    }

    #[test]
    fn synthetic_board_any_rotation() {
        let (w, h) = (320, 240);
        for k in 0..8 {
            let rot = k as f64 * 0.83;
            let pitch = 16.0;
            // board centre at the image centre
            let (cxb, cyb) = (5.0 * pitch, 3.5 * pitch);
            let (c, s) = (rot.cos(), rot.sin());
            let origin = (160.0 - (c * cxb - s * cyb), 120.0 - (s * cxb + c * cyb));
            let img = synthetic(w, h, pitch, rot, origin);
            let g = detect(&img, w, h).unwrap_or_else(|e| panic!("rotation {rot}: {e}"));
            assert_eq!(g.circles.len(), 88, "rotation {rot}: {:?}", g.dropped);
            for ci in &g.circles {
                let (bx, by) = (ci.col as f64 * pitch, ci.row as f64 * pitch);
                let u = origin.0 + c * bx - s * by;
                let v = origin.1 + s * bx + c * by;
                let e = ((ci.u - u).powi(2) + (ci.v - v).powi(2)).sqrt();
                assert!(
                    e < 0.05,
                    "rotation {rot}: circle ({}, {}) off by {e}",
                    ci.row,
                    ci.col
                );
            }
        }
    }

    #[test]
    fn mirrored_board_is_rejected() {
        let (w, h) = (320, 240);
        let pitch = 22.0;
        let img = synthetic(w, h, pitch, 0.3, (60.0, 30.0));
        // mirror left-right: a board seen from behind
        let mut m = img.clone();
        for y in 0..h {
            for x in 0..w {
                m[y * w + x] = img[y * w + (w - 1 - x)];
            }
        }
        assert!(detect(&img, w, h).is_ok());
        let e = detect(&m, w, h).unwrap_err();
        assert!(matches!(e, Error::Detection(_)), "{e}");
        assert!(e.to_string().contains("mirror"), "{e}");
    }

    #[test]
    fn bad_images_are_typed_errors() {
        let one = [7u8];
        assert!(matches!(detect(&one, 1, 1), Err(Error::InvalidInput(_))));
        for fill in [0u8, 255] {
            let img = vec![fill; 64 * 48];
            assert!(matches!(detect(&img, 64, 48), Err(Error::Detection(_))));
        }
        // noise only
        let mut s = 12345u64;
        let noise: Vec<u8> = (0..320 * 240)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 56) as u8
            })
            .collect();
        let e = detect(&noise, 320, 240).unwrap_err();
        assert!(matches!(e, Error::Detection(_)), "{e}");
        // chessboard kind
        let mut b = Board::hp3_paper();
        b.kind = BoardKind::Chessboard;
        let img = vec![0u8; 64 * 48];
        let v = ImageView::from_slice(&img, 64, 48).unwrap();
        assert!(matches!(
            detect_circles(AnyView::U8(v), &b, &CircleOptions::default()),
            Err(Error::InvalidInput(_))
        ));
    }
}
