//! Plain image buffers (u8 or u16): grayscale, the type every vision stage works on,
//! and interleaved RGB, which laser images keep until their stripe signal is formed
//! ([`crate::vision::stripe::colour`]).
//!
//! ## Conventions
//!
//! Row-major, `data[row * width + col]` (RGB: `data[3 * (row * width + col) + c]`, `c`
//! 0 red, 1 green, 2 blue); pixel `(col, row)` has its centre at `(u, v) = (col, row)`.

/// An owned grayscale image.
use crate::error::{Error, Result};

#[derive(Debug, Clone, PartialEq)]
pub struct GrayImage<T> {
    pub width: usize,
    pub height: usize,
    pub data: Vec<T>,
}

impl<T: Copy + Default> GrayImage<T> {
    /// A black image.
    ///
    /// # Panics
    ///
    /// When `width * height` overflows a `usize` (in every build profile: never an
    /// image whose buffer is smaller than its size says).
    pub fn new(width: usize, height: usize) -> Self {
        let n = width
            .checked_mul(height)
            .unwrap_or_else(|| panic!("image size {width} x {height} overflows usize"));
        GrayImage {
            width,
            height,
            data: vec![T::default(); n],
        }
    }

    /// The pixel at column `x`, row `y` (panics out of range: internal use).
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> T {
        self.data[y * self.width + x]
    }
}

/// An 8- or 16-bit grayscale image as decoded from a file.
#[derive(Debug, Clone, PartialEq)]
pub enum AnyGray {
    U8(GrayImage<u8>),
    U16(GrayImage<u16>),
}

impl AnyGray {
    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        match self {
            AnyGray::U8(i) => (i.width, i.height),
            AnyGray::U16(i) => (i.width, i.height),
        }
    }
}

/// ITU-R BT.601 luma of an RGB sample, rounded to the nearest integer:
/// `(299 R + 587 G + 114 B + 500) / 1000` (spec/DATASET.md's gray conversion), exact
/// (computed in `u64`) and never above the largest channel value.
#[inline]
pub fn luma_bt601(r: u32, g: u32, b: u32) -> u32 {
    let y = (299 * r as u64 + 587 * g as u64 + 114 * b as u64 + 500) / 1000;
    // y <= max(r, g, b) <= u32::MAX
    y as u32
}

/// BT.601 gray of interleaved colour samples with `channels` per pixel (3: RGB, 4:
/// RGBA, alpha ignored); `None` for another channel count.
pub fn gray_from_interleaved<T: Copy + Into<u32> + TryFrom<u32>>(
    samples: &[T],
    channels: usize,
) -> Option<Vec<T>> {
    if !(channels == 3 || channels == 4) {
        return None;
    }
    samples
        .chunks_exact(channels)
        .map(|c| T::try_from(luma_bt601(c[0].into(), c[1].into(), c[2].into())).ok())
        .collect()
}

/// An owned colour image: interleaved RGB samples, 3 per pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage<T> {
    pub width: usize,
    pub height: usize,
    /// `3 * width * height` samples: R, G, B of pixel 0, then of pixel 1...
    pub data: Vec<T>,
}

impl<T: Copy + Default + Into<u32> + TryFrom<u32>> RgbImage<T> {
    /// An image from interleaved samples with `channels` per pixel (3: RGB, 4: RGBA,
    /// alpha dropped); `None` for another channel count or a buffer of the wrong length.
    pub fn from_interleaved(
        samples: &[T],
        width: usize,
        height: usize,
        channels: usize,
    ) -> Option<Self> {
        if !(channels == 3 || channels == 4)
            || width.checked_mul(height)?.checked_mul(channels)? != samples.len()
        {
            return None;
        }
        let data = if channels == 3 {
            samples.to_vec()
        } else {
            samples
                .chunks_exact(4)
                .flat_map(|c| [c[0], c[1], c[2]])
                .collect()
        };
        Some(RgbImage {
            width,
            height,
            data,
        })
    }

    /// BT.601 luma ([`luma_bt601`]), the contract's gray conversion.
    pub fn to_gray(&self) -> GrayImage<T> {
        GrayImage {
            width: self.width,
            height: self.height,
            // the luma of channels <= MAX is <= MAX: the conversion cannot fail
            data: gray_from_interleaved(&self.data, 3).unwrap_or_default(),
        }
    }

