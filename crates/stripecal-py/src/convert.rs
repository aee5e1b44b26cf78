//! Conversions between Python / numpy values and the core crate's plain values.
//!
//! Array inputs accept any array-like of real numbers (numpy arrays of float or integer
//! dtype, nested lists, tuples); they are copied into Rust-owned memory before the GIL is
//! released, so arbitrary strides and byte orders work. Anything else (complex, bool,
//! strings, objects, None) is a `TypeError`; a wrong shape is an `InvalidInputError`
//! (a `ValueError`).

use nalgebra::{Matrix3, Matrix4};
use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{
    get_array_module, Element, IntoPyArray, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods,
    PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde_json::{Map, Number, Value};
use stripecal::model::geometry::{iso_from_matrix, iso_to_matrix};
use stripecal::Iso3;

use crate::errors::{invalid_input, map_err_at};

/// Tolerance on `R^T R - I` and the last row when a 4x4 matrix is read as a rigid transform.
pub const RIGID_TOL: f64 = 1e-6;

/// `(2, 4)` for a shape, as Python prints it.
pub fn fmt_shape(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|n| n.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Any array-like of real numbers as an owned float64 array.
pub fn f64_array(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<ArrayD<f64>> {
    let py = obj.py();
    let arr: Bound<'_, PyArrayDyn<f64>> = if let Ok(a) = obj.cast::<PyArrayDyn<f64>>() {
        a.clone()
    } else {
        // Not a native float64 array: let numpy build an array without casting, then
        // accept only real numeric kinds (a complex, bool, string or object array -- or
        // None, which numpy turns into an object array -- is a type error).
        let any = if obj.is_instance_of::<PyUntypedArray>() {
            obj.clone()
        } else {
            get_array_module(py)?
                .call_method1("asarray", (obj,))
                .map_err(|e| {
                    PyTypeError::new_err(format!(
                        "{name} must be an array-like of real numbers, got {}: {e}",
                        type_name(obj)
                    ))
                })?
        };
        let u = any.cast::<PyUntypedArray>()?;
        let dt = u.dtype();
        if !matches!(dt.kind(), b'f' | b'i' | b'u') {
            let what = if obj.is_instance_of::<PyUntypedArray>() {
                format!("an array of dtype {dt}")
            } else {
                format!("{} (numpy reads it as dtype {dt})", type_name(obj))
            };
            return Err(PyTypeError::new_err(format!(
                "{name} must be an array of real numbers (float64 preferred), got {what}"
            )));
        }
        u.call_method1("astype", ("float64",))?
            .cast_into::<PyArrayDyn<f64>>()?
    };
    // An array without elements is built here: numpy's view of an empty slice of
    // another array can carry strides ndarray refuses (`as_array` panicked on
    // `np.zeros(9)[:0].reshape(0, 3)`).
    if arr.len() == 0 {
        return Ok(ArrayD::zeros(IxDyn(arr.shape())));
    }
    let ro = arr
        .try_readonly()
        .map_err(|e| PyValueError::new_err(format!("{name}: cannot read the array: {e}")))?;
    Ok(ro.as_array().to_owned())
}

/// A string quoted as Python's repr would (single quotes unless it contains one).
pub fn quote(s: &str) -> String {
    if s.contains('\'') || s.contains('\\') {
        format!("{s:?}")
    } else {
        format!("'{s}'")
    }
}

/// The Python type name of an object.
pub fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

/// The TypeError of a `calibration` argument that is neither a Calibration nor a
/// ProfilerCalibration.
pub fn not_a_calibration(obj: &Bound<'_, PyAny>) -> PyErr {
    PyTypeError::new_err(format!(
        "calibration must be a Calibration or a ProfilerCalibration, got {}",
        type_name(obj)
    ))
}

/// A numpy array of shape `shape` (row-major data).
pub fn nd<'py, T: Element>(
    py: Python<'py>,
    shape: &[usize],
    data: Vec<T>,
) -> PyResult<Bound<'py, PyAny>> {
    let a = ArrayD::from_shape_vec(IxDyn(shape), data)
        .map_err(|e| PyRuntimeError::new_err(format!("internal shape error: {e}")))?;
    Ok(a.into_pyarray(py).into_any())
}

