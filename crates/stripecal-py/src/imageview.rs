//! Images from numpy: 2D `uint8` / `uint16` arrays (any strides) copied into an owned
//! gray image, and `(rows, columns, 3 or 4)` colour arrays into an owned RGB image, so
//! the GIL can be released while Rust works on them.

use numpy::{
    PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;

use stripecal::model::image::{AnyGray, AnyImage, AnyRgb, GrayImage, RgbImage};

use crate::convert::type_name;
use crate::errors::invalid_input;

fn copy<T: numpy::Element + Copy>(a: &Bound<'_, PyUntypedArray>) -> PyResult<GrayImage<T>> {
    let arr = a.cast::<PyArrayDyn<T>>()?;
    let ro = arr.try_readonly()?;
    let view = ro
        .as_array()
        .into_dimensionality::<numpy::ndarray::Ix2>()
        .map_err(|e| PyTypeError::new_err(format!("expected a 2D array: {e}")))?;
    let (h, w) = view.dim();
    // A C-contiguous array is one memcpy; other layouts are walked row by row (the
    // 2D iterator, much faster than a dynamic-dimension one).
    let data = match view.as_slice() {
        Some(s) => s.to_vec(),
        None => {
            let mut v = Vec::with_capacity(h * w);
            for row in view.rows() {
                v.extend(row.iter().copied());
            }
            v
        }
    };
    Ok(GrayImage {
        width: w,
        height: h,
        data,
    })
}

/// `image` (a 2D uint8/uint16 numpy array) as an owned gray image. Other dtypes are a
/// `TypeError`; other shapes or an empty image an `InvalidInputError` naming `name`.
pub fn gray_from_py(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<AnyGray> {
    let py = obj.py();
    let Ok(a) = obj.cast::<PyUntypedArray>() else {
        return Err(PyTypeError::new_err(format!(
            "{name} must be a 2D numpy array of uint8 or uint16, got {}",
            type_name(obj)
        )));
    };
    if a.ndim() != 2 {
        return Err(invalid_input(
            py,
            format!(
                "{name} must be a 2D array (rows, columns), got shape {:?}",
                a.shape()
            ),
        ));
    }
    if a.shape().contains(&0) {
        return Err(invalid_input(
            py,
            format!("{name} is empty (shape {:?})", a.shape()),
        ));
    }
    let dt = a.dtype();
    if dt.is_equiv_to(&numpy::dtype::<u8>(py)) {
        Ok(AnyGray::U8(copy::<u8>(a)?))
    } else if dt.is_equiv_to(&numpy::dtype::<u16>(py)) {
        Ok(AnyGray::U16(copy::<u16>(a)?))
    } else {
        Err(PyTypeError::new_err(format!(
            "{name} must have dtype uint8 or uint16, got {dt}: convert it explicitly (e.g. \
             image.astype(np.uint16)) so no scaling is guessed"
        )))
    }
}

fn copy_any<T: numpy::Element + Copy>(a: &Bound<'_, PyUntypedArray>) -> PyResult<Vec<T>> {
    let arr = a.cast::<PyArrayDyn<T>>()?;
    let ro = arr.try_readonly()?;
    let view = ro.as_array();
    Ok(match view.as_slice() {
        Some(s) => s.to_vec(),
        None => view.iter().copied().collect(),
    })
}

/// Like [`gray_from_py`], and also a colour image: a 3D `(rows, columns, 3 or 4)`
/// uint8/uint16 array (RGB or RGBA, alpha ignored) becomes gray by BT.601 luma, the
/// contract's conversion.
pub fn gray_or_colour_from_py(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<AnyGray> {
    Ok(image_from_py(obj, name)?.into_gray())
}

/// A gray `(rows, columns)` or colour `(rows, columns, 3 or 4)` uint8/uint16 array
/// (RGB or RGBA, alpha dropped) as an owned image that keeps its colour.
pub fn image_from_py(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<AnyImage> {
    let py = obj.py();
    let Ok(a) = obj.cast::<PyUntypedArray>() else {
        return gray_from_py(obj, name).map(AnyImage::Gray);
    };
    if a.ndim() != 3 {
        return gray_from_py(obj, name).map(AnyImage::Gray);
    }
    let shape = a.shape().to_vec();
    if shape.contains(&0) || !(shape[2] == 3 || shape[2] == 4) {
        return Err(invalid_input(
            py,
            format!(
                "{name} must be (rows, columns) gray or (rows, columns, 3 or 4) RGB(A), got \
                 shape {shape:?}"
            ),
        ));
    }
    let (h, w, c) = (shape[0], shape[1], shape[2]);
    let dt = a.dtype();
    let lost = || invalid_input(py, format!("{name}: colour conversion failed"));
    if dt.is_equiv_to(&numpy::dtype::<u8>(py)) {
        let c = RgbImage::from_interleaved(&copy_any::<u8>(a)?, w, h, c).ok_or_else(lost)?;
        Ok(AnyImage::Rgb(AnyRgb::U8(c)))
    } else if dt.is_equiv_to(&numpy::dtype::<u16>(py)) {
        let c = RgbImage::from_interleaved(&copy_any::<u16>(a)?, w, h, c).ok_or_else(lost)?;
        Ok(AnyImage::Rgb(AnyRgb::U16(c)))
    } else {
        Err(PyTypeError::new_err(format!(
            "{name} must have dtype uint8 or uint16, got {dt}: convert it explicitly (e.g. \
             image.astype(np.uint16)) so no scaling is guessed"
        )))
    }
}
