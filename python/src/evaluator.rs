//! `mckibben.Evaluator`: the batch evaluator as an objective for Python's
//! optimizers, over the search box `mckibben fit` searches.

use std::sync::Mutex;

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyFloat};

use mckibben::data::readable;
use mckibben::fit::chart::ModelChart;
use mckibben::fit::objective::ModelObjective;
use mckibben::fit::problem::FitProblem;
use mckibben::fit::report::model_file;
use mckibben::model::UserBound;
use mckibben::model::file::ReadSettings;
use mckibben::model::{Flow, Measure, Switching};
use mckibben::optim::engine::Objective as _;
use mckibben::optim::engine::Space;
use mckibben::search::Rows;

use crate::convert::{backend, family, loop_shape, rows, rows_view, runtime_error, value_error};
use crate::data::data_arg;
use crate::model::{Model, provenance};
use crate::named;

/// The batch evaluator as an objective: `ev(thetas)` scores an `(N, d)`
/// array of candidates at once (on the CPU, or a GPU) and returns their N
/// free-run SSEs on the estimation half (the first half) of the data;
/// `inf` or NaN for a candidate that diverges.
///
/// A candidate is a vector of the search coordinates `mckibben fit`'s
/// staged engine moves (`names`, in the box `bounds`: the data's own scale,
/// loops in the bounded class unless `loop="free"`); values outside the box
/// are clamped into it, as the engine does. With `checked` (the default)
/// the objective is the fit's own: a candidate whose loop leaves the
/// bounded class or whose output runs away on the whole record's input
/// also scores `inf`. Without, it is the batch evaluator's SSE alone, as
/// `mckibben bench` times it.
#[pyclass(module = "mckibben", frozen)]
pub struct Evaluator {
    problem: FitProblem,
    /// The user's bounds the box was made with (a model's file keeps them).
    bounds: Vec<UserBound>,
    /// The data's source and how it was read (a model's provenance names
    /// them).
    source: String,
    read: ReadSettings,
    space: Space<ModelChart>,
    checked: bool,
    /// The free coordinates' names.
    names: Vec<String>,
    describe: String,
    evaluator: Mutex<Box<dyn mckibben::eval::Evaluator + Send>>,
}

impl Evaluator {
    /// The costs of canonical rows, with the interpreter released.
    fn score(&self, py: Python<'_>, canonical: Vec<f64>) -> PyResult<Vec<f32>> {
        let canonical = Rows::new(&canonical, self.space.dim());
        py.detach(|| {
            let mut evaluator = self
                .evaluator
                .lock()
                .map_err(|_| anyhow::anyhow!("the evaluator failed in an earlier call"))?;
            if self.checked {
                ModelObjective::for_problem(evaluator.as_mut(), &self.problem)
                    .costs(canonical, Measure::FreeRun)
            } else {
                Ok(evaluator
                    .evaluate(&self.problem.est_problem(), canonical)?
                    .total)
            }
        })
        .map_err(runtime_error)
    }

