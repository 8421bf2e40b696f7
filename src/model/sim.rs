//! The reference simulation of every family, in `f32`.
//!
//! This file is the single source of truth for the model equations. The
//! batched CPU evaluator calls the same step functions, and the WGSL shaders
//! in `shaders/` spell the same operations in the same order, which the tests
//! check bit for bit on lavapipe. So: no `mul_add`, and every sum is written
//! with explicit parentheses in the order the shaders use.
//!
//! Deviation coordinates (`docs/ARCHITECTURE.md`): the input `u` and the
//! measured output `y` have had the estimation means removed. The simulation
//! starts from the measured `x(0) = y(0)` and `w(0) = 0`, runs free (it never
//! sees the measured output again) and is scored by
//! `SSE = Σ_{k≥1} (x(k) − y(k))²`.
//!
//! One parameter is not in deviation coordinates: the generalized family's
//! switching level `x_s`, in the output's own units, so that a model switches
//! where the muscle does whatever record's mean it runs in. Every simulation
//! is therefore told the output mean `ȳ` its data had removed (`y_mean`), and
//! the sign terms switch at `x = x_s − ȳ`, formed once per candidate in `f32`
//! ([`switch_threshold`]). A model that switches at its estimation mean
//! (`x_s = ȳ`, as the thesis' model does and as a model file without `x_s`
//! reads) forms `0` exactly there, and `x − 0` is `x` bit for bit: the same
//! numbers as sign terms that switch at `x = 0` with no level at all.

use super::family::Family;
use crate::data::Trace;
use crate::search::Measure;

/// A simulated state whose magnitude exceeds this bound (in the units of the
/// data) counts as diverged, and so does any non-finite state: the candidate's
/// SSE is then `+∞`. Displacements of a muscle are tens of millimetres; a state
/// of a million is an explosion, not a fit.
pub const DIVERGENCE_BOUND: f32 = 1.0e6;

/// `|v|^e` for `v ≥ 0`, with `0^e = 0` for `e > 0` and `v^0 = 1` exactly, so
/// that the free-exponent formula reproduces the `n = 1` one bit for bit.
#[inline(always)]
pub fn abs_pow(v: f32, e: f32) -> f32 {
    if e == 0.0 {
        1.0
    } else if v == 0.0 {
        0.0
    } else {
        v.powf(e)
    }
}

/// `sgn` with `sgn(0) = 0`, as WGSL's `sign`.
#[inline(always)]
pub fn sgn(v: f32) -> f32 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// The linear part of eq. 13 with intercept:
/// `x(k) = a·[α·x(k−1) + (1−α)·w(k−1)] + b·u(k−1) + c`.
/// The linear family is the case α = 1, w = 0 (eq. 12 plus `c`).
#[inline(always)]
pub fn linear_part(
    a: f32,
    alpha: f32,
    b: f32,
    c: f32,
    x_prev: f32,
    w_prev: f32,
    u_prev: f32,
) -> f32 {
    ((a * ((alpha * x_prev) + ((1.0 - alpha) * w_prev))) + (b * u_prev)) + c
}

/// Where a model held at the input `u` (deviation units) rests: the state
/// `x` that [`linear_part`] keeps with `w = 0`, `x = a·α·x + b·u + c`
/// (`α = 1` for the linear family). The output does not move there, so
/// neither does `w`. `None` where `|a·α| ≥ 1`: no stable rest.
pub fn rest_state(family: Family, theta: &[f64], u: f64) -> Option<f64> {
    let [ia, ib, ic] = family.linear_indices();
    let alpha = family.index_of("alpha").map_or(1.0, |i| theta[i]);
    let pole = theta[ia] * alpha;
    (pole.abs() < 1.0).then(|| (theta[ib] * u + theta[ic]) / (1.0 - pole))
}

/// The linear family's step (eq. 12 plus intercept): `x(k) = a·x(k−1) + b·u(k−1) + c`.
#[inline(always)]
pub fn linear_step(a: f32, b: f32, c: f32, x_prev: f32, u_prev: f32) -> f32 {
    ((a * x_prev) + (b * u_prev)) + c
}

