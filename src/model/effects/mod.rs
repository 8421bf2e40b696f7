//! The effects catalogue (docs/DIAGNOSIS.md): parametric additions to the
//! nominal (baseline) model, in the units of the data.
//!
//! An [`Augmented`] model is a baseline [`Family`] plus a list of effects. Its
//! parameter vector is the baseline's canonical vector followed by each
//! effect's parameters in list order. The step reuses the model equations of
//! [`crate::model::sim`] (`linear_part`, `classic_w`, `generalized_w`) and only
//! changes what goes into them or what comes out of them, so that every effect
//! at its neutral value reproduces the baseline simulation bit for bit (the
//! tests check it): a neutral effect adds `+0`, multiplies by `1`, or never
//! binds.
//!
//! The catalogue (names, parameters, boxes, sizes) is here; the lane-wise
//! step, [`Prepared::step`] in `step.rs`, is the one definition every
//! backend follows (docs/ARCHITECTURE.md, "The model description"). (Over
//! 700 lines: the catalogue of nineteen realisations is about 635; the rest
//! are unit tests, which check every realisation's neutral value against the
//! baseline bit for bit.)

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::model::Experiment;
use crate::model::Family;

mod step;
pub use step::{EffectState, Prepared};

/// One unmodelled effect of the catalogue. Flags, JSON and reports use these
/// names, so they are part of the interface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Effect {
    /// Input transport delay: `u(k−1−d)` replaces `u(k−1)`; `d ≥ 0` samples,
    /// fractional `d` interpolates linearly between neighbouring samples.
    Delay,
    /// Threshold `p0` (absolute input units) below which the muscle does not
    /// respond: `p_eff = max(p − p0, 0)`.
    Deadzone,
    /// End stop: the output cannot pass `l_max` (absolute output units) in the
    /// direction the input drives it (hard bound).
    Saturation,
    /// Loading and unloading differ: the input gain is `b·(1+ε)` on the rising
    /// branch and `b·(1−ε)` on the falling one, i.e. `b_up`, `b_down`.
    Asymmetry,
    /// An extra pole (load mass, hose compliance): `x(k) += a2·(x(k−1) − x(k−2))`,
    /// a second-order linear part with the same static gain.
    Inertia,
    /// Play of width `r` (input units) on the input (braid stick–slip).
    Backlash,
    /// A slow first-order state added to the output:
    /// `z(k) = ρ·z(k−1) + (1−ρ)·κ·u(k−1)`, `ŷ = x + z`; `κ` is its static
    /// gain (output per input unit), `ρ` its pole, `z(0) = z0` where the
    /// record's history left it.
    Creep,
    /// Rate-dependent hysteresis: the Bouc-Wen stiffness grows with the input
    /// rate, `A_eff = A·(1 + η·|u(k−1) − u(k−2)|/dt)`, so the loop widens with
    /// rate; `η` in seconds per input unit.
    Rate,
    /// Parameters that depend on the hanging load: the input gain of dataset
    /// `e ≥ 1` is `b·(1 + g_e)` on the absolute input (dataset 0 is the reference). Needs several datasets.
    Load,
    // Other realisations of the same physical effects (docs/DIAGNOSIS.md,
    // "The effects catalogue"): each is named for its physical effect
    // ([`Effect::physical`]) and says how it is realised.
    /// Lag as a first-order lag on the input, `v = ρ·v + (1−ρ)·p` (pressure
    /// reaching the muscle through the hose); mean delay `ρ/(1−ρ)` samples.
    InputLag,
    /// Lag as a first-order lag on the measured output, `ŷ ← ρ·ŷ(k−1) +
    /// (1−ρ)·ŷ` (a slow sensor).
    OutputLag,
    /// Inertia as a second-order mode of the hanging load on the output,
    /// `q = a1·q(k−1) − a2·q(k−2) + (1 − a1 + a2)·ŷ`, unit static gain:
    /// underdamped (ringing) when `a1² < 4·a2`, with pole radius `√a2` and
    /// angle `acos(a1/(2√a2))` per sample.
    LoadMode,
    /// Asymmetry in time constant: the input passes at once on one branch
    /// and through a first-order lag `|ρ|` on the other (`ρ > 0`: drains
    /// slower than it fills; `ρ < 0`: fills slower).
    DrainLag,
    /// End stop on the measured output only (the state runs on).
    OutputClip,
    /// End stop as a smooth knee: a quadratic blend into `l_max` over a
    /// fixed half-width of 2.5 % of the output range on each side.
    SoftStop,
    /// Creep driven by the muscle's output: `z = ρ·z + (1−ρ)·κ·x`,
    /// `ŷ = x + z`; `κ` per output unit; `z(0) = z0`.
    OutputCreep,
    /// Creep with two time constants: two input-driven slow states, a
    /// faster and a slower one, two terms of a Prony series: gains `s·κ`
    /// and `(1−s)·κ` of one sign; the slower starts at `z0`.
    TwoPoleCreep,
    /// Hysteretic threshold: the muscle starts to contract when the input
    /// passes `p_on` and lets go below `p_off = p_on − gap`; while off it
    /// rests where the lowest input recorded leaves it (it sees that input).
    OnOffThreshold,
    /// Inertia as the hanging load ringing after each input step, on top of
    /// a muscle that follows the force quasi-statically: a mode excited by
    /// the input's change, `r = a1·r(k−1) − a2·r(k−2) + g·(u(k−1) − u(k−2))`,
    /// `ŷ = x + r`. Unlike [`Effect::LoadMode`], it rings however slowly the
    /// baseline's own output moves (a real muscle's force follows the
    /// pressure at once while the baseline's slow pole describes creep of
    /// the rubber: measured on the Cavatappi muscle, docs/lab/diagnosis.md).
    Ringing,
}