    /// Scores candidates of search coordinates given as `obj` (see
    /// [`rows`]): a float for one vector, else an array of N.
    fn call<'py>(
        &self,
        py: Python<'py>,
        obj: &Bound<'py, PyAny>,
        what: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (view, _, single) = rows_view(obj, &self.names, what)?;
        let free = view.as_slice()?;
        let canonical = py.detach(|| self.embed(free));
        let costs = self.score(py, canonical)?;
        sses(py, costs, single)
    }

    /// The canonical rows of rows of free search coordinates
    /// ([`Space::embed`], what the engine scores), a block of rows at a
    /// time: each block's buffers stay small enough for the allocator to
    /// reuse, where one call for 10⁵ rows maps and faults in fresh pages
    /// (measured: docs/PYTHON.md, "Throughput from Python").
    fn embed(&self, free: &[f64]) -> Vec<f64> {
        const BLOCK: usize = 1024;
        let d = self.space.free_dim();
        let mut canonical = Vec::with_capacity(free.len() / d * self.space.dim());
        for block in free.chunks(BLOCK * d) {
            canonical.extend(self.space.embed(Rows::new(block, d)).into_flat());
        }
        canonical
    }

    /// The canonical vector of one candidate.
    fn one(&self, theta: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
        let (free, n, _) = rows(theta, &self.names, "theta")?;
        if n != 1 {
            return Err(PyValueError::new_err(format!(
                "theta must be one candidate (a vector of {}), got {n}",
                self.names.len()
            )));
        }
        Ok(self
            .space
            .embed(Rows::new(&free, self.space.free_dim()))
            .into_flat())
    }

    /// A `UserWarning` naming the first search coordinate of `thetas` (rows
    /// of d) outside this Evaluator's box: scoring the coordinates, or
    /// `to_params`, takes it to the box's edge, so they stand for another
    /// model (a model fitted on another record, or with other `bounds`,
    /// returned such coordinates without a word).
    fn warn_outside_the_box(&self, py: Python<'_>, thetas: &[f64]) -> PyResult<()> {
        let b = self.space.bounds();
        let d = self.names.len();
        let outside = thetas.chunks_exact(d).enumerate().find_map(|(row, theta)| {
            (0..d)
                .find(|&i| theta[i] < b.lower[i] || theta[i] > b.upper[i])
                .map(|i| (row, i, theta[i]))
        });
        let Some((row, i, value)) = outside else {
            return Ok(());
        };
        let edge = value.clamp(b.lower[i], b.upper[i]);
        let message = format!(
            "params[{row}]: {} is {} in the search coordinates, outside this Evaluator's box \
             [{}, {}]: scoring the coordinates, or `to_params`, takes it to the box's edge, {}, \
             another model (`score_params` scores the model itself; `bounds` widens the box)",
            self.names[i],
            readable(value),
            readable(b.lower[i]),
            readable(b.upper[i]),
            readable(edge)
        );
        py.import("warnings")?.call_method1("warn", (message,))?;
        Ok(())
    }

    /// Refuses canonical rows that a held coordinate of the box cannot
    /// stand for: their search coordinates would score the hold instead.
    fn check_holds(&self, canonical: &[f64]) -> PyResult<()> {
        let d = self.space.dim();
        for (row, theta) in canonical.chunks_exact(d).enumerate() {
            let Some((i, value)) = self.space.off_hold(theta) else {
                continue;
            };
            let name = &self.space.names[i];
            let hold = readable(self.space.lower[i]);
            let (by, free) = if self.bounds.iter().any(|b| &b.name == name) {
                (" (`bounds`)", "")
            } else if name == "n" {
                (" (free_n=False)", "; free_n=True searches it")
            } else {
                ("", "")
            };
            return Err(PyValueError::new_err(format!(
                "params[{row}]: {name} is {}, where this Evaluator's box holds it at {hold}{by}: \
                 the search coordinates have no place for it, and scoring them would use \
                 {hold}{free}",
                readable(value)
            )));
        }
        Ok(())
    }

    /// The canonical parameter names of the family.
    fn canonical_names(&self) -> Vec<String> {
        self.problem
            .model
            .family
            .params()
            .iter()
            .map(|p| p.name.to_string())
            .collect()
    }
}

/// Costs as Python values: a float for a single vector, else an array.
fn sses<'py>(py: Python<'py>, costs: Vec<f32>, single: bool) -> PyResult<Bound<'py, PyAny>> {
    let costs: Vec<f64> = costs.into_iter().map(f64::from).collect();
    if single {
        return Ok(PyFloat::new(py, costs[0]).into_any());
    }
    Ok(PyArray1::from_vec(py, costs).into_any())
}

/// Checks the rows (of `names.len()` values each) that the rows of `what`
/// map to: a non-finite value is an error naming the row and the column,
/// where the map would return it silently (`to_thetas` of a parameter of
/// 1e308 gave `inf` or NaN).
fn finite_rows(values: &[f64], names: &[String], what: &str, kind: &str) -> PyResult<()> {
    let Some(i) = values.iter().position(|v| !v.is_finite()) else {
        return Ok(());
    };
    let d = names.len().max(1);
    let (row, column) = (i / d, i % d);
    Err(PyValueError::new_err(format!(
        "{what}[{row}] maps to a non-finite {kind}: {} (column {column}) is {}; \
         a value of that row is too large in size for it",
        names.get(column).map_or("?", String::as_str),
        values[i]
    )))
}

/// Rows of `d` values as a 1-D array (one vector) or an `(N, d)` array.
fn matrix<'py>(
    py: Python<'py>,
    values: Vec<f64>,
    d: usize,
    single: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let n = values.len() / d.max(1);
    let array = PyArray1::from_vec(py, values);
    if single {
        return Ok(array.into_any());
    }
    Ok(array.reshape([n, d])?.into_any())
}

