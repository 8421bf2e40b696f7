//! The effect chain of a model read with `control --from` (a diagnosed
//! model, or `fit --effects`), in the controllers' prediction: each effect
//! enters where it can, and [`EffectUse`] says how, or why not.
//!
//! - **Linear states** (`creep`, `creep:output`, `creep:two-pole`,
//!   `creep:log`, `inertia:ringing`): these act on the output side of the
//!   baseline only (`ŷ = x + Σ zᵢ + r`; they never feed back into `x` or
//!   `w`), so they are extra states driven by the pressure and by `x`:
//!
//!   ```text
//!   zᵢ(k+1) = ρᵢ·zᵢ(k) + κ̃ᵢ·u(k)          (input-driven; κ̃ᵢ = (1−ρᵢ)·κᵢ)
//!   zᵢ(k+1) = ρᵢ·zᵢ(k) + κ̃ᵢ·x(k+1)        (output-driven)
//!   r(k+1)  = a₁·r(k) − a₂·r(k−1) + g·(p(k) − p(k−1))
//!   ```
//!
//!   Their linear form is derived from the catalogue's parameters here, in
//!   one place ([`ControlChain::of`]); a test (tests/control_effects.rs)
//!   pins it to the step of record (`model::effects::Prepared::step`) on a
//!   random input. The MPC's Jacobian carries them exactly (they are
//!   linear); the feedforward inverts the whole output, `x` plus them.
//! - **Dead zone** (`deadzone`): `p_eff = max(p − p₀, 0)` enters the
//!   prediction, and the feedforward asks for `p₀` more pressure: inverted
//!   in the input path.
//! - **End stops** (`saturation`, `saturation:output`, `saturation:soft`):
//!   as a constraint on what is tracked: the reference is held short of the
//!   stop `l_max`, so neither controller winds up against it. The state
//!   clip and the soft stop bound the baseline's `x`, not the output, so
//!   with effect states adding to the output they are left out.
//! - Everything else is left out, with its reason ([`EffectUse`]).
//!
//! **Estimating the unmeasured states.** The creeps' and the ringing's
//! states are not measured. The observer (`super::observer`) runs them
//! forward on its pressure estimate (mostly predicted, so the 2 kPa
//! sensor noise does not ring the model's mode) and on its displacement
//! estimate, and corrects the baseline's `x` with the measured output less
//! them — the restart the diagnosis' h-step-ahead predictor uses
//! (`Prepared::restart`), so the controller predicts as the model was
//! fitted to. They start as the fit started them ([`ControlChain::start`]).
//! A ringing mode also takes its steady-state Kalman share of each
//! innovation ([`Ring::observer_gains`]): a ringing the model's kick did
//! not start goes into the mode, not into `x`. Why not correct the effect states
//! from the measurement too: one displacement cannot tell a creep from the
//! baseline's own slow pole; whatever the split gets wrong as an offset is
//! taken by the observer's integrating disturbance.

use serde::{Deserialize, Serialize};

use crate::model::Model;
use crate::model::effects::Effect;

/// Most effect states a prediction carries: every linear realisation at
/// once (creep 1, output creep 1, two-pole 2, log 3, ringing 2).
pub const MAX_EFFECT_STATES: usize = 9;

/// What drives a first-order slow state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Drive {
    /// The pressure into the baseline (deviation, after a dead zone).
    Input,
    /// The baseline's displacement `x(k+1)`.
    Output,
}

/// A first-order slow state `z ← ρ·z + weight·drive`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Lag {
    pub rho: f64,
    /// `(1 − ρ)·κ`.
    pub weight: f64,
    pub drive: Drive,
    /// Where the state starts (mm): the fitted `z0` for a creep's slowest
    /// state, 0 for the others, as the step of record starts them.
    pub start: f64,
}

/// The load's mode kicked by the pressure's change.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Ring {
    pub a1: f64,
    pub a2: f64,
    /// Kick per MPa of pressure change (mm/MPa).
    pub g: f64,
    /// The observer's gains `[k_x, k_r1, k_r2]`: the shares of the output's
    /// innovation taken into the baseline's `x` and into the mode's two
    /// states ([`Ring::observer_gains`]).
    pub gains: [f64; 3],
}