/// Name and meaning of one effect parameter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EffectParam {
    pub name: String,
    pub meaning: &'static str,
}

impl Effect {
    /// The whole catalogue, in the order reports list it.
    pub const ALL: [Effect; 19] = [
        Effect::Delay,
        Effect::Deadzone,
        Effect::Saturation,
        Effect::Asymmetry,
        Effect::Inertia,
        Effect::Backlash,
        Effect::Creep,
        Effect::Rate,
        Effect::Load,
        Effect::InputLag,
        Effect::OutputLag,
        Effect::LoadMode,
        Effect::DrainLag,
        Effect::OutputClip,
        Effect::SoftStop,
        Effect::OutputCreep,
        Effect::TwoPoleCreep,
        Effect::OnOffThreshold,
        Effect::Ringing,
    ];

    /// The physical effects: the catalogue's first realisation of each, the
    /// first nine of [`Effect::ALL`].
    pub const PHYSICAL: &'static [Effect] = Effect::ALL.split_at(9).0;

    /// The physical effect this realises (one of the nine of
    /// [`Effect::PHYSICAL`], whose names flags, reports and the self-tests'
    /// confusion tables use): the first realisation of each is the physical
    /// effect itself.
    pub fn physical(self) -> Effect {
        match self {
            Effect::InputLag | Effect::OutputLag => Effect::Delay,
            Effect::LoadMode | Effect::Ringing => Effect::Inertia,
            Effect::DrainLag => Effect::Asymmetry,
            Effect::OutputClip | Effect::SoftStop => Effect::Saturation,
            Effect::OutputCreep | Effect::TwoPoleCreep => Effect::Creep,
            Effect::OnOffThreshold => Effect::Deadzone,
            e => e,
        }
    }

