//! The independent self-test's data generator: its own `f64` simulation of
//! the classic Bouc-Wen model and its own realisations of every physical
//! effect listed in [`Effect::PHYSICAL`](crate::model::effects::Effect::PHYSICAL) (docs/DIAGNOSIS.md, "The
//! independent self-test").
//!
//! Why a second implementation: data made by adding the catalogue's own
//! equations to the nominal model can be matched exactly by the catalogue,
//! so a self-test built on them cannot see an effect realised any other way.
//! This file therefore never calls into `model::effects`, `diagnose::effects`
//! or `model::sim`; the model's mathematics is copied from `model::sim`'s
//! documentation (eq. 13 with the classic state of eq. 20, deviation
//! coordinates, free run from `x(0) = y(0) + x₀`, `w(0) = 0`), in `f64`.
//! Every realisation has one size whose value 0 reproduces the nominal
//! output exactly (it adds `+0`, multiplies by `1` or never binds).

use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use super::mechanism::Mechanism;
use crate::data::Trace;

/// The nominal classic model in the coordinates it was fitted in.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Plant {
    pub big_a: f64,
    pub alpha: f64,
    pub beta: f64,
    pub gamma: f64,
    pub n: f64,
    pub a: f64,
    pub b: f64,
    pub c: f64,
    pub x0: f64,
    /// Input and output means removed before fitting (absolute = deviation + mean).
    pub u_mean: f64,
    pub y_mean: f64,
    pub dt: f64,
}

impl Plant {
    /// From the classic model's canonical vector `[A, α, β, γ, n, a, b, c, x₀]`.
    pub fn classic(theta: &[f64], u_mean: f64, y_mean: f64, dt: f64) -> Plant {
        assert_eq!(theta.len(), 9, "the classic model takes 9 parameters");
        Plant {
            big_a: theta[0],
            alpha: theta[1],
            beta: theta[2],
            gamma: theta[3],
            n: theta[4],
            a: theta[5],
            b: theta[6],
            c: theta[7],
            x0: theta[8],
            u_mean,
            y_mean,
            dt,
        }
    }

    /// Whether a rising input drives the output up (the side an end stop sits on).
    pub fn drives_up(&self) -> bool {
        self.b >= 0.0
    }

    /// `w(k) = w + A·Δ − β·|Δ|·|w|^(n−1)·w − γ·Δ·|w|^n`.
    fn bouc_wen(&self, big_a: f64, w: f64, delta: f64) -> f64 {
        // |w|^(n−1)·w and |w|^n, with n = 1 taken exactly.
        let (wn1w, wn) = if self.n == 1.0 {
            (w, w.abs())
        } else if w == 0.0 {
            (0.0, 0.0)
        } else {
            let p = w.abs().powf(self.n - 1.0);
            (p * w, p * w.abs())
        };
        w + big_a * delta - self.beta * delta.abs() * wn1w - self.gamma * delta * wn
    }
}

/// The size ranges belong with the generator: they are read off the
/// excitation a case is generated on.
impl Mechanism {
    /// The far end of the size's range on `exc`: where calibration stops if
    /// even there the mark is smaller than asked for.
    fn max_size(self, exc: &Excitation, ry: f64) -> f64 {
        use Mechanism::*;
        let ru = exc.input_range();
        match self {
            PureDelay | InputLag | OutputLag | DrainLag => 30.0,
            ExtraPole => 0.9,
            LoadMode => 60.0,
            GainAsymmetry | LoadGain => 0.5,
            StateClip | OutputClip | SoftLimit => 0.4 * ry,
            CreepInput | CreepTwo | CrossTalk => 2.0 * ry / ru,
            CreepOutput => 2.0,
            DeadZone | HystereticThreshold => 0.6 * ru,
            ViscousRate => 10.0 / exc.max_rate().max(f64::MIN_POSITIVE),
            Play => 0.5 * ru,
            MullinsSoftening | CyclicSoftening => 1.0,
            PermanentSet | Ratchet => 0.5 * ry,
        }
    }
}

