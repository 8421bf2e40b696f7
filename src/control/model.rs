//! The prediction model of the model-based controllers, with its Jacobian:
//! the valve → pressure model ([`ValveModel`]) feeding the displacement model
//! of eq. 13 with its Bouc-Wen state, plus a curvature of the pressure →
//! displacement map. In deviation coordinates (`x = y − ȳ`, `u = p − ū`):
//!
//! ```text
//! x(k+1) = a·α·x(k) + a·(1−α)·w(k) + b·u(k) + b₂·u(k)² + c
//! w(k+1) = w(k) + A·Δ − β·|Δ|·|w(k)|^(n−1)·w(k) − γ·Δ·|w(k)|^n,   Δ = x(k+1) − x(k)
//! p(k+1) = π·p(k) + g(V(k))
//! ```
//!
//! The `w` update is `model::sim::classic_w` in `f64` (the reference there is
//! `f32` for the GPU's sake; a test pins the two together), and its partial
//! derivatives, which the MPC's linearisation needs.

use serde::{Deserialize, Serialize};

use super::chain::{ControlChain, MAX_EFFECT_STATES};
use super::valve::ValveModel;
use crate::model::{Family, FittedBaseline};

/// What a model-based controller knows about the plant, identified from data
/// (`control::design`), never read from a plant's internals.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControlModel {
    /// Pressure (MPa) → displacement (mm): eq. 13, classic family (or the
    /// linear one, which has no `w`), in deviation coordinates.
    pub displacement: FittedBaseline,
    /// `b₂` (mm/MPa²): the curvature of the pressure → displacement map
    /// (0 for a model read from `fit` or `identify`).
    pub curvature: f64,
    pub valve: ValveModel,
    /// The effects of a model read with `--from` that the prediction
    /// carries (`super::chain`); absent for a baseline.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chain: Option<ControlChain>,
    /// Start the Bouc-Wen state at rest at the first measurement (`w`
    /// solved from the displacement equation at rest), not at 0: set for a
    /// model from `--from`, whose `w` lives in the frame of the data it was
    /// fitted on (with `β`, `γ` near 0 its `w` barely forgets, and from
    /// `w = 0` at 30 mm such a model asks for several MPa). Absent (false)
    /// for the model identified here, which keeps today's numbers.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub rest_start: bool,
}

/// The model's state at one sample: pressure (MPa, absolute), displacement
/// (mm, deviation from the model's output mean) and the Bouc-Wen state;
/// with an effect chain also the effects' states and the pressure of the
/// sample before (the ringing's kick). Without a chain `e` stays 0 and
/// the output is `x`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct State {
    pub p: f64,
    pub x: f64,
    pub w: f64,
    pub e: [f64; MAX_EFFECT_STATES],
    pub p_prev: f64,
}

impl State {
    /// A state without effect states (`p_prev = p`).
    pub fn new(p: f64, x: f64, w: f64) -> State {
        State {
            p,
            x,
            w,
            e: [0.0; MAX_EFFECT_STATES],
            p_prev: p,
        }
    }
}

/// Partial derivatives of one step: `ds/ds` (rows and columns in the order
/// p, x, w) and `ds/dV`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jacobian {
    pub ds_ds: [[f64; 3]; 3],
    pub ds_dv: [f64; 3],
}

/// The classic Bouc-Wen parameters in `f64`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoucWen {
    pub big_a: f64,
    pub beta: f64,
    pub gamma: f64,
    pub n: f64,
}

impl BoucWen {
    /// `|w|^e` with the convention of `model::sim::abs_pow`: `|w|^0 = 1`
    /// and `0^e = 0` otherwise. For `n < 1` (`e < 0`) `0^e` is infinite,
    /// and the step's `0^e · w` was NaN where the fitted model's is `0`.
    fn pow(w: f64, e: f64) -> f64 {
        if e == 0.0 {
            1.0
        } else if w == 0.0 {
            0.0
        } else {
            w.abs().powf(e)
        }
    }

    /// `w(k+1)` after a displacement step `delta`.
    pub fn step(&self, w: f64, delta: f64) -> f64 {
        let pw = Self::pow(w, self.n - 1.0);
        w + self.big_a * delta
            - self.beta * delta.abs() * pw * w
            - self.gamma * delta * pw * w.abs()
    }

