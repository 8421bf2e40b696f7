//! `mckibben.diagnose`: the library's diagnosis, its `--json` document as
//! Python objects and its models as `Model`s.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use mckibben::diagnose::report::{DiagnosisJson, baseline_caution, plain_fit_caution};
use mckibben::diagnose::transfer::check_others;
use mckibben::diagnose::{Effect, Settings};
use mckibben::model::ModelFile;
use mckibben::report::json::Versioned;

use crate::args::family_or_start;
use crate::convert::{backend, in_python_terms, to_python, value_error};
use crate::data::{located, placed, traces};
use crate::interrupt::interruptible;
use crate::model::model_arg;
use crate::model::{Model, provenance};
use crate::named;

crate::state::with_state! {
    /// What `mckibben.diagnose` returns: the document `mckibben diagnose
    /// --json` prints and the models `diagnose --out` writes.
    #[pyclass(module = "mckibben", frozen, get_all)]
    pub struct Diagnosis {
        /// The `--json` document (docs/JSON.md), as dicts and lists.
        document: Py<PyAny>,
        /// The final model: the baseline with the effects the diagnosis kept
        /// (`--out`'s `model.json`).
        model: Py<Model>,
        /// The baseline alone, fitted on the same data (`--out`'s `baseline.json`).
        baseline: Py<Model>,
    }
}

impl Diagnosis {
    /// `__repr__`'s text.
    fn repr(&self, _py: Python<'_>) -> PyResult<String> {
        let model = self.model.get();
        let names: Vec<&str> = model.inner.effects().iter().map(|e| e.name()).collect();
        Ok(format!(
            "Diagnosis({} + [{}])",
            model.inner.base.family,
            names.join(", ")
        ))
    }
}

