//! The GPU evaluator: one WGSL invocation per candidate (wgpu), run by the
//! project's one wgpu host (`host.rs`: adapters, device, pipelines, buffers,
//! chunked dispatch).
//!
//! A pipeline's WGSL is assembled from the model description
//! ([`shader_source`]: a generated header, `shaders/prologue.wgsl`, one file
//! per family, `driver.wgsl` or, with effect stages, `effects.wgsl`, and
//! `entry.wgsl`; with effect stages the header holds what `stages`
//! generates from the catalogue and its step order); it spells the
//! operations of `src/model/sim.rs` and `src/model/effects/` in the same
//! order. `tests/wgsl_variants.rs` validates every source it assembles
//! with naga, without a GPU. On an unfused f32
//! implementation (Mesa's lavapipe) the `n = 1` scores are bit-identical to
//! the CPU's; a real GPU may fuse `a·b + c` into an fma, so there compare
//! within a tolerance and compare rankings (`mckibben bench` reports both).

pub mod calibration;
pub mod host;
mod stages;

pub use host::{GpuOptions, adapters, describe_adapter, is_hardware};
use host::{Host, Kernel, Output, Submitted, best_adapter};
use rayon::prelude::*;

use super::{Evaluator, Pending, Problem, Scores, check_dim, to_f32};
use crate::model::Family;
use crate::model::effects::Context as EffectContext;
use crate::search::{Params, Rows};

/// The bindings every pipeline of the host declares (`host::Host`), the
/// muscle models' and the benchmark oscillator's (`benchmark::evaluator`).
pub const PROLOGUE: &str = include_str!("../../../shaders/prologue.wgsl");
const DRIVER: &str = include_str!("../../../shaders/driver.wgsl");
const EFFECTS: &str = include_str!("../../../shaders/effects.wgsl");
const ENTRY: &str = include_str!("../../../shaders/entry.wgsl");

fn family_source(family: Family) -> &'static str {
    match family {
        Family::Linear => include_str!("../../../shaders/linear.wgsl"),
        Family::Classic => include_str!("../../../shaders/classic.wgsl"),
        Family::Generalized => include_str!("../../../shaders/generalized.wgsl"),
    }
}

/// The complete WGSL of the pipeline that scores `problem`'s model: a
/// header generated from the model description, the prologue, the family's
/// file, the scoring loop (the plain family's, or the one with effect
/// stages) and the entry point.
pub fn shader_source(problem: &Problem, n_one: bool, residuals: bool) -> String {
    let mut header = format!(
        "const N_ONE: bool = {n_one};\nconst RESIDUALS: bool = {residuals};\n\
         const STRIDE: u32 = {}u;\n",
        problem.dim()
    );
    let driver = if problem.effects.is_empty() {
        // The generalized family's switching level is placed by each
        // experiment's output mean (the effects' header has them too).
        if problem.family.switch_index().is_some() {
            let means = problem.experiments.iter().map(|e| e.y_mean as f32);
            header.push_str(&private_array(
                "Y_MEAN",
                "f32",
                means.map(float_literal).collect(),
            ));
        }
        DRIVER
    } else {
        header.push_str(&effects_header(problem));
        EFFECTS
    };
    format!(
        "{header}{PROLOGUE}\n{}\n{driver}\n{ENTRY}",
        family_source(problem.family)
    )
}

