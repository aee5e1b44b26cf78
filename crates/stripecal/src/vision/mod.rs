//! Image processing on plain buffers: circle-grid targets and laser stripes.
//!
//! ## Conventions
//!
//! - Images are borrowed views over 8- or 16-bit grayscale buffers with any row stride
//!   ([`ImageView`]); nothing here allocates an image copy unless it must.
//! - Pixel coordinates: `u` along columns, `v` along rows, the centre of the top-left
//!   pixel is `(0, 0)` (spec/DATASET.md). A pixel's value is its mean over
//!   `[u - 0.5, u + 0.5] x [v - 0.5, v + 0.5]`.
//! - Errors are [`crate::Error`]; a detection that cannot be trusted is an error that
//!   says what was found, never a guess.

mod affine;
pub mod chessboard;
pub mod circles;
mod coord;
pub mod stripe;
pub mod target;

/// Whether the CPU runs AVX2 (std detects it once and caches it). The library is built
/// for the x86-64 baseline (SSE2); the hot passes of the stripe extractor and of the
/// chessboard fit are compiled a second time with AVX2 enabled (32 byte lanes) and
/// chosen here at run time.
#[inline]
pub(crate) fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
