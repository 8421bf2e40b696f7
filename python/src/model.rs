//! A fitted model: the library's model file, read and written by one call
//! each, and its free-run simulation.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use numpy::{PyArray1, ToPyArray};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use mckibben::data::write_atomic;
use mckibben::model::FittedModel;

use crate::convert::{file_error, series};

/// Writes `model` as `mckibben fit` writes its `model.json` (pretty JSON,
/// replaced atomically): the one place that says what a model file is on
/// the way out, as [`FittedModel::load`] is on the way in.
pub fn save_model(path: &Path, model: &FittedModel) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(model)?;
    write_atomic(path, text.as_bytes()).with_context(|| format!("cannot write {}", path.display()))
}

/// A fitted hysteresis model, in the coordinates it was fitted in: what
/// `mckibben fit` writes to `model.json` and `simulate`, `diagnose` and
/// `control` read.
#[pyclass(module = "mckibben", frozen)]
#[derive(Clone)]
pub struct Model {
    pub inner: FittedModel,
}

#[pymethods]
impl Model {
    /// Reads a model file written by `mckibben fit` (or `identify --out`).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Model> {
        let inner = py.detach(|| FittedModel::load(&path)).map_err(file_error)?;
        Ok(Model { inner })
    }

    /// Writes the model file `mckibben fit` writes (the command line reads it back).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| save_model(&path, &self.inner))
            .map_err(file_error)
    }

    /// The free-run output on the input `u` (absolute units, one value per
    /// sample), from the output `x0` at the first sample (default: the
    /// output mean the model was fitted around). A run that leaves the
    /// model's range warns and goes on (the values after it mean nothing).
    #[pyo3(signature = (u, x0 = None))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        u: &Bound<'py, PyAny>,
        x0: Option<f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let input = series(u, "u")?;
        let y0 = match x0 {
            Some(v) if !v.is_finite() => {
                return Err(pyo3::exceptions::PyValueError::new_err(format!(
                    "x0 must be a finite number, got {v}"
                )));
            }
            Some(v) => v,
            None => self.inner.output_mean,
        };
        let (y, sim) = py.detach(|| self.inner.simulate_absolute(&input, y0));
        if let Some(k) = sim.diverged_at {
            py.import("warnings")?.call_method1(
                "warn",
                (format!(
                    "the simulation diverged at sample {k}: the values from there on mean nothing"
                ),),
            )?;
        }
        Ok(y.to_pyarray(py))
    }

    /// The parameters by name, in the family's canonical order.
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (name, value) in self.inner.named_params() {
            d.set_item(name, value)?;
        }
        Ok(d)
    }

    /// The effect stages after the family, by name: none yet (the model
    /// file holds a plain family until it carries effects).
    #[getter]
    fn effects<'py>(&self, py: Python<'py>) -> Bound<'py, PyList> {
        PyList::empty(py)
    }

    /// The family: `classic` or `generalized`.
    #[getter]
    fn family(&self) -> &'static str {
        self.inner.family.name()
    }

    /// Sample time the model was fitted at (s).
    #[getter]
    fn dt(&self) -> f64 {
        self.inner.dt
    }

    /// The input mean removed before fitting (input units).
    #[getter]
    fn input_mean(&self) -> f64 {
        self.inner.input_mean
    }

    /// The output mean removed before fitting (output units).
    #[getter]
    fn output_mean(&self) -> f64 {
        self.inner.output_mean
    }

    #[getter]
    fn input_name(&self) -> &str {
        &self.inner.input_name
    }

    #[getter]
    fn output_name(&self) -> &str {
        &self.inner.output_name
    }

    fn __eq__(&self, other: &Model) -> bool {
        self.inner == other.inner
    }

    fn __repr__(&self) -> String {
        let params: Vec<String> = self
            .inner
            .named_params()
            .iter()
            .map(|(n, v)| format!("{n}={v}"))
            .collect();
        format!(
            "Model({}: {}; dt = {} s, {} -> {})",
            self.inner.family,
            params.join(", "),
            self.inner.dt,
            self.inner.input_name,
            self.inner.output_name
        )
    }
}
