//! The state estimate a model-based controller starts its predictions from,
//! and the disturbances that make its tracking offset-free.
//!
//! A fixed-gain observer on the [`Predictor`]: each sample it predicts the
//! measurement from its last estimate and the command that was applied, and
//! corrects with the innovation `e`:
//!
//! ```text
//! x̂ = x⁻ + Lx·eₓ        d_x ← d_x + Ldx·eₓ      (displacement)
//! p̂ = p⁻ + Lp·eₚ        d_p ← d_p + Ldp·eₚ      (pressure)
//! ```
//!
//! `d_x` and `d_p` are integrating disturbances added to the model's
//! displacement and pressure equations over the whole horizon: whatever the
//! model gets wrong as a steady offset (another load, a map that is off) is
//! driven into them, and the MPC's prediction converges to the measurement —
//! offset-free tracking (Pannocchia & Rawlings, "Disturbance models for
//! offset-free model-predictive control", AIChE J. 49(2), 2003).
//!
//! The disturbances enter the model's equations, not its output: a state
//! disturbance acts like integral action inside the loop's dynamics, and an
//! output offset (`y = x + d`) tracks worse at every gain (measured on the
//! twin: docs/CONTROL.md, "3 rad/s against the tuned PID").
//!
//! Why these gains (`MpcSettings::default`, measured on the twin:
//! docs/CONTROL.md, "3 rad/s against the tuned PID"): the displacement is
//! trusted (`Lx = 1`, its noise is 0.03 mm); the pressure is mostly
//! predicted (`Lp = 0.2`), because the displacement model multiplies
//! a pressure error by `b/(1 − π)` ≈ 90 mm/MPa over a horizon, so the raw
//! 2 kPa sensor noise would move the plan by 0.2 mm; and the pressure
//! disturbance is off (`Ldp = 0`) for the same reason, the displacement
//! disturbance absorbing what the pressure model misses.

use serde::{Deserialize, Serialize};

use super::model::{Predictor, State};
use super::plant::Measurement;

/// Gains of the observer, each in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ObserverGains {
    /// `Lx`: share of the displacement innovation taken into the estimate.
    pub displacement: f64,
    /// `Lp`: share of the pressure innovation taken into the estimate.
    pub pressure: f64,
    /// `Ldx`: share integrated into the displacement disturbance.
    pub displacement_disturbance: f64,
    /// `Ldp`: share integrated into the pressure disturbance.
    pub pressure_disturbance: f64,
}

impl Default for ObserverGains {
    fn default() -> Self {
        ObserverGains {
            displacement: 1.0,
            pressure: 0.2,
            displacement_disturbance: 0.5,
            pressure_disturbance: 0.0,
        }
    }
}

/// The observer's memory.
#[derive(Debug, Clone, Default)]
pub struct Observer {
    pub gains: ObserverGains,
    last: Option<State>,
    /// Disturbance on the displacement equation (mm per sample).
    pub dx: f64,
    /// Disturbance on the pressure equation (MPa per sample).
    pub dp: f64,
}

impl Observer {
    pub fn new(gains: ObserverGains) -> Self {
        Observer {
            gains,
            ..Observer::default()
        }
    }

    /// Forgets everything (a new episode).
    pub fn reset(&mut self) {
        *self = Observer::new(self.gains);
    }

    /// The state estimate at this sample from its measurement `m` and the
    /// valve command `u_prev` held over the sample before (the first call
    /// takes the measurement as it is, with `w = 0`).
    pub fn update(&mut self, pr: &Predictor, m: Measurement, u_prev: f64) -> State {
        let y = m.displacement_mm - pr.output_mean;
        let p = m.pressure_mpa;
        let estimate = match self.last {
            None => pr.at_start(p, y),
            Some(last) => {
                let predicted = pr.step(&last, u_prev, self.dx, self.dp);
                // The measured output less the effects' states run on
                // (`super::chain`): the baseline's `x` as measured.
                let x = match &pr.chain {
                    Some(c) => {
                        let u = c.effective(last.p, pr.input_mean).0;
                        c.restart(&last.e, u, last.p - last.p_prev, y).0
                    }
                    None => y,
                };
                let (mut ex, ep) = (x - predicted.x, p - predicted.p);
                // A ringing mode takes its share of the innovation.
                let ring = pr
                    .chain
                    .as_ref()
                    .and_then(|c| Some((c.ring?.gains, c.lags.len())));
                if let Some((k, _)) = ring {
                    ex *= k[0];
                }
                let g = &self.gains;
                self.dx += g.displacement_disturbance * ex;
                self.dp += g.pressure_disturbance * ep;
                let x_new = predicted.x + g.displacement * ex;
                let w = pr.hysteresis.step(last.w, x_new - last.x);
                let mut s = pr.moved(&last, predicted.p + g.pressure * ep, x_new, w);
                if let Some((k, i)) = ring {
                    let ey = y - pr.output(&predicted);
                    s.e[i] += k[1] * ey;
                    s.e[i + 1] += k[2] * ey;
                }
                s
            }
        };
        self.last = Some(estimate);
        estimate
    }

    /// A sample without a measurement: the estimate moves on with the model
    /// alone, the command `u_prev` held over the sample before.
    pub fn coast(&mut self, pr: &Predictor, u_prev: f64) {
        if let Some(last) = self.last {
            self.last = Some(pr.step(&last, u_prev, self.dx, self.dp));
        }
    }
}
