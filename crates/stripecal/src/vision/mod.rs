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

pub mod chessboard;
pub mod circles;
pub mod stripe;
pub mod target;

use crate::error::{Error, Result};

/// A pixel type: `u8` or `u16`.
pub trait Pixel: Copy + Ord + Send + Sync + 'static {
    /// Largest value (255 or 65535).
    const MAX: f32;
    /// The value as `f32`.
    fn to_f32(self) -> f32;
    /// The value as `u32`.
    fn to_u32(self) -> u32;
}

impl Pixel for u8 {
    const MAX: f32 = 255.0;
    #[inline]
    fn to_f32(self) -> f32 {
        self as f32
    }
    #[inline]
    fn to_u32(self) -> u32 {
        self as u32
    }
}

impl Pixel for u16 {
    const MAX: f32 = 65535.0;
    #[inline]
    fn to_f32(self) -> f32 {
        self as f32
    }
    #[inline]
    fn to_u32(self) -> u32 {
        self as u32
    }
}

/// A borrowed grayscale image: `height` rows of `width` pixels, row `y` starting at
/// `data[y * stride]`.
#[derive(Debug, Clone, Copy)]
pub struct ImageView<'a, T> {
    data: &'a [T],
    width: usize,
    height: usize,
    stride: usize,
}

impl<'a, T: Pixel> ImageView<'a, T> {
    /// A view; errors when the buffer is too short, the stride is smaller than the
    /// width, or the image is empty.
    pub fn new(data: &'a [T], width: usize, height: usize, stride: usize) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::InvalidInput(format!(
                "image is empty ({width} x {height})"
            )));
        }
        if stride < width {
            return Err(Error::InvalidInput(format!(
                "row stride {stride} is smaller than the width {width}"
            )));
        }
        let need = (height - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(width))
            .ok_or_else(|| Error::InvalidInput("image size overflows".into()))?;
        if data.len() < need {
            return Err(Error::InvalidInput(format!(
                "buffer holds {} pixels, a {width} x {height} image with stride {stride} needs {need}",
                data.len()
            )));
        }
        Ok(ImageView {
            data,
            width,
            height,
            stride,
        })
    }

    /// A view over a contiguous row-major buffer.
    pub fn from_slice(data: &'a [T], width: usize, height: usize) -> Result<Self> {
        Self::new(data, width, height, width)
    }

    /// Columns.
    #[inline]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows.
    #[inline]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Row `y` (`width` pixels). Panics if `y >= height` (internal indexing).
    #[inline]
    pub fn row(&self, y: usize) -> &'a [T] {
        &self.data[y * self.stride..y * self.stride + self.width]
    }

    /// Pixel at column `x`, row `y`. Panics out of range (internal indexing).
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> T {
        self.data[y * self.stride + x]
    }
}

/// An 8- or 16-bit view, for APIs that take either.
#[derive(Debug, Clone, Copy)]
pub enum AnyView<'a> {
    U8(ImageView<'a, u8>),
    U16(ImageView<'a, u16>),
}

impl AnyView<'_> {
    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        match self {
            AnyView::U8(v) => (v.width(), v.height()),
            AnyView::U16(v) => (v.width(), v.height()),
        }
    }
}

impl crate::image::AnyGray {
    /// A view of the whole image.
    pub fn view(&self) -> Result<AnyView<'_>> {
        Ok(match self {
            crate::image::AnyGray::U8(i) => {
                AnyView::U8(ImageView::from_slice(&i.data, i.width, i.height)?)
            }
            crate::image::AnyGray::U16(i) => {
                AnyView::U16(ImageView::from_slice(&i.data, i.width, i.height)?)
            }
        })
    }
}