impl Ring {
    /// The steady-state Kalman gains of `[x, r(k), r(k−1)]` measured as
    /// `y = x + r(k)`: `x` a random walk (whatever the model gets wrong
    /// moves it), the mode driven by a disturbance of the same size, the
    /// measurement trusted ten times more than either (the displacement
    /// sensor is trusted, as the observer's `Lx = 1` says). A ringing that
    /// the model's kick did not start is then taken into the mode's
    /// states, not into `x`, which the controller would fight.
    pub fn observer_gains(a1: f64, a2: f64) -> [f64; 3] {
        let a = [[1.0, 0.0, 0.0], [0.0, a1, -a2], [0.0, 1.0, 0.0]];
        let (q, r) = ([1.0, 1.0, 0.0], 0.1);
        let mut p = [[0.0f64; 3]; 3];
        let mut k = [1.0, 0.0, 0.0];
        for _ in 0..2000 {
            // P ← A·P·Aᵀ + Q
            let mut ap = [[0.0; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    ap[i][j] = (0..3).map(|l| a[i][l] * p[l][j]).sum();
                }
            }
            let mut next = [[0.0; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    next[i][j] = (0..3).map(|l| ap[i][l] * a[j][l]).sum::<f64>();
                }
                next[i][i] += q[i];
            }
            // K = P·Cᵀ/(C·P·Cᵀ + R), C = [1, 1, 0]; P ← (I − K·C)·P
            let pc: [f64; 3] = std::array::from_fn(|i| next[i][0] + next[i][1]);
            let s = pc[0] + pc[1] + r;
            k = pc.map(|v| v / s);
            for i in 0..3 {
                for j in 0..3 {
                    p[i][j] = next[i][j] - k[i] * (next[0][j] + next[1][j]);
                }
            }
        }
        k
    }
}

/// The effects a controller's prediction carries besides the baseline.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ControlChain {
    /// Slow states, one each, in the order of the model's chain.
    pub lags: Vec<Lag>,
    /// The ringing's two states follow the lags'.
    pub ring: Option<Ring>,
    /// Dead-zone threshold `p₀` (MPa, absolute).
    pub deadzone_mpa: Option<f64>,
    /// End stop (mm, absolute) and whether the pressure drives the output
    /// up toward it.
    pub end_stop: Option<(f64, bool)>,
}

/// How one effect of the model entered the controllers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EffectUse {
    /// The realisation, e.g. `creep:two-pole`.
    pub effect: String,
    /// `states`, `input-path`, `constraint` or `left-out`.
    pub used: String,
    /// How, or why not.
    pub detail: String,
}

impl EffectUse {
    fn new(effect: Effect, used: &str, detail: impl Into<String>) -> Self {
        EffectUse {
            effect: effect.name().into(),
            used: used.into(),
            detail: detail.into(),
        }
    }

    /// One line for a person: `creep:two-pole: used as states (…)`.
    pub fn line(&self) -> String {
        let how = match self.used.as_str() {
            "states" => "used as states",
            "input-path" => "inverted in the input path",
            "constraint" => "as a constraint",
            _ => "left out",
        };
        format!("effect {}: {how}: {}", self.effect, self.detail)
    }
}

