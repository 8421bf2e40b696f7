//! `mckibben.control`: closed-loop tracking on the rig twin, the call
//! `mckibben control` makes without `--plant`, its `--json` document and
//! each run's samples.

use std::sync::Mutex;

use numpy::ToPyArray;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};

use mckibben::control::session::{self, ControlPlan};
use mckibben::control::sweep::{DesignColumns, GivenModel, Kind};
use mckibben::control::{MpcSettings, PiGains};
use mckibben::report::json::Versioned;

use crate::args::{names, path, real};
use crate::convert::{given, in_python_terms, to_python, value_error};
use crate::interrupt::interruptible;
use crate::model::{Model, model_arg};
use crate::named;
use crate::twin::effect_settings;

crate::state::with_state! {
    /// What `mckibben.control` returns: the document `mckibben control
    /// --json` prints and each run's samples.
    #[pyclass(module = "mckibben", frozen, get_all)]
    pub struct ControlResult {
        /// The `--json` document (docs/JSON.md): settings, design, tuned
        /// gains, one row a run, the robustness rows.
        document: Py<PyAny>,
        /// One dict a run, in the order of `document["runs"]`: its
        /// controller, frequency, load and hysteresis scale, and the
        /// arrays `t`, `reference`, `displacement`, `pressure` and `valve`
        /// (the columns `control --csv` writes).
        runs: Py<PyList>,
    }
}

impl ControlResult {
    /// `__repr__`'s text.
    fn repr(&self, py: Python<'_>) -> PyResult<String> {
        Ok(format!("ControlResult({} runs)", self.runs.bind(py).len()))
    }
}

/// Tracks the reference with each controller on the rig twin, as
/// `mckibben control` does without `--plant`: `controller` (`"pi"`,
/// `"pi-tuned"`, `"ff-pid"`, `"mpc"`, or a list) at each `freq` (rad/s)
/// under each `load` (kg). The model-based controllers identify their model
/// on the twin's design multisine at `design_load`, or from `design_data`
/// (a record's path; its columns `design_columns`), or take the
/// displacement model `model` (a `Model` or a model file's path). Returns
/// the `--json` document and each run's samples; every warning the command
/// prints is a `UserWarning`.
#[pyfunction]
#[pyo3(signature = (
    controller = None, freq = None, load = None, *, seed = 1, model = None,
    design_data = None, design_columns = None, design_load = None,
    hysteresis_scale = None, robustness = false, tuned_gains = None,
    algo = None, pop = None, gens = None, horizon = None, r_move = None,
    reference = "sine", warmup = None, duration = None, steady_from = None,
    effects = None,
))]
#[allow(clippy::too_many_arguments)]
pub fn control<'py>(
    py: Python<'py>,
    controller: Option<&Bound<'py, PyAny>>,
    freq: Option<&Bound<'py, PyAny>>,
    load: Option<&Bound<'py, PyAny>>,
    #[pyo3(from_py_with = named::seed_arg)] seed: u64,
    model: Option<&Bound<'py, PyAny>>,
    design_data: Option<&Bound<'py, PyAny>>,
    design_columns: Option<&Bound<'py, PyAny>>,
    #[pyo3(from_py_with = named::design_load)] design_load: Option<f64>,
    hysteresis_scale: Option<&Bound<'py, PyAny>>,
    #[pyo3(from_py_with = named::robustness)] robustness: bool,
    tuned_gains: Option<&Bound<'py, PyAny>>,
    #[pyo3(from_py_with = named::algo_opt)] algo: Option<&str>,
    #[pyo3(from_py_with = named::pop)] pop: Option<usize>,
    #[pyo3(from_py_with = named::gens)] gens: Option<usize>,
    #[pyo3(from_py_with = named::horizon)] horizon: Option<usize>,
    #[pyo3(from_py_with = named::r_move)] r_move: Option<f64>,
    #[pyo3(from_py_with = named::reference)] reference: &str,
    #[pyo3(from_py_with = named::warmup)] warmup: Option<f64>,
    #[pyo3(from_py_with = named::duration)] duration: Option<f64>,
    #[pyo3(from_py_with = named::steady_from)] steady_from: Option<f64>,
    effects: Option<&Bound<'py, PyAny>>,
) -> PyResult<ControlResult> {
    let defaults = ControlPlan::default();
    let kinds = match controller {
        Some(c) => one_or_many(c, "controller", |item, what| {
            let name = crate::args::text(item, what)?;
            name.parse::<Kind>()
                .map_err(|e| PyValueError::new_err(e.to_string()))
        })?,
        None => defaults.kinds.clone(),
    };
    let numbers = |obj: Option<&Bound<'py, PyAny>>, what: &str, default: &[f64]| match obj {
        Some(o) => one_or_many(o, what, |item, what| real(item, what)),
        None => Ok(default.to_vec()),
    };
    let notes: Mutex<Vec<String>> = Mutex::new(Vec::new());
    let note = |s: String| notes.lock().expect("notes").push(s);
    let design_columns = design_columns
        .map(|c| {
            let names = names(c, "design_columns")?;
            DesignColumns::from_names(&names).map_err(value_error)
        })
        .transpose()?
        .unwrap_or_default();
    let tuned_gains = tuned_gains.map(gains).transpose()?;
    let shape = defaults.shape;
    let mut plan = ControlPlan {
        kinds,
        freqs: numbers(freq, "freq", &defaults.freqs)?,
        loads: numbers(load, "load", &defaults.loads)?,
        hysteresis_scales: numbers(hysteresis_scale, "hysteresis_scale", &[])?,
        robustness,
        design_record: design_data.map(|d| path(d, "design_data")).transpose()?,
        design_columns,
        model: None,
        design_load_kg: design_load.unwrap_or(defaults.design_load_kg),
        tuned_gains,
        algo: algo.map_or(defaults.algo.clone(), str::to_string),
        pop: pop.unwrap_or(defaults.pop),
        gens: gens.unwrap_or(defaults.gens),
        mpc: MpcSettings {
            horizon: horizon.unwrap_or(defaults.mpc.horizon),
            r_move: r_move.unwrap_or(defaults.mpc.r_move),
            ..MpcSettings::default()
        },
        shape: mckibben::control::sweep::Shape {
            warmup_s: warmup.unwrap_or(shape.warmup_s),
            duration_s: duration.unwrap_or(shape.duration_s),
            steady_from_s: steady_from.unwrap_or(shape.steady_from_s),
            waveform: reference
                .parse()
                .map_err(|e: mckibben::names::UnknownName| PyValueError::new_err(e.to_string()))?,
        },
        effects: effects
            .map(effect_settings)
            .transpose()?
            .unwrap_or_default(),
        seed,
        stop: Default::default(),
    };
    let warn = py.import("warnings")?;
    let say = |text: &str| {
        warn.call_method1("warn", (in_python_terms(text),))
            .map(|_| ())
    };
    for text in plan.unread(model.map(|_| "`model`")) {
        say(&text)?;
    }
    // Read only where a controller reads it, as `control --from`.
    if plan.designs() {
        plan.model = model.map(|m| given_model(m, &note)).transpose()?;
    }
    // Ctrl-C stops the call between two runs, or in the tuning between
    // two generations, and raises KeyboardInterrupt.
    let outcome = interruptible(py, &plan.stop, || plan.on_twin(&|_| (), &note))?;
    // The notes as the command prints them, before the run's error too.
    for text in notes.into_inner().expect("notes") {
        say(&text)?;
    }
    let outcome = outcome.map_err(value_error)?;
    for text in session::warnings(&outcome.rows, &outcome.runs) {
        say(&text)?;
    }
    let runs = PyList::empty(py);
    for (row, run) in outcome.rows.iter().zip(&outcome.runs) {
        let r = &run.result;
        let d = PyDict::new(py);
        d.set_item("controller", &row.controller)?;
        d.set_item("freq_rad_s", row.freq_rad_s)?;
        d.set_item("load_kg", row.load_kg)?;
        d.set_item("hysteresis_scale", row.hysteresis_scale)?;
        d.set_item("t", r.t.to_pyarray(py))?;
        d.set_item("reference", r.reference.to_pyarray(py))?;
        d.set_item("displacement", r.displacement.to_pyarray(py))?;
        d.set_item("pressure", r.pressure.to_pyarray(py))?;
        d.set_item("valve", r.valve.to_pyarray(py))?;
        runs.append(d)?;
    }
    Ok(ControlResult {
        document: to_python(py, &Versioned::new(outcome.json(&plan)))?.unbind(),
        runs: runs.unbind(),
    })
}

