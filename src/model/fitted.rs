//! A fitted baseline: a family's parameters in the coordinates of the data
//! it was fitted on ([`super::file::Model`] adds the effects; the model file
//! holds both).

use serde::{Deserialize, Serialize};

use super::effects::Unit;
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

    /// The same model for an input read in units `per_input` times the
    /// fitted ones and an output `per_output` times (a model fitted in psi
    /// and m, wanted in MPa and mm: `per_input` 0.006895, `per_output`
    /// 1000). It predicts the same motion, each number in the new units:
    /// the gain `b` takes both factors, the intercept `c`, the start offset
    /// `x0` and the switching level `x_s` the output's; the hysteretic
    /// state moves with the output (its update is driven by the output's
    /// step), so the loop-shape weights `β`, `γ` and `β1..β6` scale by
    /// `per_output^−n`; the poles, `A`, `α` and `n` stay. The columns keep
    /// their names.
    pub fn rescaled(&self, per_input: f64, per_output: f64) -> FittedBaseline {
        let params = (self.params.iter().enumerate())
            .map(|(i, v)| v * self.unit(i).factor(per_input, per_output))
            .collect();
        FittedBaseline {
            params,
            input_mean: self.input_mean * per_input,
            output_mean: self.output_mean * per_output,
            ..self.clone()
        }
    }

    /// What the canonical parameter `i` is measured in (the loop-shape
    /// weights at this model's exponent `n`): the factor
    /// [`FittedBaseline::rescaled`] takes it by.
    pub fn unit(&self, i: usize) -> Unit {
        let family = self.family;
        let n = family.exponent_index().map_or(1.0, |k| self.params[k]);
        let [_, ib, ic] = family.linear_indices();
        match family.params()[i].name {
            "beta" | "gamma" | "beta1" | "beta2" | "beta3" | "beta4" | "beta5" | "beta6" => {
                Unit::PerOutputToThe(n)
            }
            "x0" | "x_s" => Unit::Output,
            _ if i == ib => Unit::OutputPerInput,
            _ if i == ic => Unit::Output,
            _ => Unit::Pure,
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A model in psi and metres, rescaled to MPa and mm, runs the same
    /// motion on the same pressures: every family, a free exponent too.
    #[test]
    fn a_rescaled_model_predicts_the_same_motion_in_its_new_units() {
        let (per_input, per_output) = (6.894757293168e-3, 1000.0);
        let psi: Vec<f64> = (0..400)
            .map(|k| 30.0 + 25.0 * (k as f64 * 0.05).sin() + 10.0 * (k as f64 * 0.013).sin())
            .collect();
        let mpa: Vec<f64> = psi.iter().map(|p| p * per_input).collect();
        let models = [
            (Family::Linear, vec![0.95, 2e-4, 1e-5, 2e-4]),
            (
                Family::Classic,
                vec![1.0, 0.6, 40.0, 25.0, 1.0, 0.95, 2e-4, 1e-5, 2e-4],
            ),
            (
                Family::Classic,
                vec![1.0, 0.6, 4.0, 2.5, 1.5, 0.95, 2e-4, 1e-5, 2e-4],
            ),
            (
                Family::Generalized,
                vec![
                    1.0, 0.6, 30.0, -5.0, 8.0, 3.0, -2.0, 1.0, 1.0, 0.95, 2e-4, 1e-5, 2e-4, 0.012,
                ],
            ),
        ];
        for (family, params) in models {
            assert_eq!(params.len(), family.dim(), "{family}");
            let fitted = FittedBaseline {
                family,
                params,
                input_mean: 32.0,
                output_mean: 0.011,
                dt: 0.01,
                input_name: "pressure_psi".into(),
                output_name: "x_m".into(),
            };
            let (metres, _) = fitted.simulate_absolute(&psi, 0.012);
            let rescaled = fitted.rescaled(per_input, per_output);
            let (mm, _) = rescaled.simulate_absolute(&mpa, 12.0);
            let span = metres.iter().fold(0.0f64, |m, v| m.max((v - 0.011).abs()));
            assert!(
                span > 1e-4,
                "{family}: the test model barely moves ({span} m)"
            );
            for (k, (m, x)) in metres.iter().zip(&mm).enumerate() {
                assert!(
                    (m * per_output - x).abs() <= 1e-4 * span * per_output,
                    "{family}, sample {k}: {} mm against {x} mm",
                    m * per_output
                );
            }
        }
    }
}
