//! `mckibben.fit`: the library's [`Fit`], the run `mckibben fit` makes,
//! with Python's progress callback and Ctrl-C.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::{PyKeyboardInterrupt, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use mckibben::diagnose::StopFlag;
use mckibben::diagnose::chain::with_chain_start;
use mckibben::fit::edge::active_bounds;
use mckibben::fit::objective::{GENERATIONS, POPULATION};
use mckibben::fit::run::{Fit, FitBox, FitSettings, Overrides, model_file, yardstick_warnings};
use mckibben::model::effects::Effect;
use mckibben::model::{ModelFile, UserBound};
use mckibben::optim::engine::{Observer, StopReason, StopRules};
use mckibben::optim::history::{GenerationRecord, History};

use crate::convert::{
    algorithm, backend, family, file_error, in_python_terms, loop_shape, runtime_error, switching,
    to_python, value_error,
};
use crate::data::data_arg;
use crate::interrupt::interruptible;
use crate::model::{Model, provenance};

/// What `mckibben.fit` returns: the fields of `mckibben fit --json` as
/// Python values, the model, and the history as arrays.
#[pyclass(module = "mckibben", frozen, get_all)]
pub struct FitResult {
    /// The fitted model (`None` when every candidate diverged).
    model: Option<Py<Model>>,
    /// Fitted parameters by name: the family's in canonical order, then the
    /// effects' as `effect.param` (empty when none was found).
    params: Py<PyDict>,
    /// Estimation SSE of the free run (first half of the data; `inf` when
    /// every candidate diverged).
    sse: f64,
    /// Free-run RMSE and fit % (MATLAB's `compare`) on the validation half.
    val_rmse: Option<f64>,
    val_fit_percent: Option<f64>,
    /// The first-order ARX model's validation fit on the same halves: what
    /// the fit should beat.
    linear_val_fit_percent: Option<f64>,
    /// With `start`: the start model as it was, on this record's halves
    /// (`None` without a start, or where it diverges).
    start_sse: Option<f64>,
    start_val_fit_percent: Option<f64>,
    /// With effects and no start: the search from scratch against the
    /// chain built one effect at a time (`scratch_sse`, `chain_sse`,
    /// `kept_chain`); `None` otherwise.
    built: Option<Py<PyAny>>,
    /// A generalized fit under the default `switch="starts"`: both starts'
    /// estimation SSEs and which was kept (`mean_sse`, `zero_sse`,
    /// `kept_zero`; `fit --json`'s `switching`); `None` otherwise.
    switching: Option<Py<PyAny>>,
    evaluations: u64,
    generations: usize,
    seconds: f64,
    /// Where populations were scored.
    backend: String,
    /// `classic` or `generalized`.
    family: String,
    /// The effect stages fitted after the family, in chain order.
    effects: Vec<String>,
    algo: String,
    /// `joint` or `thesis`.
    flow: String,
    seed: u64,
    population: usize,
    /// Why the fit ended: `completed`, `target-sse`, `time-budget`, `interrupted`.
    stop: String,
    /// Ctrl-C (or an exception in `progress`) stopped it: the result is the best so far.
    interrupted: bool,
    /// One dict per stage run (`fit --json`'s `stages`).
    stages: Py<PyAny>,
    /// Search coordinates that ended on a bound (`fit --json`'s `on_edge`).
    on_edge: Py<PyAny>,
    /// The edge rule's widenings and refits (`fit --json`'s `widened`).
    widened: Py<PyAny>,
    /// The box searched: `names`, `lower`, `upper` (after widening).
    search_box: Py<PyDict>,
    /// One entry per generation and polish start: arrays `generation`,
    /// `stage`, `horizon` (0 for the free run), `evaluations`, `seconds`,
    /// `best_sse`, `stage_best`, `generation_best_sse`, `mean_sse`,
    /// `std_sse` (NaN where none), `diverged`, and `params` (rows of the
    /// stage's best canonical parameters, named by `names`).
    history: Py<PyDict>,
}

