//! Plain grayscale image buffers (u8 or u16), the only image type the core crate uses.
//!
//! ## Conventions
//!
//! Row-major, `data[row * width + col]`; pixel `(col, row)` has its centre at
//! `(u, v) = (col, row)`.

/// An owned grayscale image.
#[derive(Debug, Clone, PartialEq)]
pub struct GrayImage<T> {
    pub width: usize,
    pub height: usize,
    pub data: Vec<T>,
}

impl<T: Copy + Default> GrayImage<T> {
    /// A black image.
    pub fn new(width: usize, height: usize) -> Self {
        GrayImage {
            width,
            height,
            data: vec![T::default(); width * height],
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
/// `(299 R + 587 G + 114 B + 500) / 1000` (spec/DATASET.md's gray conversion). Exact
/// in `u32` for 16-bit channels, and never above the largest channel value.
#[inline]
pub fn luma_bt601(r: u32, g: u32, b: u32) -> u32 {
    (299 * r + 587 * g + 114 * b + 500) / 1000
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
}
