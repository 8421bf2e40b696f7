//! The keyword arguments the bindings share, checked and turned into the
//! library's types, with errors in Python's terms (`ValueError`,
//! `TypeError`).

use std::path::PathBuf;

use pyo3::exceptions::{PyOverflowError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyDict, PyFrozenSet, PyInt, PySet, PyString};

use mckibben::model::effects::Effect;
use mckibben::model::{UserBound, UserBoundError};

use crate::convert::{family, given, in_python_terms, must_pass};

/// Whether `obj` is a boolean, Python's or NumPy's: both convert to
/// numbers, and `True` taken as 1 is a mistake more often than not.
fn is_bool(obj: &Bound<'_, PyAny>) -> PyResult<bool> {
    if obj.is_instance_of::<PyBool>() {
        return Ok(true);
    }
    let numpy_bool = obj.py().import("numpy")?.getattr("bool_")?;
    obj.is_instance(&numpy_bool)
}

/// A real-number argument: an int or a float (or a NumPy number), not a
/// bool or text.
pub fn real(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<f64> {
    let wrong = || {
        PyTypeError::new_err(format!(
            "{what} must be a number (an int or a float), got {}",
            given(obj)
        ))
    };
    if is_bool(obj)? || obj.is_instance_of::<PyString>() || obj.is_instance_of::<PyBytes>() {
        return Err(wrong());
    }
    obj.extract::<f64>().map_err(|e| {
        if e.is_instance_of::<PyOverflowError>(obj.py()) {
            PyValueError::new_err(format!(
                "{what} must be a finite number, got an integer too large for a float"
            ))
        } else if must_pass(&e, obj.py()) {
            e
        } else {
            wrong()
        }
    })
}

/// An integer's value where an `i128` holds it, else its sign and how a
/// message shows it.
enum Int {
    Value(i128),
    Huge { negative: bool, text: String },
}

/// An integer argument: a Python int or a NumPy integer (anything with
/// `__index__`), not a bool or a float.
fn integer(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Int> {
    let py = obj.py();
    let wrong = || PyTypeError::new_err(format!("{what} must be an integer, got {}", given(obj)));
    if is_bool(obj)? {
        return Err(wrong());
    }
    let index = py
        .import("operator")?
        .call_method1("index", (obj,))
        .map_err(|e| {
            if e.is_instance_of::<PyTypeError>(py) {
                wrong()
            } else {
                e
            }
        })?;
    if let Ok(v) = index.extract::<i128>() {
        return Ok(Int::Value(v));
    }
    // Printed in full up to about 90 digits (Python refuses to print an
    // int of more than 4300 digits at all).
    let bits: u64 = index.call_method0("bit_length")?.extract()?;
    let text = if bits <= 300 {
        index.str()?.to_string()
    } else {
        format!("an integer of {bits} bits")
    };
    Ok(Int::Huge {
        negative: index.lt(0)?,
        text,
    })
}

/// An integer argument of at least `min` and less than 2**63 (a count:
/// `pop`, `gens`, `seeds`, ...): a `ValueError` naming it otherwise.
pub fn at_least(obj: &Bound<'_, PyAny>, what: &str, min: usize) -> PyResult<usize> {
    let below = |v: &str| PyValueError::new_err(format!("{what} must be at least {min}, got {v}"));
    let above = |v: &str| PyValueError::new_err(format!("{what} must be less than 2**63, got {v}"));
    match integer(obj, what)? {
        Int::Value(v) if v < min as i128 => Err(below(&v.to_string())),
        Int::Value(v) if v > i64::MAX as i128 => Err(above(&v.to_string())),
        Int::Value(v) => usize::try_from(v).map_err(|_| above(&v.to_string())),
        Int::Huge {
            negative: true,
            text,
        } => Err(below(&text)),
        Int::Huge { text, .. } => Err(above(&text)),
    }
}

/// A seed: an integer in [0, 2**53), as the command's `--seed`.
pub fn seed(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<u64> {
    let outside = |v: &str| {
        PyValueError::new_err(format!("{what} must be an integer in [0, 2**53), got {v}"))
    };
    match integer(obj, what)? {
        Int::Value(v) => u64::try_from(v)
            .ok()
            .and_then(|v| mckibben::optim::streams::checked_seed(v).ok())
            .ok_or_else(|| outside(&v.to_string())),
        Int::Huge { text, .. } => Err(outside(&text)),
    }
}

/// A flag: `True` or `False` (Python's or NumPy's), not a number.
pub fn flag(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<bool> {
    if !is_bool(obj)? {
        return Err(PyTypeError::new_err(format!(
            "{what} must be True or False, got {}",
            given(obj)
        )));
    }
    obj.is_truthy()
}

/// A text argument (a name, a column): a `str`.
pub fn text<'a>(obj: &'a Bound<'_, PyAny>, what: &str) -> PyResult<&'a str> {
    let s = obj
        .cast::<PyString>()
        .map_err(|_| PyTypeError::new_err(format!("{what} must be a str, got {}", given(obj))))?;
    s.to_str()
        .map_err(|e| PyValueError::new_err(format!("{what}: {e}")))
}

/// A list of names (`effects`): any iterable of `str`, but not one `str`
/// (whose letters would each be a name).
pub fn names(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<String>> {
    let wrong = || {
        PyTypeError::new_err(format!(
            "{what} must be a list of names (str), got {}",
            given(obj)
        ))
    };
    if obj.is_instance_of::<PyString>() {
        return Err(PyTypeError::new_err(format!(
            "{what} must be a list of names (str), got str {}: a list of one is [{0}]",
            obj.repr()?
        )));
    }
    // The order is the chain's: a set's changes from one interpreter to the
    // next (PYTHONHASHSEED), and with it the fit. A dict's keys are no list.
    if obj.is_instance_of::<PySet>() || obj.is_instance_of::<PyFrozenSet>() {
        return Err(PyTypeError::new_err(format!(
            "{what} must be a list of names (str), got {}: its order is the chain's, and a \
             set's changes from one interpreter to the next",
            given(obj)
        )));
    }
    if obj.is_instance_of::<PyDict>() {
        return Err(wrong());
    }
    obj.try_iter()
        .map_err(|_| wrong())?
        .enumerate()
        .map(|(i, item)| Ok(text(&item?, &format!("{what}[{i}]"))?.to_string()))
        .collect()
}

/// A path, as Python's `open` takes one: a `str`, `bytes` (decoded with the
/// file system's encoding, `os.fsdecode`) or an `os.PathLike`.
pub fn path(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<PathBuf> {
    let py = obj.py();
    let os = py.import("os")?;
    let fspath = os.call_method1("fspath", (obj,)).map_err(|e| {
        if e.is_instance_of::<PyTypeError>(py) {
            PyTypeError::new_err(format!(
                "{what} must be a file's path (a str, bytes or os.PathLike), got {}",
                given(obj)
            ))
        } else {
            e
        }
    })?;
    let fspath = if fspath.is_instance_of::<PyBytes>() {
        os.call_method1("fsdecode", (fspath,))?
    } else {
        fspath
    };
    fspath.extract()
}

/// `conv` of `obj`, or `None` for Python's `None`.
pub fn optional<'a, 'py, T>(
    obj: &'a Bound<'py, PyAny>,
    conv: impl FnOnce(&'a Bound<'py, PyAny>) -> PyResult<T>,
) -> PyResult<Option<T>> {
    if obj.is_none() {
        return Ok(None);
    }
    conv(obj).map(Some)
}

/// `bounds` as the library's bounds: `{name: (lo, hi)}` bounds a parameter
/// (a canonical name or a search coordinate's), `{name: value}` fixes it,
/// checked by the parser `--bound NAME=LO:HI` goes through. Any mapping
/// will do.
pub fn user_bounds(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<UserBound>> {
    let py = obj.py();
    let bounds = match obj.cast::<PyDict>() {
        Ok(d) => d.clone(),
        Err(_) => {
            let mapping = py.import("collections.abc")?.getattr("Mapping")?;
            if !obj.is_instance(&mapping)? {
                return Err(PyTypeError::new_err(format!(
                    "{what} must be a dict, {{name: (lo, hi)}} or {{name: value}}, got {}",
                    given(obj)
                )));
            }
            PyDict::from_sequence(&obj.call_method0("items")?)?
        }
    };
    let mut out = Vec::new();
    for (key, value) in bounds.iter() {
        let name: String = key.extract().map_err(|_| {
            PyTypeError::new_err(format!("{what}' keys must be parameter names (str)"))
        })?;
        let wrong = || {
            PyTypeError::new_err(format!(
                "{what}[{name:?}] must be a (lo, hi) pair (a tuple, list or array of two numbers) \
                 or a number (to fix it), got {}",
                given(&value)
            ))
        };
        // A bool converts to a number: `True` would fix the parameter at 1.
        let (lo, hi) = if is_bool(&value)? {
            return Err(wrong());
        } else if let (false, Ok(v)) = (value.is_instance_of::<PyString>(), value.extract::<f64>())
        {
            (v, v)
        } else if value.is_instance_of::<PyInt>() {
            // A number all the same, one no float holds: `real` says so.
            let v = real(&value, &format!("{what}[{name:?}]"))?;
            (v, v)
        } else if let Ok(pair) = value.extract::<Vec<Bound<'_, PyAny>>>()
            && pair.len() == 2
        {
            let end = |i: usize| real(&pair[i], &format!("{what}[{name:?}][{i}]"));
            (end(0)?, end(1)?)
        } else {
            return Err(wrong());
        };
        // `{}` prints an f64 so that it parses back to the same bits.
        let bound: UserBound =
            format!("{name}={lo}:{hi}")
                .parse()
                .map_err(|e: UserBoundError| {
                    PyValueError::new_err(in_python_terms(&format!("{what}: {e}")))
                })?;
        out.push(bound);
    }
    Ok(out)
}

/// Effect names checked against the catalogue (an unknown name is a
/// `ValueError` listing the known ones).
pub fn effects_arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Effect>> {
    let effects: Vec<Effect> = names(obj, what)?
        .iter()
        .map(|n| {
            n.parse::<Effect>()
                .map_err(|e| PyValueError::new_err(e.to_string()))
        })
        .collect::<PyResult<_>>()?;
    // As the commands' --effects: a chain holds an effect once, and the
    // diagnosis tries each once.
    for (k, e) in effects.iter().enumerate() {
        if effects[..k].contains(e) {
            return Err(PyValueError::new_err(format!(
                "{what} names `{e}` twice: each effect enters once"
            )));
        }
    }
    Ok(effects)
}

/// The family asked for as the argument `what`, else the start model's,
/// else classic (as the commands' `--model`/`--baseline` with `--from`).
pub fn family_or_start(
    (what, asked): (&str, Option<&str>),
    start: Option<&mckibben::model::Model>,
) -> PyResult<mckibben::model::Family> {
    Ok(match (asked, start) {
        (Some(name), _) => family(name, what)?,
        (None, Some(m)) => m.base.family,
        (None, None) => mckibben::model::Family::Classic,
    })
}