#[pymethods]
impl FitResult {
    fn __repr__(&self) -> String {
        format!(
            "FitResult({} {} fit, val_fit_percent = {}, sse = {}, stop = {}, {:.2} s)",
            self.algo,
            self.family,
            self.val_fit_percent
                .map_or("None".to_string(), |v| format!("{v:.4}")),
            self.sse,
            self.stop,
            self.seconds
        )
    }
}

/// Sees each generation's record: hands it to Python's `progress` callable
/// and checks for Ctrl-C, with the interpreter attached for just that. A
/// signal's exception or one from `progress` raises the engine's stop flag,
/// which it reads before the next generation; an exception other than
/// `KeyboardInterrupt` is kept, to be raised once the fit has stopped.
struct PythonObserver<'a> {
    progress: Option<Py<PyAny>>,
    interrupt: &'a AtomicBool,
    error: Option<PyErr>,
}

impl PythonObserver<'_> {
    fn stop(&mut self, py: Python<'_>, e: PyErr) {
        self.interrupt.store(true, Ordering::SeqCst);
        if !e.is_instance_of::<PyKeyboardInterrupt>(py) {
            self.error.get_or_insert(e);
        }
    }
}

impl Observer for PythonObserver<'_> {
    fn record(&mut self, record: &GenerationRecord, planned: usize) {
        if self.interrupt.load(Ordering::SeqCst) {
            return;
        }
        Python::attach(|py| {
            if let Err(e) = py.check_signals() {
                return self.stop(py, e);
            }
            let Some(progress) = self.progress.as_ref().map(|p| p.clone_ref(py)) else {
                return;
            };
            let called = to_python(py, record).and_then(|r| {
                r.set_item("planned", planned)?;
                progress.call1(py, (r,))
            });
            if let Err(e) = called {
                self.stop(py, e);
            }
        });
    }
}