/// The header of `shaders/effects.wgsl`: the WGSL generated from the
/// model description ([`stages::source`]: the realisations' parameter
/// structs, the loads of the present ones' parameters and the calls of
/// their stages in the step order), and each experiment's constants as
/// [`crate::model::effects::ModelDescription::prepare`] rounds them to `f32`
/// (written in Rust's shortest round-trip form, which the WGSL compiler
/// reads back to the same bits).
fn effects_header(problem: &Problem) -> String {
    let mut h = stages::source(&problem.model());
    let float = |f: &dyn Fn(&EffectContext) -> f32| {
        problem
            .contexts
            .iter()
            .map(|c| float_literal(f(c)))
            .collect::<Vec<_>>()
    };
    let f32s = |name: &str, values| private_array(name, "f32", values);
    h.push_str(&f32s("U_MEAN", float(&|c| c.u_mean as f32)));
    h.push_str(&f32s("Y_MEAN", float(&|c| c.y_mean as f32)));
    h.push_str(&f32s("BRANCH_TOL", float(&|c| c.branch_tol as f32)));
    h.push_str(&f32s("INV_DT", float(&|c| (1.0 / c.dt) as f32)));
    h.push_str(&f32s("KNEE_H", float(&|c| c.knee()[0])));
    h.push_str(&f32s("KNEE_2H", float(&|c| c.knee()[1])));
    h.push_str(&f32s("KNEE_INV_4H", float(&|c| c.knee()[2])));
    h.push_str(&f32s("REST", float(&|c| c.rest_input())));
    let up = problem
        .contexts
        .iter()
        .map(|c| c.drives_up.to_string())
        .collect();
    h.push_str(&private_array("DRIVES_UP", "bool", up));
    h
}

/// A per-experiment constant array of the header: `values` indexed by
/// experiment.
fn private_array(name: &str, ty: &str, values: Vec<String>) -> String {
    let n = values.len();
    format!(
        "var<private> {name}: array<{ty}, {n}> = array<{ty}, {n}>({});\n",
        values.join(", ")
    )
}

/// `v` as a WGSL literal, in Rust's shortest round-trip form (which the
/// WGSL compiler reads back to the same bits).
fn float_literal(v: f32) -> String {
    format!("{v:?}f")
}

/// Scores populations on a wgpu device.
pub struct GpuEvaluator {
    host: Host,
}

impl GpuEvaluator {
    /// Opens the best adapter present (see [`adapters`]); an error, not a
    /// panic, when there is none.
    pub fn open(options: GpuOptions) -> anyhow::Result<Self> {
        Self::with_adapter(best_adapter()?, options)
    }

    /// Opens `adapter` with the largest limits it offers.
    pub fn with_adapter(adapter: wgpu::Adapter, options: GpuOptions) -> anyhow::Result<Self> {
        Ok(GpuEvaluator {
            host: Host::open(adapter, options)?,
        })
    }

    /// The adapter scoring.
    pub fn adapter_info(&self) -> &wgpu::AdapterInfo {
        &self.host.info
    }

    /// Times the calibration kernel on this evaluator's device
    /// ([`calibration::ceiling`]); `None` where the adapter offers no
    /// timestamp queries.
    pub fn calibrate(
        &mut self,
        sizing: calibration::Sizing,
    ) -> anyhow::Result<Option<calibration::Ceiling>> {
        calibration::ceiling(&mut self.host, sizing)
    }

    /// Runs one variant of the calibration kernel ([`calibration::run`]):
    /// what each invocation wrote and the pass's device time.
    pub fn calibration_run(
        &mut self,
        variant: calibration::Variant,
        invocations: u32,
        steps: u32,
    ) -> anyhow::Result<(Vec<f32>, Option<f64>)> {
        calibration::run(&mut self.host, variant, invocations, steps)
    }

    /// Scores `population` writing `output`: per candidate, its SSE on every
    /// experiment or its residuals, candidate-major.
    fn run(
        &mut self,
        problem: &Problem,
        population: Rows<'_, Params>,
        output: Output,
    ) -> anyhow::Result<Vec<f32>> {
        let submitted = self.submit_run(problem, population, output)?;
        self.host.collect(submitted)
    }

    /// [`GpuEvaluator::run`] handed to the device, not waited for.
    fn submit_run(
        &mut self,
        problem: &Problem,
        population: Rows<'_, Params>,
        output: Output,
    ) -> anyhow::Result<Submitted> {
        let family = problem.family;
        let d = problem.dim();
        check_dim(problem, population)?;
        if population.is_empty() || problem.experiments.is_empty() {
            // No kernel runs: this call's device time is none.
            return Ok(self.host.nothing());
        }
        let rows = to_f32(population.as_flat());
        let n_one = match family.exponent_index() {
            Some(ni) => rows.chunks_exact(d).all(|r| r[ni] == 1.0),
            None => true,
        };
        let mut samples: Vec<[f32; 2]> = Vec::with_capacity(problem.samples());
        let mut spans: Vec<[u32; 2]> = Vec::new();
        for e in &problem.experiments {
            anyhow::ensure!(
                e.u.len() == e.y.len(),
                "experiment `{}`: input and output lengths differ",
                e.name
            );
            spans.push([samples.len() as u32, e.len() as u32]);
            samples.extend(e.u.iter().zip(&e.y).map(|(&u, &y)| [u, y]));
        }
        self.host.upload(samples, spans)?;
        let kernel = Kernel {
            source: shader_source(problem, n_one, output == Output::Residuals),
            label: family.name(),
            dim: d,
            traces: problem.experiments.len(),
            horizon: horizon_of(problem),
            output,
            residual_len: residual_len(problem),
        };
        self.host.submit(&kernel, &rows)
    }
}

