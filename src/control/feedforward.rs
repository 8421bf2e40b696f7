//! Inverse-hysteresis feedforward plus PID: the standard answer of the
//! hysteresis-compensation literature, here as the comparison the MPC must
//! beat. The identified model is inverted along the reference — the
//! pressure that makes the model's displacement follow it, with the
//! Bouc-Wen state driven by the reference itself (the inverse multiplicative
//! structure of Rakotondrabe, "Bouc–Wen modeling and inverse multiplicative
//! structure to compensate hysteresis nonlinearity in piezoelectric
//! actuators", IEEE Trans. Autom. Sci. Eng. 8(2), 428–431, 2011; inverse
//! hysteresis compensation in general: Tao & Kokotović, "Adaptive control of
//! plants with unknown hystereses", IEEE Trans. Autom. Control 40(2), 1995)
//! — then through the inverse of the valve model to a voltage. A PID on the
//! tracking error adds what the inverse misses.

use super::controller::Controller;
use super::model::{ControlModel, Predictor};
use super::pi::Pi;
use super::plant::Measurement;

/// The model inverted along a reference.
#[derive(Debug, Clone)]
pub struct InverseModel {
    predictor: Predictor,
    /// The Bouc-Wen state along the reference.
    w: f64,
}

impl InverseModel {
    pub fn new(model: &ControlModel) -> anyhow::Result<InverseModel> {
        Ok(InverseModel {
            predictor: Predictor::new(model)?,
            w: 0.0,
        })
    }

    pub fn reset(&mut self) {
        self.w = 0.0;
    }

    /// The pressure (MPa) at which the model moves from `x` to `x_next`
    /// (deviation, mm) with Bouc-Wen state `w`: the root of
    /// `b₂u² + b·u + (a·α·x + a·(1−α)·w + c − x_next) = 0` nearest the
    /// linear solution.
    fn pressure_for(&self, x: f64, x_next: f64, w: f64) -> f64 {
        let pr = &self.predictor;
        let k = pr.rho * x + pr.h * w + pr.c - x_next;
        let linear = -k / pr.b;
        let u = if pr.b2.abs() < 1e-12 {
            linear
        } else {
            let disc = pr.b * pr.b - 4.0 * pr.b2 * k;
            if disc < 0.0 {
                -pr.b / (2.0 * pr.b2)
            } else {
                let roots = [
                    (-pr.b + disc.sqrt()) / (2.0 * pr.b2),
                    (-pr.b - disc.sqrt()) / (2.0 * pr.b2),
                ];
                if (roots[0] - linear).abs() < (roots[1] - linear).abs() {
                    roots[0]
                } else {
                    roots[1]
                }
            }
        };
        u + pr.input_mean
    }

    /// The feedforward voltage for this sample from the reference preview
    /// (`reference[j]` at `j` samples ahead, at least three values), and
    /// the Bouc-Wen state moved on by one sample of the reference.
    pub fn voltage(&mut self, reference: &[f64]) -> f64 {
        let pr = &self.predictor;
        let r = |j: usize| reference[j.min(reference.len() - 1)] - pr.output_mean;
        // The voltage held now sets p(k+1), which sets x(k+2).
        let w1 = pr.hysteresis.step(self.w, r(1) - r(0));
        let p_now = self.pressure_for(r(0), r(1), self.w);
        let p_next = self.pressure_for(r(1), r(2), w1);
        self.w = w1;
        pr.valve.inverse(p_next - pr.valve.pole * p_now)
    }
}

/// PID with the inverse model's feedforward.
pub struct FeedforwardPid {
    pub pid: Pi,
    inverse: InverseModel,
    label: String,
    started: bool,
}

impl FeedforwardPid {
    pub fn new(pid: Pi, model: &ControlModel, label: impl Into<String>) -> anyhow::Result<Self> {
        Ok(FeedforwardPid {
            pid,
            inverse: InverseModel::new(model)?,
            label: label.into(),
            started: false,
        })
    }
}

impl Controller for FeedforwardPid {
    fn name(&self) -> &str {
        &self.label
    }

    fn reset(&mut self, u0: f64) {
        self.pid.reset(u0);
        self.inverse.reset();
        self.started = false;
    }

    fn command(&mut self, m: Measurement, reference: &[f64]) -> f64 {
        let ff = self.inverse.voltage(reference);
        if !self.started {
            // Bumpless: the integrator gives way to the feedforward.
            self.pid.shift_integral(-ff);
            self.started = true;
        }
        self.pid.command_with(m, reference[0], ff)
    }
}