/// An input signal the cases are generated on, with the state the free run
/// starts from.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Excitation {
    pub name: String,
    pub dt: f64,
    /// Absolute input.
    pub input: Vec<f64>,
    /// `x(0)` in the plant's deviation coordinates (`w(0) = 0`).
    pub x_start: f64,
    /// The data's trace for the stair (its time column and names kept).
    #[serde(skip)]
    pub template: Option<Trace>,
}

impl Excitation {
    /// The data's own input, started where the nominal model starts on it.
    pub fn stair(trace: &Trace, plant: &Plant) -> Excitation {
        Excitation {
            name: "stair".into(),
            dt: trace.dt(),
            input: trace.input.clone(),
            x_start: trace.output[0] - plant.y_mean + plant.x0,
            template: Some(trace.clone()),
        }
    }

    /// A multisine of `len` samples within `[lo, hi]`: 8 sines log-spaced
    /// from 2 periods per record to 3 Hz (or 0.3 × the sample rate if that is
    /// lower), equal amplitudes, phases drawn from `rng`. Started at the
    /// nominal equilibrium of its first input with `w = 0` (a constant input
    /// leaves `w` at 0, so the diagnosis' `w(0) = 0` is right).
    pub fn multisine(
        len: usize,
        dt: f64,
        (lo, hi): (f64, f64),
        plant: &Plant,
        rng: &mut ChaCha8Rng,
    ) -> Excitation {
        let f_lo = 2.0 / (len as f64 * dt);
        let f_hi = 3.0f64.min(0.3 / dt).max(2.0 * f_lo);
        let k = 8;
        let sines: Vec<(f64, f64)> = (0..k)
            .map(|i| {
                let f = f_lo * (f_hi / f_lo).powf(i as f64 / (k - 1) as f64);
                (f, rng.random_range(0.0..std::f64::consts::TAU))
            })
            .collect();
        let raw: Vec<f64> = (0..len)
            .map(|j| {
                let t = j as f64 * dt;
                sines
                    .iter()
                    .map(|(f, ph)| (std::f64::consts::TAU * f * t + ph).sin())
                    .sum()
            })
            .collect();
        let (rmin, rmax) = extremes(&raw);
        let input: Vec<f64> = raw
            .iter()
            .map(|v| lo + (hi - lo) * (v - rmin) / (rmax - rmin))
            .collect();
        let u0 = input[0] - plant.u_mean;
        let x_start = (plant.b * u0 + plant.c) / (1.0 - plant.a * plant.alpha);
        Excitation {
            name: "multisine".into(),
            dt,
            input,
            x_start,
            template: None,
        }
    }

    /// Pulses from `lo` to `lo + level·(hi − lo)`, one per level, each
    /// half of its period, after a quarter period at rest, through a valve
    /// (a first-order lag of 0.4 per sample): a muscle loaded again and
    /// again, as a lab cycles one. Started at the nominal equilibrium of
    /// its first input, as the multisine.
    pub fn pulses(
        name: &str,
        levels: &[f64],
        len: usize,
        dt: f64,
        (lo, hi): (f64, f64),
        plant: &Plant,
    ) -> Excitation {
        let period = len as f64 / (levels.len() as f64 + 0.5);
        let target = |j: usize| {
            let t = j as f64 / period - 0.25;
            let (i, frac) = (t.floor(), t - t.floor());
            match levels.get(i as usize) {
                Some(level) if t >= 0.0 && frac < 0.5 => lo + level * (hi - lo),
                _ => lo,
            }
        };
        let mut input = vec![lo; len];
        for j in 1..len {
            input[j] = 0.6 * input[j - 1] + 0.4 * target(j);
        }
        let x_start = (plant.b * (lo - plant.u_mean) + plant.c) / (1.0 - plant.a * plant.alpha);
        Excitation {
            name: name.into(),
            dt,
            input,
            x_start,
            template: None,
        }
    }

    fn input_range(&self) -> f64 {
        let (lo, hi) = extremes(&self.input);
        (hi - lo).max(f64::MIN_POSITIVE)
    }

    fn input_min(&self) -> f64 {
        extremes(&self.input).0
    }

    /// Largest input rate (input units per second).
    fn max_rate(&self) -> f64 {
        self.input
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f64::max)
            / self.dt
    }
}