/// Classic Bouc-Wen state update (eq. 20 with the factor `w` restored):
/// `w(k) = w(k−1) + A·Δ − β·|Δ|·|w|^(n−1)·w − γ·Δ·|w|^n`, `w = w(k−1)`.
#[inline(always)]
pub fn classic_w(big_a: f32, beta: f32, gamma: f32, n: f32, w_prev: f32, delta: f32) -> f32 {
    let aw = w_prev.abs();
    let pw = abs_pow(aw, n - 1.0);
    ((w_prev + (big_a * delta)) - ((beta * delta.abs()) * (pw * w_prev)))
        - ((gamma * delta) * (pw * aw))
}

/// The level in deviation coordinates where the generalized sign terms in
/// `x` switch: the switching level `x_s` (output units) less the output mean
/// `ȳ` the data had removed, in `f32` (`shaders/generalized.wgsl` forms it
/// the same way). `x_s = ȳ` gives exactly 0.
#[inline(always)]
pub fn switch_threshold(x_s: f32, y_mean: f32) -> f32 {
    x_s - y_mean
}

/// Generalized Bouc-Wen state update (eq. 23 with `w(k−1)` on the right):
/// `w(k) = w(k−1) + Δ·[A − |w(k−1)|^n·Ψ(k)]`.
///
/// `Ψ = β1·sgn(Δ·w) + β2·sgn(Δ·ξ) + β3·sgn(ξ·w) + β4·sgn(Δ) + β5·sgn(w) + β6·sgn(ξ)`
/// with `ξ = x − threshold` (the output against the switching level,
/// [`switch_threshold`]), where the sign of a product is taken as the
/// product of signs (the same number, but immune to underflow of the
/// product).
#[allow(clippy::too_many_arguments)] // the equation's inputs, one each
#[inline(always)]
pub fn generalized_w(
    big_a: f32,
    betas: &[f32; 6],
    n: f32,
    w_prev: f32,
    x: f32,
    delta: f32,
    threshold: f32,
) -> f32 {
    let sd = sgn(delta);
    let sw = sgn(w_prev);
    let sx = sgn(x - threshold);
    let psi = (((((betas[0] * (sd * sw)) + (betas[1] * (sd * sx))) + (betas[2] * (sx * sw)))
        + (betas[3] * sd))
        + (betas[4] * sw))
        + (betas[5] * sx);
    let aw = w_prev.abs();
    let pwn = abs_pow(aw, n - 1.0) * aw;
    w_prev + (delta * (big_a - (pwn * psi)))
}

/// True while a state is finite and within [`DIVERGENCE_BOUND`].
#[inline(always)]
pub fn in_bounds(v: f32) -> bool {
    v.abs() <= DIVERGENCE_BOUND
}

/// One family's parameters unpacked from the canonical vector, ready for the
/// inner loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stepper {
    Linear {
        a: f32,
        b: f32,
        c: f32,
        x0: f32,
    },
    Classic {
        big_a: f32,
        alpha: f32,
        beta: f32,
        gamma: f32,
        n: f32,
        a: f32,
        b: f32,
        c: f32,
        x0: f32,
    },
    Generalized {
        big_a: f32,
        alpha: f32,
        betas: [f32; 6],
        n: f32,
        /// Where the sign terms in `x` switch, in deviation coordinates
        /// ([`switch_threshold`]).
        threshold: f32,
        a: f32,
        b: f32,
        c: f32,
        x0: f32,
    },
}

impl Stepper {
    /// Unpacks a canonical parameter vector of `family` (see
    /// [`Family::params`]) for data whose output had the mean `y_mean`
    /// removed (what places the generalized switching level: the other
    /// families do not read it).
    pub fn new(family: Family, theta: &[f32], y_mean: f32) -> Self {
        assert_eq!(
            theta.len(),
            family.dim(),
            "{family} takes {} parameters",
            family.dim()
        );
        match family {
            Family::Linear => Stepper::Linear {
                a: theta[0],
                b: theta[1],
                c: theta[2],
                x0: theta[3],
            },
            Family::Classic => Stepper::Classic {
                big_a: theta[0],
                alpha: theta[1],
                beta: theta[2],
                gamma: theta[3],
                n: theta[4],
                a: theta[5],
                b: theta[6],
                c: theta[7],
                x0: theta[8],
            },
            Family::Generalized => Stepper::Generalized {
                big_a: theta[0],
                alpha: theta[1],
                betas: [theta[2], theta[3], theta[4], theta[5], theta[6], theta[7]],
                n: theta[8],
                threshold: switch_threshold(theta[9], y_mean),
                a: theta[10],
                b: theta[11],
                c: theta[12],
                x0: theta[13],
            },
        }
    }

