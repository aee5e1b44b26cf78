//! Image files (PNG, TIFF, BMP, JPEG) through the `image` crate, with decoder limits.
//! [`load_gray`] gives gray: colour images become gray by ITU-R BT.601 luma, `0.299 R +
//! 0.587 G + 0.114 B` (spec/DATASET.md; the `image` crate's own conversion uses other
//! weights), rounded to the nearest integer at the image's bit depth. [`load_image`]
//! keeps a colour image's three channels (laser images, whose stripe may be found in one
//! colour: `stripe.channel`).

use std::io::Cursor;
use std::path::Path;

use image::codecs::png::PngEncoder;
use image::{DynamicImage, ExtendedColorType, ImageEncoder, ImageFormat, ImageReader, Limits};

use super::atomic::write_atomic;
use crate::error::{Error, Result};
use crate::model::image::{AnyGray, AnyImage, AnyRgb, GrayImage, RgbImage};

/// The largest image width or height [`load_gray`] accepts (pixels).
pub const MAX_IMAGE_SIDE: u32 = 32768;
/// The most memory (bytes) the decoder may allocate for one image.
pub const MAX_IMAGE_BYTES: u64 = 1 << 30;

fn image_err(path: &Path, message: impl Into<String>) -> Error {
    Error::Image {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// What a loaded image file was.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageInfo {
    /// `png`, `tiff`, `bmp` or `jpeg`.
    pub format: &'static str,
    /// The file held colour (converted to gray by BT.601 luma).
    pub colour: bool,
    /// A lossy format (JPEG): accepted, but compression artefacts cost accuracy.
    pub lossy: bool,
}

/// Loads a PNG, TIFF, BMP or JPEG image as grayscale ([`load_gray_info`] without the
/// file facts).
pub fn load_gray(p: impl AsRef<Path>) -> Result<AnyGray> {
    load_gray_info(p).map(|(g, _)| g)
}

/// Loads a PNG, TIFF, BMP or JPEG image as grayscale, with what the file was.
///
/// 8-bit gray gives [`AnyGray::U8`], 16-bit gray [`AnyGray::U16`]; colour (and
/// gray + alpha) images are converted to BT.601 luma at their bit depth, alpha dropped.
/// Float images and other formats are [`Error::Image`]; a file that cannot be opened
/// is [`Error::Io`]. The decoder is limited to [`MAX_IMAGE_SIDE`] pixels per side and
/// [`MAX_IMAGE_BYTES`] of memory, so a hostile header cannot make it allocate more.
pub fn load_gray_info(p: impl AsRef<Path>) -> Result<(AnyGray, ImageInfo)> {
    load_image_info(p).map(|(img, info)| (img.into_gray(), info))
}

/// Loads a PNG, TIFF, BMP or JPEG image keeping its colour ([`load_image_info`] without
/// the file facts).
pub fn load_image(p: impl AsRef<Path>) -> Result<AnyImage> {
    load_image_info(p).map(|(g, _)| g)
}

/// Loads a PNG, TIFF, BMP or JPEG image, with what the file was: gray (and gray +
/// alpha, alpha dropped) as [`AnyImage::Gray`], colour (RGB, RGBA with alpha dropped)
/// as [`AnyImage::Rgb`], 8- or 16-bit. Errors and decoder limits as [`load_gray_info`].
pub fn load_image_info(p: impl AsRef<Path>) -> Result<(AnyImage, ImageInfo)> {
    let path = p.as_ref();
    let mut reader = ImageReader::open(path)
        .map_err(|e| Error::io(path, e))?
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    let format = match reader.format() {
        Some(ImageFormat::Png) => "png",
        Some(ImageFormat::Tiff) => "tiff",
        Some(ImageFormat::Bmp) => "bmp",
        Some(ImageFormat::Jpeg) => "jpeg",
        Some(other) => {
            return Err(image_err(
                path,
                format!("unsupported image format {other:?}: expected PNG, TIFF, BMP or JPEG"),
            ))
        }
        None => {
            return Err(image_err(
                path,
                "not a PNG, TIFF, BMP or JPEG file (unrecognised content)",
            ))
        }
    };
    let mut limits = Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    limits.max_alloc = Some(MAX_IMAGE_BYTES);
    reader.limits(limits);
    let img = reader
        .decode()
        .map_err(|e| image_err(path, e.to_string()))?;
    let colour = !matches!(
        img,
        DynamicImage::ImageLuma8(_)
            | DynamicImage::ImageLuma16(_)
            | DynamicImage::ImageLumaA8(_)
            | DynamicImage::ImageLumaA16(_)
    );
    let image = to_image(path, img)?;
    Ok((
        image,
        ImageInfo {
            format,
            colour,
            lossy: format == "jpeg",
        },
    ))
}

fn to_image(path: &Path, img: DynamicImage) -> Result<AnyImage> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let u8_image = |data: Vec<u8>| {
        AnyImage::Gray(AnyGray::U8(GrayImage {
            width: w,
            height: h,
            data,
        }))
    };
    let u16_image = |data: Vec<u16>| {
        AnyImage::Gray(AnyGray::U16(GrayImage {
            width: w,
            height: h,
            data,
        }))
    };
    // the decoder's buffers hold w * h pixels of n samples: this cannot fail
    let bad = || image_err(path, "decoded buffer does not match the image size");
    let rgb8 = |px: &[u8], n: usize| -> Result<AnyImage> {
        Ok(AnyImage::Rgb(AnyRgb::U8(
            RgbImage::from_interleaved(px, w, h, n).ok_or_else(bad)?,
        )))
    };
    let rgb16 = |px: &[u16], n: usize| -> Result<AnyImage> {
        Ok(AnyImage::Rgb(AnyRgb::U16(
            RgbImage::from_interleaved(px, w, h, n).ok_or_else(bad)?,
        )))
    };
    Ok(match img {
        DynamicImage::ImageLuma8(b) => u8_image(b.into_raw()),
        DynamicImage::ImageLuma16(b) => u16_image(b.into_raw()),
        DynamicImage::ImageLumaA8(b) => u8_image(b.pixels().map(|p| p.0[0]).collect()),
        DynamicImage::ImageLumaA16(b) => u16_image(b.pixels().map(|p| p.0[0]).collect()),
        DynamicImage::ImageRgb8(b) => rgb8(b.as_raw(), 3)?,
        DynamicImage::ImageRgba8(b) => rgb8(b.as_raw(), 4)?,
        DynamicImage::ImageRgb16(b) => rgb16(b.as_raw(), 3)?,
        DynamicImage::ImageRgba16(b) => rgb16(b.as_raw(), 4)?,
        other => {
            return Err(image_err(
                path,
                format!(
                    "unsupported colour type {:?}: expected 8- or 16-bit gray or colour",
                    other.color()
                ),
            ))
        }
    })
}

