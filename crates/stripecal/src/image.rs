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