/// Exactly `K` numbers, shape `(K,)`.
pub fn fixed<const K: usize>(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<[f64; K]> {
    let a = f64_array(obj, name)?;
    if a.shape() != [K] {
        return Err(invalid_input(
            obj.py(),
            format!(
                "{name} must have shape ({K},), got {}",
                fmt_shape(a.shape())
            ),
        ));
    }
    let mut out = [0.0; K];
    for (o, v) in out.iter_mut().zip(a.iter()) {
        *o = *v;
    }
    Ok(out)
}

/// Rows of `K` numbers: shape `(K,)` (one row, `single = true`) or `(N, K)`.
pub fn rows_of<const K: usize>(
    obj: &Bound<'_, PyAny>,
    name: &str,
) -> PyResult<(Vec<[f64; K]>, bool)> {
    let a = f64_array(obj, name)?;
    let single = match a.shape() {
        [k] if *k == K => true,
        [_, k] if *k == K => false,
        s => {
            return Err(invalid_input(
                obj.py(),
                format!(
                    "{name} must have shape ({K},) or (N, {K}), got {}",
                    fmt_shape(s)
                ),
            ))
        }
    };
    let n = if single { 1 } else { a.shape()[0] };
    let mut out = vec![[0.0; K]; n];
    for (i, v) in a.iter().enumerate() {
        out[i / K][i % K] = *v;
    }
    Ok((out, single))
}

/// Rows as a `(N, K)` array, or `(K,)` when `single`.
pub fn rows_to_py<'py, const K: usize>(
    py: Python<'py>,
    rows: &[[f64; K]],
    single: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let data: Vec<f64> = rows.iter().flatten().copied().collect();
    if single && rows.len() == 1 {
        nd(py, &[K], data)
    } else {
        nd(py, &[rows.len(), K], data)
    }
}

/// A 4x4 matrix, row-major.
pub fn mat4_data(m: &Matrix4<f64>) -> Vec<f64> {
    (0..16).map(|i| m[(i / 4, i % 4)]).collect()
}

/// A rigid transform as a `(4, 4)` homogeneous numpy array.
pub fn iso_to_py<'py>(py: Python<'py>, t: &Iso3) -> PyResult<Bound<'py, PyAny>> {
    nd(py, &[4, 4], mat4_data(&iso_to_matrix(t)))
}

/// Several rigid transforms as a `(N, 4, 4)` array.
pub fn isos_to_py<'py>(py: Python<'py>, ts: &[Iso3]) -> PyResult<Bound<'py, PyAny>> {
    let data: Vec<f64> = ts
        .iter()
        .flat_map(|t| mat4_data(&iso_to_matrix(t)))
        .collect();
    nd(py, &[ts.len(), 4, 4], data)
}

/// A `(4, 4)` homogeneous rigid transform.
pub fn py_to_iso(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Iso3> {
    let py = obj.py();
    let a = f64_array(obj, name)?;
    if a.shape() != [4, 4] {
        return Err(invalid_input(
            py,
            format!(
                "{name} must have shape (4, 4), got {}",
                fmt_shape(a.shape())
            ),
        ));
    }
    let m = Matrix4::from_fn(|r, c| a[[r, c].as_slice()]);
    iso_from_matrix(&m, RIGID_TOL).map_err(|e| map_err_at(py, e, name))
}

/// A `(3, 3)` matrix.
pub fn py_to_mat3(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Matrix3<f64>> {
    let a = f64_array(obj, name)?;
    if a.shape() != [3, 3] {
        return Err(invalid_input(
            obj.py(),
            format!(
                "{name} must have shape (3, 3), got {}",
                fmt_shape(a.shape())
            ),
        ));
    }
    Ok(Matrix3::from_fn(|r, c| a[[r, c].as_slice()]))
}

/// A `(3, 3)` numpy array.
pub fn mat3_to_py<'py>(py: Python<'py>, m: &Matrix3<f64>) -> PyResult<Bound<'py, PyAny>> {
    nd(py, &[3, 3], (0..9).map(|i| m[(i / 3, i % 3)]).collect())
}

/// A non-negative integer that fits `u32` and is positive (image sizes).
pub fn positive_u32(py: Python<'_>, v: i64, name: &str) -> PyResult<u32> {
    if v <= 0 || v > u32::MAX as i64 {
        return Err(invalid_input(
            py,
            format!("{name} must be a positive integer, got {v}"),
        ));
    }
    Ok(v as u32)
}

/// A non-negative integer as `usize`.
pub fn non_negative(py: Python<'_>, v: i64, name: &str) -> PyResult<usize> {
    usize::try_from(v)
        .map_err(|_| invalid_input(py, format!("{name} must be non-negative, got {v}")))
}

