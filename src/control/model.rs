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

use super::valve::ValveModel;
use crate::model::{Family, FittedModel};

/// What a model-based controller knows about the plant, identified from data
/// (`control::design`), never read from a plant's internals.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControlModel {
    /// Pressure (MPa) → displacement (mm): eq. 13, classic family (or the
    /// linear one, which has no `w`), in deviation coordinates.
    pub displacement: FittedModel,
    /// `b₂` (mm/MPa²): the curvature of the pressure → displacement map
    /// (0 for a model read from `fit` or `identify`).
    pub curvature: f64,
    pub valve: ValveModel,
}

/// The model's state at one sample: pressure (MPa, absolute), displacement
/// (mm, deviation from the model's output mean) and the Bouc-Wen state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct State {
    pub p: f64,
    pub x: f64,
    pub w: f64,
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
    /// `|w|^e` with the project's convention `|w|^0 = 1` (`model::sim::abs_pow`).
    fn pow(w: f64, e: f64) -> f64 {
        if e == 0.0 { 1.0 } else { w.abs().powf(e) }
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
        })
    }

    /// `x(k+1)` from the state at `k`, before any disturbance.
    pub fn next_x(&self, s: &State) -> f64 {
        let u = s.p - self.input_mean;
        self.rho * s.x + self.h * s.w + self.b * u + self.b2 * u * u + self.c
    }

    /// One step with valve voltage `v`; `dx`, `dp` are additive
    /// disturbances on the displacement and pressure equations.
    pub fn step(&self, s: &State, v: f64, dx: f64, dp: f64) -> State {
        let x = self.next_x(s) + dx;
        State {
            p: self.valve.step(s.p, v) + dp,
            x,
            w: self.hysteresis.step(s.w, x - s.x),
        }
    }

    /// The Jacobian of [`Predictor::step`] at `s`, `v`, where the step
    /// reached `next`.
    pub fn jacobian(&self, s: &State, v: f64, next: &State) -> Jacobian {
        let u = s.p - self.input_mean;
        let dx = [self.b + 2.0 * self.b2 * u, self.rho, self.h];
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
        displacement: FittedModel {
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

    #[test]
    fn bouc_wen_matches_the_reference_simulation() {
        let m = bw();
        for (w, d) in [(0.3, 0.2), (-0.7, 0.05), (1.1, -0.4), (0.0, 0.3)] {
            let reference = crate::model::sim::classic_w(1.0, 0.3, 0.5, 1.0, w as f32, d as f32);
            assert!((m.step(w, d) - reference as f64).abs() < 1e-6);
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let model = example_model();
        let pr = Predictor::new(&model).unwrap();
        let s = State {
            p: 0.25,
            x: 1.3,
            w: 0.4,
        };
        let v = 5.5;
        let next = pr.step(&s, v, 0.0, 0.0);
        let j = pr.jacobian(&s, v, &next);
        let eps = 1e-7;
        let as_vec = |s: &State| [s.p, s.x, s.w];
        for col in 0..3 {
            let mut sp = as_vec(&s);
            sp[col] += eps;
            let moved = pr.step(
                &State {
                    p: sp[0],
                    x: sp[1],
                    w: sp[2],
                },
                v,
                0.0,
                0.0,
            );
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
