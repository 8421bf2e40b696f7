//! The augmented step: `L` candidates of an augmented model advanced side by
//! side ([`Prepared::step`]), the one definition the scalar simulation, the
//! CPU batch path and `shaders/effects.wgsl` follow, and the simulations and
//! sums of squared errors built on it. The baseline's part is here; each
//! realisation's stage is its own (`stages/`), run where the step order in
//! `catalogue.rs` places it.

use super::catalogue::{Stages, States};
use super::stage::{At, Columns, Frame};
use super::{Context, ModelDescription};
use crate::model::sim::{
    classic_w, generalized_w, in_bounds, linear_part, linear_step, restart_w, switch_threshold,
};
use crate::model::{Experiment, Family, Measure};

/// `L` candidates' augmented model on one dataset, unpacked for the inner
/// loop, lane `l` in slot `l` of every array: the baseline's parameters,
/// each present realisation's constants and the dataset's. `L = 1` is the
/// scalar simulation; the CPU batch path ([`crate::eval::effects`]) runs
/// [`crate::eval::cpu::LANES`] side by side.
///
/// [`Prepared::step`] is the one definition of the augmented step: both
/// follow it, and the WGSL kernel (`shaders/effects.wgsl`) spells the same
/// operations in the same order. Each stage is a loop over the lanes under a
/// test that is the same for every lane (which effects are present), so the
/// compiler turns the loops into vector instructions. Minima and maxima are
/// written as comparisons, and the input rate is multiplied by `1/dt`, so
/// that no operation depends on how a platform treats signed zeros or
/// divides.
#[derive(Debug, Clone)]
pub struct Prepared<const L: usize> {
    family: Family,
    /// Every lane has `n = 1` (compiled without `powf`, as the plain path).
    n_one: bool,
    a: [f32; L],
    alpha: [f32; L],
    b: [f32; L],
    c: [f32; L],
    x0: [f32; L],
    big_a: [f32; L],
    n: [f32; L],
    /// β, γ (classic) or β₁..β₆ (generalized).
    betas: [[f32; L]; 6],
    /// Where the generalized sign terms in `x` switch, in the dataset's
    /// deviation coordinates ([`switch_threshold`]; 0 for the others).
    threshold: [f32; L],
    /// Each realisation's constants, `None` where the model lacks it.
    stages: Stages<L>,
    frame: Frame,
}

/// The states an augmented model carries from sample to sample, per lane:
/// the baseline's output `x` and Bouc-Wen state `w`, and the realisations'
/// own. Laid out in order and aligned to a cache line, so that every lane
/// array starts on one (128 bytes each at `L = 32`): a vector load of an
/// array that straddles two lines costs two (docs/PERFORMANCE.md, "Effect
/// stages on the CPU batch path").
#[derive(Debug, Clone)]
#[repr(C, align(64))]
pub struct EffectState<const L: usize> {
    pub x: [f32; L],
    pub w: [f32; L],
    stages: States<L>,
    /// Whether a step was taken (the play and the lags start at the first
    /// input).
    started: bool,
}

impl<const L: usize> Prepared<L> {
    /// The state at the first sample, from the first measured output `y0`
    /// and the first input `u0` ([`crate::model::sim::Stepper::start`]).
    #[inline(always)]
    pub fn start(&self, y0: f32, u0: f32) -> EffectState<L> {
        let x = std::array::from_fn(|l| y0 + self.x0[l]);
        EffectState {
            x,
            w: [0.0; L],
            stages: self.stages.start(&x, u0),
            started: false,
        }
    }

    /// Advances one sample, `k ≥ 1`, on the input `u`; returns the predicted
    /// output `ŷ(k)` of every lane.
    ///
    /// Input side, state side (the baseline's equations, `model::sim`, in
    /// one loop over the lanes with the state side's first stages, so that
    /// the new output stays in registers from the linear part to the end
    /// stop: stage loops of their own spilled it between them), the
    /// Bouc-Wen state, output side.
    #[inline(always)]
    pub fn step(&self, s: &mut EffectState<L>, k: usize, u: &[f32]) -> [f32; L] {
        let raw = u[k - 1];
        let at = At {
            u,
            k,
            raw,
            started: s.started,
            x: &s.x,
            frame: &self.frame,
        };
        s.started = true;
        let mut ui = [raw; L];
        self.stages.input(&mut s.stages, &mut ui, &at);
        let linear = self.family == Family::Linear;
        let mut xk = [0.0f32; L];
        self.stages.state_before(&mut s.stages, &at);
        for l in 0..L {
            let x = if linear {
                linear_step(self.a[l], self.b[l], self.c[l], s.x[l], ui[l])
            } else {
                linear_part(
                    self.a[l],
                    self.alpha[l],
                    self.b[l],
                    self.c[l],
                    s.x[l],
                    s.w[l],
                    ui[l],
                )
            };
            xk[l] = self.stages.state_lane(&mut s.stages, l, x, &at);
        }
        self.stages.state_after(&mut s.stages, &at);
        let mut a_eff = self.big_a;
        self.stages.state(&mut s.stages, &mut xk, &mut a_eff, &at);
        self.hysteresis(&s.x, &mut s.w, &xk, &a_eff);
        let mut y = xk;
        self.stages.output(&mut s.stages, &mut y, &ui, &xk, &at);
        // Last: the stages read x(k−1) from `at` up to here.
        s.x = xk;
        y
    }

