//! The augmented step: `L` candidates of an augmented model advanced side by
//! side ([`Prepared::step`]), the one definition the scalar simulation, the
//! CPU batch path and `shaders/effects.wgsl` follow, and the simulations and
//! sums of squared errors built on it.
//!
//! (Over 700 lines: the step holds a stage for each realisation of the
//! catalogue in one function, so that the lanes' values stay in
//! registers from stage to stage; the runs and sums on it follow.)

use super::{Augmented, Context, Effect};
use crate::model::sim::{classic_w, generalized_w, in_bounds, linear_part, linear_step, restart_w};
use crate::model::{Experiment, Family, Measure};

/// `L` candidates' augmented model on one dataset, unpacked for the inner
/// loop, lane `l` in slot `l` of every array: the baseline's parameters,
/// each present effect's parameters and the dataset's constants. `L = 1`
/// is the scalar simulation; the CPU batch path ([`crate::eval::effects`])
/// runs [`crate::eval::cpu::LANES`] side by side.
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
    /// The delay split into whole samples and the fraction of the sample
    /// before them, once per candidate rather than once per sample.
    delay: Option<([i32; L], [f32; L])>,
    deadzone: Option<[f32; L]>,
    /// The end stop in deviation coordinates, times [`Prepared::toward`].
    saturation: Option<[f32; L]>,
    asymmetry: Option<[f32; L]>,
    inertia: Option<[f32; L]>,
    backlash: Option<[f32; L]>,
    creep: Option<([f32; L], [f32; L])>,
    /// The creeps' slow states at the first sample (0 without the effect):
    /// the input-driven one's, the output-driven one's and the two-pole
    /// creep's slower one's.
    z0: [f32; L],
    z0_out: [f32; L],
    z0_slow: [f32; L],
    rate: Option<[f32; L]>,
    load: Option<[f32; L]>,
    input_lag: Option<[f32; L]>,
    output_lag: Option<[f32; L]>,
    /// The load mode's `a1`, `a2` and its input weight `(1 − a1) + a2`.
    mode: Option<([f32; L], [f32; L], [f32; L])>,
    drain_lag: Option<[f32; L]>,
    /// The output clip's bound in deviation coordinates, times
    /// [`Prepared::toward`].
    output_clip: Option<[f32; L]>,
    /// The soft stop's bound in deviation coordinates, times [`Prepared::toward`].
    soft_stop: Option<[f32; L]>,
    output_creep: Option<([f32; L], [f32; L])>,
    two_pole_creep: Option<[[f32; L]; 4]>,
    /// The log-time creep's poles and input weights `(1 − ρ)·κ`, fastest
    /// first, and its slowest term's start.
    log_creep: Option<[[f32; L]; 6]>,
    z0_log: [f32; L],
    /// The hysteretic threshold's `p_on` and `p_off` in deviation
    /// coordinates.
    on_off: Option<([f32; L], [f32; L])>,
    /// The ringing's `a1`, `a2` and kick `g`.
    ringing: Option<([f32; L], [f32; L], [f32; L])>,
    /// [`Context::knee`] and [`Context::rest_input`].
    knee: [f32; 3],
    rest: f32,
    u_mean: f32,
    branch_tol: f32,
    inv_dt: f32,
    drives_up: bool,
}

