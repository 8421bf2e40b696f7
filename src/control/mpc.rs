//! Model predictive control with the hysteresis in its model, a quadratic
//! program at every sample.
//!
//! The thesis' MPC (§6.3) failed because the Bouc-Wen model made CVXGEN's
//! problem non-convex. Here the nonlinear model ([`Predictor`]: valve map,
//! eq. 13 with its Bouc-Wen state, curvature) is linearised at every sample
//! along the previous plan shifted by one sample — the real-time iteration
//! of nonlinear MPC (Diehl, Bock & Schlöder, "A real-time iteration scheme
//! for nonlinear optimization in optimal feedback control", SIAM J. Control
//! Optim. 43(5), 2005). The predicted displacement is then affine in the
//! valve plan, with sensitivities that carry the hysteresis' local slope
//! (stiff just after a reversal, soft once the loop saturates) and the valve
//! map's; tracking the reference over the horizon under the valve range and
//! slew limit is a convex QP, solved exactly by a warm-started active-set
//! method ([`super::qp`]). The valve voltage is the QP's variable, so the
//! limits are exact constraints, never clipped afterwards.
//!
//! Reference preview: the QP tracks the reference at every sample of the
//! horizon, so the plan moves the valve before the reference turns.
//! Offset-free: the observer's integrating disturbances ([`super::observer`]).

use serde::{Deserialize, Serialize};

use super::chain::MAX_EFFECT_STATES;
use super::controller::{Controller, ControllerStats};
use super::limits::ValveLimits;
use super::model::{ControlModel, Predictor, State};
use super::observer::{Observer, ObserverGains};
use super::plant::Measurement;
use super::qp::{ActiveSetQp, Limits};

/// Tuning of the MPC.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MpcSettings {
    /// Prediction horizon in samples: 20 (0.2 s at 10 ms) spans the rig's
    /// time constant and a sixth of a 3 rad/s period.
    pub horizon: usize,
    /// Weight of the squared tracking error (per mm²).
    pub q_error: f64,
    /// Weight of the squared valve move (per V²).
    pub r_move: f64,
    /// Linearisations per sample: the second and later re-linearise along
    /// the plan just found.
    pub passes: usize,
    /// Active-set iterations per QP at most; a solve cut short still gives a
    /// feasible plan.
    pub max_qp_iterations: usize,
    pub observer: ObserverGains,
}

impl Default for MpcSettings {
    fn default() -> Self {
        MpcSettings {
            horizon: 20,
            q_error: 1.0,
            r_move: 0.1,
            passes: 2,
            max_qp_iterations: 60,
            observer: ObserverGains::default(),
        }
    }
}

/// The MPC controller.
pub struct Mpc {
    pub settings: MpcSettings,
    pub limits: ValveLimits,
    predictor: Predictor,
    observer: Observer,
    qp: ActiveSetQp,
    label: String,
    prev_u: f64,
    /// The plan of the last sample (valve voltages, first one applied).
    plan: Vec<f64>,
    pub stats: ControllerStats,
    // Buffers reused every sample.
    states: Vec<State>,
    /// `gx[j·n + i] = ∂y(j)/∂V(i)`, j = 0..=N+1, `y` the predicted output
    /// (`x` without an effect chain).
    gx: Vec<f64>,
    hessian: Vec<f64>,
    linear: Vec<f64>,
}

impl Mpc {
    /// An MPC on `model`; fails if the model's family has no predictor.
    pub fn new(
        model: &ControlModel,
        settings: MpcSettings,
        limits: ValveLimits,
        label: impl Into<String>,
    ) -> anyhow::Result<Mpc> {
        anyhow::ensure!(
            settings.horizon >= 2,
            "the MPC horizon must be at least 2 samples"
        );
        anyhow::ensure!(
            settings.r_move > 0.0 && settings.q_error > 0.0,
            "the MPC weights must be positive"
        );
        Ok(Mpc {
            settings,
            limits,
            predictor: Predictor::new(model)?,
            observer: Observer::new(settings.observer),
            qp: ActiveSetQp::default(),
            label: label.into(),
            prev_u: 0.0,
            plan: Vec::new(),
            stats: ControllerStats::default(),
            states: Vec::new(),
            gx: Vec::new(),
            hessian: Vec::new(),
            linear: Vec::new(),
        })
    }