    /// How the physical effect is realised, for reports.
    pub fn realisation(self) -> &'static str {
        match self {
            Effect::Delay => "pure delay",
            Effect::Deadzone => "input dead zone",
            Effect::Saturation => "state clip",
            Effect::Asymmetry => "in gain",
            Effect::Inertia => "extra real pole",
            Effect::Backlash => "play on the input",
            Effect::Creep => "driven by the input",
            Effect::Rate => "stiffness grows with input rate",
            Effect::Load => "input gain per dataset",
            Effect::InputLag => "first-order lag on the input",
            Effect::OutputLag => "first-order lag on the output",
            Effect::LoadMode => "second-order load mode",
            Effect::DrainLag => "in time constant (fill vs drain)",
            Effect::OutputClip => "output clip",
            Effect::SoftStop => "soft limit",
            Effect::OutputCreep => "driven by the output",
            Effect::TwoPoleCreep => "two time constants",
            Effect::OnOffThreshold => "hysteretic threshold (on/off)",
            Effect::Ringing => "load rings after input steps",
        }
    }

    /// The realisation's size in words a person reads, where its parameters
    /// do not say it directly (`params`: the effect's own, `dt` the sample
    /// time): a lag's time constant, a mode's frequency and damping.
    pub fn size_text(self, params: &[f64], dt: f64) -> Option<String> {
        let samples = |rho: f64| {
            let tau = rho / (1.0 - rho);
            format!("{tau:.1} samples ({:.0} ms)", 1000.0 * tau * dt)
        };
        match self {
            Effect::Delay => Some(format!(
                "{:.1} samples ({:.0} ms)",
                params[0],
                1000.0 * params[0] * dt
            )),
            Effect::InputLag | Effect::OutputLag => {
                Some(format!("time constant {}", samples(params[0])))
            }
            Effect::DrainLag => Some(format!(
                "{} time constant {}",
                if params[0] >= 0.0 { "drain" } else { "fill" },
                samples(params[0].abs())
            )),
            Effect::LoadMode | Effect::Ringing => {
                let (a1, a2) = (params[0], params[1]);
                if a2 > 0.0 && a1 * a1 < 4.0 * a2 {
                    let r = a2.sqrt();
                    let theta = (a1 / (2.0 * r)).acos();
                    let zeta = -r.ln() / (r.ln().powi(2) + theta * theta).sqrt();
                    Some(format!(
                        "rings at {:.2} Hz, damping ratio {zeta:.2}",
                        theta / (2.0 * std::f64::consts::PI * dt)
                    ))
                } else {
                    let root = (a1 * a1 - 4.0 * a2).max(0.0).sqrt();
                    Some(format!(
                        "no ringing: real poles {:.3} and {:.3}",
                        0.5 * (a1 + root),
                        0.5 * (a1 - root)
                    ))
                }
            }
            _ => None,
        }
    }

    /// The name as a WGSL identifier (`shaders/effects.wgsl`'s `HAS_*`).
    pub fn ident(self) -> String {
        self.name().replace([':', '-'], "_").to_ascii_uppercase()
    }

    pub fn name(self) -> &'static str {
        match self {
            Effect::Delay => "delay",
            Effect::Deadzone => "deadzone",
            Effect::Saturation => "saturation",
            Effect::Asymmetry => "asymmetry",
            Effect::Inertia => "inertia",
            Effect::Backlash => "backlash",
            Effect::Creep => "creep",
            Effect::Rate => "rate",
            Effect::Load => "load",
            Effect::InputLag => "delay:input-lag",
            Effect::OutputLag => "delay:output-lag",
            Effect::LoadMode => "inertia:mode",
            Effect::DrainLag => "asymmetry:drain",
            Effect::OutputClip => "saturation:output",
            Effect::SoftStop => "saturation:soft",
            Effect::OutputCreep => "creep:output",
            Effect::TwoPoleCreep => "creep:two-pole",
            Effect::OnOffThreshold => "deadzone:on-off",
            Effect::Ringing => "inertia:ringing",
        }
    }

    /// Whether the effect can be fitted on `datasets` datasets (`load` needs two).
    pub fn applicable(self, datasets: usize) -> bool {
        self != Effect::Load || datasets >= 2
    }

    /// Parameters of the effect for `datasets` datasets, in vector order.
    pub fn params(self, datasets: usize) -> Vec<EffectParam> {
        let p = |name: &str, meaning| EffectParam {
            name: name.into(),
            meaning,
        };
        match self {
            Effect::Delay => vec![p("d", "input delay (samples)")],
            Effect::Deadzone => vec![p("p0", "input threshold (absolute input units)")],
            Effect::Saturation => vec![p("l_max", "output end stop (absolute output units)")],
            Effect::Asymmetry => vec![p(
                "eps",
                "gain asymmetry: b_up = b·(1+eps), b_down = b·(1−eps)",
            )],
            Effect::Inertia => vec![p("a2", "weight of x(k−1) − x(k−2): the extra pole")],
            Effect::Backlash => vec![p("r", "play width (input units)")],
            Effect::Creep => vec![
                p("rho", "pole of the slow state (close to 1)"),
                p(
                    "kappa",
                    "static gain of the slow state (output per input unit)",
                ),
                p(
                    "z0",
                    "the slow state at the first sample (output units): where the record's history left it",
                ),
            ],
            Effect::Rate => vec![p("eta", "growth of A with input rate (s per input unit)")],
            Effect::Load => (1..datasets.max(1))
                .map(|e| EffectParam {
                    name: format!("g{e}"),
                    meaning: "relative input gain of this dataset against dataset 0",
                })
                .collect(),
            Effect::InputLag | Effect::OutputLag => {
                vec![p("rho", "pole of the lag (mean delay rho/(1−rho) samples)")]
            }
            Effect::LoadMode => vec![
                p("a1", "first coefficient of the mode: 2·r·cos θ"),
                p(
                    "a2",
                    "second coefficient of the mode: r², the pole radius squared",
                ),
            ],
            Effect::DrainLag => vec![p(
                "rho",
                "pole of the slow branch: > 0 drains slower, < 0 fills slower",
            )],
            Effect::OutputClip | Effect::SoftStop => {
                vec![p("l_max", "output end stop (absolute output units)")]
            }
            Effect::OutputCreep => vec![
                p("rho", "pole of the slow state (close to 1)"),
                p("kappa", "static gain of the slow state (per output unit)"),
                p(
                    "z0",
                    "the slow state at the first sample (output units): where the record's history left it",
                ),
            ],
            Effect::TwoPoleCreep => vec![
                p("rho_fast", "pole of the faster slow state"),
                p("rho_slow", "pole of the slower slow state"),
                p(
                    "kappa",
                    "static gain of both together (output per input unit)",
                ),
                p("fast_share", "the faster state's share of kappa, in [0, 1]"),
                p(
                    "z0",
                    "the slower state at the first sample (output units): where the record's history left it",
                ),
            ],
            Effect::OnOffThreshold => vec![
                p(
                    "p_on",
                    "input above which the muscle contracts (absolute input units)",
                ),
                p(
                    "gap",
                    "p_on − p_off, the input it lets go below (input units)",
                ),
            ],
            Effect::Ringing => vec![
                p("a1", "first coefficient of the mode: 2·r·cos θ"),
                p(
                    "a2",
                    "second coefficient of the mode: r², the pole radius squared",
                ),
                p("g", "kick of an input step (output per input unit)"),
            ],
        }
    }

    pub fn dim(self, datasets: usize) -> usize {
        self.params(datasets).len()
    }

    /// Index (within the effect's parameters) of the one that measures its
    /// size, which the self-test recovers.
    pub fn primary(self) -> usize {
        match self {
            Effect::Creep | Effect::OutputCreep | Effect::LoadMode => 1,
            Effect::TwoPoleCreep => 2,
            Effect::Ringing => 2,
            _ => 0,
        }
    }

    /// The residual signature that points to this effect, for the report.
    pub fn signature(self) -> &'static str {
        match self {
            Effect::Delay => {
                "residual–input cross-correlation peaks at a positive lag; energy right after each input step"
            }
            Effect::Deadzone => "residual energy concentrated in the lowest input band",
            Effect::Saturation => "residual energy concentrated in the highest input band",
            Effect::Asymmetry => "rising and falling branches carry unequal residual energy",
            Effect::Inertia => {
                "energy in the transient after steps (overshoot or sluggish rise), mid frequencies"
            }
            Effect::Backlash => "residual right after input reversals; loop too narrow",
            Effect::Creep => "low-frequency residual that drifts while the input is steady",
            Effect::Rate => {
                "residual grows with input rate: rising/falling branches, high frequencies"
            }
            Effect::Load => "one dataset (load) carries most of the residual energy",
            Effect::InputLag | Effect::OutputLag => {
                "residual–input cross-correlation over a spread of positive lags; rounded steps"
            }
            Effect::LoadMode | Effect::Ringing => {
                "a peak in the residual spectrum: ringing after each input step"
            }
            Effect::DrainLag => "falling branches carry more residual energy, later in the step",
            Effect::OutputClip | Effect::SoftStop => {
                "residual energy concentrated in the highest input band"
            }
            Effect::OutputCreep | Effect::TwoPoleCreep => {
                "low-frequency residual that drifts while the input is steady"
            }
            Effect::OnOffThreshold => {
                "residual in the lowest input band, unlike on rising and falling branches"
            }
        }
    }
}

