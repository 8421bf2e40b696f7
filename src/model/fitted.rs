//! A fitted baseline: a family's parameters in the coordinates of the data
//! it was fitted on ([`super::file::Model`] adds the effects; the model file
//! holds both).

use serde::{Deserialize, Serialize};

use super::family::Family;
use super::sim::{Simulation, rest_state, simulate};
use crate::data::Trace;

/// A baseline model with its parameters and the coordinates it was fitted in
/// (version 1 of the model file is this struct as JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FittedBaseline {
    pub family: Family,
    /// Canonical parameter vector (see [`Family::params`]).
    pub params: Vec<f64>,
    /// Input mean removed before fitting (`ū`, input units).
    pub input_mean: f64,
    /// Output mean removed before fitting (`ȳ`, output units).
    pub output_mean: f64,
    /// Sample time the model was fitted at (s).
    pub dt: f64,
    pub input_name: String,
    pub output_name: String,
}

impl FittedBaseline {
    /// Parameters by name, in canonical order.
    pub fn named_params(&self) -> Vec<(&'static str, f64)> {
        self.family
            .params()
            .iter()
            .map(|p| p.name)
            .zip(self.params.iter().copied())
            .collect()
    }

    /// The absolute output from which a free run held at the absolute input
    /// `u` stays put ([`rest_state`], less the start offset `x0` the run
    /// adds): where a muscle that has sat at `u` is. `None` where the model
    /// has no stable rest.
    pub fn rest_output(&self, u: f64) -> Option<f64> {
        let x = rest_state(self.family, &self.params, u - self.input_mean)?;
        let x0 = self.params[self.family.start_index()];
        Some(x - x0 + self.output_mean)
    }

    /// Free-run simulation on an input in absolute units, starting from the
    /// absolute output `y0`; returns the output in absolute units and the
    /// simulation in deviation coordinates.
    pub fn simulate_absolute(&self, input: &[f64], y0: f64) -> (Vec<f64>, Simulation) {
        let theta: Vec<f32> = self.params.iter().map(|&v| v as f32).collect();
        let u: Vec<f32> = input
            .iter()
            .map(|&p| (p - self.input_mean) as f32)
            .collect();
        let sim = simulate(
            self.family,
            &theta,
            self.output_mean as f32,
            &u,
            (y0 - self.output_mean) as f32,
        );
        let y = sim.x.iter().map(|&x| x as f64 + self.output_mean).collect();
        (y, sim)
    }

    /// Simulates on a trace's input, from its first measured output.
    pub fn simulate_trace(&self, trace: &Trace) -> Vec<f64> {
        self.simulate_absolute(
            &trace.input,
            trace.output.first().copied().unwrap_or(self.output_mean),
        )
        .0
    }
}