    /// The state a free run starts in from the first measured output `y0`:
    /// `(y0 + x₀, 0)`.
    #[inline(always)]
    pub fn start(&self, y0: f32) -> (f32, f32) {
        let x0 = match *self {
            Stepper::Linear { x0, .. }
            | Stepper::Classic { x0, .. }
            | Stepper::Generalized { x0, .. } => x0,
        };
        (y0 + x0, 0.0)
    }

    /// Advances one sample: from `(x(k−1), w(k−1))` and `u(k−1)` to `(x(k), w(k))`.
    #[inline(always)]
    pub fn step(&self, x_prev: f32, w_prev: f32, u_prev: f32) -> (f32, f32) {
        let x = match *self {
            Stepper::Linear { a, b, c, .. } => linear_step(a, b, c, x_prev, u_prev),
            Stepper::Classic { alpha, a, b, c, .. }
            | Stepper::Generalized { alpha, a, b, c, .. } => {
                linear_part(a, alpha, b, c, x_prev, w_prev, u_prev)
            }
        };
        (x, self.hysteresis(w_prev, x, x - x_prev))
    }

    /// The Bouc-Wen state after the output moved by `delta` to `x` (0 for
    /// the linear family).
    #[inline(always)]
    pub fn hysteresis(&self, w_prev: f32, x: f32, delta: f32) -> f32 {
        match *self {
            Stepper::Linear { .. } => 0.0,
            Stepper::Classic {
                big_a,
                beta,
                gamma,
                n,
                ..
            } => classic_w(big_a, beta, gamma, n, w_prev, delta),
            Stepper::Generalized {
                big_a,
                ref betas,
                n,
                threshold,
                ..
            } => generalized_w(big_a, betas, n, w_prev, x, delta, threshold),
        }
    }

    /// A restart of the prediction: the output state is set to the
    /// measurement `y`, and the Bouc-Wen state takes the jump's elastic part,
    /// `w + A·(y − x)`.
    ///
    /// Why not leave `w` alone: it would integrate the simulated motion only,
    /// drift from the measured motion by the sum of all jumps, and push the
    /// output away through `a·(1 − α)·w`. Why not the whole Bouc-Wen step: a
    /// jump is mostly measurement noise, and the loop terms `β·|Δ|`, `γ·Δ`
    /// rectify noise into a bias; the elastic part is linear in the jump, so
    /// zero-mean noise leaves no bias. The three rules measured against each
    /// other: docs/ARCHITECTURE.md, "Restart = elastic step".
    #[inline(always)]
    pub fn restart(&self, x: f32, w: f32, y: f32) -> (f32, f32) {
        match *self {
            Stepper::Linear { .. } => (y, 0.0),
            Stepper::Classic { big_a, .. } | Stepper::Generalized { big_a, .. } => {
                (y, restart_w(big_a, w, x, y))
            }
        }
    }
}

/// The Bouc-Wen state after a restart from `x` to the measurement `y`:
/// `w + A·(y − x)` ([`Stepper::restart`]).
#[inline(always)]
pub fn restart_w(big_a: f32, w: f32, x: f32, y: f32) -> f32 {
    w + (big_a * (y - x))
}

/// A free-run simulation: the output and hysteretic state at every sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Simulation {
    pub x: Vec<f32>,
    pub w: Vec<f32>,
    /// First sample whose state left [`DIVERGENCE_BOUND`] or became non-finite.
    pub diverged_at: Option<usize>,
}

