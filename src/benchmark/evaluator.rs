//! The benchmark oscillator ([`super::boucwen`]) as a scored problem, and
//! the evaluators that score its populations. It is not a muscle model: it
//! integrates at a multiple of the data rate on an upsampled input, so it has
//! its own problem type and its own evaluator interface,
//! [`OscillatorEvaluator`], apart from the muscle models' `eval::Evaluator`:
//! on the CPU the `f32` twin [`sse_f32`], one candidate per rayon task; on a
//! GPU `shaders/boucwen_oscillator.wgsl`, run by the project's one wgpu host
//! (`eval::gpu::host`) on the bindings every pipeline of it declares. The two
//! give the same bits on lavapipe.

use rayon::prelude::*;

use super::boucwen::{self, DIM, sse_f32};
use crate::eval::gpu::host::{Host, Kernel, Output, best_adapter};
use crate::eval::gpu::{GpuOptions, PROLOGUE, describe_adapter};
use crate::eval::{Backend, Choice, choose, to_f32};
use crate::search::{Params, Rows};

const OSCILLATOR: &str = include_str!("../../shaders/boucwen_oscillator.wgsl");

/// The trace a population of oscillators is scored on.
#[derive(Debug, Clone, PartialEq)]
pub struct OscillatorProblem {
    /// The input at the integration rate (step `h`).
    pub u: Vec<f32>,
    /// The measured displacement, at every `stride`-th integration step.
    pub y: Vec<f32>,
    /// Integration steps per measured sample.
    pub stride: usize,
    /// The integration step (s).
    pub h: f32,
}

impl OscillatorProblem {
    /// Integration steps scored: from rest to the last measured sample.
    fn steps(&self) -> usize {
        (self.y.len() - 1) * self.stride + 1
    }

    /// Errors unless the trace can be scored.
    pub fn check(&self) -> anyhow::Result<()> {
        anyhow::ensure!(!self.y.is_empty(), "no measured samples to score");
        anyhow::ensure!(self.stride > 0, "the integration stride must be positive");
        anyhow::ensure!(
            self.u.len() >= self.steps(),
            "the input has {} integration steps; scoring {} samples at stride {} needs {}",
            self.u.len(),
            self.y.len(),
            self.stride,
            self.steps()
        );
        Ok(())
    }

    /// The trace as the GPU binds it (`shaders/boucwen_oscillator.wgsl`):
    /// `(u, y)` per integration step, `y` the measurement at the scored
    /// steps and 0 between them; one span over all of them.
    pub fn samples(&self) -> (Vec<[f32; 2]>, Vec<[u32; 2]>) {
        let steps = self.steps();
        let samples = (0..steps)
            .map(|i| {
                let y = if i % self.stride == 0 {
                    self.y[i / self.stride]
                } else {
                    0.0
                };
                [self.u[i], y]
            })
            .collect();
        (samples, vec![[0, steps as u32]])
    }
}

/// Scores populations of the oscillator. Implementations keep their
/// resources (threads, device, buffers) across calls, so one evaluator serves
/// a whole identification.
pub trait OscillatorEvaluator {
    /// Backend and device, for the user ("cpu, 2 threads", "gpu: …").
    fn describe(&self) -> String;

    /// The SSE of every candidate (`population`: [`boucwen`]'s canonical
    /// vectors), `+∞` where its simulation diverged.
    /// Bit-identical across backends where the muscle models' scores are.
    fn evaluate(
        &mut self,
        problem: &OscillatorProblem,
        population: Rows<'_, Params>,
    ) -> anyhow::Result<Vec<f32>>;
}

/// Opens the evaluator `backend` asks for, chosen as `eval::open` chooses
/// the muscle models' (`eval::choose`).
pub fn open(backend: Backend) -> anyhow::Result<Box<dyn OscillatorEvaluator + Send>> {
    Ok(match choose(backend)? {
        Choice::Cpu { note } => Box::new(CpuOscillator { note }),
        Choice::Gpu(adapter) => Box::new(GpuOscillator::with_adapter(adapter, Default::default())?),
    })
}

