//! Batch evaluation: the fitness (SSE) of a whole population of candidate
//! parameter vectors on one or more experiments.
//!
//! Population layout: row-major `N × d`, each row a canonical parameter
//! vector of the problem's [`Family`] (see [`Family::params`]). Rows are
//! converted to `f32` the same way on every backend, so that backends agree.

pub mod agreement;
mod batch;
pub mod cpu;
pub mod effects;
pub mod gpu;
pub mod workload;

use crate::model::effects::{Context, Effect, ModelDescription};
use crate::model::{Experiment, Family, Measure};
use crate::search::{Params, Rows};

/// What is scored: a model family against one or more experiments (e.g. two
/// loads), each in deviation coordinates, under a measure (the free run's
/// error, or a multi-step-ahead prediction's).
///
/// The model is a description: a baseline family and an ordered chain of
/// effect stages ([`crate::model::effects`], empty for the plain family),
/// from which every backend builds its batch kernel. Effects need each
/// experiment's constants (its [`Context`]); experiment `e` is dataset `e`
/// of the effects (the `load` effect's gain per dataset).
#[derive(Debug, Clone)]
pub struct Problem {
    pub family: Family,
    pub effects: Vec<Effect>,
    /// One per experiment when there are effects; empty otherwise.
    pub contexts: Vec<Context>,
    pub experiments: Vec<Experiment>,
    pub measure: Measure,
}

impl Problem {
    /// The free-run problem (the thesis' fitness, eq. 29).
    pub fn new(family: Family, experiments: Vec<Experiment>) -> Self {
        Problem {
            family,
            effects: Vec::new(),
            contexts: Vec::new(),
            experiments,
            measure: Measure::FreeRun,
        }
    }

    /// The same problem with effect stages after the family, `contexts`
    /// holding each experiment's constants.
    pub fn with_effects(mut self, effects: Vec<Effect>, contexts: Vec<Context>) -> Self {
        assert_eq!(
            contexts.len(),
            self.experiments.len(),
            "one effect context per experiment"
        );
        self.effects = effects;
        self.contexts = contexts;
        self
    }

    /// The model scored: the family and its effect stages.
    pub fn model(&self) -> ModelDescription {
        ModelDescription::new(self.family, self.effects.clone(), self.experiments.len())
    }

    /// Parameters per candidate.
    pub fn dim(&self) -> usize {
        if self.effects.is_empty() {
            self.family.dim()
        } else {
            self.model().dim()
        }
    }

    /// The rows of `flat` as candidates of this problem (panics unless it
    /// holds whole rows of [`Problem::dim`]).
    pub fn rows<'a>(&self, flat: &'a [f64]) -> Rows<'a, Params> {
        Rows::new(flat, self.dim())
    }

    /// The same problem under another measure.
    pub fn with_measure(mut self, measure: Measure) -> Self {
        self.measure = measure;
        self
    }

    /// Total samples over all experiments.
    pub fn samples(&self) -> usize {
        self.experiments.iter().map(|e| e.len()).sum()
    }
}

/// SSE of every candidate: per experiment and summed.
#[derive(Debug, Clone, PartialEq)]
pub struct Scores {
    /// `per_experiment[e][i]`: SSE of candidate `i` on experiment `e`.
    pub per_experiment: Vec<Vec<f32>>,
    /// Sum over experiments, in experiment order, in `f32`; `+∞` if any diverged.
    pub total: Vec<f32>,
}

impl Scores {
    /// Builds the totals from per-experiment scores.
    pub fn from_per_experiment(per_experiment: Vec<Vec<f32>>) -> Scores {
        let n = per_experiment.first().map_or(0, |v| v.len());
        let total = (0..n)
            .map(|i| per_experiment.iter().fold(0.0f32, |acc, e| acc + e[i]))
            .collect();
        Scores {
            per_experiment,
            total,
        }
    }
}

/// Scores populations. Implementations keep their resources (threads,
/// device, buffers) across calls, so one evaluator serves a whole run.
pub trait Evaluator {
    /// Backend and device, for the user ("cpu, 2 threads", "gpu: NVIDIA H100").
    fn describe(&self) -> String;

    /// An evaluator of its own that gives the same numbers, for a search run
    /// beside others (a diagnosis fits its candidates side by side); `None`
    /// for a backend that holds one device, on which searches take turns.
    fn fork(&self) -> Option<Box<dyn Evaluator + Send>> {
        None
    }

    /// The GPU adapter that scores (name, kind, driver); `None` on the CPU.
    fn adapter(&self) -> Option<String> {
        None
    }

    /// Whether each call pays a round trip to a device, so that fewer,
    /// larger calls pay (a GPU), rather than costing its rows alone (the
    /// CPU). The polish then scores every start's points in one call a
    /// round (`optim::lm::levenberg_marquardt_lockstep`).
    fn round_trips(&self) -> bool {
        false
    }

    /// The device time of the last call's kernels alone (no upload,
    /// read-back or host work), where the device records timestamps;
    /// `None` on the CPU and on adapters without timestamp queries.
    fn kernel_seconds(&self) -> Option<f64> {
        None
    }