    /// The Bouc-Wen state `w` of every lane after the output moved from `x`
    /// to `xk` under the stiffness `a_eff` ([`crate::model::sim::Stepper::hysteresis`]).
    #[inline(always)]
    fn hysteresis(&self, x: &[f32; L], w: &mut [f32; L], xk: &[f32; L], a_eff: &[f32; L]) {
        let bt = &self.betas;
        match (self.family, self.n_one) {
            (Family::Linear, _) => *w = [0.0; L],
            (Family::Classic, true) => {
                for l in 0..L {
                    let delta = xk[l] - x[l];
                    w[l] = classic_w(a_eff[l], bt[0][l], bt[1][l], 1.0, w[l], delta);
                }
            }
            (Family::Classic, false) => {
                for l in 0..L {
                    let delta = xk[l] - x[l];
                    w[l] = classic_w(a_eff[l], bt[0][l], bt[1][l], self.n[l], w[l], delta);
                }
            }
            (Family::Generalized, n_one) => {
                for l in 0..L {
                    let betas = [bt[0][l], bt[1][l], bt[2][l], bt[3][l], bt[4][l], bt[5][l]];
                    let n = if n_one { 1.0 } else { self.n[l] };
                    let delta = xk[l] - x[l];
                    let threshold = self.threshold[l];
                    w[l] = generalized_w(a_eff[l], &betas, n, w[l], xk[l], delta, threshold);
                }
            }
        }
    }

    /// Whether lane `l`'s states after a step that predicted `y_hat` are in
    /// bounds.
    #[inline(always)]
    pub fn in_bounds(s: &EffectState<L>, l: usize, y_hat: f32) -> bool {
        in_bounds(s.x[l]) & in_bounds(s.w[l]) & in_bounds(y_hat)
    }

    /// A restart of the prediction to the measurement `y`: the output state
    /// takes `y` less what the realisations add to the output (each one's
    /// restart term, which may also restart its states: the load mode and
    /// the output lag restart at `y`), and the Bouc-Wen state the jump's
    /// elastic part, as the baseline's ([`crate::model::sim::Stepper::restart`]);
    /// the other states run on.
    #[inline(always)]
    pub fn restart(&self, s: &mut EffectState<L>, y: f32) {
        for l in 0..L {
            let x = Stages::restart(&mut s.stages, l, y);
            s.w[l] = restart_w(self.big_a[l], s.w[l], s.x[l], x);
            s.x[l] = x;
        }
    }
}

impl ModelDescription {
    /// Unpacks `L` rows of parameters (`rows`: row-major, `L × dim`) for
    /// dataset `dataset` with its context.
    pub fn prepare<const L: usize>(
        &self,
        rows: &[f32],
        dataset: usize,
        ctx: &Context,
    ) -> Prepared<L> {
        let d = self.dim();
        assert_eq!(
            rows.len(),
            L * d,
            "augmented model takes {d} parameters per candidate"
        );
        let col = |j: usize| -> [f32; L] { std::array::from_fn(|l| rows[l * d + j]) };
        let fam = self.family;
        let [ia, ib, ic] = fam.linear_indices();
        let n = fam.exponent_index().map_or([1.0; L], col);
        let (big_a, alpha, betas) = match fam {
            Family::Linear => ([0.0; L], [1.0; L], [[0.0; L]; 6]),
            Family::Classic => {
                let mut betas = [[0.0; L]; 6];
                betas[0] = col(2);
                betas[1] = col(3);
                (col(0), col(1), betas)
            }
            Family::Generalized => (col(0), col(1), std::array::from_fn(|j| col(2 + j))),
        };
        let frame = Frame::of(ctx, dataset);
        let threshold = fam.switch_index().map_or([0.0; L], |i| {
            col(i).map(|x_s| switch_threshold(x_s, frame.y_mean))
        });
        let mut stages = Stages::none();
        let mut at = fam.dim();
        for &e in &self.effects {
            stages.prepare(e, &Columns { rows, dim: d, at }, &frame);
            at += e.dim(self.datasets);
        }
        Prepared {
            family: fam,
            n_one: n.iter().all(|&v| v == 1.0),
            a: col(ia),
            alpha,
            b: col(ib),
            c: col(ic),
            x0: col(fam.start_index()),
            big_a,
            n,
            betas,
            threshold,
            stages,
            frame,
        }
    }