    /// `(∂w(k+1)/∂Δ, ∂w(k+1)/∂w(k))` (a subgradient at `Δ = 0` or `w = 0`).
    pub fn partials(&self, w: f64, delta: f64) -> (f64, f64) {
        let pw = Self::pow(w, self.n - 1.0);
        let d_delta = self.big_a - self.beta * delta.signum() * pw * w - self.gamma * pw * w.abs();
        let d_w = 1.0 - self.n * pw * (self.beta * delta.abs() + self.gamma * delta * w.signum());
        (d_delta, d_w)
    }
}

/// A predicted displacement (mm, from the model's mean) beyond this has
/// diverged: no muscle holds it.
pub const DIVERGED_MM: f64 = 1e4;

/// [`ControlModel`] unpacked for prediction.
#[derive(Debug, Clone, PartialEq)]
pub struct Predictor {
    /// `a·α`: the displacement's own pole.
    pub rho: f64,
    /// `a·(1−α)`: the weight of `w`.
    pub h: f64,
    pub b: f64,
    pub b2: f64,
    pub c: f64,
    pub hysteresis: BoucWen,
    pub valve: ValveModel,
    /// `ū` (MPa) and `ȳ` (mm) of the displacement model.
    pub input_mean: f64,
    pub output_mean: f64,
    /// The effects the prediction carries (`super::chain`).
    pub chain: Option<ControlChain>,
    /// [`ControlModel::rest_start`].
    pub rest_start: bool,
}

impl Predictor {
    /// Unpacks a classic or linear displacement model (`n` free allowed).
    pub fn new(model: &ControlModel) -> anyhow::Result<Predictor> {
        let m = &model.displacement;
        let get = |name: &str| m.family.index_of(name).map(|i| m.params[i]);
        let [ia, ib, ic] = m.family.linear_indices();
        let (a, b, c) = (m.params[ia], m.params[ib], m.params[ic]);
        let (alpha, hysteresis) = match m.family {
            Family::Linear => (
                1.0,
                BoucWen {
                    big_a: 0.0,
                    beta: 0.0,
                    gamma: 0.0,
                    n: 1.0,
                },
            ),
            Family::Classic => (
                get("alpha").unwrap_or(1.0),
                BoucWen {
                    big_a: get("A").unwrap_or(1.0),
                    beta: get("beta").unwrap_or(0.0),
                    gamma: get("gamma").unwrap_or(0.0),
                    n: get("n").unwrap_or(1.0),
                },
            ),
            Family::Generalized => anyhow::bail!(
                "the controller's model must be the classic or the linear family (got the generalized one)"
            ),
        };
        Ok(Predictor {
            rho: a * alpha,
            h: a * (1.0 - alpha),
            b,
            b2: model.curvature,
            c,
            hysteresis,
            valve: model.valve.clone(),
            input_mean: m.input_mean,
            output_mean: m.output_mean,
            chain: model.chain.clone(),
            rest_start: model.rest_start,
        })
    }

    /// The pressure deviation the displacement equation sees at absolute
    /// pressure `p` (after a dead zone), and its slope in `p`.
    fn input_of(&self, p: f64) -> (f64, f64) {
        match &self.chain {
            Some(c) => c.effective(p, self.input_mean),
            None => (p - self.input_mean, 1.0),
        }
    }

    /// `x(k+1)` from the state at `k`, before any disturbance.
    pub fn next_x(&self, s: &State) -> f64 {
        let u = self.input_of(s.p).0;
        self.rho * s.x + self.h * s.w + self.b * u + self.b2 * u * u + self.c
    }

    /// The predicted output (mm, deviation): `x` plus the effects'.
    pub fn output(&self, s: &State) -> f64 {
        match &self.chain {
            Some(c) => s.x + c.output(&s.e),
            None => s.x,
        }
    }

    /// One step with valve voltage `v`; `dx`, `dp` are additive
    /// disturbances on the displacement and pressure equations.
    pub fn step(&self, s: &State, v: f64, dx: f64, dp: f64) -> State {
        let x = self.next_x(s) + dx;
        let w = self.hysteresis.step(s.w, x - s.x);
        self.moved(s, self.valve.step(s.p, v) + dp, x, w)
    }

    /// The state after `s` with the new pressure, displacement and
    /// Bouc-Wen state given: the effect states advanced on `s`'s pressure.
    pub fn moved(&self, s: &State, p: f64, x: f64, w: f64) -> State {
        let e = match &self.chain {
            Some(c) => c.advance(&s.e, self.input_of(s.p).0, s.p - s.p_prev, x),
            None => s.e,
        };
        State {
            p,
            x,
            w,
            e,
            p_prev: s.p,
        }
    }