/// Simulates `family` with parameters `theta` on input `u` from the first
/// measured output `y0` (the state [`Stepper::start`]), in the deviation
/// coordinates of the output mean `y_mean` ([`Stepper::new`]). The whole
/// trace is produced even after divergence, so that a plot shows where it
/// happened.
pub fn simulate(family: Family, theta: &[f32], y_mean: f32, u: &[f32], y0: f32) -> Simulation {
    let stepper = Stepper::new(family, theta, y_mean);
    let mut x = Vec::with_capacity(u.len());
    let mut w = Vec::with_capacity(u.len());
    let mut diverged_at = None;
    if u.is_empty() {
        return Simulation { x, w, diverged_at };
    }
    let (x0, w0) = stepper.start(y0);
    // A start already out of bounds (the rest of a model whose gain is
    // 1e308) is a divergence at the first sample, not the second.
    if !(in_bounds(x0) && in_bounds(w0)) {
        diverged_at = Some(0);
    }
    x.push(x0);
    w.push(w0);
    for k in 1..u.len() {
        let (xk, wk) = stepper.step(x[k - 1], w[k - 1], u[k - 1]);
        if diverged_at.is_none() && !(in_bounds(xk) && in_bounds(wk)) {
            diverged_at = Some(k);
        }
        x.push(xk);
        w.push(wk);
    }
    Simulation { x, w, diverged_at }
}

/// Runs `family` over the data (output mean `y_mean` removed) under
/// `measure`, calling `sink(k, x(k) − y(k))` for every `k ≥ 1`; returns
/// false at the first out-of-bounds state (the candidate diverged). The
/// single definition of what every backend scores.
fn run_scored(
    family: Family,
    theta: &[f32],
    y_mean: f32,
    u: &[f32],
    y: &[f32],
    measure: Measure,
    mut sink: impl FnMut(usize, f32),
) -> bool {
    assert_eq!(u.len(), y.len(), "input and output lengths differ");
    if u.is_empty() {
        return true;
    }
    let stepper = Stepper::new(family, theta, y_mean);
    let every = measure.restart_every();
    let (mut x, mut w) = stepper.start(y[0]);
    for k in 1..u.len() {
        (x, w) = stepper.step(x, w, u[k - 1]);
        if !(in_bounds(x) && in_bounds(w)) {
            return false;
        }
        sink(k, x - y[k]);
        if k % every == 0 {
            (x, w) = stepper.restart(x, w, y[k]);
        }
    }
    true
}

/// The fitness of eq. 29 as a cost: `Σ_{k≥1} (x(k) − y(k))²` accumulated in
/// `f32` in sample order, or `+∞` if the simulation diverged (data with the
/// output mean `y_mean` removed).
pub fn sse(family: Family, theta: &[f32], y_mean: f32, u: &[f32], y: &[f32]) -> f32 {
    measured_sse(family, theta, y_mean, u, y, Measure::FreeRun)
}

/// The sum of squared errors under `measure`, `+∞` if the simulation diverged.
pub fn measured_sse(
    family: Family,
    theta: &[f32],
    y_mean: f32,
    u: &[f32],
    y: &[f32],
    measure: Measure,
) -> f32 {
    let mut acc = 0.0f32;
    let ok = run_scored(family, theta, y_mean, u, y, measure, |_, e| acc += e * e);
    if ok { acc } else { f32::INFINITY }
}

/// The errors `x(k) − y(k)`, `k ≥ 1`, under `measure` (what a
/// Levenberg–Marquardt polish differentiates); `None` if the simulation diverged.
pub fn residuals(
    family: Family,
    theta: &[f32],
    y_mean: f32,
    u: &[f32],
    y: &[f32],
    measure: Measure,
) -> Option<Vec<f32>> {
    let mut r = Vec::with_capacity(u.len().saturating_sub(1));
    run_scored(family, theta, y_mean, u, y, measure, |_, e| r.push(e)).then_some(r)
}

/// Refuses a trace whose values would overflow the `f32` arithmetic of the
/// simulation: the estimation SSE sums squared output deviations over every
/// sample, so each column's deviation from its mean, times √(samples), must
/// stay well inside `√f32::MAX` (10⁻³ of it: room for candidates far off).
/// And the output's deviations must stay well inside the bound past which
/// a simulated state counts as diverged ([`DIVERGENCE_BOUND`]; a quarter of
/// it: room for a candidate's overshoot), or even the truth would be.
/// Without this check such data "diverges" for every candidate. Nor may
/// the output's deviations be so small that their squares fall under
/// `f32`'s smallest normal number (10³ times its square root: room for
/// errors far smaller than the swing), where every candidate would score
/// an SSE of 0.
pub fn check_f32_range(trace: &Trace) -> anyhow::Result<()> {
    check_f32_range_about(trace, None)
}