/// Serialized as its name (`delay`, `delay:input-lag`, ...).
impl Serialize for Effect {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Effect {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Effect::ALL
            .iter()
            .copied()
            .find(|e| e.name() == s.trim().to_ascii_lowercase())
            .ok_or_else(|| {
                let names: Vec<_> = Effect::ALL.iter().map(|e| e.name()).collect();
                format!("unknown effect `{s}`: expected one of {}", names.join(", "))
            })
    }
}

/// What an effect needs to know about one dataset: its deviation offsets,
/// sample time, and the scales the parameter bounds derive from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Context {
    /// Input mean `ū` removed from the data (absolute = deviation + `ū`).
    pub u_mean: f64,
    /// Output mean `ȳ` removed from the data.
    pub y_mean: f64,
    pub dt: f64,
    /// Input move (input units) that switches the loading/unloading branch:
    /// 2 % of the input range, so that sensor noise does not flip it.
    pub branch_tol: f64,
    /// Whether a rising input drives the output up (sign of the baseline's `b`):
    /// the side the saturation bound sits on.
    pub drives_up: bool,
    /// Absolute input and output ranges of the data.
    pub input_min: f64,
    pub input_max: f64,
    pub output_min: f64,
    pub output_max: f64,
    /// Largest input change in one sample (input units).
    pub max_step: f64,
}