/// Writes an 8- or 16-bit grayscale PNG atomically (encoded in memory, then
/// [`super::write_atomic`]). Errors when the buffer does not match the size.
pub fn save_gray_png(p: impl AsRef<Path>, img: &AnyGray) -> Result<()> {
    let path = p.as_ref();
    let (w, h) = img.size();
    let len = match img {
        AnyGray::U8(i) => i.data.len(),
        AnyGray::U16(i) => i.data.len(),
    };
    let (Ok(w32), Ok(h32)) = (u32::try_from(w), u32::try_from(h)) else {
        return Err(Error::InvalidInput(format!(
            "image size {w}x{h} is too large for PNG"
        )));
    };
    if w == 0 || h == 0 || w.checked_mul(h) != Some(len) {
        return Err(Error::InvalidInput(format!(
            "image size {w}x{h} does not match its {len} pixels (or is empty)"
        )));
    }
    let mut buf = Vec::new();
    let encoder = PngEncoder::new(Cursor::new(&mut buf));
    let result = match img {
        AnyGray::U8(i) => encoder.write_image(&i.data, w32, h32, ExtendedColorType::L8),
        AnyGray::U16(i) => {
            // `write_image` takes 16-bit samples in native byte order.
            let bytes: Vec<u8> = i.data.iter().flat_map(|v| v.to_ne_bytes()).collect();
            encoder.write_image(&bytes, w32, h32, ExtendedColorType::L16)
        }
    };
    result
        .map_err(|e| Error::InvalidInput(format!("{}: cannot encode PNG: {e}", path.display())))?;
    write_atomic(path, &buf)
}

/// Writes an 8- or 16-bit RGB PNG atomically. Errors when the buffer does not match the
/// size.
pub fn save_rgb_png(p: impl AsRef<Path>, img: &AnyRgb) -> Result<()> {
    let path = p.as_ref();
    let (w, h) = img.size();
    let len = match img {
        AnyRgb::U8(i) => i.data.len(),
        AnyRgb::U16(i) => i.data.len(),
    };
    let (Ok(w32), Ok(h32)) = (u32::try_from(w), u32::try_from(h)) else {
        return Err(Error::InvalidInput(format!(
            "image size {w}x{h} is too large for PNG"
        )));
    };
    if w == 0 || h == 0 || w.checked_mul(h).and_then(|n| n.checked_mul(3)) != Some(len) {
        return Err(Error::InvalidInput(format!(
            "RGB image size {w}x{h} does not match its {len} samples (or is empty)"
        )));
    }
    let mut buf = Vec::new();
    let encoder = PngEncoder::new(Cursor::new(&mut buf));
    let result = match img {
        AnyRgb::U8(i) => encoder.write_image(&i.data, w32, h32, ExtendedColorType::Rgb8),
        AnyRgb::U16(i) => {
            let bytes: Vec<u8> = i.data.iter().flat_map(|v| v.to_ne_bytes()).collect();
            encoder.write_image(&bytes, w32, h32, ExtendedColorType::Rgb16)
        }
    };
    result
        .map_err(|e| Error::InvalidInput(format!("{}: cannot encode PNG: {e}", path.display())))?;
    write_atomic(path, &buf)
}

/// Writes a gray or RGB PNG ([`save_gray_png`], [`save_rgb_png`]).
pub fn save_png(p: impl AsRef<Path>, img: &AnyImage) -> Result<()> {
    match img {
        AnyImage::Gray(g) => save_gray_png(p, g),
        AnyImage::Rgb(c) => save_rgb_png(p, c),
    }
}
