//! Python exception types and the mapping of [`stripecal::Error`] onto them.
//!
//! | core error                    | Python exception                                   |
//! |-------------------------------|----------------------------------------------------|
//! | `Io` (not found, permission…) | `FileNotFoundError`, `PermissionError`, `OSError`… |
//! | `Format`, `Image`             | `FormatError(StripecalError, ValueError)`          |
//! | `InvalidInput`                | `InvalidInputError(StripecalError, ValueError)`    |
//! | `NotConverged`                | `ConvergenceError(StripecalError, RuntimeError)`   |
//! | `Degenerate`                  | `DegenerateError(StripecalError, ValueError)`      |
//! | `Detection`                   | `DetectionError(StripecalError, ValueError)`       |
//! | `Quality`                     | `CalibrationQualityError(StripecalError, ValueError)` |
//! | `BadImage`                    | `BadImageError(FormatError)`, with `frame`, `line`, `path`, `reason` |
//! | `Cancelled`                   | `KeyboardInterrupt` (callers return the interrupt they saw instead) |

use std::io::ErrorKind;

use pyo3::exceptions::{
    PyException, PyFileExistsError, PyFileNotFoundError, PyIsADirectoryError, PyKeyboardInterrupt,
    PyNotADirectoryError, PyOSError, PyPermissionError, PyRuntimeError, PyValueError,
};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};
use stripecal::Error;

static STRIPECAL_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static FORMAT_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static INVALID_INPUT_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static CONVERGENCE_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static DEGENERATE_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static DETECTION_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static QUALITY_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static BAD_IMAGE_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// Creates `class name(*bases)` with a docstring, shown as `stripecal.<name>`.
fn new_exception<'py>(
    py: Python<'py>,
    name: &str,
    doc: &str,
    bases: Vec<Bound<'py, PyType>>,
) -> PyResult<Py<PyType>> {
    let dict = PyDict::new(py);
    dict.set_item("__doc__", doc)?;
    dict.set_item("__module__", "stripecal")?;
    let bases = PyTuple::new(py, bases)?;
    let ty = py.get_type::<PyType>().call1((name, bases, dict))?;
    Ok(ty.cast_into::<PyType>()?.unbind())
}

/// Creates the exception types (once) and adds them to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    let base = STRIPECAL_ERROR
        .get_or_try_init(py, || {
            new_exception(
                py,
                "StripecalError",
                "Base class of the errors stripecal raises (file-system errors are OSError).",
                vec![py.get_type::<PyException>()],
            )
        })?
        .bind(py)
        .clone();
    let with = |cell: &'static PyOnceLock<Py<PyType>>,
                name: &str,
                doc: &str,
                builtin: Bound<'_, PyType>|
     -> PyResult<()> {
        let ty = cell.get_or_try_init(py, || {
            new_exception(py, name, doc, vec![base.clone(), builtin])
        })?;
        m.add(name, ty.bind(py))
    };
    m.add("StripecalError", &base)?;
    with(
        &FORMAT_ERROR,
        "FormatError",
        "A file that does not follow the stripecal file contract (spec/DATASET.md), or an \
         image that cannot be decoded. The message names the file and the line, column or \
         JSON key.",
        py.get_type::<PyValueError>(),
    )?;
    with(
        &INVALID_INPUT_ERROR,
        "InvalidInputError",
        "An argument outside the domain of a function (wrong size, NaN, unknown name...).",
        py.get_type::<PyValueError>(),
    )?;
    with(
        &CONVERGENCE_ERROR,
        "ConvergenceError",
        "An iterative method that did not reach its tolerance.",
        py.get_type::<PyRuntimeError>(),
    )?;
    with(
        &DEGENERATE_ERROR,
        "DegenerateError",
        "A geometric configuration where the requested quantity does not exist (a point \
         behind the camera, a ray parallel to a plane...).",
        py.get_type::<PyValueError>(),
    )?;
    with(
        &DETECTION_ERROR,
        "DetectionError",
        "An image in which the target (circle grid, stripe) cannot be found or indexed \
         without guessing; the message says what was found.",
        py.get_type::<PyValueError>(),
    )?;
    with(
        &QUALITY_ERROR,
        "CalibrationQualityError",
        "A calibration that failed its quality gates (views that disagree and cannot be \
         left out, undetermined parameters, no convergence): not trustworthy, so not \
         returned. `checks` lists the failed checks (dicts: name, passed, message, views); \
         `calibration` is the calibration for inspection (None when none could be \
         computed). `calibrate(..., accept_poor=True)` returns it instead, marked.",
        py.get_type::<PyValueError>(),
    )?;
    // A FormatError (a bad file) with the frame, its scan.csv line, the image file and
    // what is wrong, as attributes (class defaults: no frame).
    let format = FORMAT_ERROR
        .get(py)
        .map(|t| t.bind(py).clone())
        .unwrap_or_else(|| py.get_type::<PyValueError>());
    let bad = BAD_IMAGE_ERROR.get_or_try_init(py, || {
        let ty = new_exception(
            py,
            "BadImageError",
            "A scan frame whose image cannot be used: missing or unreadable, truncated or \
             corrupted, not the calibrated camera's size, or another bit depth than the \
             scan's other frames. Attributes: `frame` (index, from 0), `line` (its scan.csv \
             line), `path` (the image file) and `reason` (what is wrong).",
            vec![format],
        )?;
        let b = ty.bind(py);
        b.setattr("frame", -1)?;
        b.setattr("line", 0)?;
        b.setattr("path", "")?;
        b.setattr("reason", "")?;
        Ok::<_, PyErr>(ty)
    })?;
    m.add("BadImageError", bad.bind(py))?;
    Ok(())
}