impl Context {
    /// The context of an experiment (deviation coordinates with its means).
    pub fn of(exp: &Experiment, drives_up: bool) -> Context {
        let fold = |v: &[f32], m: f64| {
            v.iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
                    (lo.min(x as f64 + m), hi.max(x as f64 + m))
                })
        };
        let (input_min, input_max) = fold(&exp.u, exp.u_mean);
        let (output_min, output_max) = fold(&exp.y, exp.y_mean);
        let max_step = exp
            .u
            .windows(2)
            .map(|w| (w[1] - w[0]).abs() as f64)
            .fold(0.0, f64::max);
        Context {
            u_mean: exp.u_mean,
            y_mean: exp.y_mean,
            dt: exp.dt,
            branch_tol: 0.02 * (input_max - input_min),
            drives_up,
            input_min,
            input_max,
            output_min,
            output_max,
            max_step,
        }
    }

    fn input_range(&self) -> f64 {
        (self.input_max - self.input_min).max(f64::MIN_POSITIVE)
    }

    fn output_range(&self) -> f64 {
        (self.output_max - self.output_min).max(f64::MIN_POSITIVE)
    }

    /// The soft end stop's knee in `f32`: its half-width `h` (2.5 % of the
    /// output range), `2h`, and `1/(4h)`; computed here once, so that no
    /// backend divides.
    pub fn knee(&self) -> [f32; 3] {
        let h = 0.025 * self.output_range();
        [h as f32, (2.0 * h) as f32, (0.25 / h) as f32]
    }

    /// The input a muscle whose threshold is off rests at: the lowest input
    /// recorded, in deviation coordinates.
    pub fn rest_input(&self) -> f32 {
        (self.input_min - self.u_mean) as f32
    }
}

/// Neutral value and search bounds of each parameter of `effect`, from the
/// context of the first dataset. The neutral value always lies in the box (an
/// augmented fit can always fall back on the baseline).
pub fn effect_box(
    effect: Effect,
    ctx: &Context,
    datasets: usize,
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (ru, ry) = (ctx.input_range(), ctx.output_range());
    match effect {
        Effect::Delay => (vec![0.0], vec![0.0], vec![30.0]),
        Effect::Deadzone => {
            let lo = ctx.input_min.min(0.0);
            (vec![0.0], vec![lo], vec![ctx.input_min.max(0.0) + 0.6 * ru])
        }
        Effect::Saturation => {
            // An end stop sits near the largest output recorded: the box is
            // from 40 % of the range below it to 5 % beyond it, where a model
            // that follows the data never reaches it (the neutral edge).
            if ctx.drives_up {
                let far = ctx.output_max + 0.05 * ry;
                (vec![far], vec![ctx.output_max - 0.4 * ry], vec![far])
            } else {
                let far = ctx.output_min - 0.05 * ry;
                (vec![far], vec![far], vec![ctx.output_min + 0.4 * ry])
            }
        }
        Effect::Asymmetry => (vec![0.0], vec![-0.5], vec![0.5]),
        Effect::Inertia => (vec![0.0], vec![-0.5], vec![0.9]),
        Effect::Backlash => (vec![0.0], vec![0.0], vec![0.5 * ru]),
        // A creep's slow state starts where the record's history left it,
        // `z0`, anywhere within the output range: a state at rest in some
        // other frame (the deviation coordinates of another record, or
        // absolute units) starts a transient that neither `x0` nor the
        // intercept can take (measured on the independent self-test's
        // output-driven creep on the multisine, docs/lab/diagnosis.md).
        Effect::Creep => {
            let g = 2.0 * ry / ru;
            (
                vec![0.995, 0.0, 0.0],
                vec![0.98, -g, -ry],
                vec![0.9995, g, ry],
            )
        }
        Effect::Rate => {
            let v = (ctx.max_step / ctx.dt).max(f64::MIN_POSITIVE);
            (vec![0.0], vec![-0.9 / v], vec![10.0 / v])
        }
        Effect::Load => {
            let k = effect.dim(datasets);
            (vec![0.0; k], vec![-0.5; k], vec![0.5; k])
        }
        // A pole of 0.97 is a mean delay of about 32 samples, the pure
        // delay's 30.
        Effect::InputLag | Effect::OutputLag => (vec![0.0], vec![0.0], vec![0.97]),
        // Every stable mode lies in a2 < 1, |a1| < 1 + a2.
        Effect::LoadMode => (vec![0.0, 0.0], vec![-1.9, 0.0], vec![1.98, 0.98]),
        // A kick of g·Δu rings at most about 1/sin θ times higher; a whole
        // input range's step then spans the output range at θ ≈ 1 rad.
        // Neutral at any mode without a kick; this mode rings (the
        // diagnosis admits only ringing ones: `diagnose::Data::admits`).
        Effect::Ringing => {
            let g = ry / ru;
            (
                vec![0.0, 0.5, 0.0],
                vec![-1.9, 0.0, -g],
                vec![1.98, 0.98, g],
            )
        }
        Effect::DrainLag => (vec![0.0], vec![-0.97], vec![0.97]),
        Effect::OutputClip | Effect::SoftStop => effect_box(Effect::Saturation, ctx, datasets),
        Effect::OutputCreep => (
            vec![0.995, 0.0, 0.0],
            vec![0.98, -0.5, -ry],
            vec![0.9995, 0.5, ry],
        ),
        // Two terms of a Prony series: a passive material creeps the same
        // way at every time scale, so the two gains share a sign (a total
        // and the faster state's share of it). With gains of either sign
        // the pair is a band-pass of the input, not creep: on the twin's
        // stair, which has no creep, gains of −118 and +125 were named
        // first (docs/lab/diagnosis.md). The faster state forgets its start
        // within a few hundred samples; the slower one gets `z0`.
        Effect::TwoPoleCreep => {
            let g = 2.0 * ry / ru;
            (
                vec![0.98, 0.999, 0.0, 0.5, 0.0],
                vec![0.9, 0.995, -g, 0.0, -ry],
                vec![0.995, 0.9999, g, 1.0, ry],
            )
        }
        Effect::OnOffThreshold => {
            // Neutral: on below every input, so the muscle is always on.
            let never = ctx.input_min.min(0.0) - 0.05 * ru;
            (
                vec![never, 0.0],
                vec![never, 0.0],
                vec![ctx.input_min.max(0.0) + 0.6 * ru, 0.3 * ru],
            )
        }
    }
}

