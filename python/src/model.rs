//! A fitted model: the library's model file, read and written by one call
//! each, and its free-run simulation.

use std::path::{Path, PathBuf};

use numpy::{PyArray1, ToPyArray};
use pyo3::exceptions::{PyIsADirectoryError, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use mckibben::model::file::{Provenance, ReadSettings};
use mckibben::model::{FittedBaseline, ModelFile};

use crate::args::path;
use crate::convert::{file_error_at, given, series};
use crate::named;

/// A fitted hysteresis model, a baseline family and its effect chain, in
/// the coordinates it was fitted in: what `mckibben fit` writes to
/// `model.json` and `simulate`, `diagnose --from`, `fit --from` and
/// `control` read.
#[pyclass(module = "mckibben", frozen)]
#[derive(Clone)]
pub struct Model {
    /// The model file (box, bounds, provenance), written back as read.
    pub file: ModelFile,
    /// The model it holds.
    pub inner: mckibben::model::Model,
}

impl Model {
    /// The model a file holds (an error names what is wrong with it).
    pub fn of_file(file: ModelFile) -> anyhow::Result<Model> {
        let inner = file.model()?;
        Ok(Model { file, inner })
    }

    /// The baseline.
    fn base(&self) -> &FittedBaseline {
        &self.inner.base
    }
}

/// Where a model made in Python came from: `what` called (`mckibben.fit`,
/// ...) in this library version, on the files `sources` name that exist
/// (hashed), read as `read` says (as `simulate --from` then reads a file),
/// with `seed`.
pub fn provenance(
    what: &str,
    sources: &[&str],
    read: &ReadSettings,
    seed: Option<u64>,
) -> Provenance {
    // Each source as `fit` names it: a `--split-gaps` piece (`file.csv[2]`)
    // by its file, hashed; a name that is no file (an array's `source`)
    // as given, with no hash.
    let mut files: Vec<String> = Vec::new();
    for source in sources {
        let file = source
            .strip_suffix(']')
            .and_then(|s| s.rsplit_once('['))
            .filter(|(file, k)| k.parse::<usize>().is_ok() && std::path::Path::new(file).is_file())
            .map_or(*source, |(file, _)| file);
        if !files.iter().any(|f| f == file) {
            files.push(file.to_string());
        }
    }
    Provenance {
        command: format!("{what} (Python)"),
        ..Provenance::here(&files, seed, read.clone())
    }
}

/// Where `path` names a folder (one that exists, or a path that ends in a
/// separator), an `IsADirectoryError` that says so: the library's write
/// reports the OS's bare "Is a directory" or "Not a directory".
fn folder_error(path: &Path) -> Option<PyErr> {
    let text = path.to_string_lossy();
    let example = path.join("model.json");
    let why = if text.ends_with(std::path::is_separator) {
        format!(
            "{} ends in a separator, so it names a folder",
            path.display()
        )
    } else if path.is_dir() {
        format!("{} is a folder", path.display())
    } else {
        return None;
    };
    Some(PyIsADirectoryError::new_err(format!(
        "{why}: give the model file's path (such as {})",
        example.display()
    )))
}

#[pymethods]
impl Model {
    /// Reads a model file written by `mckibben fit`, `diagnose --out` or
    /// `identify --out` (version 2, or the bare version 1).
    #[staticmethod]
    fn load(
        py: Python<'_>,
        #[pyo3(from_py_with = named::model_path)] path: PathBuf,
    ) -> PyResult<Model> {
        py.detach(|| ModelFile::load(&path).and_then(Model::of_file))
            .map_err(|e| file_error_at(e, &path))
    }

    /// Writes the model file (`mckibben fit`'s `model.json`; the command
    /// line reads it back).
    fn save(
        &self,
        py: Python<'_>,
        #[pyo3(from_py_with = named::model_path)] path: PathBuf,
    ) -> PyResult<()> {
        if let Some(e) = folder_error(&path) {
            return Err(e);
        }
        py.detach(|| self.file.save(&path))
            .map_err(|e| file_error_at(e, &path))
    }

    /// The free-run output on the input `u` (absolute units, one value per
    /// sample), from the output `x0` at the first sample (default: at rest
    /// at the first input, as `simulate --input stair` starts). `u` may be a
    /// `Trace`: then its input, from its first measured output unless `x0`
    /// is given, as `simulate --from` runs a CSV (a `Trace` in other units
    /// of the same kinds runs the model converted into them, with a
    /// warning, and the run is in them). A run that leaves the
    /// model's range warns and goes on (the values after it mean nothing).
    #[pyo3(signature = (u, x0 = None))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        u: &Bound<'py, PyAny>,
        #[pyo3(from_py_with = named::x0)] x0: Option<f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let converted;
        let (model, input, x0) = match u.cast::<crate::data::Trace>() {
            Ok(trace) => {
                let trace = &trace.borrow().inner;
                // A record in other units of the same kinds is read as
                // `simulate --from` reads such a file, with a warning; here
                // the model goes into the record's units, so that the run
                // compares with its output. Another sample time, or units
                // of another kind, are an error (an array is taken at its
                // word).
                let (model, notes) = self.inner.in_units_of(trace, "the model");
                for note in notes {
                    py.import("warnings")?.call_method1("warn", (note,))?;
                }
                model
                    .check_data(trace)
                    .map_err(crate::convert::value_error)?;
                converted = model;
                (
                    &converted,
                    trace.input.clone(),
                    x0.or(trace.output.first().copied()),
                )
            }
            Err(_) => (&self.inner, series(u, "u")?, x0),
        };
        if let Some(v) = x0.filter(|v| !v.is_finite()) {
            return Err(pyo3::exceptions::PyValueError::new_err(format!(
                "x0 must be a finite number, got {v}"
            )));
        }
        let run = py.detach(|| match x0 {
            Some(y0) => model.simulate_absolute(&input, y0),
            None => model.simulate_from_rest(&input),
        });
        if let Some(k) = run.diverged_at {
            py.import("warnings")?.call_method1(
                "warn",
                (format!(
                    "the simulation diverged at sample {k}: the values from there on mean nothing"
                ),),
            )?;
        }
        Ok(run.output.to_pyarray(py))
    }

    /// The parameters by name: the family's in canonical order, then the
    /// effects' as `effect.param` (`creep:two-pole.kappa`).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (name, value) in self.inner.named_params() {
            d.set_item(name, value)?;
        }
        Ok(d)
    }

    /// Each parameter's unit by name, as `params` holds them, written with
    /// the units the model's columns state (`"mm/MPa"`, `"1/mm"`; `"1"` for
    /// a pure number), as `simulate --list` shows them.
    #[getter]
    fn units<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (name, unit) in self.inner.units() {
            d.set_item(name, unit)?;
        }
        Ok(d)
    }

    /// The effect stages after the family, in chain order, by realisation
    /// (`creep:two-pole`, ...); empty for a baseline alone.
    #[getter]
    fn effects<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        PyList::new(py, self.inner.effects().iter().map(|e| e.name()))
    }

    /// The family: `classic` or `generalized` (`linear` for an `identify`
    /// model).
    #[getter]
    fn family(&self) -> &'static str {
        self.base().family.name()
    }

    /// The largest step of the output in one sample within which the
    /// hysteresis update settles (`fit --json`'s `stable_step`): a record
    /// that steps further makes it overshoot, and at larger steps diverge.
    /// `None` for a loop that never saturates and for a model with effects.
    #[getter]
    fn stable_step(&self) -> Option<f64> {
        match self.inner.effects().is_empty() {
            true => self.base().family.stable_step(&self.base().params),
            false => None,
        }
    }

    /// Sample time the model was fitted at (s).
    #[getter]
    fn dt(&self) -> f64 {
        self.base().dt
    }

    /// The input mean removed before fitting (input units).
    #[getter]
    fn input_mean(&self) -> f64 {
        self.base().input_mean
    }

    /// The output mean removed before fitting (output units).
    #[getter]
    fn output_mean(&self) -> f64 {
        self.base().output_mean
    }

    /// The input column the model was fitted on (its name states the
    /// unit, where it states one).
    #[getter]
    fn input_name(&self) -> &str {
        &self.base().input_name
    }

    /// The output column the model was fitted on (its name states the
    /// unit, where it states one).
    #[getter]
    fn output_name(&self) -> &str {
        &self.base().output_name
    }

    /// Pickles as its model file's text, so that a model crosses to and
    /// from worker processes (`multiprocessing`, `concurrent.futures`) and
    /// `copy.deepcopy` copies it: the file, provenance and box included,
    /// comes back as it was.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (String,))> {
        let text = serde_json::to_string(&self.file)
            .map_err(|e| crate::convert::runtime_error(e.into()))?;
        Ok((py.get_type::<Model>().getattr("_from_state")?, (text,)))
    }

    /// The model `__reduce__` pickled.
    #[classmethod]
    fn _from_state(_class: &Bound<'_, pyo3::types::PyType>, text: &str) -> PyResult<Model> {
        serde_json::from_str::<ModelFile>(text)
            .map_err(anyhow::Error::from)
            .and_then(Model::of_file)
            .map_err(crate::convert::value_error)
    }

    /// Equal models: the same chain, parameters and coordinates (where
    /// they came from aside).
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
        let chain: String = self
            .inner
            .effects()
            .iter()
            .map(|e| format!(" + {e}"))
            .collect();
        format!(
            "Model({}{chain}: {}; dt = {} s, {} -> {})",
            self.base().family,
            params.join(", "),
            self.base().dt,
            self.base().input_name,
            self.base().output_name
        )
    }
}

/// A warm start: a `Model`, or the path of a model file.
pub fn model_arg(start: &Bound<'_, PyAny>, keyword: &str) -> PyResult<ModelFile> {
    if let Ok(m) = start.cast::<Model>() {
        return Ok(m.get().file.clone());
    }
    let path = path(start, keyword).map_err(|e| {
        if e.is_instance_of::<PyTypeError>(start.py()) {
            PyTypeError::new_err(format!(
                "{keyword} must be a Model or the path of a model file, got {}",
                given(start)
            ))
        } else {
            e
        }
    })?;
    start
        .py()
        .detach(|| ModelFile::load(&path))
        .map_err(|e| file_error_at(e, &path))
}
