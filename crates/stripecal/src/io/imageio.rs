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

use super::atomic::{check_regular, write_atomic};
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
///
/// Damage is an error, never a silently wrong image: a path that is not a regular file
/// (a folder, a FIFO, a device, a symbolic-link loop) is refused before it is opened; a
/// PNG's compressed data is checked against its zlib (Adler-32) checksum as well as its
/// chunks' CRCs, and a PNG must end with its `IEND` chunk; a JPEG must end with its
/// end-of-image marker (a truncated JPEG otherwise decodes with its missing rows made
/// up). Both are [`Error::Image`] saying what is wrong.
pub fn load_image_info(p: impl AsRef<Path>) -> Result<(AnyImage, ImageInfo)> {
    let path = p.as_ref();
    check_regular(path)?;
    let reader = ImageReader::open(path)
        .map_err(|e| Error::io(path, e))?
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    let format = format_name(path, reader.format())?;
    let img = match format {
        "png" => decode_png(path)?,
        "jpeg" => {
            let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
            check_jpeg_complete(&bytes).map_err(|why| image_err(path, why))?;
            let mut r = ImageReader::with_format(Cursor::new(bytes), ImageFormat::Jpeg);
            r.limits(limits());
            r.decode().map_err(|e| image_err(path, e.to_string()))?
        }
        _ => {
            let mut reader = reader;
            reader.limits(limits());
            reader
                .decode()
                .map_err(|e| image_err(path, e.to_string()))?
        }
    };
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

/// An image file's width and height from its header, without decoding its pixels: a
/// caller that knows the size it needs (rig.json's, the calibrated camera's) refuses
/// another size before the decoder allocates anything for it. Errors as
/// [`load_image_info`] for files that are not images.
pub fn image_size(p: impl AsRef<Path>) -> Result<(u32, u32)> {
    let path = p.as_ref();
    check_regular(path)?;
    let mut reader = ImageReader::open(path)
        .map_err(|e| Error::io(path, e))?
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    let format = format_name(path, reader.format())?;
    let mut l = limits();
    // the header only: a size beyond the decoder's limits is still reported as a size
    l.max_image_width = None;
    l.max_image_height = None;
    reader.limits(l);
    reader.into_dimensions().map_err(|e| {
        // a JPEG cut inside its headers: say so rather than the decoder's byte counts
        let cut = (format == "jpeg")
            .then(|| std::fs::read(path).ok())
            .flatten()
            .and_then(|b| check_jpeg_complete(&b).err());
        image_err(path, cut.unwrap_or_else(|| e.to_string()))
    })
}

/// The decoder limits ([`MAX_IMAGE_SIDE`], [`MAX_IMAGE_BYTES`]).
fn limits() -> Limits {
    let mut limits = Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    limits.max_alloc = Some(MAX_IMAGE_BYTES);
    limits
}

/// `png`, `tiff`, `bmp` or `jpeg`; other formats and unrecognised content are errors.
fn format_name(path: &Path, format: Option<ImageFormat>) -> Result<&'static str> {
    match format {
        Some(ImageFormat::Png) => Ok("png"),
        Some(ImageFormat::Tiff) => Ok("tiff"),
        Some(ImageFormat::Bmp) => Ok("bmp"),
        Some(ImageFormat::Jpeg) => Ok("jpeg"),
        Some(other) => Err(image_err(
            path,
            format!("unsupported image format {other:?}: expected PNG, TIFF, BMP or JPEG"),
        )),
        None => Err(image_err(
            path,
            "not a PNG, TIFF, BMP or JPEG file (unrecognised content)",
        )),
    }
}