/// One item, or a list (a tuple, an array) of them, each converted by
/// `convert` under the name `what` (`what[i]` for a list's).
fn one_or_many<'py, T>(
    obj: &Bound<'py, PyAny>,
    what: &str,
    convert: impl Fn(&Bound<'py, PyAny>, &str) -> PyResult<T>,
) -> PyResult<Vec<T>> {
    if obj.is_instance_of::<PyString>() || obj.try_iter().is_err() {
        return Ok(vec![convert(obj, what)?]);
    }
    obj.try_iter()?
        .enumerate()
        .map(|(i, item)| convert(&item?, &format!("{what}[{i}]")))
        .collect()
}

/// `tuned_gains`: three numbers kp, ki, kd, or a dict of them by name (a
/// tuning's `document["tuned"]["gains"]`).
fn gains(obj: &Bound<'_, PyAny>) -> PyResult<PiGains> {
    let wrong = || {
        PyTypeError::new_err(format!(
            "tuned_gains must be three numbers (kp, ki, kd) or a dict of them by name, got {}",
            given(obj)
        ))
    };
    if let Ok(d) = obj.cast::<PyDict>() {
        let gain = |name: &str| match d.get_item(name)? {
            Some(v) => real(&v, &format!("tuned_gains[{name:?}]")),
            None => Err(wrong()),
        };
        return Ok(PiGains {
            kp: gain("kp")?,
            ki: gain("ki")?,
            kd: gain("kd")?,
        });
    }
    if obj.is_instance_of::<PyString>() {
        return Err(wrong());
    }
    let items: Vec<Bound<'_, PyAny>> = obj.extract().map_err(|_| wrong())?;
    let [kp, ki, kd] = &items[..] else {
        return Err(wrong());
    };
    Ok(PiGains {
        kp: real(kp, "tuned_gains[0]")?,
        ki: real(ki, "tuned_gains[1]")?,
        kd: real(kd, "tuned_gains[2]")?,
    })
}

/// `model`: a `Model`, or a model file's path, checked as `control --from`
/// checks its file.
fn given_model(obj: &Bound<'_, PyAny>, note: &dyn Fn(String)) -> PyResult<GivenModel> {
    let file = model_arg(obj, "model")?;
    let m = file.model().map_err(value_error)?;
    let (named, source) = match obj.cast::<Model>() {
        Ok(_) => ("model".to_string(), "a Model (Python)".to_string()),
        Err(_) => {
            let p = path(obj, "model")?;
            (format!("model {}", p.display()), p.display().to_string())
        }
    };
    GivenModel::checked(m, named, source, note).map_err(value_error)
}
