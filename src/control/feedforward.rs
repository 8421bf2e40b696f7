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

use super::controller::{Controller, ControllerStats};
use super::model::{ControlModel, Predictor, State};
use super::pi::Pi;
use super::plant::Measurement;

/// The model inverted along a reference.
#[derive(Debug, Clone)]
pub struct InverseModel {
    predictor: Predictor,
    /// The Bouc-Wen state along the reference.
    w: f64,
    /// With an effect chain (`super::chain`): the whole state along the
    /// reference, from rest at the first measured pressure.
    state: Option<State>,
}

/// The root of `a2·u² + a1·u + k = 0` nearest the linear solution `−k/a1`
/// (the vertex where there is none).
fn root(a2: f64, a1: f64, k: f64) -> f64 {
    let linear = -k / a1;
    if a2.abs() < 1e-12 {
        linear
    } else {
        let disc = a1 * a1 - 4.0 * a2 * k;
        if disc < 0.0 {
            -a1 / (2.0 * a2)
        } else {
            let roots = [
                (-a1 + disc.sqrt()) / (2.0 * a2),
                (-a1 - disc.sqrt()) / (2.0 * a2),
            ];
            if (roots[0] - linear).abs() < (roots[1] - linear).abs() {
                roots[0]
            } else {
                roots[1]
            }
        }
    }
}

impl InverseModel {
    pub fn new(model: &ControlModel) -> anyhow::Result<InverseModel> {
        Ok(InverseModel {
            predictor: Predictor::new(model)?,
            w: 0.0,
            state: None,
        })
    }

    pub fn reset(&mut self) {
        self.w = 0.0;
        self.state = None;
    }

    /// The pressure (MPa) at which the model moves from `x` to `x_next`
    /// (deviation, mm) with Bouc-Wen state `w`: the root of
    /// `b₂u² + b·u + (a·α·x + a·(1−α)·w + c − x_next) = 0` nearest the
    /// linear solution.
    fn pressure_for(&self, x: f64, x_next: f64, w: f64) -> f64 {
        let pr = &self.predictor;
        let k = pr.rho * x + pr.h * w + pr.c - x_next;
        root(pr.b2, pr.b, k) + pr.input_mean
    }

    /// With an effect chain: the pressure at which the model's whole output
    /// (`x` plus the effects') reaches `y_next` one sample after `s`, and
    /// the state it then reaches (its pressure still `s`'s own, set when
    /// the next pressure is solved). The effects are linear in `x(k+1)` and
    /// in the pressure, so the output stays a quadratic in the pressure.
    fn chain_step(&self, s: &State, y_next: f64) -> (f64, State) {
        let pr = &self.predictor;
        let c = pr.chain.as_ref().expect("a chain");
        let p0 = c.deadzone_mpa.unwrap_or(0.0);
        let (k_x, k_u, rest) = c.output_terms(&s.e, pr.input_mean + p0, s.p_prev);
        let k0 = pr.rho * s.x + pr.h * s.w + pr.c;
        let u = root(k_x * pr.b2, k_x * pr.b + k_u, k_x * k0 + rest - y_next);
        // The dead zone inverted: p₀ more, never below it.
        let p = match c.deadzone_mpa {
            Some(p0) => (u + pr.input_mean).max(0.0) + p0,
            None => u + pr.input_mean,
        };
        let now = State { p, ..*s };
        let x = pr.next_x(&now);
        let w = pr.hysteresis.step(s.w, x - s.x);
        (p, pr.moved(&now, p, x, w))
    }

    /// Starts the inverse from the first measurement, pressure `p` (MPa)
    /// and displacement `y` (mm), toward the reference `r0` (mm): with an
    /// effect chain the effects at rest at `p` and the output at `r0`;
    /// with [`ControlModel::rest_start`] the Bouc-Wen state at rest at the
    /// measurement, moved on to `r0` (else 0, as always).
    pub fn start(&mut self, p: f64, y: f64, r0: f64) {
        let pr = &self.predictor;
        let there = pr.at_start(p, self.clip(r0) - pr.output_mean);
        let w = if pr.rest_start {
            let here = pr.at_start(p, y - pr.output_mean);
            pr.hysteresis.step(here.w, there.x - here.x)
        } else {
            0.0
        };
        if pr.chain.is_some() {
            self.state = Some(State { w, ..there });
        }
        self.w = w;
    }

    /// With an effect chain: the pressure (MPa) the inverse asks for now,
    /// so that the model's output reaches `reference[1]`, and the output
    /// (mm) it reaches; moves the inverse on by one sample. `None` without
    /// a chain or before [`InverseModel::start`].
    pub fn pressure_and_state(&mut self, reference: &[f64]) -> Option<(f64, f64)> {
        let pr = &self.predictor;
        let (c, s) = (pr.chain.as_ref()?, self.state?);
        let y = c.clip_reference(reference[1.min(reference.len() - 1)]) - pr.output_mean;
        let (p, next) = self.chain_step(&s, y);
        self.state = Some(next);
        Some((p, self.predictor.output(&next) + self.predictor.output_mean))
    }

    /// The reference held short of the model's end stop, if it has one.
    pub fn clip(&self, r: f64) -> f64 {
        match &self.predictor.chain {
            Some(c) => c.clip_reference(r),
            None => r,
        }
    }

    /// The feedforward voltage for this sample from the reference preview
    /// (`reference[j]` at `j` samples ahead, at least three values), and
    /// the Bouc-Wen state moved on by one sample of the reference.
    pub fn voltage(&mut self, reference: &[f64]) -> f64 {
        let pr = &self.predictor;
        if let (Some(c), Some(s)) = (&pr.chain, self.state) {
            let r =
                |j: usize| c.clip_reference(reference[j.min(reference.len() - 1)]) - pr.output_mean;
            let (p_now, s1) = self.chain_step(&s, r(1));
            let (p_next, _) = self.chain_step(&s1, r(2));
            self.state = Some(s1);
            return pr.valve.inverse(p_next - pr.valve.pole * p_now);
        }
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
    /// Samples whose feedforward was at the valve's range or not finite.
    at_limit: usize,
}

impl FeedforwardPid {
    pub fn new(pid: Pi, model: &ControlModel, label: impl Into<String>) -> anyhow::Result<Self> {
        Ok(FeedforwardPid {
            pid,
            inverse: InverseModel::new(model)?,
            label: label.into(),
            started: false,
            at_limit: 0,
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
        self.at_limit = 0;
    }

    fn command(&mut self, m: Measurement, reference: &[f64]) -> f64 {
        if !self.started {
            self.inverse
                .start(m.pressure_mpa, m.displacement_mm, reference[0]);
        }
        let ff = self.inverse.voltage(reference);
        let limits = &self.pid.limits;
        if !(ff > limits.min_v && ff < limits.max_v) {
            self.at_limit += 1;
        }
        if !self.started {
            // Bumpless: the integrator gives way to the feedforward.
            self.pid.shift_integral(-ff);
            self.started = true;
        }
        self.pid
            .command_with(m, self.inverse.clip(reference[0]), ff)
    }

    fn stats(&self) -> Option<ControllerStats> {
        Some(ControllerStats {
            feedforward_at_limit: self.at_limit,
            ..ControllerStats::default()
        })
    }
}
