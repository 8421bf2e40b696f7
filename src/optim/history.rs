//! What a run records each generation, as CSV and JSON (`report::history`
//! draws it).

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use super::stage::Stage;
use crate::search::Measure;

/// One generation of a population stage, or one start of the polish. Costs
/// are on the estimation data; `None` stands for "no finite value" (JSON has
/// no infinity).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GenerationRecord {
    /// 1-based: the number of records so far.
    pub generation: usize,
    pub stage: Stage,
    /// What this stage's costs measure.
    pub measure: Measure,
    /// Candidates evaluated so far.
    pub evaluations: u64,
    /// Wall-clock seconds since the run started (the only field that is not
    /// a function of the seed).
    pub seconds: f64,
    /// Lowest free-run SSE seen so far: in the global stage, of its islands
    /// that measure the free run (the last ones, whose horizon reaches the
    /// record's length); none before any.
    pub best_sse: Option<f64>,
    /// Lowest cost of this stage so far, under its measure.
    pub stage_best: Option<f64>,
    /// Lowest cost in this generation's population (none for a polish).
    pub generation_best_sse: Option<f64>,
    /// Mean and standard deviation of the finite SSEs of this population.
    pub mean_sse: Option<f64>,
    pub std_sse: Option<f64>,
    /// Candidates of this population whose simulation diverged (SSE = +∞).
    pub diverged: usize,
    /// Canonical parameter vector of the stage's best so far (empty before
    /// any finite cost).
    pub best_params: Vec<f64>,
}

impl GenerationRecord {
    /// Summary statistics of a population's costs: (best, mean, std, diverged),
    /// over finite values only, so a diverged candidate never poisons them.
    pub fn stats(costs: &[f32]) -> (Option<f64>, Option<f64>, Option<f64>, usize) {
        let finite = || costs.iter().filter(|c| c.is_finite()).map(|&c| c as f64);
        let count = finite().count();
        let diverged = costs.len() - count;
        if count == 0 {
            return (None, None, None, diverged);
        }
        let n = count as f64;
        let best = finite().fold(f64::INFINITY, f64::min);
        let mean = finite().sum::<f64>() / n;
        let var = finite().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
        (Some(best), Some(mean), Some(var.sqrt()), diverged)
    }
}

/// The records of a fit, in order.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct History {
    /// Names of the canonical parameters.
    pub names: Vec<String>,
    pub records: Vec<GenerationRecord>,
}

impl History {
    pub fn new(names: Vec<String>) -> History {
        History {
            names,
            records: Vec::new(),
        }
    }

    fn param_names(&self) -> Vec<&str> {
        self.names.iter().map(String::as_str).collect()
    }

    /// CSV: one row per generation, the best parameters as named columns.
    /// A value the row has not (`None`) is an empty cell, which pandas and
    /// MATLAB's `readtable` read as NaN, a gap in a plot; `inf` would read
    /// as a cost, and a polish row's population figures are not one.
    pub fn to_csv(&self) -> String {
        let names = self.param_names();
        let mut s = String::from(
            "generation,stage,horizon,evaluations,seconds,best_sse,stage_best,generation_best_sse,mean_sse,std_sse,diverged",
        );
        for n in &names {
            let _ = write!(s, ",{n}");
        }
        s.push('\n');
        let opt = |v: Option<f64>| v.map(|v| format!("{v:e}")).unwrap_or_default();
        for r in &self.records {
            let horizon = match r.measure {
                Measure::FreeRun => String::new(),
                Measure::Ahead { horizon } => horizon.to_string(),
            };
            let _ = write!(
                s,
                "{},{},{horizon},{},{:.3},{},{},{},{},{},{}",
                r.generation,
                r.stage.name(),
                r.evaluations,
                r.seconds,
                opt(r.best_sse),
                opt(r.stage_best),
                opt(r.generation_best_sse),
                opt(r.mean_sse),
                opt(r.std_sse),
                r.diverged
            );
            for i in 0..names.len() {
                match r.best_params.get(i) {
                    Some(v) => {
                        let _ = write!(s, ",{v:e}");
                    }
                    None => s.push(','),
                }
            }
            s.push('\n');
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statistics_skip_diverged_candidates() {
        let (best, mean, std, div) = GenerationRecord::stats(&[1.0, f32::INFINITY, 3.0, f32::NAN]);
        assert_eq!((best, mean, std, div), (Some(1.0), Some(2.0), Some(1.0), 2));
        assert_eq!(
            GenerationRecord::stats(&[f32::INFINITY]),
            (None, None, None, 1)
        );
    }

    #[test]
    fn csv_has_named_parameter_columns() {
        let mut h = History::new(vec!["a".into(), "b".into(), "c".into()]);
        h.records.push(GenerationRecord {
            generation: 1,
            stage: Stage::Global,
            measure: Measure::Ahead { horizon: 7 },
            evaluations: 10,
            seconds: 0.5,
            best_sse: None,
            stage_best: Some(2.0),
            generation_best_sse: Some(2.0),
            mean_sse: None,
            std_sse: None,
            diverged: 10,
            best_params: vec![0.9, 1.0, 0.0],
        });
        let csv = h.to_csv();
        let mut lines = csv.lines();
        assert!(lines.next().unwrap().ends_with("diverged,a,b,c"));
        let row = lines.next().unwrap();
        assert!(
            row.starts_with("1,global,7,10,0.500,,2e0,2e0,,,10,9e-1"),
            "{row}"
        );
    }
}