/// The smallest and the largest value of `v`.
pub(super) fn extremes(v: &[f64]) -> (f64, f64) {
    v.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        })
}

/// Constants a realisation needs besides its size: from the excitation and
/// the nominal output on it.
#[derive(Debug, Clone, Copy)]
struct Scales {
    p_lo: f64,
    /// The excitation's input range, and the nominal output at rest at
    /// its lowest input (deviation coordinates).
    ru: f64,
    rest: f64,
    /// The nominal output's peak on the side the input drives it to
    /// (deviation coordinates), and the output range.
    peak: f64,
    ry: f64,
    branch_tol: f64,
    drives_up: bool,
}

/// The states the realisations carry from sample to sample.
#[derive(Debug, Clone, Default)]
struct States {
    lag_in: f64,
    drain: f64,
    play: f64,
    engaged: bool,
    dir: f64,
    extreme: f64,
    rate: f64,
    out_lag: f64,
    mode: [f64; 2],
    creep: [f64; 2],
    cross_talk: f64,
    /// The loadings so far, whether one is under way, the input's low
    /// since the last fall and its high since the last rise, the largest
    /// input so far, and the muscle's largest displacement toward its
    /// drive so far.
    loadings: f64,
    loading: bool,
    low: f64,
    high: f64,
    top: f64,
    reach: f64,
}

/// The plant's output (absolute) on `exc`'s input with `effects` at their
/// sizes, for dataset `dataset` (only [`Mechanism::LoadGain`] tells the
/// datasets apart).
pub fn simulate(
    plant: &Plant,
    exc: &Excitation,
    effects: &[(Mechanism, f64)],
    dataset: usize,
) -> Vec<f64> {
    let mut y = deviation(plant, exc, effects, dataset);
    for v in &mut y {
        *v += plant.y_mean;
    }
    y
}

/// [`simulate`] in the plant's deviation coordinates.
fn deviation(
    plant: &Plant,
    exc: &Excitation,
    effects: &[(Mechanism, f64)],
    dataset: usize,
) -> Vec<f64> {
    // The nominal output's extremes in the same coordinates as the state,
    // so that an end stop at the peak (size 0) never binds.
    let (omin, omax) = if effects.is_empty() {
        (0.0, 0.0)
    } else {
        extremes(&deviation(plant, exc, &[], 0))
    };
    let sc = Scales {
        p_lo: exc.input_min(),
        ru: exc.input_range(),
        rest: (plant.b * (exc.input_min() - plant.u_mean) + plant.c)
            / (1.0 - plant.a * plant.alpha),
        peak: if plant.drives_up() { omax } else { omin },
        ry: omax - omin,
        branch_tol: 0.02 * exc.input_range(),
        drives_up: plant.drives_up(),
    };
    run(plant, exc, effects, dataset, &sc)
}

/// The free run of `plant` on `exc`'s input with `effects` at their sizes
/// (deviation coordinates): every sample, the input side's effects shape
/// the pressure the muscle sees, the muscle and its Bouc-Wen state step,
/// and the output side's effects shape what the sensor sees.
fn run(
    plant: &Plant,
    exc: &Excitation,
    effects: &[(Mechanism, f64)],
    dataset: usize,
    sc: &Scales,
) -> Vec<f64> {
    use Mechanism::*;
    let p = &exc.input;
    let n = p.len();
    let mut out = Vec::with_capacity(n);
    if n == 0 {
        return out;
    }
    let r = Run {
        plant,
        p,
        effects,
        dataset,
        sc,
        toward: if sc.drives_up { 1.0 } else { -1.0 },
        soft_h: 0.05 * sc.ry,
    };
    let mut st = States {
        lag_in: p[0],
        drain: p[0],
        cross_talk: p[0],
        extreme: p[0],
        low: p[0],
        top: p[0],
        ..States::default()
    };
    let (mut x, mut w) = (exc.x_start, 0.0);
    st.reach = r.toward * x;
    let mut q = x;
    st.out_lag = x;
    st.mode = [x, x];
    out.push(x);
    for k in 1..n {
        let raw = p[k - 1];
        r.follow_loadings(&mut st, raw);
        let pe = r.input_side(&mut st, k);
        let u = pe - plant.u_mean;
        let xk = r.muscle(x, w, u);
        // The Bouc-Wen state follows the motion it sees: the muscle's, or
        // the load's behind an extra pole.
        let mut big_a = plant.big_a;
        if let Some(eta) = r.size(ViscousRate) {
            let prev = if k >= 2 { p[k - 2] } else { p[0] };
            st.rate = 0.5 * st.rate + 0.5 * (raw - prev).abs() / plant.dt;
            big_a *= 1.0 + eta * st.rate;
        }
        let qk = match r.size(ExtraPole) {
            Some(rho) => rho * q + (1.0 - rho) * xk,
            None => xk,
        };
        w = plant.bouc_wen(big_a, w, qk - q);
        x = xk;
        q = qk;
        out.push(r.output_side(&mut st, raw, qk, xk, u));
    }
    out
}