    /// The device's `f32` rate from the calibration kernel, timed by its
    /// clock (`gpu::calibration`); `None` on the CPU and on adapters
    /// without timestamp queries.
    fn calibrate(
        &mut self,
        sizing: gpu::calibration::Sizing,
    ) -> anyhow::Result<Option<gpu::calibration::Ceiling>> {
        let _ = sizing;
        Ok(None)
    }

    /// Scores `population`, whose rows must have `problem.dim()` entries.
    fn evaluate(
        &mut self,
        problem: &Problem,
        population: Rows<'_, Params>,
    ) -> anyhow::Result<Scores>;

    /// Starts scoring `population` as [`Evaluator::evaluate`] does, and
    /// returns before the scores are read where the work runs elsewhere (a
    /// device): the caller may do its own work meanwhile, then
    /// [`Evaluator::collect`]s them. The same scores, bit for bit. Where
    /// scoring is the caller's own threads' work (the CPU), it scores here.
    fn submit(
        &mut self,
        problem: &Problem,
        population: Rows<'_, Params>,
    ) -> anyhow::Result<Pending> {
        Ok(Pending::Scored(self.evaluate(problem, population)?))
    }

    /// The scores of a [`Evaluator::submit`] of this evaluator, once done;
    /// [`Evaluator::kernel_seconds`] then says its kernels' device time.
    fn collect(&mut self, pending: Pending) -> anyhow::Result<Scores> {
        match pending {
            Pending::Scored(scores) => Ok(scores),
            Pending::Device(_) => anyhow::bail!(
                "{}: asked for scores another evaluator submitted",
                self.describe()
            ),
        }
    }

    /// The errors `x(k) − y(k)` of every candidate under the problem's
    /// measure, `k ≥ 1` of each experiment in turn (what a
    /// Levenberg–Marquardt polish differentiates); `None` for a candidate
    /// whose simulation diverged. Bit-identical across backends where the
    /// scores are.
    fn residuals(
        &mut self,
        problem: &Problem,
        population: Rows<'_, Params>,
    ) -> anyhow::Result<Vec<Option<Vec<f32>>>>;
}

/// Scores on their way ([`Evaluator::submit`]).
pub enum Pending {
    /// Scored already.
    Scored(Scores),
    /// On a device, to be read back.
    Device(gpu::Queued),
}

/// A population must have the problem's parameters in every row.
fn check_dim(problem: &Problem, population: Rows<'_, Params>) -> anyhow::Result<()> {
    let d = problem.dim();
    anyhow::ensure!(
        population.dim() == d,
        "rows of {} values, but the {} model has {d} parameters",
        population.dim(),
        problem.family
    );
    Ok(())
}

/// Converts a row-major `f64` population to the `f32` rows every backend scores.
pub fn to_f32(population: &[f64]) -> Vec<f32> {
    population.iter().map(|&v| v as f32).collect()
}

/// Where populations are scored (`--backend`).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    clap::ValueEnum,
    serde::Serialize,
    serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    /// A real GPU (discrete or integrated adapter) if there is one, else the
    /// CPU: a CPU adapter such as lavapipe is slower than the batched CPU path.
    #[default]
    Auto,
    /// The batched, multi-threaded CPU evaluator.
    Cpu,
    /// The best adapter present, lavapipe included; an error if there is none.
    Gpu,
}

/// What `backend` resolves to on this machine: the CPU (with why, when
/// `auto` fell back to it) or a GPU adapter. The muscle models' evaluator
/// ([`open`]) and the benchmark oscillator's (`benchmark::evaluator::open`)
/// both choose by it.
pub enum Choice {
    Cpu { note: Option<String> },
    Gpu(wgpu::Adapter),
}

/// Resolves `backend`: `auto` takes a hardware GPU if there is one and
/// otherwise the CPU, saying why; `gpu` takes the best adapter, lavapipe
/// included, and is an error without one.
pub fn choose(backend: Backend) -> anyhow::Result<Choice> {
    Ok(match backend {
        Backend::Cpu => Choice::Cpu { note: None },
        Backend::Gpu => Choice::Gpu(gpu::host::best_adapter()?),
        Backend::Auto => match gpu::adapters().into_iter().next() {
            Some(adapter) if gpu::is_hardware(&adapter.get_info()) => Choice::Gpu(adapter),
            Some(a) => Choice::Cpu {
                note: Some(format!(
                    "no hardware GPU; {} is slower than the CPU path",
                    gpu::describe_adapter(&a.get_info())
                )),
            },
            None => Choice::Cpu {
                note: Some("no GPU adapter found".to_string()),
            },
        },
    })
}

/// Opens the evaluator `backend` asks for (`Send`, so a run may move it to a
/// worker thread). It prints nothing: the caller
/// reports [`Evaluator::describe`], which names the backend and adapter (and,
/// for `auto` falling back to the CPU, why).
pub fn open(backend: Backend) -> anyhow::Result<Box<dyn Evaluator + Send>> {
    Ok(match choose(backend)? {
        Choice::Cpu { note: None } => Box::new(cpu::CpuEvaluator::new()),
        Choice::Cpu { note: Some(why) } => Box::new(cpu::CpuEvaluator::with_note(why)),
        Choice::Gpu(adapter) => Box::new(gpu::GpuEvaluator::with_adapter(
            adapter,
            Default::default(),
        )?),
    })
}