/// A count argument (`pop`, `gens`, ...): at least 1.
fn count(value: Option<i64>, default: usize, what: &str) -> PyResult<usize> {
    match value {
        None => Ok(default),
        Some(v) if v >= 1 => Ok(v as usize),
        Some(v) => Err(PyValueError::new_err(format!(
            "{what} must be at least 1, got {v}"
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
        let (lo, hi) = if let Ok(v) = value.extract::<f64>() {
            (v, v)
        } else if let Ok(pair) = value.extract::<(f64, f64)>() {
            pair
        } else {
            return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "bounds[{name:?}] must be a (lo, hi) pair or a number (to fix it), got {}",
                value.repr()?
            )));
        };
        // `{}` prints an f64 so that it parses back to the same bits.
        let bound: UserBound = format!("{name}={lo}:{hi}")
            .parse()
            .map_err(|e: String| PyValueError::new_err(in_python_terms(&format!("bounds: {e}"))))?;
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
                .map(|n| n.parse::<Effect>().map_err(PyValueError::new_err))
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
pub fn start_arg(start: &Bound<'_, PyAny>) -> PyResult<ModelFile> {
    if let Ok(m) = start.cast::<Model>() {
        return Ok(m.get().file.clone());
    }
    let path: std::path::PathBuf = start
        .extract()
        .map_err(|_| PyTypeError::new_err("start must be a Model or the path of a model file"))?;
    start
        .py()
        .detach(|| ModelFile::load(&path))
        .map_err(file_error)
}

/// A history as a dict of arrays, one entry per record; `names` name the
/// canonical parameters its records hold. (`History::names` are the search
/// coordinates' names, which label the canonical values only where the box
/// is in canonical coordinates.)
fn history_arrays<'py>(
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

/// Fits a hysteresis model to one experiment with the staged engine of
/// `mckibben fit`, its defaults and its edge rule: the same parameters, bit
/// for bit, for the same data, settings and seed, on any backend.
#[pyfunction]
#[pyo3(signature = (
    u, y = None, dt = None, model = None, effects = None, algo = "de", pop = None,
    gens = None, seed = 1, backend = "cpu", bounds = None, progress = None, *,
    free_n = false, r#loop = "bounded", switch = "starts", thesis_flow = false,
    target_sse = None, time_budget = None, stall = None, start = None
))]
#[allow(clippy::too_many_arguments)]
pub fn fit(
    py: Python<'_>,
    u: &Bound<'_, PyAny>,
    y: Option<&Bound<'_, PyAny>>,
    dt: Option<f64>,
    model: Option<&str>,
    effects: Option<Vec<String>>,
    algo: &str,
    pop: Option<i64>,
    gens: Option<i64>,
    seed: i128,
    backend: &str,
    bounds: Option<&Bound<'_, PyDict>>,
    progress: Option<Py<PyAny>>,
    free_n: bool,
    r#loop: &str,
    switch: &str,
    thesis_flow: bool,
    target_sse: Option<f64>,
    time_budget: Option<f64>,
    stall: Option<i64>,
    start: Option<&Bound<'_, PyAny>>,
) -> PyResult<FitResult> {
    let trace = data_arg(u, y, dt)?;
    // As `fit --from`: the start's family, effects and bounds unless given
    // here (the bounds given here after the file's, so that they win).
    let start = start.map(start_arg).transpose()?;
    let start_model = start
        .as_ref()
        .map(|f| f.model())
        .transpose()
        .map_err(value_error)?;
    let family = family_or_start(model, start_model.as_ref())?;
    let effects: Vec<Effect> = match (effects_arg(effects)?, &start_model) {
        (Some(e), _) => e,
        (None, Some(m)) => m.effects().to_vec(),
        (None, None) => Vec::new(),
    };
    let mut all_bounds: Vec<UserBound> = match &start {
        Some(f) => f
            .user_bounds
            .iter()
            .map(|b| {
                b.parse().map_err(|e: String| {
                    PyValueError::new_err(format!("start: its user_bounds: {e}"))
                })
            })
            .collect::<PyResult<_>>()?,
        None => Vec::new(),
    };
    all_bounds.extend(user_bounds(bounds)?);
    let what = FitBox {
        family,
        effects,
        free_n,
        loop_shape: loop_shape(r#loop)?,
        switching: switching(switch)?,
        bounds: all_bounds,
    };
    if let Some(p) = progress.as_ref()
        && !p.bind(py).is_callable()
    {
        return Err(pyo3::exceptions::PyTypeError::new_err(
            "progress must be callable: it is called with each generation's record (a dict)",
        ));
    }
    let settings = FitSettings {
        algo: algorithm(algo)?,
        pop: count(pop, POPULATION, "pop")?,
        gens: count(gens, GENERATIONS, "gens")?,
        seed: seed_arg(seed)?,
        thesis_flow,
        islands: None,
        horizon: None,
        overrides: Overrides::default(),
        stops: StopRules {
            target_sse,
            time_budget_s: time_budget,
            stall_generations: stall.map(|s| count(Some(s), 1, "stall")).transpose()?,
            stall_tolerance: 0.0,
        },
    };
    let backend = self::backend(backend)?;
    let notes = Mutex::new(Vec::new());
    let note = |s: String| notes.lock().expect("notes").push(s);
    let fit = py
        .detach(|| Fit::new(&trace, &what, &settings, start_model.as_ref(), None, &note))
        .map_err(value_error)?;
    // With effects from scratch, a second start: the chain built one effect
    // at a time, as `mckibben fit --effects` does. Ctrl-C while it is built
    // raises `KeyboardInterrupt`: there is no fit yet to return.
    let stop = StopFlag::default();
    let mut fit = interruptible(py, &stop, || {
        with_chain_start(fit, &trace, &settings, backend, stop.clone())
    })?
    .map_err(runtime_error)?;
    let interrupt = AtomicBool::new(false);
    let mut observer = PythonObserver {
        progress,
        interrupt: &interrupt,
        error: None,
    };
    let (ran, describe) = py
        .detach(|| {
            let mut evaluator = mckibben::eval::open(backend)?;
            let describe = evaluator.describe();
            let ran = fit.run(
                evaluator.as_mut(),
                &mut [&mut observer],
                Some(&interrupt),
                None,
            )?;
            anyhow::Ok((ran, describe))
        })
        .map_err(runtime_error)?;
    if let Some(e) = observer.error.take() {
        return Err(e);
    }
    // A Ctrl-C during the polish or the edge rule's refit, which the engine
    // does not stop for, comes too late to stop anything: the fit is done.
    if let Err(e) = py.check_signals() {
        if !e.is_instance_of::<PyKeyboardInterrupt>(py) {
            return Err(e);
        }
    }
    let warn = py.import("warnings")?;
    for n in notes.into_inner().expect("notes") {
        warn.call_method1("warn", (in_python_terms(&n),))?;
    }
    let (outcome, widened) = ran;
    let start = fit.start_scores();
    let built = fit.built;
    let switched = fit.switched;
    let Fit { task, engine, .. } = fit;
    let found = !outcome.params.is_empty();
    let val = found.then(|| task.validate(&outcome.params));
    let finite = |v: f64| v.is_finite().then_some(v);
    let linear = task.linear_yardstick().and_then(|v| finite(v.fit_percent));
    if let Some(fit) = val.and_then(|v| finite(v.fit_percent)) {
        for w in yardstick_warnings(outcome.sse, fit, linear, start) {
            warn.call_method1("warn", (w,))?;
        }
    }
    let names = task.augmented().param_names();
    let names: Vec<&str> = names.iter().map(|n| n.as_str()).collect();
    let params = PyDict::new(py);
    for (name, v) in names.iter().zip(&outcome.params) {
        params.set_item(name, v)?;
    }
    let search_box = PyDict::new(py);
    search_box.set_item("names", task.space.names())?;
    search_box.set_item("lower", PyArray1::from_slice(py, &task.space.lower))?;
    search_box.set_item("upper", PyArray1::from_slice(py, &task.space.upper))?;
    let global = engine.plan.global.as_ref();
    let model = if found {
        let file = model_file(
            &task,
            &outcome.params,
            &what.bounds,
            provenance("mckibben.fit", &[&trace.source], Some(engine.seed)),
        );
        Some(Py::new(py, Model::of_file(file).map_err(runtime_error)?)?)
    } else {
        None
    };
    Ok(FitResult {
        model,
        params: params.unbind(),
        sse: outcome.sse,
        val_rmse: val.and_then(|v| finite(v.rmse)),
        val_fit_percent: val.and_then(|v| finite(v.fit_percent)),
        linear_val_fit_percent: linear,
        start_sse: start.and_then(|s| finite(s.est_sse)),
        start_val_fit_percent: start.and_then(|s| finite(s.validation.fit_percent)),
        built: built
            .map(|b| to_python(py, &b))
            .transpose()?
            .map(|b| b.unbind()),
        switching: switched
            .map(|s| to_python(py, &s))
            .transpose()?
            .map(|s| s.unbind()),
        evaluations: outcome.evaluations,
        generations: outcome.generations,
        seconds: outcome.seconds,
        backend: describe,
        family: task.family.name().to_string(),
        effects: task.effects.iter().map(|e| e.name().to_string()).collect(),
        algo: global.map_or(settings.algo, |g| g.algorithm()).to_string(),
        flow: to_python(py, &task.flow)?.extract()?,
        seed: engine.seed,
        population: global.map_or(0, |g| g.population),
        stop: to_python(py, &outcome.stop)?.extract()?,
        interrupted: outcome.stop == StopReason::Interrupted,
        stages: to_python(py, &outcome.stages)?.unbind(),
        on_edge: to_python(py, &active_bounds(&task, &outcome.params))?.unbind(),
        widened: to_python(py, &widened)?.unbind(),
        search_box: search_box.unbind(),
        history: history_arrays(py, &engine.history, &names)?.unbind(),
    })
}
