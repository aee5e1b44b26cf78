//! Python arguments bound into one record: a function or constructor with many
//! keywords takes `(*args, **kwargs)`, [`bind`] matches them to its parameter names as
//! Python would (positional, then by keyword; unknown, repeated or missing ones are a
//! `TypeError` naming the function) and returns a dict that the function's
//! `#[derive(FromPyObject)] #[pyo3(from_item_all)]` record reads, each default on its
//! field. The callable keeps its Python signature (given as its `text_signature`, which
//! `_core.pyi` and `mypy.stubtest` check); the Rust side takes one record instead of a
//! dozen arguments.

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString, PyTuple};

/// A callable's parameters: `positional` may be passed by position or keyword (the
/// first `required` of them must be passed), `keyword` only by keyword.
pub(crate) struct Params {
    pub name: &'static str,
    pub positional: &'static [&'static str],
    pub required: usize,
    pub keyword: &'static [&'static str],
}

/// `args` and `kwargs` as a dict `{parameter: value}` of the parameters passed (a
/// parameter not passed is absent: its record field's default applies).
pub(crate) fn bind<'py>(
    p: &Params,
    args: &Bound<'py, PyTuple>,
    kwargs: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let py = args.py();
    let name = p.name;
    if args.len() > p.positional.len() {
        return Err(PyTypeError::new_err(format!(
            "{name}() takes at most {} positional arguments ({} given)",
            p.positional.len(),
            args.len()
        )));
    }
    let out = PyDict::new(py);
    for (k, v) in p.positional.iter().zip(args.iter()) {
        out.set_item(*k, v)?;
    }
    if let Some(kw) = kwargs {
        for (k, v) in kw.iter() {
            let key = k.cast::<PyString>()?.to_cow()?;
            if !p.positional.contains(&&*key) && !p.keyword.contains(&&*key) {
                return Err(PyTypeError::new_err(format!(
                    "{name}() got an unexpected keyword argument '{key}'"
                )));
            }
            if out.contains(&*key)? {
                return Err(PyTypeError::new_err(format!(
                    "{name}() got multiple values for argument '{key}'"
                )));
            }
            out.set_item(&*key, v)?;
        }
    }
    for k in &p.positional[..p.required] {
        if !out.contains(*k)? {
            return Err(PyTypeError::new_err(format!(
                "{name}() missing required argument '{k}'"
            )));
        }
    }
    Ok(out)
}

/// [`bind`], then the record `T` read from the bound dict. A field that does not
/// convert is reported as pyo3 reports an argument: a `TypeError` "argument 'name':
/// why", another error (an `OverflowError`) as it is.
pub(crate) fn bind_as<'py, T>(
    p: &Params,
    args: &Bound<'py, PyTuple>,
    kwargs: Option<&Bound<'py, PyDict>>,
) -> PyResult<T>
where
    T: for<'a> FromPyObject<'a, 'py, Error = PyErr>,
{
    let py = args.py();
    bind(p, args, kwargs)?.extract::<T>().map_err(|e| {
        // the derive's "failed to extract field Record.name", the cause being the error
        let msg = e.value(py).to_string();
        let Some(field) = msg
            .strip_prefix("failed to extract field ")
            .and_then(|s| s.rsplit('.').next())
        else {
            return e;
        };
        match e.cause(py) {
            Some(c) if c.get_type(py).is(py.get_type::<PyTypeError>()) => {
                PyTypeError::new_err(format!("{}() argument '{field}': {}", p.name, c.value(py)))
            }
            Some(c) => c,
            None => e,
        }
    })
}