/// Decodes a PNG with every checksum verified (the `png` crate's default skips the zlib
/// stream's Adler-32, so damaged compressed data under intact chunk CRCs decoded to a
/// wrong image) and the file read to its `IEND` chunk.
fn decode_png(path: &Path) -> Result<DynamicImage> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut options = png::DecodeOptions::default();
    options.set_ignore_adler32(false);
    options.set_ignore_crc(false);
    let mut decoder = png::Decoder::new_with_options(std::io::BufReader::new(file), options);
    decoder.set_limits(png::Limits {
        bytes: usize::try_from(MAX_IMAGE_BYTES).unwrap_or(usize::MAX),
    });
    let png_err = |e: png::DecodingError| image_err(path, png_message(e));
    let (w, h) = {
        let info = decoder.read_header_info().map_err(png_err)?;
        (info.width, info.height)
    };
    if w > MAX_IMAGE_SIDE || h > MAX_IMAGE_SIDE {
        return Err(image_err(
            path,
            format!("{w} x {h} pixels exceeds the decoder's limit of {MAX_IMAGE_SIDE} per side"),
        ));
    }
    // as the image crate: palettes and gray below 8 bits expanded, tRNS to alpha
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(png_err)?;
    let size = reader
        .output_buffer_size()
        .filter(|&n| n as u64 <= MAX_IMAGE_BYTES)
        .ok_or_else(|| {
            image_err(
                path,
                format!("{w} x {h} pixels exceeds the decoder's memory limit"),
            )
        })?;
    let mut buf = vec![0u8; size];
    reader.next_frame(&mut buf).map_err(png_err)?;
    // the rest of the file: the end of the zlib stream (its checksum) and IEND
    reader.finish().map_err(png_err)?;
    let (colour, depth) = reader.output_color_type();
    let bad = || image_err(path, "decoded buffer does not match the image size");
    let sixteen = |b: Vec<u8>| -> Vec<u16> {
        b.chunks_exact(2)
            .map(|c| u16::from_be_bytes([c[0], c[1]]))
            .collect()
    };
    use png::{BitDepth as B, ColorType as C};
    Ok(match (colour, depth) {
        (C::Grayscale, B::Eight) => {
            DynamicImage::ImageLuma8(image::ImageBuffer::from_raw(w, h, buf).ok_or_else(bad)?)
        }
        (C::Grayscale, B::Sixteen) => DynamicImage::ImageLuma16(
            image::ImageBuffer::from_raw(w, h, sixteen(buf)).ok_or_else(bad)?,
        ),
        (C::GrayscaleAlpha, B::Eight) => {
            DynamicImage::ImageLumaA8(image::ImageBuffer::from_raw(w, h, buf).ok_or_else(bad)?)
        }
        (C::GrayscaleAlpha, B::Sixteen) => DynamicImage::ImageLumaA16(
            image::ImageBuffer::from_raw(w, h, sixteen(buf)).ok_or_else(bad)?,
        ),
        (C::Rgb, B::Eight) => {
            DynamicImage::ImageRgb8(image::ImageBuffer::from_raw(w, h, buf).ok_or_else(bad)?)
        }
        (C::Rgb, B::Sixteen) => DynamicImage::ImageRgb16(
            image::ImageBuffer::from_raw(w, h, sixteen(buf)).ok_or_else(bad)?,
        ),
        (C::Rgba, B::Eight) => {
            DynamicImage::ImageRgba8(image::ImageBuffer::from_raw(w, h, buf).ok_or_else(bad)?)
        }
        (C::Rgba, B::Sixteen) => DynamicImage::ImageRgba16(
            image::ImageBuffer::from_raw(w, h, sixteen(buf)).ok_or_else(bad)?,
        ),
        (c, d) => {
            return Err(image_err(
                path,
                format!("unsupported PNG colour type {c:?} at {d:?} bits"),
            ))
        }
    })
}

/// What a PNG decoding error means for the user.
fn png_message(e: png::DecodingError) -> String {
    match e {
        png::DecodingError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "truncated PNG: the file ends before its image data (or its IEND chunk) is \
             complete"
                .into()
        }
        png::DecodingError::IoError(io) => format!("read error: {io}"),
        png::DecodingError::Format(f) => {
            let f = f.to_string();
            if f.contains("WrongChecksum") {
                "damaged PNG: its compressed image data does not match its zlib (Adler-32) \
                 checksum, though its chunks' CRCs do: the pixels would be wrong"
                    .into()
            } else {
                format!("damaged PNG: {f}")
            }
        }
        png::DecodingError::LimitsExceeded => "exceeds the decoder's memory limit".into(),
        other => other.to_string(),
    }
}

/// Checks that a JPEG file is complete: its marker segments walked from the start of
/// image to the end-of-image marker (`FF D9`), through every scan's entropy-coded data.
/// A truncated file ends before that marker; the decoder would make up the missing rows.
fn check_jpeg_complete(b: &[u8]) -> std::result::Result<(), String> {
    const TRUNCATED: &str = "truncated JPEG: the file ends";
    if b.len() < 4 || b[0] != 0xFF || b[1] != 0xD8 {
        return Err("not a JPEG file (no start-of-image marker)".into());
    }
    let mut i = 2;
    loop {
        // a marker: FF (fill bytes FF allowed), then its code
        if i >= b.len() {
            return Err(format!("{TRUNCATED} before its end-of-image marker"));
        }
        if b[i] != 0xFF {
            return Err(format!(
                "damaged JPEG: byte {i} (0x{:02X}) where a marker should start",
                b[i]
            ));
        }
        while i < b.len() && b[i] == 0xFF {
            i += 1;
        }
        let Some(&code) = b.get(i) else {
            return Err(format!("{TRUNCATED} before its end-of-image marker"));
        };
        i += 1;
        match code {
            0xD9 => return Ok(()),
            // markers without a segment
            0x01 | 0xD0..=0xD7 => continue,
            0x00 => return Err(format!("damaged JPEG: a stray 0xFF00 at byte {}", i - 2)),
            _ => {}
        }
        let Some(len) = b
            .get(i..i + 2)
            .map(|l| usize::from(u16::from_be_bytes([l[0], l[1]])))
        else {
            return Err(format!("{TRUNCATED} inside a segment header"));
        };
        if len < 2 {
            return Err(format!(
                "damaged JPEG: a segment of length {len} at byte {i}"
            ));
        }
        if i + len > b.len() {
            return Err(format!(
                "{TRUNCATED} inside a segment (marker 0xFF{code:02X})"
            ));
        }
        i += len;
        if code == 0xDA {
            // entropy-coded data: FF is stuffed as FF 00; restart markers FF D0..D7
            loop {
                match b.get(i..i + 2) {
                    None => {
                        return Err(format!(
                            "{TRUNCATED} inside its image data, before the end-of-image marker \
                             (rows at the bottom would be made up)"
                        ))
                    }
                    Some([0xFF, 0x00]) | Some([0xFF, 0xD0..=0xD7]) => i += 2,
                    Some([0xFF, 0xFF]) => i += 1,
                    Some([0xFF, _]) => break,
                    Some(_) => i += 1,
                }
            }
        }
    }
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
