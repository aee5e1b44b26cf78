//! Reconstruction: stripe pixels -> camera ray -> laser plane -> hand -> robot base.
//!
//! ## The chain (spec/DATASET.md)
//!
//! For a stripe point at pixel `(u, v)` of a frame taken at encoder readings `q`:
//!
//! 1. Distorted normalised coordinates `xd = (u - u0) / fu`, `yd = (v - v0) / fv`;
//!    undistorted `(xn, yn)` by Newton's method, started at the previous point's
//!    solution (neighbouring stripe points converge in 1-2 steps): for radial-only
//!    models (`p1 = p2 = 0`: `radial1`, `radial2`) a 1D iteration on the scale
//!    `r_n / r_d`, otherwise the 2D one of [`Camera::undistort_from`]. Both stop at
//!    ~1e-15 relative (far below 1e-9 px).
//! 2. The viewing ray `r = (xn, yn, 1)` (camera frame, through the optical centre).
//! 3. Its intersection with the laser plane `n . p = d` (camera frame, `d > 0`):
//!    `s = d / (n . r)`, `p_cam = s r` (mm).
//! 4. `p_base = T_base_hand(q) * T_hand_cam * p_cam` (mm).
//!
//! ## Dropped points
//!
//! A ray that meets the laser plane at a grazing angle gives a point whose depth is
//! `1 / sin(angle)` times as sensitive to the pixel error and that lies far away; the
//! camera cannot see the stripe there in a working rig. Rays whose angle to the plane
//! is below [`ReconstructOptions::min_ray_plane_angle_deg`] (default
//! [`DEFAULT_MIN_RAY_PLANE_ANGLE_DEG`] = 2 deg: `|n . r| / |r| < sin(2 deg) = 0.035`)
//! are dropped and counted, never turned into far points. So are rays meeting the plane
//! behind the camera (`n . r <= 0`) and pixels where the undistortion fails (outside the
//! distortion model's valid zone). For the paper's rig the rays of the whole image meet
//! the plane at 34 to 69 deg (k1 neglected).
//!
//! ## Entry points
//!
//! - [`Triangulator`]: points only, from `(u, v)` and `T_base_hand` (benchmarks, tests,
//!   callers with their own stripe extraction).
//! - [`Reconstructor`]: one frame at a time for line software: an image plus joint
//!   readings (or a flange pose) in, points appended to a [`ScanPoints`] out. It owns a
//!   [`StripeExtractor`] and its buffers: after the first frame of a given size it does
//!   not allocate (when the caller clears and reuses its `ScanPoints`).
//! - [`reconstruct_frames`]: many in-memory frames in parallel (rayon), points in frame
//!   order; [`reconstruct_scan`]: a scan folder (scan.csv + images), decoding images in
//!   parallel, with progress reports that can stop the run.
//!
//! ## Bad images in a scan
//!
//! A scan frame whose image is missing, unreadable, truncated or corrupted, of another
//! size than the calibrated camera's or of another bit depth than most of the scan's
//! frames stops [`reconstruct_scan`] with [`crate::Error::BadImage`] naming the frame,
//! its scan.csv line, the file and what is wrong ([`BadImage::Stop`], the default), or
//! is left out and listed in [`ScanPoints::skipped`] ([`BadImage::Skip`]). A frame whose
//! image is fine but shows no stripe is not a bad image: it simply gives no points.
//!
//! A calibrated line profiler's scan (profiles in mm, no images) is mapped to the base
//! frame by [`reconstruct_profile_scan`] (`p_base = T_base_hand(q) * T_hand_sensor *
//! (x, 0, z)`).
//!
//! Fits of the points (sphere, plane) are in [`fit`], with the correction of a sphere
//! scan for the curved-surface stripe bias ([`correct_sphere_bias`]: it takes the
//! points' pixels and widths, `T_base_cam` per frame, the camera and the laser plane).

pub mod fit;
mod frame;
mod options;
mod points;
mod profile;
mod profile_points;
mod scan;
mod triangulate;
pub mod uncertainty;

pub use fit::{
    correct_sphere_bias, fit_plane, fit_sphere, FitOptions, PlaneFit, SheetSigmaEstimate,
    SphereBiasCorrection, SphereFitResult, StripeBiasOptions,
};
pub use frame::Reconstructor;
pub use options::{
    stripe_direction_from_plane, BadImage, ReconstructOptions, DEFAULT_MIN_RAY_PLANE_ANGLE_DEG,
};
pub use points::{at_frame, ScanPoints};
pub use profile::{
    load_profile_frames, read_profile_scan, reconstruct_profile_scan, ProfileReconstructOptions,
    ProfileScanSummary,
};
pub use profile_points::{profile_scan_points, ProfileFrame};
pub use scan::{load_scan, reconstruct_frames, reconstruct_scan};
pub use triangulate::{laser_plane_of, triangulate, DropCounts, Triangulator};
pub use uncertainty::{point_covariances, UncertaintyModel, UncertaintyOptions};