/// [`check_f32_range`] about a model's means (input, output) instead of the
/// trace's own: the origin of the coordinates a model read from a file
/// simulates in. Means far from the data (a file edited by hand, a model
/// of other units) leave the `f32` range as values too large do.
pub fn check_f32_range_about(trace: &Trace, means: Option<(f64, f64)>) -> anyhow::Result<()> {
    let limit = (f32::MAX as f64).sqrt() * 1e-3 / (trace.len().max(1) as f64).sqrt();
    for (name, column, given) in [
        (&trace.input_name, &trace.input, means.map(|m| m.0)),
        (&trace.output_name, &trace.output, means.map(|m| m.1)),
    ] {
        let own = || column.iter().sum::<f64>() / column.len().max(1) as f64;
        let mean = given.unwrap_or_else(own);
        let (the_mean, fix) = match given {
            Some(m) => (
                format!("the model's mean {m:e}"),
                "the model describes data far from these (or its file was edited): fit afresh",
            ),
            None => (
                "the mean".to_string(),
                "rescale the column (for example Pa to MPa, or m to mm)",
            ),
        };
        let (lo, hi) = column
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let reach = (hi - mean).abs().max((lo - mean).abs());
        anyhow::ensure!(
            reach <= limit,
            "column `{name}` of {} spans [{lo:e}, {hi:e}]: over {} samples its squared \
             errors overflow the f32 arithmetic of the simulation (deviations from {the_mean} \
             must stay below {limit:.3e}); {fix}",
            trace.source,
            trace.len()
        );
        let states = f64::from(DIVERGENCE_BOUND) / 4.0;
        anyhow::ensure!(
            name != &trace.output_name || reach <= states,
            "the output `{name}` of {} spans [{lo:e}, {hi:e}]: the simulation counts a state \
             beyond ±{:e} as diverged, and deviations from {the_mean} must stay below \
             {states:e} to leave a model room; {}",
            trace.source,
            DIVERGENCE_BOUND,
            match given {
                Some(_) => fix,
                None => "rescale the column (for example nm to mm)",
            }
        );
        let floor = f64::from(f32::MIN_POSITIVE).sqrt() * 1e3;
        // A constant output (reach 0) is refused where its dynamics are sought.
        anyhow::ensure!(
            name != &trace.output_name || reach == 0.0 || reach >= floor,
            "the output `{name}` of {} spans [{lo:e}, {hi:e}]: deviations from the mean this \
             small (under {floor:.1e}) have squared errors that vanish in the f32 arithmetic of \
             the simulation, so every model would score an SSE of 0; rescale the column (for \
             example m to µm)",
            trace.source,
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Steps of one size from `w = 0`, all one way (`turn` false) or each
    /// the other way from the last (`turn`): the update's state after
    /// `steps` of them, and how far its last step moved it.
    fn steps_of(
        family: Family,
        theta: &[f64],
        (delta, turn): (f64, bool),
        x: f64,
        steps: usize,
    ) -> (f32, f32) {
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        let (mut w, mut moved, mut delta) = (0.0f32, 0.0f32, delta as f32);
        for _ in 0..steps {
            let next = match family {
                Family::Classic => classic_w(t[0], t[2], t[3], t[4], w, delta),
                _ => {
                    let betas = [t[2], t[3], t[4], t[5], t[6], t[7]];
                    generalized_w(t[0], &betas, t[8], w, x as f32, delta, 0.0)
                }
            };
            (moved, w) = ((next - w).abs(), next);
            if turn {
                delta = -delta;
            }
        }
        (w, moved)
    }

    #[test]
    fn the_update_settles_within_its_stable_step_and_not_past_it() {
        // A, α, β, γ, n, a, b, c, x0.
        let classic =
            |beta: f64, gamma: f64, n: f64| [1.0, 0.9, beta, gamma, n, 0.97, 0.1, 0.0, 0.0];
        // A loading branch binds: a ramp settles on the saturation or not.
        // The 400 g Cavatappi fit's loop (β + γ = 14.93 a mm: 0.134 mm), a
        // thesis-like one, n ≠ 1, and a generalized one above its switching
        // level.
        let settling = [
            (Family::Classic, classic(14.176, 0.7565, 1.0).to_vec(), 1.0),
            (Family::Classic, classic(0.3, 0.2, 1.0).to_vec(), 1.0),
            (Family::Classic, classic(0.3, 0.2, 2.0).to_vec(), 1.0),
            (
                Family::Generalized,
                vec![
                    1.0, 0.9, 0.4, 0.1, 0.05, 0.2, 0.1, 0.3, 1.0, 0.0, 0.97, 0.1, 0.0, 0.0,
                ],
                1.0,
            ),
        ];
        // An unloading branch binds (γ < 0: unloading steeper than
        // loading): a record that turns each sample stays bounded or is
        // pumped. A fit of the 400 g Cavatappi record at --pop 4000 (β + γ
        // = 0: the loading branch never saturates), a saturating one, n ≠ 1.
        let returning = [
            (Family::Classic, classic(153.56, -153.56, 1.0).to_vec(), 1.0),
            (Family::Classic, classic(0.4, -0.1, 1.0).to_vec(), 1.0),
            (Family::Classic, classic(0.4, -0.1, 1.5).to_vec(), 1.0),
        ];
        let cases = settling
            .into_iter()
            .map(|c| (c, false))
            .chain(returning.into_iter().map(|c| (c, true)));
        for ((family, theta, x), turn) in cases {
            let step = family.stable_step(&theta).unwrap();
            let (settled, moved) = steps_of(family, &theta, (0.9 * step, turn), x, 400);
            let bound = settled.abs().max(step as f32);
            assert!(
                settled.is_finite() && (turn || moved < 1e-4 * bound),
                "{family} {theta:?}: {settled} moved {moved}"
            );
            let (w, moved) = steps_of(family, &theta, (1.1 * step, turn), x, 400);
            assert!(
                !w.is_finite()
                    || if turn {
                        w.abs() > 1e3 * bound
                    } else {
                        moved > 1e-2 * bound
                    },
                "{family} {theta:?}: {w} moved {moved} (within: {settled})"
            );
        }
        let cavatappi = Family::Classic
            .stable_step(&classic(14.176, 0.7565, 1.0))
            .unwrap();
        assert!((cavatappi - 2.0 / 14.9325).abs() < 1e-12, "{cavatappi}");
        let pumped = Family::Classic
            .stable_step(&classic(153.56, -153.56, 1.0))
            .unwrap();
        assert!((pumped - 2.0 / 307.12).abs() < 1e-12, "{pumped}");
        // No loop, no step.
        assert_eq!(
            Family::Classic.stable_step(&[0.0, 0.9, 1.0, 1.0, 1.0, 0.9, 0.1, 0.0, 0.0]),
            None
        );
        assert_eq!(Family::Linear.stable_step(&[0.9, 0.1, 0.0, 0.0]), None);
    }

    #[test]
    fn a_model_started_at_rest_stays_there() {
        let classic = [1.0, 0.6, 0.02, 0.01, 1.0, 0.97, 8.0, 0.3, 0.5];
        let generalized = [
            1.0, 0.6, 0.02, 0.01, 0.02, 0.01, 0.03, 0.01, 1.0, 5.0, 0.97, 8.0, 0.3, 0.5,
        ];
        for (family, theta) in [
            (Family::Linear, &[0.95, 2.0, 0.1, 0.0][..]),
            (Family::Classic, &classic[..]),
            (Family::Generalized, &generalized[..]),
        ] {
            let u = 0.25;
            let x = rest_state(family, theta, u).unwrap();
            let f32s: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
            let stepper = Stepper::new(family, &f32s, 0.0);
            let (mut xk, mut wk) = (x as f32, 0.0);
            for _ in 0..200 {
                (xk, wk) = stepper.step(xk, wk, u as f32);
            }
            assert!(
                (f64::from(xk) - x).abs() < 1e-4 * x.abs(),
                "{family}: {xk} vs {x}"
            );
            assert!(wk.abs() < 1e-3, "{family}: w {wk}");
        }
        let unstable = [1.0, 1.0, 0.02, 0.01, 1.0, 1.01, 8.0, 0.3, 0.5];
        assert_eq!(rest_state(Family::Classic, &unstable, 0.25), None);
    }

    #[test]
    fn linear_step_is_eq_12_plus_intercept() {
        let s = Stepper::new(Family::Linear, &[0.5, 2.0, 1.0, 0.0], 0.0);
        assert_eq!(s.step(4.0, 123.0, 3.0), (0.5 * 4.0 + 2.0 * 3.0 + 1.0, 0.0));
    }

    #[test]
    fn classic_with_alpha_one_is_linear() {
        let u: Vec<f32> = (0..200).map(|k| ((k / 20) % 2) as f32).collect();
        let lin = simulate(Family::Linear, &[0.9, 2.0, 0.1, 0.0], 0.0, &u, 0.5);
        let cl = simulate(
            Family::Classic,
            &[0.9, 1.0, 0.1, 0.05, 1.0, 0.9, 2.0, 0.1, 0.0],
            0.0,
            &u,
            0.5,
        );
        assert_eq!(lin.x, cl.x);
    }

    #[test]
    fn free_exponent_at_one_equals_the_n_one_formula() {
        // n = 1 exactly through abs_pow must not change a single bit.
        for &(w, d) in &[(0.0f32, 0.3f32), (0.7, -0.2), (-1.3, 0.05), (2.0, 0.0)] {
            let explicit = ((w + 0.9 * d) - (0.2 * d.abs()) * w) - (0.1 * d) * w.abs();
            assert_eq!(classic_w(0.9, 0.2, 0.1, 1.0, w, d), explicit);
        }
    }

    #[test]
    fn divergence_gives_infinite_sse() {
        let u = vec![1.0f32; 100];
        let y = vec![0.0f32; 100];
        // An unstable pole explodes past the bound.
        assert_eq!(
            sse(Family::Linear, &[1.5, 1.0, 0.0, 0.0], 0.0, &u, &y),
            f32::INFINITY
        );
        let sim = simulate(Family::Linear, &[1.5, 1.0, 0.0, 0.0], 0.0, &u, 0.0);
        assert!(sim.diverged_at.is_some());
        assert!(sse(Family::Linear, &[0.5, 1.0, 0.0, 0.0], 0.0, &u, &y).is_finite());
    }

    #[test]
    fn prediction_restarts_the_output_from_the_measurement() {
        let u: Vec<f32> = (0..300).map(|k| ((k / 25) % 3) as f32 * 0.1).collect();
        let y: Vec<f32> = (0..300).map(|k| (k as f32 * 0.03).sin()).collect();
        let theta = [0.9f32, 0.6, 0.05, -0.02, 1.0, 0.95, 1.5, 0.01, 0.0];
        let fam = Family::Classic;
        // A horizon past the data is the free run.
        let free = sse(fam, &theta, 0.0, &u, &y);
        assert_eq!(
            measured_sse(fam, &theta, 0.0, &u, &y, Measure::Ahead { horizon: 300 }),
            free
        );
        // One step ahead: every x(k) starts from the measured y(k − 1), the
        // Bouc-Wen state from its own run moved by the elastic part of the
        // jump to the measurement.
        let r = residuals(fam, &theta, 0.0, &u, &y, Measure::Ahead { horizon: 1 }).unwrap();
        let stepper = Stepper::new(fam, &theta, 0.0);
        let mut w = 0.0;
        for k in 1..u.len() {
            let (x, wn) = stepper.step(y[k - 1], w, u[k - 1]);
            assert_eq!(r[k - 1], x - y[k], "sample {k}");
            w = wn + theta[0] * (y[k] - x);
        }
        let ahead = measured_sse(fam, &theta, 0.0, &u, &y, Measure::Ahead { horizon: 10 });
        assert_eq!(
            ahead,
            residuals(fam, &theta, 0.0, &u, &y, Measure::Ahead { horizon: 10 })
                .unwrap()
                .iter()
                .fold(0.0f32, |acc, e| acc + e * e)
        );
        assert_ne!(ahead, free);
    }

    #[test]
    fn sse_matches_simulation_residual() {
        let u: Vec<f32> = (0..300).map(|k| (k as f32 * 0.05).sin()).collect();
        let theta = [0.9f32, 0.6, 0.05, -0.02, 1.0, 0.95, 1.5, 0.01, 0.0];
        let y: Vec<f32> = (0..300).map(|k| (k as f32 * 0.04).cos()).collect();
        let sim = simulate(Family::Classic, &theta, 0.0, &u, y[0]);
        let mut acc = 0.0f32;
        for (x, y) in sim.x.iter().zip(&y).skip(1) {
            let e = x - y;
            acc += e * e;
        }
        assert_eq!(sse(Family::Classic, &theta, 0.0, &u, &y), acc);
    }

    #[test]
    fn the_sign_terms_in_x_switch_at_the_switching_level() {
        // x_s = ȳ forms the threshold 0 exactly, whatever ȳ.
        for y_mean in [23.134_275f32, -0.615, 1.0e4] {
            assert_eq!(switch_threshold(y_mean, y_mean).to_bits(), 0);
        }
        // Only β6·sgn(x − threshold): crossing the threshold flips the term,
        // a step of 2·Δ·|w|·β6 in the new state (all exact in binary), and
        // nothing else matters.
        let betas = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0625];
        let (w, delta, threshold) = (2.0f32, 0.25f32, 3.0f32);
        let above = generalized_w(1.0, &betas, 1.0, w, threshold + 0.01, delta, threshold);
        let below = generalized_w(1.0, &betas, 1.0, w, threshold - 0.01, delta, threshold);
        assert_eq!(below - above, 2.0 * delta * w * 0.0625);
        let elsewhere = generalized_w(1.0, &betas, 1.0, w, threshold + 5.0, delta, threshold);
        assert_eq!(elsewhere, above);
    }

    #[test]
    fn the_switching_level_is_in_the_outputs_own_units() {
        // One absolute model (x_s inside the output's swing) simulated in two
        // deviation frames, ȳ = 0 and ȳ = 17: the intercept carries the shift
        // (c − (1 − a·α)·ȳ), x_s does not move, and the outputs agree.
        let u: Vec<f32> = (0..800)
            .map(|k| 0.5 + 0.5 * (k as f32 * 0.03).sin())
            .collect();
        let (a, alpha, c) = (0.95f32, 0.6f32, 3.7f32);
        let theta = |c: f32| {
            [
                1.0, alpha, 0.05, 0.02, 0.03, -0.02, 0.01, 0.04, 1.0, 18.0, a, 8.0, c, 0.0,
            ]
        };
        let fam = Family::Generalized;
        let absolute = simulate(fam, &theta(c), 0.0, &u, 14.0).x;
        let lo = absolute.iter().fold(f32::INFINITY, |m, &v| m.min(v));
        let hi = absolute.iter().fold(f32::NEG_INFINITY, |m, &v| m.max(v));
        assert!(lo < 18.0 && 18.0 < hi, "the output crosses x_s: {lo}..{hi}");
        let y_mean = 17.0f32;
        let shifted = simulate(
            fam,
            &theta(c - (1.0 - a * alpha) * y_mean),
            y_mean,
            &u,
            -3.0,
        )
        .x;
        for (k, (l, x)) in absolute.iter().zip(&shifted).enumerate() {
            assert!(
                (l - (x + y_mean)).abs() < 1e-3,
                "sample {k}: {l} against {}",
                x + y_mean
            );
        }
        // Read in the frame's own coordinates (switching at its mean, as a
        // model without x_s does), the same numbers are another model.
        let at_mean = {
            let mut t = theta(c - (1.0 - a * alpha) * y_mean);
            t[9] = y_mean;
            simulate(fam, &t, y_mean, &u, -3.0).x
        };
        let apart = at_mean
            .iter()
            .zip(&shifted)
            .fold(0.0f32, |m, (p, q)| m.max((p - q).abs()));
        assert!(apart > 0.1, "{apart}");
    }
}