    /// The state at the first measurement, pressure `p` and output `y`
    /// (deviation): the effects' as [`ControlChain::start`] says, `w = 0`
    /// (or at rest with [`ControlModel::rest_start`]).
    pub fn at_start(&self, p: f64, y: f64) -> State {
        let mut s = match &self.chain {
            Some(c) => {
                let (x, e) = c.start(y);
                State {
                    e,
                    ..State::new(p, x, 0.0)
                }
            }
            None => State::new(p, y, 0.0),
        };
        if self.rest_start && self.h.abs() > 1e-12 {
            // x = ρ·x + h·w + b·u + b₂·u² + c at rest, solved for w.
            let u = self.input_of(p).0;
            s.w = ((1.0 - self.rho) * s.x - self.b * u - self.b2 * u * u - self.c) / self.h;
        }
        s
    }

    /// The Jacobian of [`Predictor::step`] at `s`, `v`, where the step
    /// reached `next`.
    pub fn jacobian(&self, s: &State, v: f64, next: &State) -> Jacobian {
        let (u, slope) = self.input_of(s.p);
        let du = self.b + 2.0 * self.b2 * u;
        let dx = [
            if self.chain.is_some() { du * slope } else { du },
            self.rho,
            self.h,
        ];
        let (w_delta, w_w) = self.hysteresis.partials(s.w, next.x - s.x);
        let dw = [
            w_delta * dx[0],
            w_delta * (dx[1] - 1.0),
            w_delta * dx[2] + w_w,
        ];
        Jacobian {
            ds_ds: [[self.valve.pole, 0.0, 0.0], dx, dw],
            ds_dv: [self.valve.slope(v), 0.0, 0.0],
        }
    }
}

/// A classic control model with a hysteresis loop and a valve map, for tests.
#[cfg(test)]
pub(crate) fn example_model() -> ControlModel {
    ControlModel {
        displacement: FittedBaseline {
            family: Family::Classic,
            params: vec![1.0, 1.07, 0.1, 0.6, 1.0, 0.87, 7.5, 0.05, 0.0],
            input_mean: 0.2,
            output_mean: 25.0,
            dt: 0.01,
            input_name: "pressure".into(),
            output_name: "displacement".into(),
        },
        curvature: -9.0,
        valve: ValveModel {
            pole: 0.92,
            map: (0..11).map(|i| 0.004 * i as f64 - 0.01).collect(),
        },
        chain: None,
        rest_start: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bw() -> BoucWen {
        BoucWen {
            big_a: 1.0,
            beta: 0.3,
            gamma: 0.5,
            n: 1.0,
        }
    }

    /// Every exponent a model may have, below 1 too, where `|w|^(n−1)` is
    /// infinite at `w = 0` and the convention must be the reference's.
    #[test]
    fn bouc_wen_matches_the_reference_simulation() {
        for n in [1.0, 0.5, 2.5] {
            let m = BoucWen { n, ..bw() };
            for (w, d) in [(0.3, 0.2), (-0.7, 0.05), (1.1, -0.4), (0.0, 0.3)] {
                let reference =
                    crate::model::sim::classic_w(1.0, 0.3, 0.5, n as f32, w as f32, d as f32);
                let step = m.step(w, d);
                assert!(
                    (step - reference as f64).abs() < 1e-6,
                    "n {n}, w {w}: {step}"
                );
                let (d_delta, d_w) = m.partials(w, d);
                assert!(d_delta.is_finite() && d_w.is_finite(), "n {n}, w {w}");
            }
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let model = example_model();
        let pr = Predictor::new(&model).unwrap();
        let s = State::new(0.25, 1.3, 0.4);
        let v = 5.5;
        let next = pr.step(&s, v, 0.0, 0.0);
        let j = pr.jacobian(&s, v, &next);
        let eps = 1e-7;
        let as_vec = |s: &State| [s.p, s.x, s.w];
        for col in 0..3 {
            let mut sp = as_vec(&s);
            sp[col] += eps;
            let moved = pr.step(&State::new(sp[0], sp[1], sp[2]), v, 0.0, 0.0);
            let d = as_vec(&moved);
            let base = as_vec(&next);
            for row in 0..3 {
                let fd = (d[row] - base[row]) / eps;
                assert!((fd - j.ds_ds[row][col]).abs() < 1e-5, "{row},{col}");
            }
        }
        let moved = pr.step(&s, v + 1e-6, 0.0, 0.0);
        assert!(((moved.p - next.p) / 1e-6 - j.ds_dv[0]).abs() < 1e-9);
    }
}