/// The states an augmented model carries from sample to sample, per lane:
/// the baseline's output `x` and Bouc-Wen state `w`, and the effects' own.
/// Laid out in order and aligned to a cache line, so that every lane array
/// starts on one (the arrays come first, 128 bytes each at `L = 32`): a
/// vector load of an array that straddles two lines costs two (measured:
/// docs/lab/performance.md).
#[derive(Debug, Clone)]
#[repr(C, align(64))]
pub struct EffectState<const L: usize> {
    pub x: [f32; L],
    pub w: [f32; L],
    /// The delayed input of the sample before, `u(j−1)` for the delay's
    /// interpolation.
    delayed: [f32; L],
    /// `x(k−2)`, for the inertia's extra pole.
    x_prev2: [f32; L],
    /// The play's output (backlash), from the first step on.
    play: [f32; L],
    /// The creep's slow state.
    z: [f32; L],
    /// The input lag's, the drain lag's and the output lag's states.
    lag_in: [f32; L],
    drain: [f32; L],
    lag_out: [f32; L],
    /// The load mode's output at the two samples before.
    mode1: [f32; L],
    mode2: [f32; L],
    /// The output-driven creep's and the two-pole creep's slow states.
    z_out: [f32; L],
    z_fast: [f32; L],
    z_slow: [f32; L],
    /// The log-time creep's terms, fastest first.
    log_fast: [f32; L],
    log_mid: [f32; L],
    log_slow: [f32; L],
    /// 1 while the hysteretic threshold is on, else 0.
    on: [f32; L],
    /// The ringing at the sample before and the one before that.
    ring1: [f32; L],
    ring2: [f32; L],
    /// Whether a step was taken (the play and the lags start at the first
    /// input).
    started: bool,
    /// Branch of the asymmetry: +1 loading, −1 unloading, 0 not yet moved.
    /// It follows the measured input only, so it is the same in every lane.
    dir: f32,
    /// The input's extreme on the current branch.
    extreme: f32,
}

