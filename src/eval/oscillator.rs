//! The benchmark oscillator ([`crate::benchmark::boucwen`]) as a scored
//! problem. It is not a muscle model: it integrates at a multiple of the
//! data rate on an upsampled input, so it has its own problem type, scored by
//! every [`super::Evaluator`] through [`super::Evaluator::evaluate_oscillator`]
//! (on the CPU by the `f32` twin [`sse_f32`], on a GPU by
//! `shaders/boucwen_oscillator.wgsl` through the one wgpu host).

use rayon::prelude::*;

use super::to_f32;
use crate::benchmark::boucwen::{DIM, sse_f32};

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

/// The `f32` rows every backend scores, after checking the problem and the
/// population's shape.
pub fn rows(problem: &OscillatorProblem, population: &[f64]) -> anyhow::Result<Vec<f32>> {
    problem.check()?;
    anyhow::ensure!(
        population.len() % DIM == 0,
        "population length {} is not a multiple of the oscillator's {DIM} parameters",
        population.len()
    );
    Ok(to_f32(population))
}

/// The SSE of every row, one candidate per rayon task (each from its own
/// inputs only, so the result does not depend on the number of threads).
pub fn score_rows(problem: &OscillatorProblem, rows: &[f32]) -> Vec<f32> {
    rows.par_chunks(DIM)
        .map(|theta| sse_f32(theta, &problem.u, &problem.y, problem.stride, problem.h))
        .collect()
}
