//! The keyword arguments the bindings share, checked and turned into the
//! library's types, with errors in Python's terms (`ValueError`,
//! `TypeError`).

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use mckibben::model::effects::Effect;
use mckibben::model::{ModelFile, UserBound, UserBoundError};

use crate::convert::{family, file_error, in_python_terms};
use crate::model::Model;

/// A count argument (`pop`, `gens`, ...): at least 1.
pub fn count(value: Option<i64>, default: usize, what: &str) -> PyResult<usize> {
    match value {
        None => Ok(default),
        Some(v) if v >= 1 => Ok(v as usize),
        Some(v) => Err(PyValueError::new_err(format!(
            "{what} must be at least 1, got {v}"
        ))),
    }
}

/// An integer argument of at least `min` (`default` when `None`): a
/// `ValueError` naming it otherwise, where a `usize` parameter would raise
/// an `OverflowError` on a negative one.
pub fn at_least(value: Option<i64>, default: usize, min: usize, what: &str) -> PyResult<usize> {
    match value {
        None => Ok(default),
        Some(v) if v >= min as i64 => Ok(v as usize),
        Some(v) => Err(PyValueError::new_err(format!(
            "{what} must be at least {min}, got {v}"
        ))),
    }
}

/// A seed: an integer in [0, 2⁶⁴).
pub fn seed_arg(seed: i128) -> PyResult<u64> {
    u64::try_from(seed).map_err(|_| {
        PyValueError::new_err(format!("seed must be an integer in [0, 2**64), got {seed}"))
    })
}

/// `bounds` as the library's bounds: `{name: (lo, hi)}` bounds a parameter
/// (a canonical name or a search coordinate's), `{name: value}` fixes it,
/// checked by the parser `--bound NAME=LO:HI` goes through.
pub fn user_bounds(bounds: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<UserBound>> {
    let Some(bounds) = bounds else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for (key, value) in bounds.iter() {
        let name: String = key.extract().map_err(|_| {
            pyo3::exceptions::PyTypeError::new_err("bounds' keys must be parameter names (str)")
        })?;
        // A bool extracts as a number: `True` would fix the parameter at 1.
        let boolean = value.is_instance_of::<pyo3::types::PyBool>();
        let pair = value
            .extract::<Vec<f64>>()
            .ok()
            .filter(|p| p.len() == 2 && !boolean);
        let (lo, hi) = if let (false, Ok(v)) = (boolean, value.extract::<f64>()) {
            (v, v)
        } else if let Some(pair) = pair {
            (pair[0], pair[1])
        } else {
            return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "bounds[{name:?}] must be a (lo, hi) pair (a tuple, list or array of two numbers) \
                 or a number (to fix it), got {}",
                value.repr()?
            )));
        };
        // `{}` prints an f64 so that it parses back to the same bits.
        let bound: UserBound =
            format!("{name}={lo}:{hi}")
                .parse()
                .map_err(|e: UserBoundError| {
                    PyValueError::new_err(in_python_terms(&format!("bounds: {e}")))
                })?;
        out.push(bound);
    }
    Ok(out)
}

/// Effect names checked against the catalogue (an unknown name is a
/// `ValueError` listing the known ones).
pub fn effects_arg(effects: Option<Vec<String>>) -> PyResult<Option<Vec<Effect>>> {
    effects
        .map(|names| {
            names
                .iter()
                .map(|n| {
                    n.parse::<Effect>()
                        .map_err(|e| PyValueError::new_err(e.to_string()))
                })
                .collect()
        })
        .transpose()
}

/// The family asked for, else the start model's, else classic (as the
/// commands' `--model`/`--baseline` with `--from`).
pub fn family_or_start(
    given: Option<&str>,
    start: Option<&mckibben::model::Model>,
) -> PyResult<mckibben::model::Family> {
    Ok(match (given, start) {
        (Some(name), _) => family(name)?,
        (None, Some(m)) => m.base.family,
        (None, None) => mckibben::model::Family::Classic,
    })
}

/// A warm start: a `Model`, or the path of a model file.
pub fn model_arg(start: &Bound<'_, PyAny>, keyword: &str) -> PyResult<ModelFile> {
    if let Ok(m) = start.cast::<Model>() {
        return Ok(m.get().file.clone());
    }
    let path: std::path::PathBuf = start.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "{keyword} must be a Model or the path of a model file"
        ))
    })?;
    start
        .py()
        .detach(|| ModelFile::load(&path))
        .map_err(file_error)
}