/// `a` if it is the larger (ties and NaN: `b`), spelled as in the shader.
#[inline(always)]
fn larger(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// `a` if it is the smaller (ties and NaN: `b`), spelled as in the shader.
#[inline(always)]
fn smaller(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// The soft end stop on an output that the input drives up: `x` blended
/// into `bound` over `bound − h` by a quadratic whose slope runs from 1 to 0
/// (`knee` = [`Context::knee`]), `bound` beyond; `x` itself short of the
/// knee. A stop below is this one on `−x` and `−bound`, negated: the same
/// bits as writing it out (negation is exact, and `(b + h) − x` is
/// `−x − (−b − h)`).
#[inline(always)]
fn soft_stop(x: f32, bound: f32, knee: [f32; 3]) -> f32 {
    let [h, two_h, inv_4h] = knee;
    // How far into the knee x is.
    let into = x - (bound - h);
    let bend = (into * into) * inv_4h;
    let bent = x - bend;
    if into <= 0.0 {
        x
    } else if into >= two_h {
        bound
    } else {
        bent
    }
}

/// `ρ^10` by products (`ρ²`, `ρ⁴`, `ρ⁸·ρ²`), spelled as in the shader: a
/// pole whose time constant is a tenth of `ρ`'s.
#[inline(always)]
fn tenth_power(rho: f32) -> f32 {
    let p2 = rho * rho;
    let p4 = p2 * p2;
    (p4 * p4) * p2
}

/// A delay of `d ≥ 0` samples as whole samples and the fraction of a sample
/// beyond them (`d − ⌊d⌋`, exact in `f32`).
#[inline(always)]
fn split_delay(d: f32) -> (i32, f32) {
    let whole = d.floor();
    (whole as i32, d - whole)
}

/// The input `whole + frac` samples before `u(last)`, `last = k − 1`
/// (`u(0)` before the start): `u(j)` moved by `frac` of the way to
/// `before = u(j−1)`, `j = last − whole`, and `u(j)`, which is the next
/// sample's `before` (the delay is fixed). The move is computed in every
/// lane and the result selected, so that the lanes become one vector gather
/// without a branch on `frac` (which differs from lane to lane).
#[inline(always)]
fn delayed(past: &[f32], last: i32, whole: i32, frac: f32, before: f32) -> (f32, f32) {
    assert!(
        last >= 0 && (last as usize) < past.len(),
        "sample {last} is past the input"
    );
    // SAFETY: the index is in 0..=last, which is in `past` (asserted
    // above). Unchecked, because a bounds check per lane keeps the loads
    // scalar and branchy; 32-bit indices, because then one vector gathers 16
    // lanes and is stored whole (two half-vector stores read back as one
    // vector stall the next loop's load).
    let now = unsafe { *past.get_unchecked((last - whole).max(0) as usize) };
    let moved = now + (frac * (before - now));
    (if frac == 0.0 { now } else { moved }, now)
}

impl<const L: usize> Prepared<L> {
    /// +1 where the input drives the output up, −1 where down. The end
    /// stops are stored times it and applied as `toward · min(toward · x,
    /// bound)`: `max(x, b)` is `−min(−x, −b)` bit for bit (negation is
    /// exact, and ties and NaN pick the bound either way), so each stop is
    /// one lane loop with no branch on the direction (choosing per lane,
    /// the output clip ran at 47 % of the plain model's speed, and with one
    /// loop per direction at 33 %; this way at 80 %: docs/lab/performance.md).
    /// WGSL writes each direction out (`shaders/effects.wgsl`).
    #[inline(always)]
    fn toward(&self) -> f32 {
        if self.drives_up { 1.0 } else { -1.0 }
    }

    /// The state at the first sample, from the first measured output `y0`
    /// and the first input `u0` ([`crate::model::sim::Stepper::start`]).
    #[inline(always)]
    pub fn start(&self, y0: f32, u0: f32) -> EffectState<L> {
        let x = std::array::from_fn(|l| y0 + self.x0[l]);
        EffectState {
            x,
            w: [0.0; L],
            delayed: [u0; L],
            x_prev2: x,
            play: [0.0; L],
            z: self.z0,
            lag_in: [0.0; L],
            drain: [0.0; L],
            lag_out: x,
            mode1: x,
            mode2: x,
            z_out: self.z0_out,
            z_fast: [0.0; L],
            z_slow: self.z0_slow,
            log_fast: [0.0; L],
            log_mid: [0.0; L],
            log_slow: self.z0_log,
            on: [0.0; L],
            ring1: [0.0; L],
            ring2: [0.0; L],
            started: false,
            dir: 0.0,
            extreme: u0,
        }
    }

    /// Advances one sample, `k ≥ 1`, on the input `u`; returns the predicted
    /// output `ŷ(k)` of every lane.
    #[inline(always)]
    pub fn step(&self, s: &mut EffectState<L>, k: usize, u: &[f32]) -> [f32; L] {
        // Input side: delay, input lag, on/off threshold, then dead zone,
        // play, branch gain and load gain in one loop over the lanes (so the
        // input stays in registers between them), then the drain lag. The
        // branch follows the measured input only (the same in every lane).
        let raw = u[k - 1];
        if self.asymmetry.is_some() {
            if s.dir >= 0.0 {
                s.extreme = larger(raw, s.extreme);
                if raw < s.extreme - self.branch_tol {
                    (s.dir, s.extreme) = (-1.0, raw);
                } else if raw > u[0] + self.branch_tol {
                    s.dir = 1.0;
                }
            } else {
                s.extreme = smaller(raw, s.extreme);
                if raw > s.extreme + self.branch_tol {
                    (s.dir, s.extreme) = (1.0, raw);
                }
            }
        }
        let started = s.started;
        s.started = true;
        let mut ui = [raw; L];
        if let Some((whole, frac)) = &self.delay {
            let before = s.delayed;
            let last = i32::try_from(k - 1).expect("an input of under 2³¹ samples");
            for l in 0..L {
                (ui[l], s.delayed[l]) = delayed(u, last, whole[l], frac[l], before[l]);
            }
        }
        // The realisations beyond the physical effects' first each have a
        // loop of their own: a lane loop with more stages in it than the
        // first realisations' four no longer compiled to vector code.
        if let Some(rho) = &self.input_lag {
            let prev = if started { s.lag_in } else { ui };
            for l in 0..L {
                ui[l] = (rho[l] * prev[l]) + ((1.0 - rho[l]) * ui[l]);
            }
            s.lag_in = ui;
        }
        if let Some((on, off)) = &self.on_off {
            // Copies in locals: a select between a lane's input and a field
            // of `self` compiled to a select of addresses, one lane at a time.
            let (mut state, rest) = (s.on, self.rest);
            for l in 0..L {
                // On above p_on, off below p_off, as it was in between.
                let kept = if ui[l] < off[l] { 0.0 } else { state[l] };
                state[l] = if ui[l] > on[l] { 1.0 } else { kept };
                ui[l] = if state[l] > 0.0 { ui[l] } else { rest };
            }
            s.on = state;
        }
        for l in 0..L {
            let mut v = ui[l];
            if let Some(p0) = &self.deadzone {
                v = larger(v - p0[l], -self.u_mean);
            }
            if let Some(r) = &self.backlash {
                let half = 0.5 * r[l];
                let prev = if started { s.play[l] } else { v };
                v = smaller(v + half, larger(v - half, prev));
                s.play[l] = v;
            }
            if let Some(eps) = &self.asymmetry {
                v += (s.dir * eps[l]) * (v + self.u_mean);
            }
            if let Some(g) = &self.load {
                // The gain acts on the absolute input, as the asymmetry's does.
                v += g[l] * (v + self.u_mean);
            }
            ui[l] = v;
        }
        if let Some(rho) = &self.drain_lag {
            for l in 0..L {
                // The slow branch follows through the lag; the other passes.
                let v = ui[l];
                let prev = if started { s.drain[l] } else { v };
                let slow = if rho[l] >= 0.0 { v < prev } else { v > prev };
                let r = if rho[l] >= 0.0 { rho[l] } else { -rho[l] };
                let lagged = (r * prev) + ((1.0 - r) * v);
                ui[l] = if slow { lagged } else { v };
                s.drain[l] = ui[l];
            }
        }
        // State: the baseline's equations (`model::sim`), the extra pole and
        // the end stop.
        // One loop over the lanes for the whole state stage, so that the
        // new output stays in registers from the linear part to the end
        // stop (stage loops of their own spilled it between them).
        let linear = self.family == Family::Linear;
        let toward = self.toward();
        let mut xk = [0.0f32; L];
        for l in 0..L {
            let mut x = if linear {
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
            if let Some(a2) = &self.inertia {
                x += a2[l] * (s.x[l] - s.x_prev2[l]);
            }
            if let Some(bound) = &self.saturation {
                x = toward * smaller(toward * x, bound[l]);
            }
            xk[l] = x;
        }
        if let Some(bound) = &self.soft_stop {
            let (knee, toward) = (self.knee, self.toward());
            for l in 0..L {
                xk[l] = toward * soft_stop(toward * xk[l], bound[l], knee);
            }
        }
        let mut a_eff = self.big_a;
        if let Some(eta) = &self.rate {
            let prev = if k >= 2 { u[k - 2] } else { u[0] };
            let rate = (raw - prev).abs() * self.inv_dt;
            for l in 0..L {
                a_eff[l] = self.big_a[l] * (1.0 + (eta[l] * rate));
            }
        }
        self.hysteresis(s, &xk, &a_eff);
        s.x_prev2 = s.x;
        s.x = xk;
        // Output side: the creeps' slow states (input-driven, output-driven,
        // two-pole, log-time), the ringing, the load mode, the output clip
        // and the output lag, a loop each.
        let mut y = xk;
        if let Some((rho, kappa)) = &self.creep {
            for l in 0..L {
                s.z[l] = (rho[l] * s.z[l]) + (((1.0 - rho[l]) * kappa[l]) * ui[l]);
                y[l] += s.z[l];
            }
        }
        if let Some((rho, kappa)) = &self.output_creep {
            for l in 0..L {
                s.z_out[l] = (rho[l] * s.z_out[l]) + (((1.0 - rho[l]) * kappa[l]) * xk[l]);
                y[l] += s.z_out[l];
            }
        }
        if let Some([rf, kf, rs, ks]) = &self.two_pole_creep {
            for l in 0..L {
                s.z_fast[l] = (rf[l] * s.z_fast[l]) + (((1.0 - rf[l]) * kf[l]) * ui[l]);
                s.z_slow[l] = (rs[l] * s.z_slow[l]) + (((1.0 - rs[l]) * ks[l]) * ui[l]);
                y[l] += s.z_fast[l];
                y[l] += s.z_slow[l];
            }
        }
        if let Some([rf, wf, rm, wm, rs, ws]) = &self.log_creep {
            for l in 0..L {
                s.log_fast[l] = (rf[l] * s.log_fast[l]) + (wf[l] * ui[l]);
                s.log_mid[l] = (rm[l] * s.log_mid[l]) + (wm[l] * ui[l]);
                s.log_slow[l] = (rs[l] * s.log_slow[l]) + (ws[l] * ui[l]);
                y[l] += s.log_fast[l];
                y[l] += s.log_mid[l];
                y[l] += s.log_slow[l];
            }
        }
        if let Some((a1, a2, kick)) = &self.ringing {
            let prev = if k >= 2 { u[k - 2] } else { u[0] };
            let change = raw - prev;
            for l in 0..L {
                let r = ((a1[l] * s.ring1[l]) - (a2[l] * s.ring2[l])) + (kick[l] * change);
                s.ring2[l] = s.ring1[l];
                s.ring1[l] = r;
                y[l] += r;
            }
        }
        if let Some((a1, a2, gain)) = &self.mode {
            for l in 0..L {
                let q = ((a1[l] * s.mode1[l]) - (a2[l] * s.mode2[l])) + (gain[l] * y[l]);
                s.mode2[l] = s.mode1[l];
                s.mode1[l] = q;
                y[l] = q;
            }
        }
        if let Some(bound) = &self.output_clip {
            let toward = self.toward();
            for l in 0..L {
                y[l] = toward * smaller(toward * y[l], bound[l]);
            }
        }
        if let Some(rho) = &self.output_lag {
            for l in 0..L {
                y[l] = (rho[l] * s.lag_out[l]) + ((1.0 - rho[l]) * y[l]);
                s.lag_out[l] = y[l];
            }
        }
        y
    }

    /// The Bouc-Wen state of every lane after the output moved from `s.x` to
    /// `xk` under the stiffness `a_eff` ([`crate::model::sim::Stepper::hysteresis`]).
    #[inline(always)]
    fn hysteresis(&self, s: &mut EffectState<L>, xk: &[f32; L], a_eff: &[f32; L]) {
        let bt = &self.betas;
        match (self.family, self.n_one) {
            (Family::Linear, _) => s.w = [0.0; L],
            (Family::Classic, true) => {
                for l in 0..L {
                    let delta = xk[l] - s.x[l];
                    s.w[l] = classic_w(a_eff[l], bt[0][l], bt[1][l], 1.0, s.w[l], delta);
                }
            }
            (Family::Classic, false) => {
                for l in 0..L {
                    let delta = xk[l] - s.x[l];
                    s.w[l] = classic_w(a_eff[l], bt[0][l], bt[1][l], self.n[l], s.w[l], delta);
                }
            }
            (Family::Generalized, n_one) => {
                for l in 0..L {
                    let betas = [bt[0][l], bt[1][l], bt[2][l], bt[3][l], bt[4][l], bt[5][l]];
                    let n = if n_one { 1.0 } else { self.n[l] };
                    let delta = xk[l] - s.x[l];
                    s.w[l] = generalized_w(a_eff[l], &betas, n, s.w[l], xk[l], delta);
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
    /// takes `y` less the creeps' states and the ringing, and the Bouc-Wen state the jump's elastic
    /// part, as the baseline's ([`crate::model::sim::Stepper::restart`]);
    /// the load mode and the output lag restart at `y`; the other effects'
    /// states run on.
    #[inline(always)]
    pub fn restart(&self, s: &mut EffectState<L>, y: f32) {
        for l in 0..L {
            let creeps = (((y - s.z[l]) - s.z_out[l]) - s.z_fast[l]) - s.z_slow[l];
            let x = (((creeps - s.log_fast[l]) - s.log_mid[l]) - s.log_slow[l]) - s.ring1[l];
            s.w[l] = restart_w(self.big_a[l], s.w[l], s.x[l], x);
            s.x[l] = x;
            s.lag_out[l] = y;
            s.mode1[l] = y;
            s.mode2[l] = y;
        }
    }
}

impl Augmented {
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
        let mut p = Prepared {
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
            delay: None,
            deadzone: None,
            saturation: None,
            asymmetry: None,
            inertia: None,
            backlash: None,
            creep: None,
            z0: [0.0; L],
            z0_out: [0.0; L],
            z0_slow: [0.0; L],
            rate: None,
            load: None,
            input_lag: None,
            output_lag: None,
            mode: None,
            drain_lag: None,
            output_clip: None,
            soft_stop: None,
            output_creep: None,
            two_pole_creep: None,
            log_creep: None,
            z0_log: [0.0; L],
            on_off: None,
            ringing: None,
            knee: ctx.knee(),
            rest: ctx.rest_input(),
            u_mean: ctx.u_mean as f32,
            branch_tol: ctx.branch_tol as f32,
            inv_dt: (1.0 / ctx.dt) as f32,
            drives_up: ctx.drives_up,
        };
        let y_mean = ctx.y_mean as f32;
        let toward = p.toward();
        let mut at = fam.dim();
        for &e in &self.effects {
            let dim = e.dim(self.datasets);
            // The load effect of a single dataset has no parameter.
            let v = if dim > 0 { col(at) } else { [0.0; L] };
            let non_negative = v.map(|x| larger(x, 0.0));
            match e {
                Effect::Delay => {
                    let split = non_negative.map(split_delay);
                    p.delay = Some((split.map(|s| s.0), split.map(|s| s.1)));
                }
                Effect::Deadzone => p.deadzone = Some(v),
                Effect::Saturation => p.saturation = Some(v.map(|l| toward * (l - y_mean))),
                Effect::Asymmetry => p.asymmetry = Some(v),
                Effect::Inertia => p.inertia = Some(v),
                Effect::Backlash => p.backlash = Some(non_negative),
                Effect::Creep => {
                    p.creep = Some((v, col(at + 1)));
                    p.z0 = col(at + 2);
                }
                Effect::Rate => p.rate = Some(v),
                Effect::Load => p.load = (dataset >= 1).then(|| col(at + dataset - 1)),
                Effect::InputLag => p.input_lag = Some(v),
                Effect::OutputLag => p.output_lag = Some(v),
                Effect::LoadMode => {
                    let a2 = col(at + 1);
                    let gain = std::array::from_fn(|l| (1.0 - v[l]) + a2[l]);
                    p.mode = Some((v, a2, gain));
                }
                Effect::DrainLag => p.drain_lag = Some(v),
                Effect::OutputClip => p.output_clip = Some(v.map(|l| toward * (l - y_mean))),
                Effect::SoftStop => p.soft_stop = Some(v.map(|l| toward * (l - y_mean))),
                Effect::OutputCreep => {
                    p.output_creep = Some((v, col(at + 1)));
                    p.z0_out = col(at + 2);
                }
                Effect::TwoPoleCreep => {
                    let (rho_slow, kappa, share) = (col(at + 1), col(at + 2), col(at + 3));
                    let kappa_fast: [f32; L] = std::array::from_fn(|l| share[l] * kappa[l]);
                    let kappa_slow = std::array::from_fn(|l| kappa[l] - kappa_fast[l]);
                    p.two_pole_creep = Some([v, kappa_fast, rho_slow, kappa_slow]);
                    p.z0_slow = col(at + 4);
                }
                Effect::OnOffThreshold => {
                    let on = v.map(|x| x - p.u_mean);
                    let gap = col(at + 1);
                    p.on_off = Some((on, std::array::from_fn(|l| on[l] - gap[l])));
                }
                Effect::Ringing => p.ringing = Some((v, col(at + 1), col(at + 2))),
                Effect::LogCreep => {
                    // Poles a decade apart in time constant: ρ^100, ρ^10, ρ.
                    let mid = v.map(tenth_power);
                    let fast = mid.map(tenth_power);
                    let kappa = col(at + 1);
                    let weight = |rho: [f32; L]| std::array::from_fn(|l| (1.0 - rho[l]) * kappa[l]);
                    p.log_creep = Some([fast, weight(fast), mid, weight(mid), v, weight(v)]);
                    p.z0_log = col(at + 2);
                }
            }
            at += dim;
        }
        p
    }

    /// Runs the model on dataset `dataset` (input `u`, deviation
    /// coordinates) from the measured `y0`, calling `sink(k, ŷ(k))` for
    /// `k ≥ 1`; returns false (and stops) at the first state out of bounds.
    /// With `restart = Some((y, h))` the prediction restarts from the
    /// measured `y(k)` after every `h`-th sample ([`Prepared::restart`]):
    /// the `h`-step-ahead predictor of [`Augmented::sse_ahead`].
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
            if let Some((y, h)) = restart {
                if k % h == 0 {
                    p.restart(&mut s, y[k]);
                }
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