/// What every sample of a [`run`] reads: the plant, the input, the effects
/// and their scales, the side the input drives the output to (`toward`,
/// ±1) and the smooth stop's knee width `soft_h`.
struct Run<'a> {
    plant: &'a Plant,
    p: &'a [f64],
    effects: &'a [(Mechanism, f64)],
    dataset: usize,
    sc: &'a Scales,
    toward: f64,
    soft_h: f64,
}

impl Run<'_> {
    /// The size of mechanism `r`, `None` where it is not among the effects.
    fn size(&self, r: Mechanism) -> Option<f64> {
        self.effects.iter().find(|(e, _)| *e == r).map(|&(_, s)| s)
    }

    /// An end stop's level for size `s`, in deviation coordinates: at the
    /// nominal peak for size 0, so that it never binds there.
    fn stop(&self, s: f64) -> f64 {
        self.sc.peak - self.toward * s
    }

    /// The pressure the muscle sees at sample `k`: the effects of the input
    /// side, in the order the air meets them: transport delay, valve and
    /// chamber lags, the muscle's threshold, the braid's play, the branch
    /// gain, the load's gain.
    fn input_side(&self, st: &mut States, k: usize) -> f64 {
        use Mechanism::*;
        let (p, sc) = (self.p, self.sc);
        let raw = p[k - 1];
        let mut pe = raw;
        if let Some(d) = self.size(PureDelay) {
            pe = delayed(p, k, d);
        }
        if let Some(tau) = self.size(InputLag) {
            let rho = tau / (1.0 + tau);
            st.lag_in = rho * st.lag_in + (1.0 - rho) * pe;
            pe = st.lag_in;
        }
        if let Some(tau) = self.size(DrainLag) {
            st.drain = if pe >= st.drain {
                pe
            } else {
                let rho = tau / (1.0 + tau);
                rho * st.drain + (1.0 - rho) * pe
            };
            pe = st.drain;
        }
        if let Some(p0) = self.size(DeadZone) {
            pe -= (pe - sc.p_lo).clamp(0.0, p0);
        }
        if let Some(s) = self.size(HystereticThreshold) {
            if pe > sc.p_lo + s {
                st.engaged = true;
            } else if pe < sc.p_lo + 0.5 * s {
                st.engaged = false;
            }
            if !st.engaged {
                pe = pe.min(sc.p_lo);
            }
        }
        if let Some(r) = self.size(Play) {
            let prev = if k == 1 { pe } else { st.play };
            st.play = prev.clamp(pe - 0.5 * r, pe + 0.5 * r);
            pe = st.play;
        }
        if let Some(eps) = self.size(GainAsymmetry) {
            pe *= 1.0 + self.branch(st, raw) * eps;
        }
        if let Some(g) = self.size(LoadGain)
            && self.dataset >= 1
        {
            pe *= 1.0 + g;
        }
        if let Some(s) = self.size(CyclicSoftening) {
            pe += (pe - sc.p_lo) * s * st.loadings / (st.loadings + 1.0);
        }
        pe
    }

    /// Counts the loadings of the raw input and keeps its largest value so
    /// far: a loading begins when the input rises `branch_tol` above its
    /// low since the last fall, and ends when it falls as far below its
    /// high.
    fn follow_loadings(&self, st: &mut States, raw: f64) {
        let tol = self.sc.branch_tol;
        if st.loading {
            st.high = st.high.max(raw);
            if raw < st.high - tol {
                st.loading = false;
                st.low = raw;
            }
        } else {
            st.low = st.low.min(raw);
            if raw > st.low + tol {
                st.loading = true;
                st.loadings += 1.0;
                st.high = raw;
            }
        }
        st.top = st.top.max(raw);
    }

    /// The branch the raw input is on (+1 rising, −1 falling, 0 before it
    /// first moves): rising until it falls `branch_tol` below its running
    /// maximum, and vice versa.
    fn branch(&self, st: &mut States, raw: f64) -> f64 {
        let sc = self.sc;
        if st.dir >= 0.0 {
            st.extreme = st.extreme.max(raw);
            if raw < st.extreme - sc.branch_tol {
                st.dir = -1.0;
                st.extreme = raw;
            } else if raw > self.p[0] + sc.branch_tol {
                st.dir = 1.0;
            }
        } else {
            st.extreme = st.extreme.min(raw);
            if raw > st.extreme + sc.branch_tol {
                st.dir = 1.0;
                st.extreme = raw;
            }
        }
        st.dir
    }

    /// The muscle's next state from state `x`, Bouc-Wen state `w` and input
    /// `u` (deviation): eq. 13's linear part on its own state, held by an
    /// end stop or a smooth stop where one is among the effects.
    fn muscle(&self, x: f64, w: f64, u: f64) -> f64 {
        use Mechanism::*;
        let (plant, sc) = (self.plant, self.sc);
        let mut xk = plant.a * (plant.alpha * x + (1.0 - plant.alpha) * w) + plant.b * u + plant.c;
        if let Some(s) = self.size(StateClip) {
            let l = self.stop(s);
            xk = if sc.drives_up { xk.min(l) } else { xk.max(l) };
        }
        if let Some(s) = self.size(SoftLimit) {
            let knee = self.stop(s);
            let over = self.toward * (xk - knee);
            if over > 0.0 {
                xk = knee + self.toward * self.soft_h * (over / self.soft_h).tanh();
            }
        }
        xk
    }

    /// What the sensor sees of the load's motion `qk`: the effects of the
    /// output side (softening, lag, load mode, creep, set, clip, cross-talk
    /// from the raw input `raw`), given the muscle's state `xk` and input
    /// `u`.
    fn output_side(&self, st: &mut States, raw: f64, qk: f64, xk: f64, u: f64) -> f64 {
        use Mechanism::*;
        let mut y = qk;
        st.reach = st.reach.max(self.toward * xk);
        if let Some(s) = self.size(MullinsSoftening) {
            let q = (st.top - self.sc.p_lo) / self.sc.ru;
            y += (y - self.sc.rest) * s * q;
        }
        if let Some(tau) = self.size(OutputLag) {
            let rho = tau / (1.0 + tau);
            st.out_lag = rho * st.out_lag + (1.0 - rho) * y;
            y = st.out_lag;
        }
        if let Some(period) = self.size(LoadMode) {
            y = mode(&mut st.mode, y, period);
        }
        if let Some(kappa) = self.size(CreepInput) {
            st.creep[0] = 0.995 * st.creep[0] + 0.005 * kappa * u;
            y += st.creep[0];
        }
        if let Some(kappa) = self.size(CreepOutput) {
            st.creep[0] = 0.995 * st.creep[0] + 0.005 * kappa * xk;
            y += st.creep[0];
        }
        if let Some(kappa) = self.size(CreepTwo) {
            st.creep[0] = 0.99 * st.creep[0] + 0.01 * 0.5 * kappa * u;
            st.creep[1] = 0.999 * st.creep[1] + 0.001 * 0.5 * kappa * u;
            y += st.creep[0] + st.creep[1];
        }
        if let Some(s) = self.size(OutputClip) {
            let l = self.stop(s);
            y = if self.sc.drives_up {
                y.min(l)
            } else {
                y.max(l)
            };
        }
        // A set and a ratchet move the rest away from the drive.
        if let Some(s) = self.size(PermanentSet) {
            y -= self.toward * s * (st.reach - self.toward * xk) / self.sc.ry;
        }
        if let Some(s) = self.size(Ratchet) {
            y -= self.toward * s * (1.0 + st.loadings).ln() / 5f64.ln();
        }
        if let Some(kappa) = self.size(CrossTalk) {
            st.cross_talk = 0.75 * st.cross_talk + 0.25 * raw;
            y += kappa * (raw - st.cross_talk);
        }
        y
    }
}

