//! `mckibben.fit`: the library's [`FitRun`], the run `mckibben fit` makes,
//! with Python's progress callback and Ctrl-C.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use numpy::PyArray1;
use pyo3::exceptions::{PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use mckibben::diagnose::chain::with_chain_start;
use mckibben::eval::Backend;
use mckibben::fit::edge::Widening;
use mckibben::fit::objective::{GENERATIONS, POPULATION};
use mckibben::fit::report::{FitReport, Note, model_file};
use mckibben::fit::request::{FitRequest, Resolved, switching_boxed, switching_misapplied};
use mckibben::fit::run::{FitRun, FitTarget};
use mckibben::fit::searches::StopFlag;
use mckibben::fit::settings::{FitSettings, Overrides};
use mckibben::model::UserBound;
use mckibben::model::effects::Effect;
use mckibben::model::file::ReadSettings;
use mckibben::optim::engine::{Observer, Outcome, StopReason, StopRules};
use mckibben::optim::history::GenerationRecord;

use crate::convert::{
    algorithm, backend, family, in_python_terms, loop_shape, overshoot as overshoot_rule,
    runtime_error, switching, to_python, value_error,
};
use crate::data::{Experiments, experiments, located};
use crate::history::history_arrays;
use crate::interrupt::interruptible;
use crate::model::model_arg;
use crate::model::{Model, provenance};
use crate::named;

crate::state::with_state! {
    /// What `mckibben.fit` returns: the fields of `mckibben fit --json` as
    /// Python values, the model, and the history as arrays.
    #[pyclass(module = "mckibben", frozen, get_all)]
    pub struct FitResult {
        /// The fitted model (`None` when every candidate diverged).
        model: Option<Py<Model>>,
        /// Fitted parameters by name: the family's in canonical order, then the
        /// effects' as `effect.param` (empty when none was found).
        params: Py<PyDict>,
        /// Each parameter's unit by the same names, in the units the data's
        /// columns state (`"mm/MPa"`; `"1"` for a pure number; `fit --json`'s
        /// `units`).
        units: Py<PyDict>,
        /// Estimation SSE of the free run (first half of the data; `inf` when
        /// every candidate diverged).
        sse: f64,
        /// Free-run RMSE on the validation half (the second half of the data).
        val_rmse: Option<f64>,
        /// Free-run fit % (MATLAB's `compare`) on the validation half.
        val_fit_percent: Option<f64>,
        /// The first-order ARX model's validation fit on the same halves: what
        /// the fit should beat.
        linear_val_fit_percent: Option<f64>,
        /// The largest pole modulus of those ARX models: at 1 or past it the
        /// yardstick drifts or grows and scores nothing a fit need clear.
        linear_largest_pole: Option<f64>,
        /// The records' input and output columns and their units, a dict
        /// (`input` and `output`, each `column` and `unit`; `fit --json`'s
        /// `columns`): what `sse`, `val_rmse` and the parameters are in.
        columns: Py<PyAny>,
        /// What `fit` prints on stderr and `fit --json` holds as `notes`, one
        /// dict each (`level`, `note` or `warning`, and `text`), in order: the
        /// notes before the run, the box's, tries that agree too little,
        /// undetermined parameters, a validation fit below its yardsticks. Each
        /// was also raised as a `UserWarning`.
        notes: Py<PyAny>,
        /// Each experiment's validation scores on its own second half, one
        /// dict per experiment (`data`, `samples`, `val_rmse`,
        /// `val_fit_percent`, `linear_val_fit_percent`, `linear_largest_pole`;
        /// `fit --json`'s `records`).
        records: Py<PyAny>,
        /// The largest output step a sample within which the fitted
        /// hysteresis update settles (`fit --json`'s `stable_step`).
        stable_step: Option<f64>,
        /// The record's largest measured output step a sample (`fit --json`'s
        /// `largest_step`): above `stable_step`, the model runs past what it
        /// settles.
        largest_step: Option<f64>,
        /// With `start`: the start model's estimation SSE as it was, on this
        /// record's first half (`None` without a start, or where it diverges).
        start_sse: Option<f64>,
        /// With `start`: the start model's fit % as it was, on this record's
        /// second half (`None` without a start, or where it diverges).
        start_val_fit_percent: Option<f64>,
        /// With effects and no start: the search from scratch against the
        /// chain built one effect at a time (`scratch_sse`, `chain_sse`,
        /// `kept_chain`); `None` otherwise.
        built: Option<Py<PyAny>>,
        /// A generalized fit with `switch="starts"`: both starts' estimation
        /// SSEs and which was kept (`mean_sse`, `zero_sse`, `kept_zero`; `fit
        /// --json`'s `switching`); `None` otherwise.
        switching: Option<Py<PyAny>>,
        /// Independent tries the population ran (from `pop=2000` on, tries of
        /// 1000 and of 100; else 1).
        tries: usize,
        /// The first try's population.
        try_population: usize,
        /// The tries by population (`fit --json`'s `try_sizes`: a list of
        /// dicts with `population` and `tries`).
        try_sizes: Py<PyAny>,
        /// How far the tries agree, `fit --json`'s `agreement` (`tries`,
        /// `agreeing`, `other_basins`, `diverged`, `threshold`); `None` for a
        /// single try. Few of many agreeing: run a larger population.
        agreement: Option<Py<PyAny>>,
        /// A generalized fit's refining rounds, `fit --json`'s `refining`
        /// (`rounds`, `cut_tries`, `largest_last_gain`); `None` for a family
        /// that is not refined.
        refining: Option<Py<PyAny>>,
        /// Each parameter's standard error on the estimation half, by name
        /// (`fit --json`'s `std_errors`; `None` where held, `inf` where the
        /// record does not determine it at all): a lower bound, since a free
        /// run's residuals are correlated.
        std_errors: Py<PyDict>,
        /// The parameters whose standard error is at least their own size,
        /// an infinite one included (`fit --json`'s `undetermined`).
        undetermined: Vec<String>,
        /// The search coordinates along which a step of a thousandth makes the
        /// estimation free run diverge (`fit --json`'s `diverging_probes`).
        diverging_probes: Vec<String>,
        /// Candidates scored, every stage and try together.
        evaluations: u64,
        /// Generations of the population stages run.
        generations: usize,
        /// Wall time of the fit (s).
        seconds: f64,
        /// Where populations were scored.
        backend: String,
        /// `classic` or `generalized`.
        family: String,
        /// The effect stages fitted after the family, in chain order.
        effects: Vec<String>,
        /// The population search's update rule that ran: `de`, `ga`, `mfa` or
        /// `pso` (`algo`).
        algo: String,
        /// `joint` or `thesis`.
        flow: String,
        /// `allow` or `refuse`: whether loops whose update overshoots were
        /// admitted (`overshoot`).
        overshoot: String,
        /// The seed every random draw of the fit came from.
        seed: u64,
        /// Candidates a generation scores, all tries together (`pop`).
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
        /// The box searched: `names`, `lower`, `upper` (after widening), and each
        /// bound's `origin` (`data`, `class` or `user`).
        search_box: Py<PyDict>,
        /// One entry per generation and polish start: arrays `generation`,
        /// `stage`, `horizon` (0 for the free run), `evaluations`, `seconds`,
        /// `best_sse`, `stage_best`, `generation_best_sse`, `mean_sse`,
        /// `std_sse` (NaN where none), `diverged`, and `params` (rows of the
        /// stage's best canonical parameters, named by `names`).
        history: Py<PyDict>,
    }
}

impl FitResult {
    /// `__repr__`'s text.
    fn repr(&self, _py: Python<'_>) -> PyResult<String> {
        Ok(format!(
            "FitResult({} {} fit, val_fit_percent = {}, sse = {}, stop = {}, {:.2} s)",
            self.algo,
            self.family,
            self.val_fit_percent
                .map_or("None".to_string(), |v| format!("{v:.4}")),
            self.sse,
            self.stop,
            self.seconds
        ))
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

/// `value` as the Python value its JSON reads as.
fn unbound(py: Python<'_>, value: &impl serde::Serialize) -> PyResult<Py<PyAny>> {
    Ok(to_python(py, value)?.unbind())
}

/// Fits a hysteresis model to one experiment with the staged engine of
/// `mckibben fit`, its defaults and its edge rule: the same parameters, bit
/// for bit, for the same data, settings and seed, on any backend. A list
/// `u` of experiments (each a `Trace` or a `(u, y, dt)` tuple) fits one
/// model to all, as `mckibben fit a.csv b.csv`.
#[pyfunction]
#[pyo3(signature = (
    u, y = None, dt = None, model = None, effects = None, algo = "de", pop = None,
    gens = None, seed = 1, backend = "cpu", bounds = None, progress = None, *,
    free_n = false, r#loop = "bounded", switch = None, overshoot = None, thesis_flow = false,
    target_sse = None, time_budget = None, stall = None, start = None, carry = None,
    refine_rounds = None
))]
#[allow(clippy::too_many_arguments)]
pub fn fit(
    py: Python<'_>,
    u: &Bound<'_, PyAny>,
    y: Option<&Bound<'_, PyAny>>,
    #[pyo3(from_py_with = named::dt_opt)] dt: Option<f64>,
    #[pyo3(from_py_with = named::family_opt)] model: Option<&str>,
    #[pyo3(from_py_with = named::effects)] effects: Option<Vec<Effect>>,
    #[pyo3(from_py_with = named::algo)] algo: &str,
    #[pyo3(from_py_with = named::pop)] pop: Option<usize>,
    #[pyo3(from_py_with = named::gens)] gens: Option<usize>,
    #[pyo3(from_py_with = named::seed_arg)] seed: u64,
    #[pyo3(from_py_with = named::backend)] backend: &str,
    #[pyo3(from_py_with = named::bounds)] bounds: Option<Vec<UserBound>>,
    progress: Option<Py<PyAny>>,
    #[pyo3(from_py_with = named::free_n)] free_n: bool,
    #[pyo3(from_py_with = named::loop_shape)] r#loop: &str,
    #[pyo3(from_py_with = named::switch)] switch: Option<&str>,
    #[pyo3(from_py_with = named::overshoot)] overshoot: Option<&str>,
    #[pyo3(from_py_with = named::thesis_flow)] thesis_flow: bool,
    #[pyo3(from_py_with = named::target_sse)] target_sse: Option<f64>,
    #[pyo3(from_py_with = named::time_budget)] time_budget: Option<f64>,
    #[pyo3(from_py_with = named::stall)] stall: Option<usize>,
    start: Option<&Bound<'_, PyAny>>,
    carry: Option<&Bound<'_, PyAny>>,
    #[pyo3(from_py_with = named::refine_rounds)] refine_rounds: Option<usize>,
) -> PyResult<FitResult> {
    let Experiments {
        traces,
        read,
        listed,
    } = experiments(u, y, dt)?;
    let traces = &traces[..];
    let refused = |e: anyhow::Error| match &listed {
        Some(records) => located(e, &[records]),
        None => value_error(e),
    };
    // As `fit --from`: the start's family, effects and bounds unless given
    // here (the bounds given here after the file's, so that they win). As
    // `fit --carry`: the carried model's family and effects, its dynamics
    // held, no warm start.
    if start.is_some() && carry.is_some() {
        return Err(PyValueError::new_err(
            "start and carry: a fit either starts from a model or carries its chain",
        ));
    }
    // As `fit --carry` refuses `--model` and `--effects`.
    if carry.is_some() {
        let given = [("model", model.is_some()), ("effects", effects.is_some())];
        if let Some((name, _)) = given.iter().find(|g| g.1) {
            return Err(PyValueError::new_err(format!(
                "carry and {name}: a carried chain keeps its model's family and effects; \
                 leave {name} out"
            )));
        }
    }
    let (start, carried) = (
        start.map(|s| model_arg(s, "start")).transpose()?,
        carry.map(|s| model_arg(s, "carry")).transpose()?,
    );
    // `None`: the search, the default; a value the classic family lacks is
    // an error below, once the start's family is known.
    let asked = switch.map(switching).transpose()?;
    let request = FitRequest {
        family: model.map(|m| family(m, "model")).transpose()?,
        effects,
        free_n,
        loop_shape: loop_shape(r#loop)?,
        switching: asked,
        overshoot: overshoot.map(overshoot_rule).transpose()?,
        bounds: bounds.unwrap_or_default(),
        carry: carried.is_some(),
    };
    let which = if carried.is_some() { "carry" } else { "start" };
    // As `fit --from`: a model fitted in other units of the same kinds as
    // the records' (psi for kPa, mm for m) is read in theirs, its recorded
    // bounds too, with a warning.
    let given = match (start.as_ref().or(carried.as_ref()), traces.first()) {
        (Some(file), Some(first)) => {
            let (file, notes) = file
                .in_units_of(first, "the start model")
                .map_err(|e| value_error(e.context(which)))?;
            for note in notes {
                py.import("warnings")?
                    .call_method1("warn", (in_python_terms(&note),))?;
            }
            Some(file)
        }
        (file, _) => file.cloned(),
    };
    let Resolved {
        what,
        start: start_model,
        carried,
    } = request
        .resolve(given.as_ref())
        .map_err(|e| value_error(e.context(which)))?;
    if let Some(model) = &carried {
        for trace in traces {
            model
                .check_data(trace)
                .map_err(|e| value_error(e.context("carry")))?;
        }
    }
    if let Some(why) = switching_misapplied(what.family, asked) {
        return Err(PyValueError::new_err(format!(
            "switch={why}: leave switch out, or fit model=\"generalized\""
        )));
    }
    if let Some(why) = switching_boxed(asked, &request.bounds) {
        return Err(PyValueError::new_err(format!(
            "switch={why} in bounds: give one of them"
        )));
    }
    if let Some(p) = progress.as_ref()
        && !p.bind(py).is_callable()
    {
        return Err(pyo3::exceptions::PyTypeError::new_err(
            "progress must be callable: it is called with each generation's record (a dict)",
        ));
    }
    let settings = FitSettings {
        algo: algorithm(algo)?,
        pop: pop.unwrap_or(POPULATION),
        gens: gens.unwrap_or(GENERATIONS),
        seed,
        thesis_flow,
        islands: None,
        horizon: None,
        refine_rounds,
        overrides: Overrides::default(),
        stops: StopRules {
            target_sse,
            time_budget_s: time_budget,
            stall_generations: stall,
            stall_tolerance: 0.0,
        },
    };
    let backend = self::backend(backend)?;
    let notes = Mutex::new(Vec::new());
    let note = |s: String| notes.lock().expect("notes").push(s);
    let fit = py
        .detach(|| FitRun::new(traces, &what, &settings, start_model.as_ref(), None, &note))
        .map_err(refused)?;
    // With effects from scratch, a second start: the chain built one effect
    // at a time, as `mckibben fit --effects` does. Ctrl-C while it is built
    // raises `KeyboardInterrupt`: there is no fit yet to return.
    let stop = StopFlag::default();
    let fit = interruptible(py, &stop, || {
        with_chain_start(fit, traces, &settings, backend, stop.clone())
    })?
    .map_err(runtime_error)?;
    let finished = run_fit(py, fit, backend, progress)?;
    let Finished {
        fit,
        outcome,
        widened,
        describe,
    } = finished;
    let mut report = FitReport::of(&fit, (&outcome, &widened), &describe, traces);
    // What `fit` prints on stderr and `fit --json` holds as `notes`: the
    // notes before the run, then the report's own, each a `UserWarning`.
    let after = report.after_notes(fit.start_scores());
    let early = notes
        .into_inner()
        .expect("notes")
        .into_iter()
        .map(Note::plain);
    report.notes = early
        .chain(after)
        .map(|n| Note {
            text: in_python_terms(&n.text),
            ..n
        })
        .collect();
    let warn = py.import("warnings")?;
    for n in &report.notes {
        warn.call_method1("warn", (&n.text,))?;
    }
    if outcome.evaluations == 0 {
        // Stopped before a score: nothing diverged, nothing was tried.
        warn.call_method1(
            "warn",
            (format!(
                "{}: the result holds no model (`model` is None)",
                fit.unscored(outcome.stop)
            ),),
        )?;
    } else if outcome.params.is_empty() {
        // The command's error, as a warning: the result still holds the
        // run's history and stages, which say where it failed.
        warn.call_method1(
            "warn",
            (
                "every candidate diverged: the result holds no model (`model` is None); check \
                 the data's units and columns, the values `bounds` hold, and whether a larger \
                 `pop` finds a stable candidate",
            ),
        )?;
    }
    fit_result(py, report, &fit, &outcome, &what, traces, &read)
}

/// A fit run to its end: the run, what it ended at, the edge rule's
/// widenings, and the evaluator that scored it, for the report.
struct Finished {
    fit: FitRun,
    outcome: Outcome,
    widened: Vec<Widening>,
    describe: String,
}

/// Runs `fit` on `backend` with the interpreter detached, Python's
/// `progress` seeing each generation and Ctrl-C stopping the fit at its
/// best so far. Raises an exception `progress` raised, and a signal's
/// other than `KeyboardInterrupt`, once the fit has stopped.
fn run_fit(
    py: Python<'_>,
    fit: FitRun,
    backend: Backend,
    progress: Option<Py<PyAny>>,
) -> PyResult<Finished> {
    let interrupt = AtomicBool::new(false);
    let mut observer = PythonObserver {
        progress,
        interrupt: &interrupt,
        error: None,
    };
    let (fit, ran, describe) = py
        .detach(|| {
            let mut evaluator = mckibben::eval::open(backend)?;
            let describe = evaluator.describe();
            let mut fit = fit;
            let ran = fit.run(
                evaluator.as_mut(),
                &mut [&mut observer],
                Some(&interrupt),
                None,
            )?;
            anyhow::Ok((fit, ran, describe))
        })
        .map_err(runtime_error)?;
    if let Some(e) = observer.error.take() {
        return Err(e);
    }
    // A Ctrl-C during the edge rule's refit, which the engine does not
    // stop for, comes too late to stop anything: the fit is done.
    if let Err(e) = py.check_signals()
        && !e.is_instance_of::<PyKeyboardInterrupt>(py)
    {
        return Err(e);
    }
    let (outcome, widened) = ran;
    Ok(Finished {
        fit,
        outcome,
        widened,
        describe,
    })
}

/// The fit's `report` as Python values: the fitted model (built within
/// `what`'s bounds, its provenance naming the data `traces` were read from),
/// the parameters and the box by name, and the history as arrays.
fn fit_result(
    py: Python<'_>,
    report: FitReport,
    fit: &FitRun,
    outcome: &Outcome,
    what: &FitTarget,
    traces: &[mckibben::data::Trace],
    read: &ReadSettings,
) -> PyResult<FitResult> {
    let (problem, engine) = (&fit.problem, &fit.engine);
    let params = PyDict::new(py);
    for (name, v) in &report.params.0 {
        params.set_item(name, v)?;
    }
    let units = PyDict::new(py);
    for (name, u) in &report.units.0 {
        units.set_item(name, u)?;
    }
    // Built here, not through the JSON: an infinite error stays `inf`
    // rather than the JSON's `null`, which would read as held.
    let std_errors = PyDict::new(py);
    for (name, e) in &report.std_errors.0 {
        std_errors.set_item(name, e)?;
    }
    let search_box = PyDict::new(py);
    search_box.set_item("names", &report.search_box.names)?;
    search_box.set_item("lower", PyArray1::from_slice(py, &report.search_box.lower))?;
    search_box.set_item("upper", PyArray1::from_slice(py, &report.search_box.upper))?;
    // Where each bound came from, as `fit --json` says: `data`, `class`
    // or `user` for each `[lower, upper]`.
    search_box.set_item("origin", to_python(py, &report.search_box.origin)?)?;
    let model = if outcome.params.is_empty() {
        None
    } else {
        let file = model_file(
            problem,
            &outcome.params,
            &what.bounds,
            provenance(
                "mckibben.fit",
                &traces.iter().map(|t| t.source.as_str()).collect::<Vec<_>>(),
                read,
                Some(engine.seed),
            ),
        );
        Some(Py::new(py, Model::of_file(file).map_err(runtime_error)?)?)
    };
    let names = problem.model.param_names();
    let names: Vec<&str> = names.iter().map(|n| n.as_str()).collect();
    Ok(FitResult {
        model,
        params: params.unbind(),
        units: units.unbind(),
        sse: report.sse.unwrap_or(f64::INFINITY),
        val_rmse: report.val_rmse,
        val_fit_percent: report.val_fit_percent,
        linear_val_fit_percent: report.linear_val_fit_percent,
        linear_largest_pole: report.linear_largest_pole,
        records: unbound(py, &report.records)?,
        columns: unbound(py, &report.columns)?,
        notes: unbound(py, &report.notes)?,
        stable_step: report.stable_step,
        largest_step: report.largest_step,
        start_sse: report.start_sse,
        start_val_fit_percent: report.start_val_fit_percent,
        built: report.built.map(|b| unbound(py, &b)).transpose()?,
        switching: report.switching.map(|s| unbound(py, &s)).transpose()?,
        tries: report.tries,
        try_population: report.try_population,
        try_sizes: unbound(py, &report.try_sizes)?,
        agreement: report
            .agreement
            .as_ref()
            .map(|a| unbound(py, a))
            .transpose()?,
        refining: report.refining.map(|r| unbound(py, &r)).transpose()?,
        std_errors: std_errors.unbind(),
        undetermined: report.undetermined.clone(),
        diverging_probes: report.diverging_probes.clone(),
        evaluations: report.evaluations,
        generations: report.generations,
        seconds: report.seconds,
        backend: report.backend.clone(),
        family: report.model.name().to_string(),
        effects: report.effects.clone(),
        algo: report.algo.to_string(),
        flow: to_python(py, &report.flow)?.extract()?,
        overshoot: to_python(py, &report.overshoot)?.extract()?,
        seed: report.seed,
        population: report.population,
        stop: to_python(py, &report.stop)?.extract()?,
        interrupted: report.stop == StopReason::Interrupted,
        stages: unbound(py, &report.stages)?,
        on_edge: unbound(py, &report.on_edge)?,
        widened: unbound(py, &report.widened)?,
        search_box: search_box.unbind(),
        history: history_arrays(py, &engine.history, &names)?.unbind(),
    })
}