/// A baseline family plus effects: the model a candidate of the diagnosis is.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Augmented {
    pub family: Family,
    pub effects: Vec<Effect>,
    /// Number of datasets scored together (the `load` effect has one gain per
    /// dataset after the first).
    pub datasets: usize,
}

impl Augmented {
    pub fn new(family: Family, effects: Vec<Effect>, datasets: usize) -> Self {
        Augmented {
            family,
            effects,
            datasets,
        }
    }

    pub fn dim(&self) -> usize {
        self.family.dim()
            + self
                .effects
                .iter()
                .map(|e| e.dim(self.datasets))
                .sum::<usize>()
    }

    /// Where `effect`'s parameters start in the vector, if it is present.
    pub fn offset_of(&self, effect: Effect) -> Option<usize> {
        let mut at = self.family.dim();
        for &e in &self.effects {
            if e == effect {
                return Some(at);
            }
            at += e.dim(self.datasets);
        }
        None
    }

    /// All parameter names, baseline first.
    pub fn param_names(&self) -> Vec<String> {
        let mut names: Vec<String> = self.family.params().iter().map(|p| p.name.into()).collect();
        for &e in &self.effects {
            names.extend(
                e.params(self.datasets)
                    .into_iter()
                    .map(|p| format!("{e}.{}", p.name)),
            );
        }
        names
    }

    /// Whether every effect's parameters in `theta` (the whole vector) are
    /// ones the fits admit: a ringing ([`Effect::Ringing`]) must ring
    /// ([`rings`]).
    pub fn effects_admit(&self, theta: &[f64]) -> bool {
        self.offset_of(Effect::Ringing)
            .is_none_or(|at| rings(theta[at], theta[at + 1]))
    }

    /// This model with one more effect.
    pub fn with(&self, effect: Effect) -> Augmented {
        let mut effects = self.effects.clone();
        effects.push(effect);
        Augmented::new(self.family, effects, self.datasets)
    }
}