/// A JSON value as plain Python objects (dict, list, str, int, float, bool, None).
pub fn json_to_py<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Number(n) => {
            if let Some(i) = n.as_i64() {
                i.into_pyobject(py)?.into_any()
            } else if let Some(u) = n.as_u64() {
                u.into_pyobject(py)?.into_any()
            } else {
                PyFloat::new(py, n.as_f64().unwrap_or(f64::NAN)).into_any()
            }
        }
        Value::String(s) => PyString::new(py, s).into_any(),
        Value::Array(a) => {
            let items = a
                .iter()
                .map(|x| json_to_py(py, x))
                .collect::<PyResult<Vec<_>>>()?;
            PyList::new(py, items)?.into_any()
        }
        Value::Object(m) => map_to_py(py, m)?.into_any(),
    })
}

/// A JSON object as a Python dict.
pub fn map_to_py<'py>(py: Python<'py>, m: &Map<String, Value>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, x) in m {
        d.set_item(k, json_to_py(py, x)?)?;
    }
    Ok(d)
}

/// A Python value as JSON: dict (str keys), list, tuple, str, int, float (finite), bool,
/// None, and numpy arrays / scalars (through `tolist()`).
pub fn py_to_json(obj: &Bound<'_, PyAny>, path: &str) -> PyResult<Value> {
    let py = obj.py();
    if obj.is_none() {
        return Ok(Value::Null);
    }
    if let Ok(b) = obj.cast::<PyBool>() {
        return Ok(Value::Bool(b.is_true()));
    }
    if obj.is_instance_of::<PyInt>() {
        if let Ok(i) = obj.extract::<i64>() {
            return Ok(Value::from(i));
        }
        if let Ok(u) = obj.extract::<u64>() {
            return Ok(Value::from(u));
        }
        return Err(invalid_input(
            py,
            format!("{path}: integer {obj} does not fit 64 bits"),
        ));
    }
    if obj.is_instance_of::<PyFloat>() {
        let f: f64 = obj.extract()?;
        return Number::from_f64(f)
            .map(Value::Number)
            .ok_or_else(|| invalid_input(py, format!("{path}: {f} cannot be stored in JSON")));
    }
    if let Ok(s) = obj.cast::<PyString>() {
        return Ok(Value::String(s.to_cow()?.into_owned()));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        return Ok(Value::Object(dict_to_map(d, path)?));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        let mut out = Vec::new();
        for (i, x) in obj.try_iter()?.enumerate() {
            out.push(py_to_json(&x?, &format!("{path}[{i}]"))?);
        }
        return Ok(Value::Array(out));
    }
    if obj.hasattr("tolist")? && obj.hasattr("dtype")? {
        return py_to_json(&obj.call_method0("tolist")?, path);
    }
    Err(PyTypeError::new_err(format!(
        "{path}: cannot store a value of type {} in JSON (use dict, list, str, int, float, bool, None or numpy arrays)",
        type_name(obj)
    )))
}

/// A dict with string keys as a JSON object.
pub fn dict_to_map(d: &Bound<'_, PyDict>, path: &str) -> PyResult<Map<String, Value>> {
    let mut m = Map::new();
    for (k, v) in d.iter() {
        let key: String = k.extract().map_err(|_| {
            PyTypeError::new_err(format!("{path}: JSON object keys must be str, got {k}"))
        })?;
        let sub = if path.is_empty() {
            key.clone()
        } else {
            format!("{path}.{key}")
        };
        let value = py_to_json(&v, &sub)?;
        m.insert(key, value);
    }
    Ok(m)
}

/// An optional dict as a JSON object (empty when `None`).
pub fn opt_dict_to_map(d: Option<&Bound<'_, PyDict>>, path: &str) -> PyResult<Map<String, Value>> {
    d.map(|d| dict_to_map(d, path))
        .transpose()
        .map(Option::unwrap_or_default)
}

/// One progress report from inside `py.detach`: checks for signals, then calls
/// `progress` with `args` (when there is one). An exception (or a pending
/// KeyboardInterrupt) is kept in `err` and stops the run.
pub fn progress_step<A>(
    progress: &Option<Py<PyAny>>,
    err: &mut Option<PyErr>,
    args: A,
) -> std::ops::ControlFlow<()>
where
    A: for<'py> pyo3::call::PyCallArgs<'py>,
{
    Python::attach(|py| {
        let r = py.check_signals().and_then(|()| match progress {
            Some(f) => f.call1(py, args).map(drop),
            None => Ok(()),
        });
        match r {
            Ok(()) => std::ops::ControlFlow::Continue(()),
            Err(e) => {
                *err = Some(e);
                std::ops::ControlFlow::Break(())
            }
        }
    })
}