    /// The plan shifted by one sample, its last voltage repeated.
    fn shift_plan(&mut self) {
        let n = self.settings.horizon;
        if self.plan.len() != n {
            self.plan = vec![self.prev_u; n];
            self.qp.clear();
        } else {
            self.plan.rotate_left(1);
            self.plan[n - 1] = self.plan[n - 2];
            self.qp.shift();
        }
    }

    /// Rolls the model out along the plan from `s0` and fills the states and
    /// the displacement's sensitivities to the plan. `false` if the
    /// prediction left the finite numbers.
    fn linearise(&mut self, s0: State) -> bool {
        let n = self.settings.horizon;
        let pr = &self.predictor;
        let (dx, dp) = (self.observer.dx, self.observer.dp);
        self.states.clear();
        self.states.push(s0);
        self.gx.clear();
        self.gx.resize((n + 2) * n, 0.0);
        // Sensitivities of (p, x, w) at step j to each V(i), one column per i.
        let mut sens = vec![[0.0f64; 3]; n];
        // With an effect chain, those of its states and of p(j−1): the
        // chain is linear, so its step maps sensitivities to sensitivities
        // (`super::chain`).
        let chain = pr.chain.as_ref();
        let mut sens_e = vec![([0.0f64; MAX_EFFECT_STATES], 0.0f64); chain.map_or(0, |_| n)];
        for j in 0..=n {
            let input = j.min(n - 1);
            let v = self.plan[input];
            let s = self.states[j];
            let next = pr.step(&s, v, dx, dp);
            if !(next.x.is_finite() && next.p.is_finite() && next.w.is_finite()) {
                return false;
            }
            let jac = pr.jacobian(&s, v, &next);
            let slope = chain.map_or(1.0, |c| c.effective(s.p, pr.input_mean).1);
            for (i, col) in sens.iter_mut().enumerate() {
                let old = *col;
                for (value, row) in col.iter_mut().zip(&jac.ds_ds) {
                    *value = row.iter().zip(&old).map(|(a, b)| a * b).sum::<f64>();
                }
                if i == input {
                    for (value, d) in col.iter_mut().zip(&jac.ds_dv) {
                        *value += d;
                    }
                }
                self.gx[(j + 1) * n + i] = match chain {
                    None => col[1],
                    Some(c) => {
                        let (e, p_prev) = sens_e[i];
                        let e = c.advance(&e, slope * old[0], old[0] - p_prev, col[1]);
                        sens_e[i] = (e, old[0]);
                        col[1] + c.output(&e)
                    }
                };
            }
            self.states.push(next);
        }
        true
    }

    /// The prediction the MPC optimises over: from the state `s0` along
    /// the valve `plan` (one voltage per sample of the horizon, the last
    /// held), the predicted output (mm, absolute) at samples `0..=N+1` and
    /// its sensitivities to the plan, `∂y(j)/∂V(i)` at `[j·N + i]`; `None`
    /// if the prediction diverges. The observer's disturbances are those
    /// of the last sample (0 before the first). What the tests check the
    /// plan's predictions and sensitivities by.
    pub fn rollout(&mut self, s0: State, plan: &[f64]) -> Option<(Vec<f64>, Vec<f64>)> {
        assert_eq!(plan.len(), self.settings.horizon, "one voltage per sample");
        self.plan = plan.to_vec();
        if !self.linearise(s0) {
            return None;
        }
        let pr = &self.predictor;
        let y = self
            .states
            .iter()
            .map(|s| pr.output(s) + pr.output_mean)
            .collect();
        Some((y, self.gx.clone()))
    }