    /// Channel `c` (0 red, 1 green, 2 blue) as a gray image.
    pub fn channel(&self, c: usize) -> GrayImage<T> {
        GrayImage {
            width: self.width,
            height: self.height,
            data: self
                .data
                .iter()
                .skip(c.min(2))
                .step_by(3)
                .copied()
                .collect(),
        }
    }
}

/// An 8- or 16-bit RGB image.
#[derive(Debug, Clone, PartialEq)]
pub enum AnyRgb {
    U8(RgbImage<u8>),
    U16(RgbImage<u16>),
}

impl AnyRgb {
    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        match self {
            AnyRgb::U8(i) => (i.width, i.height),
            AnyRgb::U16(i) => (i.width, i.height),
        }
    }

    /// BT.601 gray.
    pub fn to_gray(&self) -> AnyGray {
        match self {
            AnyRgb::U8(i) => AnyGray::U8(i.to_gray()),
            AnyRgb::U16(i) => AnyGray::U16(i.to_gray()),
        }
    }

    /// Channel `c` (0 red, 1 green, 2 blue) as a gray image.
    pub fn channel(&self, c: usize) -> AnyGray {
        match self {
            AnyRgb::U8(i) => AnyGray::U8(i.channel(c)),
            AnyRgb::U16(i) => AnyGray::U16(i.channel(c)),
        }
    }
}

/// A decoded image: gray, or colour kept as RGB (laser images, whose stripe may be in
/// one colour: [`crate::model::StripeChannel`]).
#[derive(Debug, Clone, PartialEq)]
pub enum AnyImage {
    Gray(AnyGray),
    Rgb(AnyRgb),
}

impl AnyImage {
    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        match self {
            AnyImage::Gray(g) => g.size(),
            AnyImage::Rgb(c) => c.size(),
        }
    }

    /// Whether the image has colour channels.
    pub fn is_colour(&self) -> bool {
        matches!(self, AnyImage::Rgb(_))
    }

    /// 8 or 16.
    pub fn bit_depth(&self) -> u8 {
        match self {
            AnyImage::Gray(AnyGray::U8(_)) | AnyImage::Rgb(AnyRgb::U8(_)) => 8,
            AnyImage::Gray(AnyGray::U16(_)) | AnyImage::Rgb(AnyRgb::U16(_)) => 16,
        }
    }

    /// The image as gray: itself, or BT.601 luma of a colour image.
    pub fn into_gray(self) -> AnyGray {
        match self {
            AnyImage::Gray(g) => g,
            AnyImage::Rgb(c) => c.to_gray(),
        }
    }
}

// ---- borrowed views (used by vision/) ----

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

impl AnyGray {
    /// A view of the whole image.
    pub fn view(&self) -> Result<AnyView<'_>> {
        Ok(match self {
            AnyGray::U8(i) => AnyView::U8(ImageView::from_slice(&i.data, i.width, i.height)?),
            AnyGray::U16(i) => AnyView::U16(ImageView::from_slice(&i.data, i.width, i.height)?),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bt601_luma() {
        assert_eq!(luma_bt601(255, 255, 255), 255);
        assert_eq!(luma_bt601(65535, 65535, 65535), 65535);
        assert_eq!(luma_bt601(200, 100, 50), 124); // 124.2
        let g = gray_from_interleaved(&[255u8, 0, 0, 9, 0, 255, 0, 9], 4).unwrap();
        assert_eq!(g, vec![76, 150]);
        assert!(gray_from_interleaved(&[1u16, 2], 2).is_none());
    }

    #[test]
    fn rgb_images() {
        let px = [255u8, 0, 0, 9, 0, 255, 0, 9];
        let c = RgbImage::from_interleaved(&px, 2, 1, 4).unwrap();
        assert_eq!(c.data, vec![255, 0, 0, 0, 255, 0]);
        assert_eq!(c.to_gray().data, vec![76, 150]);
        assert_eq!(c.channel(0).data, vec![255, 0]);
        assert_eq!(c.channel(1).data, vec![0, 255]);
        assert_eq!(c.channel(2).data, vec![0, 0]);
        assert!(RgbImage::from_interleaved(&px, 3, 1, 4).is_none());
        assert!(RgbImage::from_interleaved(&px, 2, 1, 2).is_none());
        let any = AnyImage::Rgb(AnyRgb::U8(c));
        assert_eq!(
            (any.size(), any.bit_depth(), any.is_colour()),
            ((2, 1), 8, true)
        );
    }
}