/// The oscillator on the CPU: one candidate per rayon task.
#[derive(Debug, Default, Clone)]
pub struct CpuOscillator {
    /// Why the CPU was chosen, when `--backend auto` chose it.
    note: Option<String>,
}

impl CpuOscillator {
    pub fn new() -> Self {
        CpuOscillator::default()
    }
}

impl OscillatorEvaluator for CpuOscillator {
    fn describe(&self) -> String {
        let base = format!("cpu ({} threads)", rayon::current_num_threads());
        match &self.note {
            Some(note) => format!("{base}; {note}"),
            None => base,
        }
    }

    fn evaluate(
        &mut self,
        problem: &OscillatorProblem,
        population: Rows<'_, Params>,
    ) -> anyhow::Result<Vec<f32>> {
        let rows = rows(problem, population)?;
        Ok(score_rows(problem, &rows))
    }
}

/// The oscillator on a wgpu device, through the project's one host.
pub struct GpuOscillator {
    host: Host,
}

impl GpuOscillator {
    /// Opens the best adapter present; an error, not a panic, when there is
    /// none.
    pub fn open(options: GpuOptions) -> anyhow::Result<Self> {
        Self::with_adapter(best_adapter()?, options)
    }

    /// Opens `adapter` with the largest limits it offers.
    pub fn with_adapter(adapter: wgpu::Adapter, options: GpuOptions) -> anyhow::Result<Self> {
        Ok(GpuOscillator {
            host: Host::open(adapter, options)?,
        })
    }
}

impl OscillatorEvaluator for GpuOscillator {
    fn describe(&self) -> String {
        format!("gpu: {}", describe_adapter(&self.host.info))
    }

    fn evaluate(
        &mut self,
        problem: &OscillatorProblem,
        population: Rows<'_, Params>,
    ) -> anyhow::Result<Vec<f32>> {
        let rows = rows(problem, population)?;
        let (samples, spans) = problem.samples();
        self.host.upload(samples, spans)?;
        let kernel = Kernel {
            source: source(problem),
            label: "boucwen oscillator",
            dim: DIM,
            traces: 1,
            horizon: 0,
            output: Output::Sse,
            residual_len: 0,
        };
        self.host.dispatch(&kernel, &rows)
    }
}

/// The WGSL of the oscillator's pipeline: a header with the integrator's
/// step sizes (as [`boucwen::StepSizes`] rounds them for the `f32` twin,
/// written in Rust's shortest round-trip form), the host's prologue, and
/// `shaders/boucwen_oscillator.wgsl`.
pub fn source(problem: &OscillatorProblem) -> String {
    let step = boucwen::StepSizes::new(problem.h);
    format!(
        "const STRIDE: u32 = {}u;\nconst SCORE_EVERY: u32 = {}u;\n\
         const NEWTON_ITERS: u32 = {}u;\nconst H: f32 = {:?}f;\n\
         const HALF_H: f32 = {:?}f;\nconst QUARTER_HH: f32 = {:?}f;\n{PROLOGUE}\n{OSCILLATOR}",
        DIM,
        problem.stride,
        boucwen::NEWTON_ITERS_F32,
        step.h,
        step.half_h,
        step.quarter_hh,
    )
}

/// The `f32` rows both backends score, after checking the problem and the
/// population's shape.
fn rows(problem: &OscillatorProblem, population: Rows<'_, Params>) -> anyhow::Result<Vec<f32>> {
    problem.check()?;
    anyhow::ensure!(
        population.dim() == DIM,
        "rows of {} values, but the oscillator has {DIM} parameters",
        population.dim()
    );
    Ok(to_f32(population.as_flat()))
}

/// The SSE of every row, one candidate per rayon task (each from its own
/// inputs only, so the result does not depend on the number of threads).
fn score_rows(problem: &OscillatorProblem, rows: &[f32]) -> Vec<f32> {
    rows.par_chunks(DIM)
        .map(|theta| sse_f32(theta, &problem.u, &problem.y, problem.stride, problem.h))
        .collect()
}