/// Whether the mode `q = a1·q(k−1) − a2·q(k−2) + …` rings: complex poles
/// `r·e^{±iθ}` (`r = √a2`, `cos θ = a1/(2r)`) with a resonance, i.e. a
/// damping ratio under `1/√2`, which is `−ln r < θ`.
///
/// Why: with real poles a ringing's kick decays as a slow drift driven by
/// the input, which is creep's mark (it was named for the drift of the
/// Cavatappi 200 g file), and a mode damped past `1/√2` has no peak in its
/// spectrum: it is a high-pass of the input, which the independent
/// self-test's sensor cross-talk is, and it was named for it (critically
/// damped, `a1 = 1.11`, `a2 = 0.31`: docs/lab/diagnosis.md).
pub fn rings(a1: f64, a2: f64) -> bool {
    if !(a2 > 0.0 && a1 * a1 < 4.0 * a2) {
        return false;
    }
    let r = a2.sqrt();
    -r.ln() < (a1 / (2.0 * r)).acos()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Measure, measured_sse, presets::thesis_params, simulate, sse};

    fn experiment() -> Experiment {
        // A stair up and down in MPa with a little ripple, gauge pressure ≥ 0.
        let p: Vec<f64> = (0..600)
            .map(|k| {
                let level = [0.1, 0.2, 0.3, 0.4, 0.3, 0.2][(k / 100) % 6];
                level + 0.003 * ((k as f64) * 0.7).sin()
            })
            .collect();
        let y: Vec<f64> = p.iter().map(|&v| 40.0 * v + 1.0).collect();
        let trace = crate::data::Trace::uniform("stair", 0.1, p, y);
        Experiment::with_means_of(&trace, 0..300)
    }

    fn neutral_vector(model: &Augmented, base: &[f64], ctx: &Context) -> Vec<f32> {
        let mut theta: Vec<f64> = base.to_vec();
        for &e in &model.effects {
            theta.extend(effect_box(e, ctx, model.datasets).0);
        }
        theta.iter().map(|&v| v as f32).collect()
    }

    #[test]
    fn every_effect_at_its_neutral_value_is_exactly_the_baseline() {
        for fam in [Family::Classic, Family::Generalized, Family::Linear] {
            let mut base = thesis_params(fam);
            let ic = fam.linear_indices()[2];
            base[ic] = 0.3;
            let base32: Vec<f32> = base.iter().map(|&v| v as f32).collect();
            // Data the baseline explains (the saturation's neutral bound lies
            // a whole output range beyond the data).
            let mut exp = experiment();
            exp.y = simulate(fam, &base32, &exp.u, 0.5).x;
            let ctx = Context::of(&exp, true);
            let reference = simulate(fam, &base32, &exp.u, exp.y[0]);
            let ref_sse = sse(fam, &base32, &exp.u, &exp.y);
            for effect in Effect::ALL {
                for datasets in [1, 3] {
                    let model = Augmented::new(fam, vec![effect], datasets);
                    let theta = neutral_vector(&model, &base, &ctx);
                    let got = model.simulate(&theta, 0, &ctx, &exp);
                    assert_eq!(got, reference.x, "{fam} + {effect}");
                    assert_eq!(
                        model.sse(&theta, 0, &ctx, &exp),
                        ref_sse,
                        "{fam} + {effect}"
                    );
                    // The prediction restarts as the baseline's does.
                    for horizon in [1, 7] {
                        let measure = Measure::Ahead { horizon };
                        assert_eq!(
                            model.measured_sse(&theta, 0, &ctx, &exp, measure).to_bits(),
                            measured_sse(fam, &base32, &exp.u, &exp.y, measure).to_bits(),
                            "{fam} + {effect}, {measure}"
                        );
                    }
                    // Also for the other datasets (the load gains are per dataset).
                    let got = model.simulate(&theta, datasets - 1, &ctx, &exp);
                    assert_eq!(got, reference.x, "{fam} + {effect}, last dataset");
                }
            }
            // All effects at once, neutral, are still the baseline.
            let model = Augmented::new(fam, Effect::ALL.to_vec(), 2);
            let theta = neutral_vector(&model, &base, &ctx);
            assert_eq!(
                model.simulate(&theta, 1, &ctx, &exp),
                reference.x,
                "{fam} + all"
            );
        }
    }

    #[test]
    fn each_effect_away_from_neutral_changes_the_output() {
        let exp = experiment();
        let ctx = Context::of(&exp, true);
        let fam = Family::Classic;
        let base = thesis_params(fam);
        let base32: Vec<f32> = base.iter().map(|&v| v as f32).collect();
        let reference = simulate(fam, &base32, &exp.u, exp.y[0]).x;
        for effect in Effect::ALL {
            let model = Augmented::new(fam, vec![effect], 2);
            let (neutral, lo, hi) = effect_box(effect, &ctx, 2);
            let mut theta = neutral_vector(&model, &base, &ctx);
            let at = model.offset_of(effect).unwrap();
            let i = effect.primary();
            // Halfway from neutral to the far edge of the box.
            let edge = if hi[i] - neutral[i] > neutral[i] - lo[i] {
                hi[i]
            } else {
                lo[i]
            };
            theta[at + i] = (0.5 * (neutral[i] + edge)) as f32;
            let got = model.simulate(&theta, 1, &ctx, &exp);
            let diff: f32 = got.iter().zip(&reference).map(|(a, b)| (a - b).abs()).sum();
            assert!(diff > 1e-2, "{effect} changed nothing (Σ|Δ| = {diff})");
        }
    }

    #[test]
    fn delay_of_whole_samples_shifts_the_input() {
        let exp = experiment();
        let ctx = Context::of(&exp, true);
        let fam = Family::Linear;
        let model = Augmented::new(fam, vec![Effect::Delay], 1);
        let theta = [0.9f32, 2.0, 0.1, 0.0, 3.0];
        let got = model.simulate(&theta, 0, &ctx, &exp);
        // The same model on the input shifted by three samples (u(0) held).
        let mut shifted = vec![exp.u[0]; 3];
        shifted.extend_from_slice(&exp.u[..exp.len() - 3]);
        let reference = simulate(fam, &[0.9, 2.0, 0.1, 0.0], &shifted, exp.y[0]);
        assert_eq!(got, reference.x);
    }

    #[test]
    fn one_step_ahead_prediction_error_is_the_equation_error() {
        // For the linear family, the 1-step-ahead predictor restarts from
        // every measurement: ŷ(k) = a·y(k−1) + b·u(k−1) + c.
        let exp = experiment();
        let ctx = Context::of(&exp, true);
        let model = Augmented::new(Family::Linear, Vec::new(), 1);
        let (a, b, c) = (0.8f32, 30.0f32, 0.2f32);
        let want: f32 = (1..exp.len())
            .map(|k| {
                let e = ((a * exp.y[k - 1]) + (b * exp.u[k - 1])) + c - exp.y[k];
                e * e
            })
            .sum();
        let got = model.sse_ahead(&[a, b, c, 0.0], 0, &ctx, &exp, 1);
        assert!((got - want).abs() <= 1e-4 * want, "{got} vs {want}");
        // Far from the data's own model, the free run piles its error up
        // through the pole; the short horizon does not.
        assert!(got < model.sse(&[a, b, c, 0.0], 0, &ctx, &exp));
    }

    #[test]
    fn a_horizon_past_the_data_is_the_free_run() {
        let exp = experiment();
        let ctx = Context::of(&exp, true);
        let model = Augmented::new(Family::Classic, vec![Effect::Creep, Effect::Inertia], 1);
        let mut theta: Vec<f32> = thesis_params(Family::Classic)
            .iter()
            .map(|&v| v as f32)
            .collect();
        theta.extend([0.99, 5.0, 1.0, 0.3]);
        let free = model.sse(&theta, 0, &ctx, &exp);
        assert_eq!(model.sse_ahead(&theta, 0, &ctx, &exp, exp.len()), free);
        assert_ne!(model.sse_ahead(&theta, 0, &ctx, &exp, 10), free);
    }

    /// Without a gain a creep's slow state only relaxes from where `z0`
    /// puts it: the output is the baseline's plus `ρ^k·z0` (`ρ` the slower
    /// pole), whatever frame the record's history left the state in.
    #[test]
    fn a_creep_without_gain_relaxes_from_its_start() {
        let exp = experiment();
        let ctx = Context::of(&exp, true);
        let fam = Family::Classic;
        let base = thesis_params(fam);
        let baseline = neutral_vector(&Augmented::new(fam, vec![], 1), &base, &ctx);
        let reference = Augmented::new(fam, vec![], 1).simulate(&baseline, 0, &ctx, &exp);
        for (effect, slow_pole) in [
            (Effect::Creep, 0),
            (Effect::OutputCreep, 0),
            (Effect::TwoPoleCreep, 1),
        ] {
            let model = Augmented::new(fam, vec![effect], 1);
            let mut theta = neutral_vector(&model, &base, &ctx);
            let z0 = theta.len() - 1;
            theta[z0] = 2.0;
            let rho = theta[fam.dim() + slow_pole] as f64;
            let got = model.simulate(&theta, 0, &ctx, &exp);
            for (k, (g, r)) in got.iter().zip(&reference).enumerate().skip(1) {
                let want = 2.0 * rho.powi(k as i32);
                assert!(
                    ((g - r) as f64 - want).abs() < 1e-4 * (1.0 + r.abs() as f64),
                    "{effect} at {k}: {} against {want}",
                    g - r
                );
            }
        }
    }

    /// The two-pole creep splits one gain between its states: both take
    /// its sign, and in steady state they add up to it.
    #[test]
    fn the_two_pole_creeps_gains_share_a_sign() {
        let mut exp = experiment();
        exp.u = vec![0.5; 4000];
        exp.y = vec![0.0; 4000];
        let ctx = Context::of(&exp, true);
        let fam = Family::Linear;
        let mut base = thesis_params(fam);
        base[fam.linear_indices()[1]] = 0.0;
        let model = Augmented::new(fam, vec![Effect::TwoPoleCreep], 1);
        for share in [0.0f32, 0.3, 1.0] {
            let mut theta = neutral_vector(&model, &base, &ctx);
            let at = fam.dim();
            theta[at..at + 4].copy_from_slice(&[0.9, 0.995, -2.0, share]);
            let y = model.simulate(&theta, 0, &ctx, &exp);
            // Both states move toward κ·u from 0, never past it or away.
            assert!(y.windows(2).all(|w| w[1] <= w[0] + 1e-6), "share {share}");
            let settled = y.last().copied().unwrap() - y[0];
            assert!(
                (settled - (-2.0 * 0.5)).abs() < 1e-3,
                "share {share}: {settled}"
            );
        }
    }

    #[test]
    fn the_physical_effects_are_the_first_realisations_and_every_one_has_one() {
        for e in Effect::PHYSICAL {
            assert_eq!(e.physical(), *e, "{e}");
        }
        for e in Effect::ALL {
            assert!(Effect::PHYSICAL.contains(&e.physical()), "{e}");
        }
        assert_eq!(
            Effect::ALL.iter().filter(|e| e.physical() == **e).count(),
            Effect::PHYSICAL.len()
        );
    }

    #[test]
    fn names_round_trip_and_unknown_names_are_listed() {
        for e in Effect::ALL {
            assert_eq!(e.name().parse::<Effect>().unwrap(), e);
        }
        let err = "friction".parse::<Effect>().unwrap_err();
        assert!(err.contains("delay") && err.contains("load"), "{err}");
    }
}