/// The input `p` delayed by `d` samples at sample `k` (the input of sample
/// `k − 1 − d`, linearly interpolated between samples; the first input
/// before the record starts).
fn delayed(p: &[f64], k: usize, d: f64) -> f64 {
    let at = (k - 1) as f64 - d;
    if at <= 0.0 {
        p[0]
    } else {
        let i = at.floor() as usize;
        let f = at - at.floor();
        if f == 0.0 {
            p[i]
        } else {
            p[i] * (1.0 - f) + p[i + 1] * f
        }
    }
}

/// One step of the underdamped mode of natural period `period` samples and
/// damping 0.1, unit static gain: `y(k) = 2r·cos θ·y(k−1) − r²·y(k−2) +
/// (1 − 2r·cos θ + r²)·x(k)`, `r = e^(−ζω)`, `θ = ω·√(1−ζ²)`, `ω = 2π/period`.
/// `period = 0` (an infinitely stiff load) passes `x` through.
fn mode(s: &mut [f64; 2], x: f64, period: f64) -> f64 {
    if period == 0.0 {
        *s = [x, s[0]];
        return x;
    }
    let zeta = 0.1;
    let omega = std::f64::consts::TAU / period;
    let r = (-zeta * omega).exp();
    let c = 2.0 * r * (omega * (1.0 - zeta * zeta).sqrt()).cos();
    let y = c * s[0] - r * r * s[1] + (1.0 - c + r * r) * x;
    *s = [y, s[0]];
    y
}