    /// Runs the model on dataset `dataset` (input `u`, deviation
    /// coordinates) from the measured `y0`, calling `sink(k, ŷ(k))` for
    /// `k ≥ 1`; returns false (and stops) at the first state out of bounds.
    /// With `restart = Some((y, h))` the prediction restarts from the
    /// measured `y(k)` after every `h`-th sample ([`Prepared::restart`]):
    /// the `h`-step-ahead predictor of [`ModelDescription::sse_ahead`].
    #[allow(clippy::too_many_arguments)] // the simulation's inputs, one each
    fn run(
        &self,
        theta: &[f32],
        dataset: usize,
        ctx: &Context,
        u: &[f32],
        y0: f32,
        restart: Option<(&[f32], usize)>,
        mut sink: impl FnMut(usize, f32),
    ) -> bool {
        let p: Prepared<1> = self.prepare(theta, dataset, ctx);
        let mut s = p.start(y0, u.first().copied().unwrap_or(0.0));
        for k in 1..u.len() {
            let [yk] = p.step(&mut s, k, u);
            if !Prepared::in_bounds(&s, 0, yk) {
                return false;
            }
            sink(k, yk);
            if let Some((y, h)) = restart
                && k % h == 0
            {
                p.restart(&mut s, y[k]);
            }
        }
        true
    }

    /// Free-run prediction `ŷ` on dataset `dataset` (deviation coordinates),
    /// `ŷ(0) = y(0)`; non-finite from the first diverged sample on.
    pub fn simulate(
        &self,
        theta: &[f32],
        dataset: usize,
        ctx: &Context,
        exp: &Experiment,
    ) -> Vec<f32> {
        let y0 = exp.y.first().copied().unwrap_or(0.0);
        let mut out = vec![f32::NAN; exp.len()];
        if let Some(first) = out.first_mut() {
            *first = y0;
        }
        self.run(theta, dataset, ctx, &exp.u, y0, None, |k, v| out[k] = v);
        out
    }

    /// `Σ_{k≥1} (ŷ(k) − y(k))²` of the free run in `f32`, `+∞` if the
    /// simulation diverged.
    pub fn sse(&self, theta: &[f32], dataset: usize, ctx: &Context, exp: &Experiment) -> f32 {
        self.measured_sse(theta, dataset, ctx, exp, Measure::FreeRun)
    }

    /// The same sum for the `horizon`-step-ahead prediction: the output
    /// state restarts from the measurement every `horizon` samples (the
    /// effects' states run on). MATLAB's `Focus` "prediction" against
    /// "simulation": errors cannot pile up through a slow pole for longer
    /// than the horizon, so the cost surface has no needle along the pole
    /// and the static gain, which the free run has.
    pub fn sse_ahead(
        &self,
        theta: &[f32],
        dataset: usize,
        ctx: &Context,
        exp: &Experiment,
        horizon: usize,
    ) -> f32 {
        let measure = Measure::Ahead {
            horizon: horizon.max(1),
        };
        self.measured_sse(theta, dataset, ctx, exp, measure)
    }

    /// The sum of squared errors under `measure`, `+∞` if the simulation
    /// diverged: what every backend's batch path reproduces bit for bit.
    pub fn measured_sse(
        &self,
        theta: &[f32],
        dataset: usize,
        ctx: &Context,
        exp: &Experiment,
        measure: Measure,
    ) -> f32 {
        if exp.is_empty() {
            return 0.0;
        }
        let mut acc = 0.0f32;
        let restart = Some((exp.y.as_slice(), measure.restart_every()));
        let ok = self.run(theta, dataset, ctx, &exp.u, exp.y[0], restart, |k, v| {
            let e = v - exp.y[k];
            acc += e * e;
        });
        if ok { acc } else { f32::INFINITY }
    }

    /// The errors `ŷ(k) − y(k)`, `k ≥ 1`, under `measure`; `None` if the
    /// simulation diverged.
    pub fn residuals(
        &self,
        theta: &[f32],
        dataset: usize,
        ctx: &Context,
        exp: &Experiment,
        measure: Measure,
    ) -> Option<Vec<f32>> {
        let mut r = Vec::with_capacity(exp.len().saturating_sub(1));
        let restart = Some((exp.y.as_slice(), measure.restart_every()));
        let y0 = exp.y.first().copied().unwrap_or(0.0);
        self.run(theta, dataset, ctx, &exp.u, y0, restart, |k, v| {
            r.push(v - exp.y[k])
        })
        .then_some(r)
    }
}
