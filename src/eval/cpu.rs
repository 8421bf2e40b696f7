//! The CPU reference evaluator.

use super::{Evaluator, Problem, Scores, to_f32};
use crate::model::sse;

/// Scores each candidate with the reference simulation, one after another.
#[derive(Debug, Default)]
pub struct CpuEvaluator;

impl Evaluator for CpuEvaluator {
    fn describe(&self) -> String {
        "cpu".into()
    }

    fn evaluate(&mut self, problem: &Problem, population: &[f64]) -> anyhow::Result<Scores> {
        let d = problem.family.dim();
        anyhow::ensure!(
            population.len() % d == 0,
            "population length is not a multiple of {d}"
        );
        let rows = to_f32(population);
        let per_experiment = problem
            .experiments
            .iter()
            .map(|e| {
                rows.chunks_exact(d)
                    .map(|theta| sse(problem.family, theta, &e.u, &e.y))
                    .collect()
            })
            .collect();
        Ok(Scores::from_per_experiment(per_experiment))
    }
}