/// The mark effects leave on the nominal output: the RMS of the change over
/// every dataset, less its mean (an offset is absorbed by the intercept);
/// `+∞` if it is not finite.
pub fn mark(plant: &Plant, exc: &Excitation, effects: &[(Mechanism, f64)]) -> f64 {
    let nominal = simulate(plant, exc, &[], 0);
    let datasets = effects.iter().map(|(r, _)| r.datasets()).max().unwrap_or(1);
    let change: Vec<f64> = (0..datasets)
        .flat_map(|i| {
            simulate(plant, exc, effects, i)
                .into_iter()
                .zip(&nominal)
                .map(|(v, o)| v - o)
                .collect::<Vec<_>>()
        })
        .collect();
    let m = change.len().max(1) as f64;
    let mean = change.iter().sum::<f64>() / m;
    let rms = (change.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / m).sqrt();
    if rms.is_finite() { rms } else { f64::INFINITY }
}

/// Standard deviation of the added noise: 0.5 % of the nominal output's
/// range on the excitation (as the catalogue self-test's).
pub fn noise_sigma(plant: &Plant, exc: &Excitation) -> f64 {
    let (lo, hi) = extremes(&simulate(plant, exc, &[], 0));
    0.005 * (hi - lo)
}

/// The largest size of `r` whose mark is at most `target` (bisection from 0
/// to the far end of its range; that end if even it leaves a smaller mark).
/// The lower end of the last bracket: a mark can jump where an effect starts
/// to bind, and a case must not be larger than asked for.
pub fn calibrate(plant: &Plant, exc: &Excitation, r: Mechanism, target: f64) -> f64 {
    let (lo_y, hi_y) = extremes(&simulate(plant, exc, &[], 0));
    let top = r.max_size(exc, hi_y - lo_y);
    if mark(plant, exc, &[(r, top)]) <= target {
        return top;
    }
    let (mut lo, mut hi) = (0.0, top);
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if mark(plant, exc, &[(r, mid)]) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The traces of a case: the plant with `effects` on `exc`, plus white
/// noise of `sigma` drawn from `rng`, the first sample left clean (the free
/// run starts from it; a noisy start would blur every case alike). One
/// trace per dataset the effects need.
pub fn traces(
    plant: &Plant,
    exc: &Excitation,
    effects: &[(Mechanism, f64)],
    sigma: f64,
    name: &str,
    rng: &mut ChaCha8Rng,
) -> Vec<Trace> {
    let datasets = effects.iter().map(|(r, _)| r.datasets()).max().unwrap_or(1);
    let noise = Normal::new(0.0, sigma).expect("finite sigma");
    (0..datasets)
        .map(|i| {
            let y: Vec<f64> = simulate(plant, exc, effects, i)
                .into_iter()
                .enumerate()
                .map(|(k, v)| if k == 0 { v } else { v + noise.sample(rng) })
                .collect();
            let source = format!("blind {name}#{i}");
            match &exc.template {
                Some(t) => {
                    let mut t = t.clone();
                    t.source = source;
                    t.output = y;
                    t
                }
                None => Trace::uniform(source, exc.dt, exc.input.clone(), y),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// The thesis-like classic plant on a stair through a valve (as the
    /// catalogue self-test's rig trace), in its own deviation coordinates.
    fn plant_and_stair() -> (Plant, Excitation) {
        let levels = [0.05, 0.2, 0.35, 0.5, 0.3, 0.1, 0.25, 0.45, 0.15];
        let mut p = vec![levels[0]; 1080];
        for k in 1..p.len() {
            p[k] = 0.6 * p[k - 1] + 0.4 * levels[(k / 60) % levels.len()];
        }
        let plant = Plant::classic(
            &[0.9, 0.6, 0.05, 0.02, 1.0, 0.95, 20.0, 0.1, 0.0],
            0.27,
            5.0,
            0.1,
        );
        let exc = Excitation {
            name: "stair".into(),
            dt: 0.1,
            input: p,
            x_start: 0.0,
            template: None,
        };
        (plant, exc)
    }

    fn excitations() -> (Plant, Vec<Excitation>) {
        let (plant, stair) = plant_and_stair();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let ms = Excitation::multisine(1080, 0.1, (0.05, 0.5), &plant, &mut rng);
        let pulses = Excitation::pulses("pulses", &[0.6, 1.0, 0.8], 1080, 0.1, (0.05, 0.5), &plant);
        (plant, vec![stair, ms, pulses])
    }

    #[test]
    fn every_realisation_at_size_zero_is_exactly_the_nominal_output() {
        let (plant, excs) = excitations();
        for exc in &excs {
            let nominal = simulate(&plant, exc, &[], 0);
            for r in Mechanism::ALL {
                for i in 0..r.datasets() {
                    let y = simulate(&plant, exc, &[(r, 0.0)], i);
                    assert_eq!(y, nominal, "{} on {}", r.label(), exc.name);
                }
            }
            // All at once, too.
            let all: Vec<_> = Mechanism::ALL.iter().map(|&r| (r, 0.0)).collect();
            assert_eq!(simulate(&plant, exc, &all, 1), nominal);
        }
    }

    #[test]
    fn every_realisation_changes_the_output_at_a_nonzero_size() {
        let (plant, excs) = excitations();
        for exc in &excs {
            for r in Mechanism::ALL {
                let s = calibrate(&plant, exc, r, 3.0 * noise_sigma(&plant, exc));
                assert!(s > 0.0, "{} on {}", r.label(), exc.name);
                assert!(mark(&plant, exc, &[(r, s)]) > 0.0);
            }
        }
    }

    #[test]
    fn sizes_are_calibrated_to_the_mark() {
        let (plant, excs) = excitations();
        for exc in &excs {
            let sigma = noise_sigma(&plant, exc);
            for r in Mechanism::ALL {
                let (lo, hi) = extremes(&simulate(&plant, exc, &[], 0));
                let top = r.max_size(exc, hi - lo);
                for k in [6.0, 15.0] {
                    let s = calibrate(&plant, exc, r, k * sigma);
                    let m = mark(&plant, exc, &[(r, s)]);
                    assert!(
                        m <= k * sigma * 1.0001,
                        "{}: {m} > {}",
                        r.label(),
                        k * sigma
                    );
                    // At the target; or short of it at the range's end, or
                    // where the mark jumps past it (a stair level crossing a
                    // threshold): just above the size it is over the target.
                    let jumps = mark(&plant, exc, &[(r, s + 1e-9 * top)]) > k * sigma;
                    assert!(
                        m >= 0.9 * k * sigma || s == top || jumps,
                        "{} on {}: mark {m} for target {}",
                        r.label(),
                        exc.name,
                        k * sigma
                    );
                }
            }
        }
    }

    /// The pulse trains tell the drivers apart: on pulses of 0.6, 0.8, 1
    /// and 1 a Mullins-type softening leaves the last two alike and a
    /// cyclic one deepens the last; a set moves the rests after the first
    /// pulse for good, a ratchet after every one.
    #[test]
    fn the_pulse_trains_tell_the_drivers_apart() {
        let (plant, _) = plant_and_stair();
        let exc = Excitation::pulses("p", &[0.6, 0.8, 1.0, 1.0], 1080, 0.1, (0.05, 0.5), &plant);
        let nominal = simulate(&plant, &exc, &[], 0);
        let period = 1080.0 / 4.5;
        // The change at the end of pulse `i` and of the rest after it.
        let change = |r: Mechanism, i: usize| {
            let y = simulate(&plant, &exc, &[(r, 0.3)], 0);
            let at = |t: f64| {
                let k = (t * period) as usize;
                y[k] - nominal[k]
            };
            let i = i as f64;
            (at(0.25 + i + 0.45), at(0.25 + i + 0.95))
        };
        let mullins: Vec<_> = (0..4)
            .map(|i| change(Mechanism::MullinsSoftening, i))
            .collect();
        let cyclic: Vec<_> = (0..4)
            .map(|i| change(Mechanism::CyclicSoftening, i))
            .collect();
        let grown = |c: &[(f64, f64)]| (c[3].0 - c[2].0).abs() / c[3].0.abs();
        assert!(grown(&mullins) < 0.01, "{mullins:?}");
        assert!(grown(&cyclic) > 0.03, "{cyclic:?}");
        for set in [Mechanism::PermanentSet, Mechanism::Ratchet] {
            let rests: Vec<f64> = (0..4).map(|i| change(set, i).1).collect();
            assert!(rests.iter().all(|r| r.abs() > 1e-3), "{set:?}: {rests:?}");
            // Away from the drive (the plant drives up), never back.
            assert!(
                rests.windows(2).all(|w| w[1] <= w[0] + 1e-9),
                "{set:?}: {rests:?}"
            );
        }
    }

    #[test]
    fn the_generator_is_deterministic_for_a_seed() {
        let (plant, stair) = plant_and_stair();
        let make = |seed| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let ms = Excitation::multisine(500, 0.1, (0.0, 1.0), &plant, &mut rng);
            let mut out = traces(&plant, &ms, &[(Mechanism::Play, 0.05)], 0.1, "x", &mut rng);
            out.extend(traces(
                &plant,
                &stair,
                &[(Mechanism::LoadGain, 0.1)],
                0.1,
                "y",
                &mut rng,
            ));
            out.into_iter()
                .map(|t| (t.input, t.output))
                .collect::<Vec<_>>()
        };
        assert_eq!(make(5), make(5));
        assert_ne!(make(5), make(6));
    }

    #[test]
    fn the_plant_is_the_fitted_model_of_model_sim() {
        // The same mathematics as the reference simulation, in f64: within
        // f32 rounding of it (this test may call `model::sim`; the generator
        // does not).
        let (plant, exc) = plant_and_stair();
        let theta: Vec<f32> = [0.9, 0.6, 0.05, 0.02, 1.0, 0.95, 20.0, 0.1, 0.0]
            .iter()
            .map(|&v| v as f32)
            .collect();
        let u: Vec<f32> = exc.input.iter().map(|&v| (v - 0.27) as f32).collect();
        let reference =
            crate::model::simulate(crate::model::Family::Classic, &theta, 0.0, &u, 0.0).x;
        let ours = simulate(&plant, &exc, &[], 0);
        for (k, (r, o)) in reference.iter().zip(&ours).enumerate() {
            let o = o - 5.0;
            assert!(
                (*r as f64 - o).abs() < 1e-3 * (1.0 + o.abs()),
                "{k}: {r} {o}"
            );
        }
    }
}