/// Diagnoses the sim-to-real gap of a `baseline` model on `datasets` (each
/// fitted on its first half; every choice made on the selection blocks of
/// its second half, the test blocks read once the model is final;
/// `blocks` as `--blocks`), as `mckibben diagnose` does: where the model
/// misses, which effects of the catalogue (`effects`, default the
/// command's) explain it, how far the gap shrinks. With `start` (a `Model`
/// or a model file's path), the selection starts from that model, as
/// `diagnose --from`; with `transfer` (datasets), the chain is fitted on
/// each of them as `--transfer` does (one sampled otherwise, in other
/// units, or holding the samples of one of `datasets` raises `ValueError`
/// before the diagnosis runs); with `repeat` K, the whole
/// diagnosis runs from K seeds as `--repeat` does (`document["repeats"]`).
/// Returns the document
/// `mckibben diagnose --json` prints, as dicts and lists, and the final
/// and baseline models as `Model`s. Ctrl-C stops it within a generation
/// or polish iteration and raises `KeyboardInterrupt`.
#[pyfunction]
#[pyo3(signature = (datasets, baseline = None, effects = None, seed = 1, seeds = None, generations = None, scratch_seeds = None, backend = "cpu", max_effects = None, start = None, blocks = None, transfer = None, repeat = 1))]
#[allow(clippy::too_many_arguments)]
pub fn diagnose<'py>(
    py: Python<'py>,
    datasets: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = named::baseline)] baseline: Option<&str>,
    #[pyo3(from_py_with = named::effects)] effects: Option<Vec<Effect>>,
    #[pyo3(from_py_with = named::seed_arg)] seed: u64,
    #[pyo3(from_py_with = named::seeds)] seeds: Option<usize>,
    #[pyo3(from_py_with = named::generations)] generations: Option<usize>,
    #[pyo3(from_py_with = named::scratch_seeds)] scratch_seeds: Option<usize>,
    #[pyo3(from_py_with = named::backend)] backend: &str,
    #[pyo3(from_py_with = named::max_effects)] max_effects: Option<usize>,
    start: Option<&Bound<'py, PyAny>>,
    #[pyo3(from_py_with = named::blocks)] blocks: Option<usize>,
    transfer: Option<&Bound<'py, PyAny>>,
    #[pyo3(from_py_with = named::repeat)] repeat: usize,
) -> PyResult<Diagnosis> {
    let records = traces(datasets, "datasets")?;
    let transfers = transfer.map(|t| self::traces(t, "transfer")).transpose()?;
    let (traces, read) = (&records.traces, &records.read);
    let others = transfers.as_ref().map_or(&[][..], |r| &r.traces[..]);
    if let Some(note) = mckibben::diagnose::assumed_unit_note(traces) {
        py.import("warnings")?
            .call_method1("warn", (in_python_terms(&note),))?;
    }
    let defaults = Settings::default();
    let seeds = seeds.unwrap_or(defaults.seeds);
    let generations = generations.unwrap_or(defaults.generations);
    let scratch_seeds = scratch_seeds.unwrap_or(defaults.scratch_seeds);
    let max_effects = max_effects.unwrap_or(defaults.max_effects);
    let start = start
        .map(|s| model_arg(s, "start"))
        .transpose()?
        .map(|f| f.model())
        .transpose()
        .map_err(value_error)?;
    // A model fitted in other units of the same kinds as the records'
    // (psi for kPa, mm for m) is read in theirs, with a warning each.
    let start = match (start, traces.first()) {
        (Some(m), Some(first)) => {
            let (m, notes) = m.in_units_of(first, "the start model");
            for note in notes {
                py.import("warnings")?
                    .call_method1("warn", (in_python_terms(&note),))?;
            }
            Some(m)
        }
        (start, _) => start,
    };
    let family = family_or_start(("baseline", baseline), start.as_ref())?;
    // An empty list is no request for the catalogue: the CLI has no way to
    // say it, and `fit`'s `effects=[]` means none.
    let effects = match effects {
        Some(e) if e.is_empty() => {
            return Err(PyValueError::new_err(
                "effects=[] names no effect to try: leave it out (None) for the default \
                 catalogue, or pass max_effects=0 for the baseline alone",
            ));
        }
        Some(e) => e,
        None => Effect::by_default(),
    };
    let settings = Settings {
        seeds,
        generations,
        scratch_seeds,
        max_effects,
        seed,
        backend: self::backend(backend)?,
        blocks,
        ..defaults
    };
    // Before the diagnosis, so that a record the chain cannot be carried to
    // fails at once, named by its place in `transfer`.
    for (other, place) in transfers.iter().flat_map(|r| r.placed("transfer")) {
        check_others(family, traces, std::slice::from_ref(other), &settings)
            .map_err(|e| placed(e.root_cause().to_string(), other, place))?;
    }
    let d = interruptible(py, &settings.stop, || {
        let mut d =
            mckibben::diagnose::diagnose_from(traces, family, &effects, &settings, start.as_ref())?;
        if !others.is_empty() {
            d.transfers = mckibben::diagnose::transfer::transfer(&d, others, &settings)?;
        }
        d.repeats = mckibben::diagnose::seeds::repeat(
            &d,
            traces,
            &effects,
            &settings,
            start.as_ref(),
            repeat,
            &mut |_| (),
        )?;
        Ok(d)
    })?
    .map_err(|e| {
        located(
            e,
            &[&records].into_iter().chain(&transfers).collect::<Vec<_>>(),
        )
    })?;
    // The report's CAUTION, where a Python user sees it.
    if let Some(caution) = baseline_caution(&d) {
        let warn = py.import("warnings")?;
        warn.call_method1(
            "warn",
            (format!(
                "{caution}; a Trace's output name is its column's: Trace(u, y, dt, output_name=\"x_m\")"
            ),),
        )?;
    }
    // The report's other CAUTION: `fit`'s own baseline beats the diagnosis',
    // which did not keep the gain when started from it.
    if let Some(caution) = plain_fit_caution(&d) {
        py.import("warnings")?.call_method1("warn", (caution,))?;
    }
    let sources: Vec<&str> = traces.iter().map(|t| t.source.as_str()).collect();
    let model = |m: &mckibben::model::Model| {
        let file = ModelFile::new(
            m,
            None,
            provenance("mckibben.diagnose", &sources, read, Some(settings.seed)),
        );
        Py::new(py, Model::of_file(file).map_err(value_error)?)
    };
    Ok(Diagnosis {
        document: to_python(py, &Versioned::new(DiagnosisJson::of(&d)))?.unbind(),
        model: model(&d.final_model)?,
        baseline: model(&d.baseline_model)?,
    })
}
