//! An experiment in the deviation coordinates the models are fitted in.

use std::ops::Range;

use crate::data::Trace;

/// A trace in deviation coordinates, as the evaluator and the simulation
/// consume it: `u(k) = p(k) − ū`, `y(k) = l(k) − ȳ`, in `f32`, with the means
/// `ū`, `ȳ` taken over the estimation segment and kept to undo the shift.
#[derive(Debug, Clone, PartialEq)]
pub struct Experiment {
    /// Where the data came from, for messages and reports.
    pub name: String,
    /// Sample time in seconds.
    pub dt: f64,
    pub u: Vec<f32>,
    pub y: Vec<f32>,
    /// The input mean `ū` removed from `u`.
    pub u_mean: f64,
    /// The output mean `ȳ` removed from `y`.
    pub y_mean: f64,
}

/// Estimation first half, validation second half, as the thesis splits (§4.3.1).
pub fn halves(len: usize) -> (Range<usize>, Range<usize>) {
    let mid = len / 2;
    (0..mid, mid..len)
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

impl Experiment {
    /// Shifts `trace` by the input and output means over `means_over`.
    pub fn with_means_of(trace: &Trace, means_over: Range<usize>) -> Self {
        let u_mean = mean(&trace.input[means_over.clone()]);
        let y_mean = mean(&trace.output[means_over]);
        Self::with_offsets(trace, u_mean, y_mean)
    }

    /// Shifts `trace` by given offsets (to score new data in a fitted model's coordinates).
    pub fn with_offsets(trace: &Trace, u_mean: f64, y_mean: f64) -> Self {
        Experiment {
            name: trace.source.clone(),
            dt: trace.dt(),
            u: trace.input.iter().map(|&p| (p - u_mean) as f32).collect(),
            y: trace.output.iter().map(|&l| (l - y_mean) as f32).collect(),
            u_mean,
            y_mean,
        }
    }

    pub fn len(&self) -> usize {
        self.u.len()
    }

    pub fn is_empty(&self) -> bool {
        self.u.is_empty()
    }

    /// The samples `range`, in the same coordinates.
    pub fn segment(&self, range: Range<usize>) -> Experiment {
        Experiment {
            name: self.name.clone(),
            dt: self.dt,
            u: self.u[range.clone()].to_vec(),
            y: self.y[range].to_vec(),
            u_mean: self.u_mean,
            y_mean: self.y_mean,
        }
    }

    /// The thesis' split: means over the first half; (estimation, validation).
    pub fn split_halves(trace: &Trace) -> (Experiment, Experiment) {
        let (est, val) = halves(trace.len());
        let whole = Experiment::with_means_of(trace, est.clone());
        (whole.segment(est), whole.segment(val))
    }
}
