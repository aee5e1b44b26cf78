//! Module-level file functions: rig, dataset, scan, calibration, truth, sphere fit, PLY,
//! images.

use crate::pool::Detach;
use std::path::PathBuf;

use numpy::{PyArray2, PyArrayDescrMethods, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use stripecal::io::{
    read_calibration, read_ply, read_rig, read_sphere_fit, read_truth, save_gray_png,
    write_calibration, write_ply as core_write_ply, write_rig, write_sphere_fit, write_truth,
    PlyFormat,
};
use stripecal::model::image::{AnyGray, AnyImage, AnyRgb, GrayImage};
use stripecal::model::{Cloud, Dataset, Scan};

use crate::convert::{f64_array, fmt_shape, nd, rows_of};
use crate::errors::{invalid_input, ResultExt};
use crate::results::PyCalibration;
use crate::rig::{PyDataset, PyRig, PyScan};
use crate::robot::PyRobot;
use crate::sphere_fit::PySphereFit;
use crate::truth::PyTruth;

/// Reads rig.json.
#[pyfunction]
pub fn load_rig(py: Python<'_>, path: PathBuf) -> PyResult<PyRig> {
    let inner = py.detach_pool(|| read_rig(&path)).py_err(py)?;
    Ok(PyRig { inner })
}

/// Writes rig.json (atomically).
#[pyfunction]
pub fn save_rig(py: Python<'_>, path: PathBuf, rig: &Bound<'_, PyRig>) -> PyResult<()> {
    let r = &rig.get().inner;
    py.detach_pool(|| write_rig(&path, r)).py_err(py)
}

/// Loads a calibration dataset folder (rig.json + views.csv, checking that every image
/// exists). Never reads truth.json.
#[pyfunction]
pub fn load_dataset(py: Python<'_>, path: PathBuf) -> PyResult<PyDataset> {
    let inner = py.detach_pool(|| Dataset::load(&path)).py_err(py)?;
    Ok(PyDataset { inner })
}

/// Loads a scan folder (scan.csv, optional rig.json, checking that every image exists);
/// `robot` checks the joint count when the scan has no rig.json.
#[pyfunction]
#[pyo3(signature = (path, robot = None))]
pub fn load_scan(
    py: Python<'_>,
    path: PathBuf,
    robot: Option<&Bound<'_, PyRobot>>,
) -> PyResult<PyScan> {
    let robot = robot.map(|r| r.get().inner.clone());
    let inner = py
        .detach_pool(|| Scan::load(&path, robot.as_ref()))
        .py_err(py)?;
    Ok(PyScan { inner })
}

/// Reads calibration.json.
#[pyfunction]
pub fn load_calibration(py: Python<'_>, path: PathBuf) -> PyResult<PyCalibration> {
    let inner = py.detach_pool(|| read_calibration(&path)).py_err(py)?;
    Ok(PyCalibration::from_inner(inner))
}

/// Writes calibration.json (atomically).
#[pyfunction]
pub fn save_calibration(
    py: Python<'_>,
    path: PathBuf,
    calibration: &Bound<'_, PyCalibration>,
) -> PyResult<()> {
    let c = &calibration.get().inner;
    py.detach_pool(|| write_calibration(&path, c)).py_err(py)
}

/// Reads truth.json.
#[pyfunction]
pub fn load_truth(py: Python<'_>, path: PathBuf) -> PyResult<PyTruth> {
    let inner = py.detach_pool(|| read_truth(&path)).py_err(py)?;
    Ok(PyTruth { inner })
}

/// Writes truth.json (atomically).
#[pyfunction]
pub fn save_truth(py: Python<'_>, path: PathBuf, truth: &Bound<'_, PyTruth>) -> PyResult<()> {
    let t = &truth.get().inner;
    py.detach_pool(|| write_truth(&path, t)).py_err(py)
}

/// Reads a sphere fit JSON file.
#[pyfunction]
pub fn load_sphere_fit(py: Python<'_>, path: PathBuf) -> PyResult<PySphereFit> {
    let inner = py.detach_pool(|| read_sphere_fit(&path)).py_err(py)?;
    Ok(PySphereFit { inner })
}

/// Writes a sphere fit JSON file (atomically).
#[pyfunction]
pub fn save_sphere_fit(
    py: Python<'_>,
    path: PathBuf,
    fit: &Bound<'_, PySphereFit>,
) -> PyResult<()> {
    let s = &fit.get().inner;
    py.detach_pool(|| write_sphere_fit(&path, s)).py_err(py)
}

/// Reads a PLY point cloud: `{"points": (N, 3) float64, "properties": {name: (N,) float64}}`.
#[pyfunction(name = "read_ply")]
pub fn read_ply_py<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let cloud = py.detach_pool(|| read_ply(&path)).py_err(py)?;
    let n = cloud.points.len();
    let d = PyDict::new(py);
    d.set_item(
        "points",
        nd(
            py,
            &[n, 3],
            cloud.points.iter().flatten().copied().collect(),
        )?,
    )?;
    let props = PyDict::new(py);
    for (name, values) in cloud.properties {
        let len = values.len();
        props.set_item(name, nd(py, &[len], values)?)?;
    }
    d.set_item("properties", props)?;
    Ok(d)
}