/// Scores a [`GpuEvaluator`] submitted ([`Evaluator::submit`]): the
/// device's work and the shape of its scores.
pub struct Queued {
    submitted: Submitted,
    candidates: usize,
    experiments: usize,
}

/// `flat`, `[candidate][experiment]` as the device writes it, as scores
/// `[experiment][candidate]`.
fn scores_of(flat: &[f32], candidates: usize, experiments: usize) -> Scores {
    let per_experiment = (0..experiments)
        .map(|e| (0..candidates).map(|i| flat[i * experiments + e]).collect())
        .collect();
    Scores::from_per_experiment(per_experiment)
}

impl Evaluator for GpuEvaluator {
    fn describe(&self) -> String {
        format!("gpu: {}", describe_adapter(&self.host.info))
    }

    fn adapter(&self) -> Option<String> {
        Some(describe_adapter(&self.host.info))
    }

    /// Every call submits and waits for its read-back.
    fn round_trips(&self) -> bool {
        true
    }

    fn kernel_seconds(&self) -> Option<f64> {
        self.host.kernel_seconds()
    }

    fn calibrate(
        &mut self,
        sizing: calibration::Sizing,
    ) -> anyhow::Result<Option<calibration::Ceiling>> {
        GpuEvaluator::calibrate(self, sizing)
    }

    fn evaluate(
        &mut self,
        problem: &Problem,
        population: Rows<'_, Params>,
    ) -> anyhow::Result<Scores> {
        let pending = self.submit(problem, population)?;
        self.collect(pending)
    }

    fn submit(
        &mut self,
        problem: &Problem,
        population: Rows<'_, Params>,
    ) -> anyhow::Result<Pending> {
        Ok(Pending::Device(Queued {
            submitted: self.submit_run(problem, population, Output::Sse)?,
            candidates: population.len(),
            experiments: problem.experiments.len(),
        }))
    }

    fn collect(&mut self, pending: Pending) -> anyhow::Result<Scores> {
        match pending {
            Pending::Scored(scores) => Ok(scores),
            Pending::Device(queued) => {
                let flat = self.host.collect(queued.submitted)?;
                Ok(scores_of(&flat, queued.candidates, queued.experiments))
            }
        }
    }

    fn residuals(
        &mut self,
        problem: &Problem,
        population: Rows<'_, Params>,
    ) -> anyhow::Result<Vec<Option<Vec<f32>>>> {
        let r = residual_len(problem);
        let flat = self.run(problem, population, Output::Residuals)?;
        // Row by row in parallel: the read-back of a polish round holds
        // thousands of rows, and this copy is host time the device waits for.
        Ok(flat
            .par_chunks(r.max(1))
            .take(population.len())
            .map(|row| row.iter().all(|v| v.is_finite()).then(|| row.to_vec()))
            .collect())
    }
}

/// Errors per candidate: `k ≥ 1` of every experiment.
fn residual_len(problem: &Problem) -> usize {
    problem
        .experiments
        .iter()
        .map(|e| e.len().saturating_sub(1))
        .sum()
}

/// The shader's `cfg.horizon`: samples between restarts, 0 for never (a
/// horizon at or past the longest experiment never restarts either).
fn horizon_of(problem: &Problem) -> u32 {
    let longest = problem
        .experiments
        .iter()
        .map(|e| e.len())
        .max()
        .unwrap_or(0);
    match problem.measure.restart_every() {
        h if h >= longest => 0,
        h => h as u32,
    }
}