impl ControlChain {
    /// The chain of `model` the controllers can use, and how each effect
    /// was used: `None` where none is used (and no lines for a model
    /// without effects).
    pub fn of(model: &Model) -> (Option<ControlChain>, Vec<EffectUse>) {
        let Some(chain) = &model.chain else {
            return (None, Vec::new());
        };
        let mut out = ControlChain::default();
        let mut uses = Vec::new();
        let mut at = 0;
        let drives_up = chain.context.drives_up;
        let mut stops = Vec::new();
        for &e in &chain.effects {
            let dim = e.dim(chain.datasets);
            let p = &chain.params[at..at + dim];
            at += dim;
            let states = |lags: &[Lag], ring: bool| lags.len() + 2 * usize::from(ring);
            let lag = |rho: f64, kappa: f64, drive, start| Lag {
                rho,
                weight: (1.0 - rho) * kappa,
                drive,
                start,
            };
            let new_lags: Vec<Lag> = match e {
                Effect::Creep => vec![lag(p[0], p[1], Drive::Input, p[2])],
                Effect::OutputCreep => vec![lag(p[0], p[1], Drive::Output, p[2])],
                Effect::TwoPoleCreep => {
                    let (fast, slow) = (p[3] * p[2], p[2] - p[3] * p[2]);
                    vec![
                        lag(p[0], fast, Drive::Input, 0.0),
                        lag(p[1], slow, Drive::Input, p[4]),
                    ]
                }
                Effect::LogCreep => {
                    // Poles ρ^100, ρ^10, ρ, each of gain κ (the catalogue's);
                    // the slowest starts at z0.
                    let mid = p[0].powi(10);
                    let fast = mid.powi(10);
                    vec![
                        lag(fast, p[1], Drive::Input, 0.0),
                        lag(mid, p[1], Drive::Input, 0.0),
                        lag(p[0], p[1], Drive::Input, p[2]),
                    ]
                }
                _ => Vec::new(),
            };
            let room = MAX_EFFECT_STATES - states(&out.lags, out.ring.is_some());
            match e {
                Effect::Creep | Effect::OutputCreep | Effect::TwoPoleCreep | Effect::LogCreep => {
                    if new_lags.len() > room {
                        uses.push(EffectUse::new(
                            e,
                            "left-out",
                            format!("no room: the prediction carries {MAX_EFFECT_STATES} effect states at most"),
                        ));
                        continue;
                    }
                    let n = new_lags.len();
                    out.lags.extend(new_lags);
                    uses.push(EffectUse::new(
                        e,
                        "states",
                        format!(
                            "{n} slow state{} driven by the {}, estimated by running the model on the observer's estimates",
                            if n == 1 { "" } else { "s" },
                            if e == Effect::OutputCreep { "displacement" } else { "pressure" }
                        ),
                    ));
                }
                Effect::Ringing => {
                    if out.ring.is_some() || room < 2 {
                        uses.push(EffectUse::new(e, "left-out", "a second ringing mode"));
                        continue;
                    }
                    out.ring = Some(Ring {
                        a1: p[0],
                        a2: p[1],
                        g: p[2],
                        gains: Ring::observer_gains(p[0], p[1]),
                    });
                    let size = e
                        .size_text(p, model.base.dt)
                        .map_or(String::new(), |s| format!(" ({s})"));
                    uses.push(EffectUse::new(
                        e,
                        "states",
                        format!(
                            "2 states of the load's mode{size}, kicked by the pressure's change"
                        ),
                    ));
                }
                Effect::Deadzone => {
                    out.deadzone_mpa = Some(p[0]);
                    uses.push(EffectUse::new(
                        e,
                        "input-path",
                        format!(
                            "the prediction sees max(p − {:.4}, 0) MPa; the feedforward asks for {:.4} MPa more",
                            p[0], p[0]
                        ),
                    ));
                }
                Effect::Saturation | Effect::OutputClip | Effect::SoftStop => {
                    // Decided once every state is known (below).
                    stops.push((uses.len(), e, p[0]));
                    uses.push(EffectUse::new(e, "left-out", ""));
                }
                other => uses.push(EffectUse::new(other, "left-out", left_out_reason(other))),
            }
        }
        // An end stop bounds what can be tracked. The output clip bounds the
        // output itself; the state clip and the soft stop bound the
        // baseline's `x`, which is the output only while no effect state
        // adds to it (on the twin with creep the diagnosis put a state clip
        // at 34 mm, the creep carrying the output past it to 44 mm: held
        // below 34 mm, the reference lost its top).
        for (i, e, l_max) in stops {
            if e != Effect::OutputClip && out.states() > 0 {
                uses[i].detail = "it bounds the baseline's x, and the effect states carry the \
                                  output past it: a bound on the reference would be wrong"
                    .into();
                continue;
            }
            out.end_stop = Some(match out.end_stop {
                Some((stop, _)) if drives_up => (stop.min(l_max), true),
                Some((stop, _)) => (stop.max(l_max), false),
                None => (l_max, drives_up),
            });
            uses[i].used = "constraint".into();
            uses[i].detail = format!(
                "the reference is held {} the end stop {l_max:.2} mm",
                if drives_up { "below" } else { "above" }
            );
        }
        // Nothing used: the baseline's own code path, bit for bit.
        let used = out.states() > 0 || out.deadzone_mpa.is_some() || out.end_stop.is_some();
        (used.then_some(out), uses)
    }

    /// Effect states this chain carries.
    pub fn states(&self) -> usize {
        self.lags.len() + 2 * usize::from(self.ring.is_some())
    }

    /// The dead zone's effective pressure deviation for the absolute
    /// pressure `p` (`u_mean` the baseline's `ū`), and its slope.
    pub fn effective(&self, p: f64, u_mean: f64) -> (f64, f64) {
        match self.deadzone_mpa {
            Some(p0) if p - p0 > 0.0 => (p - p0 - u_mean, 1.0),
            Some(_) => (-u_mean, 0.0),
            None => (p - u_mean, 1.0),
        }
    }

    /// The effects' contribution to the output.
    pub fn output(&self, e: &[f64; MAX_EFFECT_STATES]) -> f64 {
        let mut y = 0.0;
        for z in &e[..self.lags.len()] {
            y += z;
        }
        if self.ring.is_some() {
            y += e[self.lags.len()];
        }
        y
    }

    /// The states one sample on: `u` the effective pressure deviation at
    /// `k`, `dp = p(k) − p(k−1)` (absolute, before the dead zone), `x` the
    /// baseline's `x(k+1)`.
    pub fn advance(
        &self,
        e: &[f64; MAX_EFFECT_STATES],
        u: f64,
        dp: f64,
        x: f64,
    ) -> [f64; MAX_EFFECT_STATES] {
        let mut next = *e;
        for (i, lag) in self.lags.iter().enumerate() {
            let drive = match lag.drive {
                Drive::Input => u,
                Drive::Output => x,
            };
            next[i] = lag.rho * e[i] + lag.weight * drive;
        }
        if let Some(r) = &self.ring {
            let i = self.lags.len();
            next[i] = r.a1 * e[i] - r.a2 * e[i + 1] + r.g * dp;
            next[i + 1] = e[i];
        }
        next
    }