/// A `CalibrationQualityError` with its `checks` and `calibration` attributes.
pub fn quality_error(
    py: Python<'_>,
    failure: &stripecal::model::QualityFailure,
    calibration: Option<Py<PyAny>>,
) -> PyErr {
    let err = PyErr::from_type(
        exc_type(py, &QUALITY_ERROR, py.get_type::<PyValueError>()),
        failure.to_string(),
    );
    let value = err.value(py);
    let set = || -> PyResult<()> {
        value.setattr("checks", crate::results::checks_to_py(py, &failure.failed)?)?;
        value.setattr("calibration", calibration.unwrap_or_else(|| py.None()))?;
        Ok(())
    };
    match set() {
        Ok(()) => err,
        Err(e) => e,
    }
}

fn exc_type<'py>(
    py: Python<'py>,
    cell: &PyOnceLock<Py<PyType>>,
    fallback: Bound<'py, PyType>,
) -> Bound<'py, PyType> {
    cell.get(py).map(|t| t.bind(py).clone()).unwrap_or(fallback)
}

/// `"No such file or directory (os error 2)"` -> `"No such file or directory"`.
fn strerror(e: &std::io::Error) -> String {
    let s = e.to_string();
    match s.rfind(" (os error ") {
        Some(i) if s.ends_with(')') => s[..i].to_string(),
        _ => s,
    }
}

/// Maps a core error to a Python exception; `context` (e.g. `points[3]`) prefixes the
/// message when not empty.
pub fn map_err_at(py: Python<'_>, e: Error, context: &str) -> PyErr {
    let prefix = |msg: String| {
        if context.is_empty() {
            msg
        } else {
            format!("{context}: {msg}")
        }
    };
    match e {
        Error::Io { path, source } => {
            let filename = path.display().to_string();
            let args = |errno: i32| (errno, prefix(strerror(&source)), filename.clone());
            match (source.kind(), source.raw_os_error()) {
                (ErrorKind::NotFound, Some(n)) => PyFileNotFoundError::new_err(args(n)),
                (ErrorKind::PermissionDenied, Some(n)) => PyPermissionError::new_err(args(n)),
                (ErrorKind::AlreadyExists, Some(n)) => PyFileExistsError::new_err(args(n)),
                (ErrorKind::IsADirectory, Some(n)) => PyIsADirectoryError::new_err(args(n)),
                (ErrorKind::NotADirectory, Some(n)) => PyNotADirectoryError::new_err(args(n)),
                (_, Some(n)) => PyOSError::new_err(args(n)),
                // the core's own description (a folder, a FIFO...): no errno
                (ErrorKind::IsADirectory, None) => {
                    PyIsADirectoryError::new_err(prefix(format!("{filename}: {source}")))
                }
                (ErrorKind::NotFound, None) => {
                    PyFileNotFoundError::new_err(prefix(format!("{filename}: {source}")))
                }
                (_, None) => PyOSError::new_err(prefix(format!("{filename}: {source}"))),
            }
        }
        Error::Format { .. } | Error::Image { .. } => PyErr::from_type(
            exc_type(py, &FORMAT_ERROR, py.get_type::<PyValueError>()),
            prefix(e.to_string()),
        ),
        Error::InvalidInput(_) => PyErr::from_type(
            exc_type(py, &INVALID_INPUT_ERROR, py.get_type::<PyValueError>()),
            prefix(e.to_string()),
        ),
        Error::NotConverged { .. } => PyErr::from_type(
            exc_type(py, &CONVERGENCE_ERROR, py.get_type::<PyRuntimeError>()),
            prefix(e.to_string()),
        ),
        Error::Degenerate(_) => PyErr::from_type(
            exc_type(py, &DEGENERATE_ERROR, py.get_type::<PyValueError>()),
            prefix(e.to_string()),
        ),
        Error::Detection(_) => PyErr::from_type(
            exc_type(py, &DETECTION_ERROR, py.get_type::<PyValueError>()),
            prefix(e.to_string()),
        ),
        Error::Quality(f) => quality_error(py, &f, None),
        Error::BadImage(ref b) => {
            let err = PyErr::from_type(
                exc_type(py, &BAD_IMAGE_ERROR, py.get_type::<PyValueError>()),
                prefix(e.to_string()),
            );
            let v = err.value(py);
            let path = b.path.display().to_string();
            // Setting attributes on a fresh exception instance cannot fail.
            let _ = v.setattr("frame", b.frame);
            let _ = v.setattr("line", b.line);
            let _ = v.setattr("path", path);
            let _ = v.setattr("reason", b.reason.as_str());
            err
        }
        Error::Cancelled => PyKeyboardInterrupt::new_err(prefix(e.to_string())),
    }
}

/// Maps a core error to a Python exception.
pub fn map_err(py: Python<'_>, e: Error) -> PyErr {
    map_err_at(py, e, "")
}

/// `InvalidInputError` with a message (for checks done in the bindings).
pub fn invalid_input(py: Python<'_>, msg: impl Into<String>) -> PyErr {
    map_err(py, Error::InvalidInput(msg.into()))
}

/// `.py_err(py)` on core results.
pub trait ResultExt<T> {
    fn py_err(self, py: Python<'_>) -> PyResult<T>;
}

impl<T> ResultExt<T> for stripecal::Result<T> {
    fn py_err(self, py: Python<'_>) -> PyResult<T> {
        self.map_err(|e| map_err(py, e))
    }
}
