//! A fit's history as NumPy arrays.

use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use mckibben::optim::history::{GenerationRecord, History};

/// A history as a dict of arrays, one entry per record; `names` name the
/// canonical parameters its records hold. (`History::names` are the search
/// coordinates' names, which label the canonical values only where the box
/// is in canonical coordinates.)
pub fn history_arrays<'py>(
    py: Python<'py>,
    h: &History,
    names: &[&str],
) -> PyResult<Bound<'py, PyDict>> {
    let r = &h.records;
    let d = PyDict::new(py);
    let ints = |f: &dyn Fn(&GenerationRecord) -> i64| {
        PyArray1::from_vec(py, r.iter().map(f).collect::<Vec<i64>>())
    };
    let floats = |f: &dyn Fn(&GenerationRecord) -> Option<f64>| {
        PyArray1::from_vec(
            py,
            r.iter()
                .map(|x| f(x).unwrap_or(f64::NAN))
                .collect::<Vec<f64>>(),
        )
    };
    d.set_item("generation", ints(&|x| x.generation as i64))?;
    let stages: Vec<&str> = r.iter().map(|x| x.stage.name()).collect();
    d.set_item(
        "stage",
        py.import("numpy")?.call_method1("array", (stages,))?,
    )?;
    d.set_item(
        "horizon",
        ints(&|x| match x.measure {
            mckibben::model::Measure::FreeRun => 0,
            mckibben::model::Measure::Ahead { horizon } => horizon as i64,
        }),
    )?;
    d.set_item("evaluations", ints(&|x| x.evaluations as i64))?;
    d.set_item("seconds", floats(&|x| Some(x.seconds)))?;
    d.set_item("best_sse", floats(&|x| x.best_sse))?;
    d.set_item("stage_best", floats(&|x| x.stage_best))?;
    d.set_item("generation_best_sse", floats(&|x| x.generation_best_sse))?;
    d.set_item("mean_sse", floats(&|x| x.mean_sse))?;
    d.set_item("std_sse", floats(&|x| x.std_sse))?;
    d.set_item("diverged", ints(&|x| x.diverged as i64))?;
    let p = names.len();
    let rows: Vec<f64> = r
        .iter()
        .flat_map(|x| {
            if x.best_params.len() == p {
                x.best_params.clone()
            } else {
                vec![f64::NAN; p]
            }
        })
        .collect();
    d.set_item(
        "params",
        PyArray1::from_vec(py, rows).reshape([r.len(), p])?,
    )?;
    d.set_item("names", PyList::new(py, names)?)?;
    Ok(d)
}