    /// The baseline's `x(k+1)` and the effect states at `k+1` when the
    /// output `y(k+1)` (deviation) is known: the restart of
    /// `Prepared::restart` (`y` less the effects'), with an output-driven
    /// creep's own share of `x(k+1)` solved for.
    pub fn restart(
        &self,
        e: &[f64; MAX_EFFECT_STATES],
        u: f64,
        dp: f64,
        y: f64,
    ) -> (f64, [f64; MAX_EFFECT_STATES]) {
        let free = self.advance(e, u, dp, 0.0);
        let k_out: f64 = self
            .lags
            .iter()
            .filter(|l| l.drive == Drive::Output)
            .map(|l| l.weight)
            .sum();
        let x = (y - self.output(&free)) / (1.0 + k_out);
        (x, self.advance(e, u, dp, x))
    }

    /// The states at the first measurement, the output at `y` (deviation),
    /// and the baseline's `x` then: each creep where the model's fit
    /// started it (`z0`, the state the record's history left it in; the
    /// fits' records, like the twin's runs, start from the muscle at rest),
    /// the ringing at 0. Not at each creep's static value `κ·u`: the
    /// diagnosis' creeps have slow poles whose gains a record of tens of
    /// seconds does not settle (`creep:two-pole.kappa` 213 mm/MPa on the
    /// twin's 4.5 kg stair, against the baseline's 108), and started there
    /// the model predicted the validation record 16 mm off.
    pub fn start(&self, y: f64) -> (f64, [f64; MAX_EFFECT_STATES]) {
        let mut e = [0.0; MAX_EFFECT_STATES];
        for (i, lag) in self.lags.iter().enumerate() {
            e[i] = lag.start;
        }
        (y - self.output(&e), e)
    }

    /// The reference held short of the end stop (absolute mm).
    pub fn clip_reference(&self, r: f64) -> f64 {
        match self.end_stop {
            Some((stop, true)) => r.min(stop),
            Some((stop, false)) => r.max(stop),
            None => r,
        }
    }

    /// The output `y(k+1)` as `x(k+1)·k_x + u·k_u + rest`, for the
    /// feedforward's inversion: `(k_x, k_u, rest)` where `rest` holds
    /// everything that does not depend on `x(k+1)` or `u` (the ringing's
    /// kick on the raw pressure is `g·(u + ū + p₀ − p(k−1))`, `p_raw` the
    /// raw pressure less `u`).
    pub fn output_terms(
        &self,
        e: &[f64; MAX_EFFECT_STATES],
        p_raw_less_u: f64,
        p_prev: f64,
    ) -> (f64, f64, f64) {
        let (mut k_x, mut k_u, mut rest) = (1.0, 0.0, 0.0);
        for (i, lag) in self.lags.iter().enumerate() {
            rest += lag.rho * e[i];
            match lag.drive {
                Drive::Input => k_u += lag.weight,
                Drive::Output => k_x += lag.weight,
            }
        }
        if let Some(r) = &self.ring {
            let i = self.lags.len();
            rest += r.a1 * e[i] - r.a2 * e[i + 1] + r.g * (p_raw_less_u - p_prev);
            k_u += r.g;
        }
        (k_x, k_u, rest)
    }
}

/// Why an effect has no place in the controllers' prediction yet.
fn left_out_reason(e: Effect) -> &'static str {
    match e {
        Effect::Delay => {
            "a transport delay needs the past pressures as states; the prediction has none yet"
        }
        Effect::InputLag => {
            "a lag before the baseline changes the pressure its Jacobian sees; not built yet"
        }
        Effect::OutputLag => {
            "a filter on the whole output: the observer would have to invert it; not built yet"
        }
        Effect::Inertia => {
            "an extra pole inside the baseline's equation needs x(k−1) in the Jacobian; not built yet"
        }
        Effect::LoadMode => {
            "a filter on the whole output: the observer would have to invert it; not built yet"
        }
        Effect::Asymmetry | Effect::DrainLag => {
            "switches with the branch of the measured input; no smooth prediction for the MPC"
        }
        Effect::Backlash => "a play on the input has no inverse at a reversal; not built yet",
        Effect::Rate => {
            "makes the hysteresis' stiffness depend on the input rate; not in the Jacobian yet"
        }
        Effect::Load => {
            "a gain per dataset, and a run has one load: the observer's disturbance takes it"
        }
        Effect::OnOffThreshold => {
            "a hysteretic threshold has no inverse from one pressure; not built yet"
        }
        _ => "not built yet",
    }
}