#[pymethods]
impl Evaluator {
    /// An evaluator of `model` on one experiment (the arrays `u`, `y` and
    /// the sample time `dt`, or a `Trace`), scoring on `backend`: `auto` (a
    /// hardware GPU if there is one, else the CPU), `cpu` or `gpu` (any
    /// adapter, lavapipe included). `bounds`, `free_n` and `loop` shape the
    /// box as in `fit`.
    #[new]
    #[pyo3(signature = (u, y = None, dt = None, model = "classic", backend = "auto", *, bounds = None, free_n = false, r#loop = "bounded", checked = true))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        u: &Bound<'_, PyAny>,
        y: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = named::dt_opt)] dt: Option<f64>,
        #[pyo3(from_py_with = named::family)] model: &str,
        #[pyo3(from_py_with = named::backend)] backend: &str,
        #[pyo3(from_py_with = named::bounds)] bounds: Option<Vec<UserBound>>,
        #[pyo3(from_py_with = named::free_n)] free_n: bool,
        #[pyo3(from_py_with = named::loop_shape)] r#loop: &str,
        #[pyo3(from_py_with = named::checked)] checked: bool,
    ) -> PyResult<Evaluator> {
        let (trace, read) = data_arg(u, y, dt)?;
        let family = family(model, "model")?;
        let loop_shape = loop_shape(r#loop)?;
        let bounds = bounds.unwrap_or_default();
        // The box of the family alone: a bound on an effect's parameter
        // (`creep.rho`) would be left out without a word, where `fit` reads it.
        if let Some(b) = bounds.iter().find(|b| b.name.contains('.')) {
            return Err(PyValueError::new_err(format!(
                "bounds: `{}` names an effect's parameter, and an Evaluator scores the {family} \
                 family alone, without effects: leave it out",
                b.name
            )));
        }
        let backend = self::backend(backend)?;
        let problem = py
            .detach(|| {
                FitProblem::with_box(
                    std::slice::from_ref(&trace),
                    family,
                    Flow::Joint,
                    None,
                    free_n,
                    (loop_shape, Switching::default()),
                    &bounds,
                )
            })
            .map_err(value_error)?;
        let space = Space::from(&problem.space);
        // Nothing to search: a row of no coordinates is no candidate, and
        // `fit` refuses the same box.
        if space.free().is_empty() {
            return Err(PyValueError::new_err(
                "bounds: every search coordinate is held, so there is nothing to evaluate: \
                 the search space has no free parameter (`Model.simulate` runs a model whose \
                 every parameter is given)",
            ));
        }
        let evaluator = py
            .detach(|| mckibben::eval::open(backend))
            .map_err(runtime_error)?;
        Ok(Evaluator {
            names: space.bounds().names,
            describe: evaluator.describe(),
            problem,
            bounds,
            source: trace.source.clone(),
            read,
            space,
            checked,
            evaluator: Mutex::new(evaluator),
        })
    }

    /// The SSE of each candidate: `thetas` is an `(N, d)` array (any float
    /// dtype or layout, or a list) of search coordinates, one row a
    /// candidate; returns an array of N. One vector of `d` gives a float.
    fn __call__<'py>(
        &self,
        py: Python<'py>,
        thetas: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.call(py, thetas, "thetas")
    }

    /// The same objective in SciPy's layout: called with a `(d, S)` array
    /// (`differential_evolution(..., vectorized=True)`) it returns S SSEs;
    /// with one vector of `d` (the polish), a float.
    #[getter]
    fn for_scipy(slf: &Bound<'_, Self>) -> ScipyObjective {
        ScipyObjective {
            evaluator: slf.clone().unbind(),
        }
    }

    /// The box of each search coordinate, `(lower, upper)`, in `names`' order.
    #[getter]
    fn bounds(&self) -> Vec<(f64, f64)> {
        let b = self.space.bounds();
        b.lower.into_iter().zip(b.upper).collect()
    }

    /// The search coordinates' names (the columns of `thetas`).
    #[getter]
    fn names(&self) -> Vec<String> {
        self.names.clone()
    }

    /// The number of search coordinates d.
    #[getter]
    fn dim(&self) -> usize {
        self.names.len()
    }

    /// The canonical parameters' names (the columns of `to_params`).
    #[getter]
    fn param_names(&self) -> Vec<String> {
        self.canonical_names()
    }

    /// Where candidates are scored (backend and adapter).
    #[getter]
    fn backend(&self) -> &str {
        &self.describe
    }

    /// Samples each candidate is scored on (the estimation half).
    #[getter]
    fn samples(&self) -> usize {
        self.problem.estimation().len()
    }

    /// Whether the fit's bounded-loop checks apply (`checked`).
    #[getter]
    fn checked(&self) -> bool {
        self.checked
    }

    /// The canonical parameter vectors of candidates: `(N, P)` for `(N, d)`.
    fn to_params<'py>(
        &self,
        py: Python<'py>,
        thetas: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (free, _, single) = rows(thetas, &self.names, "thetas")?;
        let canonical = py.detach(|| self.embed(&free));
        finite_rows(&canonical, &self.canonical_names(), "thetas", "parameter")?;
        matrix(py, canonical, self.space.dim(), single)
    }

    /// The search coordinates of canonical parameter vectors (`(N, P)` to
    /// `(N, d)`): where a fitted model lies in this box.
    fn to_thetas<'py>(
        &self,
        py: Python<'py>,
        params: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (canonical, _, single) = rows(params, &self.canonical_names(), "params")?;
        self.check_holds(&canonical)?;
        let thetas = self
            .space
            .project(Rows::new(&canonical, self.space.dim()))
            .into_flat();
        finite_rows(&thetas, &self.names, "params", "search coordinate")?;
        self.warn_outside_the_box(py, &thetas)?;
        matrix(py, thetas, self.names.len(), single)
    }

    /// The SSE of canonical parameter vectors (`(N, P)`, or one of P), as
    /// `__call__` scores candidates: e.g. a fitted model's `params` values.
    fn score_params<'py>(
        &self,
        py: Python<'py>,
        params: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (canonical, _, single) = rows(params, &self.canonical_names(), "params")?;
        let costs = self.score(py, canonical)?;
        sses(py, costs, single)
    }

    /// The model of one candidate, in the data's coordinates (what `fit`
    /// would write for it).
    fn model(&self, theta: &Bound<'_, PyAny>) -> PyResult<Model> {
        let file = model_file(
            &self.problem,
            &self.one(theta)?,
            &self.bounds,
            provenance(
                "mckibben.Evaluator.model",
                &[&self.source],
                &self.read,
                None,
            ),
        );
        Model::of_file(file).map_err(runtime_error)
    }

    /// The validation scores of one candidate, as `fit` reports its own:
    /// `val_rmse` and `val_fit_percent` (MATLAB's `compare`) of a free run
    /// over the whole record, scored on its second half.
    fn validate<'py>(
        &self,
        py: Python<'py>,
        theta: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let canonical = self.one(theta)?;
        let v = py.detach(|| self.problem.validate(&canonical));
        let d = PyDict::new(py);
        d.set_item("val_rmse", v.rmse)?;
        d.set_item("val_fit_percent", v.fit_percent)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "Evaluator({} on {} samples, d = {} ({}), {}{})",
            self.problem.model.family,
            self.problem.estimation().len(),
            self.names.len(),
            self.names.join(", "),
            self.describe,
            if self.checked { "" } else { ", unchecked" }
        )
    }
}

/// An [`Evaluator`] in SciPy's `(d, S)` layout (`Evaluator.for_scipy`).
#[pyclass(module = "mckibben", frozen)]
pub struct ScipyObjective {
    evaluator: Py<Evaluator>,
}

#[pymethods]
impl ScipyObjective {
    /// S SSEs for a `(d, S)` array, a float for one vector of d.
    fn __call__<'py>(&self, py: Python<'py>, x: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let array = py.import("numpy")?.call_method1("asarray", (x,))?;
        let ndim: usize = array.getattr("ndim")?.extract()?;
        let rows = if ndim == 2 {
            array.getattr("T")?
        } else {
            array
        };
        self.evaluator
            .get()
            .call(py, &rows, "x (SciPy's (d, S) layout, transposed)")
    }

    /// The evaluator this wraps.
    #[getter]
    fn evaluator(&self, py: Python<'_>) -> Py<Evaluator> {
        self.evaluator.clone_ref(py)
    }
}