/// Writes a PLY point cloud: points (N, 3) in mm, optional per-point properties
/// `{name: (N,)}` (stored as double), binary little-endian or ASCII.
#[pyfunction(name = "write_ply")]
#[pyo3(signature = (path, points, properties = None, binary = true))]
pub fn write_ply_py(
    py: Python<'_>,
    path: PathBuf,
    points: &Bound<'_, PyAny>,
    properties: Option<&Bound<'_, PyDict>>,
    binary: bool,
) -> PyResult<()> {
    let a = f64_array(points, "points")?;
    let (pts, _) = match a.shape() {
        [_, 3] => rows_of::<3>(points, "points")?,
        s => {
            return Err(invalid_input(
                py,
                format!("points must have shape (N, 3), got {}", fmt_shape(s)),
            ))
        }
    };
    let mut props = Vec::new();
    if let Some(p) = properties {
        for (k, v) in p.iter() {
            let name: String = k
                .extract()
                .map_err(|_| PyTypeError::new_err("property names must be str"))?;
            let label = format!("properties[{name:?}]");
            let values = f64_array(&v, &label)?;
            if values.shape() != [pts.len()] {
                return Err(invalid_input(
                    py,
                    format!(
                        "{label} must have shape ({},) like points, got {}",
                        pts.len(),
                        fmt_shape(values.shape())
                    ),
                ));
            }
            props.push((name, values.iter().copied().collect()));
        }
    }
    let cloud = Cloud {
        points: pts,
        properties: props,
    };
    let format = if binary {
        PlyFormat::BinaryLittleEndian
    } else {
        PlyFormat::Ascii
    };
    py.detach_pool(|| core_write_ply(&path, &cloud, format))
        .py_err(py)
}

/// Reads a PNG, TIFF, BMP or JPEG image as a 2D grayscale array (rows, cols) of uint8
/// or uint16 (colour images are converted to gray by BT.601 luma). `colour=True` keeps
/// a colour image's channels: (rows, cols, 3) RGB (alpha dropped); gray images stay 2D.
/// `size=(width, height)`: the size the image must have (e.g. rig.json's); another size
/// is a `FormatError` naming both, read from the file's header before any pixel is
/// decoded. A damaged file (a truncated JPEG, a PNG whose compressed data fails its
/// checksum) is a `FormatError`; a path that is not a regular file an `OSError`.
#[pyfunction]
#[pyo3(signature = (path, colour = false, size = None))]
pub fn load_image<'py>(
    py: Python<'py>,
    path: PathBuf,
    colour: bool,
    size: Option<(u32, u32)>,
) -> PyResult<Bound<'py, PyAny>> {
    let img = py
        .detach_pool(|| {
            if let Some((w, h)) = size {
                let (fw, fh) = stripecal::io::image_size(&path)?;
                if (fw, fh) != (w, h) {
                    return Err(stripecal::Error::Image {
                        path: path.clone(),
                        message: format!("it is {fw} x {fh} pixels, expected {w} x {h}"),
                    });
                }
            }
            stripecal::io::load_image(&path).map(|i| {
                if colour {
                    i
                } else {
                    AnyImage::Gray(i.into_gray())
                }
            })
        })
        .py_err(py)?;
    match img {
        AnyImage::Gray(AnyGray::U8(i)) => nd(py, &[i.height, i.width], i.data),
        AnyImage::Gray(AnyGray::U16(i)) => nd(py, &[i.height, i.width], i.data),
        AnyImage::Rgb(AnyRgb::U8(i)) => nd(py, &[i.height, i.width, 3], i.data),
        AnyImage::Rgb(AnyRgb::U16(i)) => nd(py, &[i.height, i.width, 3], i.data),
    }
}

fn gray_from<T: numpy::Element + Copy>(a: &Bound<'_, PyUntypedArray>) -> PyResult<GrayImage<T>> {
    let a = a.cast::<PyArray2<T>>()?;
    let ro = a.try_readonly().map_err(|e| {
        pyo3::exceptions::PyValueError::new_err(format!("image: cannot read the array: {e}"))
    })?;
    let v = ro.as_array();
    let (height, width) = v.dim();
    Ok(GrayImage {
        width,
        height,
        data: v.iter().copied().collect(),
    })
}

/// Writes a 2D uint8 or uint16 array (rows, cols) as a grayscale PNG.
#[pyfunction]
pub fn save_image(py: Python<'_>, path: PathBuf, image: &Bound<'_, PyAny>) -> PyResult<()> {
    let a = image.cast::<PyUntypedArray>().map_err(|_| {
        PyTypeError::new_err(format!(
            "image must be a numpy array of dtype uint8 or uint16, got {}",
            crate::convert::type_name(image)
        ))
    })?;
    if a.ndim() != 2 || a.shape().contains(&0) {
        return Err(invalid_input(
            py,
            format!(
                "image must be 2D (rows, cols) and not empty, got shape {}",
                fmt_shape(a.shape())
            ),
        ));
    }
    let dt = a.dtype();
    let img = if dt.is_equiv_to(&numpy::dtype::<u8>(py)) {
        AnyGray::U8(gray_from::<u8>(a)?)
    } else if dt.is_equiv_to(&numpy::dtype::<u16>(py)) {
        AnyGray::U16(gray_from::<u16>(a)?)
    } else {
        return Err(PyTypeError::new_err(format!(
            "image must have dtype uint8 or uint16, got {dt}"
        )));
    };
    py.detach_pool(|| save_gray_png(&path, &img)).py_err(py)
}