    /// Builds `½VᵀHV + fᵀV` for the linearised tracking cost
    /// `q·Σ_{j=2}^{N+1} (x̄ⱼ + Gⱼ(V − V̄) − rⱼ)² + r·Σᵢ (Vᵢ − Vᵢ₋₁)²`, `V₋₁` the
    /// command in force. `x(1)` does not depend on the plan (the pressure
    /// acts one sample late), hence `j ≥ 2`.
    fn build_qp(&mut self, reference: &[f64]) {
        let n = self.settings.horizon;
        let (q, r) = (self.settings.q_error, self.settings.r_move);
        let pr = &self.predictor;
        let target = |j: usize| {
            let r = reference[j.min(reference.len() - 1)];
            match &pr.chain {
                Some(c) => c.clip_reference(r) - pr.output_mean,
                None => r - pr.output_mean,
            }
        };
        self.hessian.clear();
        self.hessian.resize(n * n, 0.0);
        self.linear.clear();
        self.linear.resize(n, 0.0);
        for j in 2..=n + 1 {
            let row = &self.gx[j * n..(j + 1) * n];
            let offset = pr.output(&self.states[j])
                - target(j)
                - row.iter().zip(&self.plan).map(|(g, v)| g * v).sum::<f64>();
            for i in 0..n {
                if row[i] == 0.0 {
                    continue;
                }
                self.linear[i] += 2.0 * q * row[i] * offset;
                for l in 0..n {
                    self.hessian[i * n + l] += 2.0 * q * row[i] * row[l];
                }
            }
        }
        // Moves: DᵀD is tridiagonal with 2 on the diagonal (1 on the last).
        for i in 0..n {
            self.hessian[i * n + i] += 2.0 * r * if i + 1 < n { 2.0 } else { 1.0 };
            if i + 1 < n {
                self.hessian[i * n + i + 1] -= 2.0 * r;
                self.hessian[(i + 1) * n + i] -= 2.0 * r;
            }
        }
        self.linear[0] -= 2.0 * r * self.prev_u;
    }
}

impl Controller for Mpc {
    fn name(&self) -> &str {
        &self.label
    }

    fn reset(&mut self, u0: f64) {
        self.prev_u = u0;
        self.plan.clear();
        self.observer.reset();
        self.qp.clear();
        self.stats = ControllerStats::default();
    }

    fn command(&mut self, m: Measurement, reference: &[f64]) -> f64 {
        let s0 = self.observer.update(&self.predictor, m, self.prev_u);
        self.shift_plan();
        let (lo, hi) = self.limits.window(self.prev_u);
        let limits = Limits {
            first: (lo, hi),
            range: (self.limits.min_v, self.limits.max_v),
            slew: self.limits.slew_v_per_step,
        };
        let mut solved = false;
        for _ in 0..self.settings.passes.max(1) {
            if !self.linearise(s0) {
                break;
            }
            self.build_qp(reference);
            let mut plan = std::mem::take(&mut self.plan);
            let outcome = self.qp.solve(
                &self.hessian,
                &self.linear,
                &limits,
                &mut plan,
                self.settings.max_qp_iterations,
            );
            self.plan = plan;
            let Some(outcome) = outcome else {
                break;
            };
            solved = true;
            self.stats.max_qp_iterations = self.stats.max_qp_iterations.max(outcome.iterations);
            if !outcome.optimal {
                self.stats.capped_solves += 1;
            }
        }
        let u = if solved {
            // The solver's iterates are feasible up to rounding.
            self.limits.clamp(self.plan[0], self.prev_u)
        } else {
            self.stats.solver_failures += 1;
            self.plan.clear();
            self.prev_u
        };
        self.prev_u = u;
        u
    }

    fn stats(&self) -> Option<ControllerStats> {
        Some(self.stats)
    }

    fn missed(&mut self, held: f64) {
        self.observer.coast(&self.predictor, self.prev_u);
        self.shift_plan();
        self.prev_u = held;
    }
}
