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
//! The step, [`Prepared::step`], is the one definition every backend
//! follows (docs/ARCHITECTURE.md, "The model description").
//!
//! (Over 700 lines: the catalogue, its boxes and the lane-wise step are
//! about 830 lines kept together, since an effect is added in all three at
//! once; the rest are unit tests, which check every effect's neutral value
//! against the baseline bit for bit.)

use std::fmt;
use std::str::FromStr;

use serde::Serialize;

use crate::model::Experiment;
use crate::model::Family;
use crate::model::Measure;
use crate::model::sim::{classic_w, generalized_w, in_bounds, linear_part, linear_step, restart_w};

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
    /// gain (output per input unit), `ρ` its pole.
    Creep,
    /// Rate-dependent hysteresis: the Bouc-Wen stiffness grows with the input
    /// rate, `A_eff = A·(1 + η·|u(k−1) − u(k−2)|/dt)`, so the loop widens with
    /// rate; `η` in seconds per input unit.
    Rate,
    /// Parameters that depend on the hanging load: the input gain of dataset
    /// `e ≥ 1` is `b·(1 + g_e)` on the absolute input (dataset 0 is the reference). Needs several datasets.
    Load,
    // Other realisations of the same physical effects (docs/DIAGNOSIS.md,
    // "Realisations"): each is named for its physical effect
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
    /// `ŷ = x + z`; `κ` per output unit.
    OutputCreep,
    /// Creep with two time constants: two input-driven slow states, a
    /// faster and a slower one, each with its own gain.
    TwoPoleCreep,
    /// Hysteretic threshold: the muscle starts to contract when the input
    /// passes `p_on` and lets go below `p_off = p_on − gap`; while off it
    /// rests where the lowest input recorded leaves it (it sees that input).
    OnOffThreshold,
}

/// Name and meaning of one effect parameter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EffectParam {
    pub name: String,
    pub meaning: &'static str,
}

impl Effect {
    /// The whole catalogue, in the order reports list it.
    pub const ALL: [Effect; 18] = [
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
    ];

    /// The physical effects: the catalogue's first realisation of each.
    pub const PHYSICAL: [Effect; 9] = [
        Effect::Delay,
        Effect::Deadzone,
        Effect::Saturation,
        Effect::Asymmetry,
        Effect::Inertia,
        Effect::Backlash,
        Effect::Creep,
        Effect::Rate,
        Effect::Load,
    ];

    /// The physical effect this realises (`DESIGN.md` §5's names): the
    /// first realisation of each is the physical effect itself.
    pub fn physical(self) -> Effect {
        match self {
            Effect::InputLag | Effect::OutputLag => Effect::Delay,
            Effect::LoadMode => Effect::Inertia,
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
            Effect::LoadMode => {
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
            ],
            Effect::TwoPoleCreep => vec![
                p("rho_fast", "pole of the faster slow state"),
                p("kappa_fast", "its static gain (output per input unit)"),
                p("rho_slow", "pole of the slower slow state"),
                p("kappa_slow", "its static gain (output per input unit)"),
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
            Effect::TwoPoleCreep => 3,
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
            Effect::LoadMode => "a peak in the residual spectrum: ringing after each input step",
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
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
        Effect::Creep => {
            let g = 2.0 * ry / ru;
            (vec![0.995, 0.0], vec![0.98, -g], vec![0.9995, g])
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
        Effect::DrainLag => (vec![0.0], vec![-0.97], vec![0.97]),
        Effect::OutputClip | Effect::SoftStop => effect_box(Effect::Saturation, ctx, datasets),
        Effect::OutputCreep => (vec![0.995, 0.0], vec![0.98, -0.5], vec![0.9995, 0.5]),
        Effect::TwoPoleCreep => {
            let g = 2.0 * ry / ru;
            (
                vec![0.98, 0.0, 0.999, 0.0],
                vec![0.9, -g, 0.995, -g],
                vec![0.995, g, 0.9999, g],
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

    /// This model with one more effect.
    pub fn with(&self, effect: Effect) -> Augmented {
        let mut effects = self.effects.clone();
        effects.push(effect);
        Augmented::new(self.family, effects, self.datasets)
    }
}

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
    /// The end stop in deviation coordinates.
    saturation: Option<[f32; L]>,
    asymmetry: Option<[f32; L]>,
    inertia: Option<[f32; L]>,
    backlash: Option<[f32; L]>,
    creep: Option<([f32; L], [f32; L])>,
    rate: Option<[f32; L]>,
    load: Option<[f32; L]>,
    input_lag: Option<[f32; L]>,
    output_lag: Option<[f32; L]>,
    /// The load mode's `a1`, `a2` and its input weight `(1 − a1) + a2`.
    mode: Option<([f32; L], [f32; L], [f32; L])>,
    drain_lag: Option<[f32; L]>,
    /// The output clip's bound in deviation coordinates.
    output_clip: Option<[f32; L]>,
    /// The soft stop's bound in deviation coordinates.
    soft_stop: Option<[f32; L]>,
    output_creep: Option<([f32; L], [f32; L])>,
    two_pole_creep: Option<[[f32; L]; 4]>,
    /// The hysteretic threshold's `p_on` and `p_off` in deviation
    /// coordinates.
    on_off: Option<([f32; L], [f32; L])>,
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
#[derive(Debug, Clone)]
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
    /// 1 while the hysteretic threshold is on, else 0.
    on: [f32; L],
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

/// The soft end stop: `x` blended into `bound` over `bound ∓ h` by a
/// quadratic whose slope runs from 1 to 0 (`knee` = [`Context::knee`]),
/// `bound` beyond; `x` itself short of the knee.
#[inline(always)]
fn soft_stop(x: f32, bound: f32, knee: [f32; 3], drives_up: bool) -> f32 {
    let [h, two_h, inv_4h] = knee;
    // How far into the knee x is, in the direction the input drives it.
    let into = if drives_up {
        x - (bound - h)
    } else {
        (bound + h) - x
    };
    let bend = (into * into) * inv_4h;
    let bent = if drives_up { x - bend } else { x + bend };
    if into <= 0.0 {
        x
    } else if into >= two_h {
        bound
    } else {
        bent
    }
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
            z: [0.0; L],
            lag_in: [0.0; L],
            drain: [0.0; L],
            lag_out: x,
            mode1: x,
            mode2: x,
            z_out: [0.0; L],
            z_fast: [0.0; L],
            z_slow: [0.0; L],
            on: [0.0; L],
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
                x = if self.drives_up {
                    smaller(x, bound[l])
                } else {
                    larger(x, bound[l])
                };
            }
            xk[l] = x;
        }
        if let Some(bound) = &self.soft_stop {
            for l in 0..L {
                xk[l] = soft_stop(xk[l], bound[l], self.knee, self.drives_up);
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
        // Output side: the creeps' slow states, the load mode, the output
        // clip and the output lag, a loop each.
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
        if let Some((a1, a2, gain)) = &self.mode {
            for l in 0..L {
                let q = ((a1[l] * s.mode1[l]) - (a2[l] * s.mode2[l])) + (gain[l] * y[l]);
                s.mode2[l] = s.mode1[l];
                s.mode1[l] = q;
                y[l] = q;
            }
        }
        if let Some(bound) = &self.output_clip {
            for l in 0..L {
                y[l] = if self.drives_up {
                    smaller(y[l], bound[l])
                } else {
                    larger(y[l], bound[l])
                };
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
    /// takes `y` less the creeps, and the Bouc-Wen state the jump's elastic
    /// part, as the baseline's ([`crate::model::sim::Stepper::restart`]);
    /// the load mode and the output lag restart at `y`; the other effects'
    /// states run on.
    #[inline(always)]
    pub fn restart(&self, s: &mut EffectState<L>, y: f32) {
        for l in 0..L {
            let x = (((y - s.z[l]) - s.z_out[l]) - s.z_fast[l]) - s.z_slow[l];
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
            on_off: None,
            knee: ctx.knee(),
            rest: ctx.rest_input(),
            u_mean: ctx.u_mean as f32,
            branch_tol: ctx.branch_tol as f32,
            inv_dt: (1.0 / ctx.dt) as f32,
            drives_up: ctx.drives_up,
        };
        let y_mean = ctx.y_mean as f32;
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
                Effect::Saturation => p.saturation = Some(v.map(|l| l - y_mean)),
                Effect::Asymmetry => p.asymmetry = Some(v),
                Effect::Inertia => p.inertia = Some(v),
                Effect::Backlash => p.backlash = Some(non_negative),
                Effect::Creep => p.creep = Some((v, col(at + 1))),
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
                Effect::OutputClip => p.output_clip = Some(v.map(|l| l - y_mean)),
                Effect::SoftStop => p.soft_stop = Some(v.map(|l| l - y_mean)),
                Effect::OutputCreep => p.output_creep = Some((v, col(at + 1))),
                Effect::TwoPoleCreep => {
                    p.two_pole_creep = Some([v, col(at + 1), col(at + 2), col(at + 3)]);
                }
                Effect::OnOffThreshold => {
                    let on = v.map(|x| x - p.u_mean);
                    let gap = col(at + 1);
                    p.on_off = Some((on, std::array::from_fn(|l| on[l] - gap[l])));
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{measured_sse, presets::thesis_params, simulate, sse};

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
        theta.extend([0.99, 5.0, 0.3]);
        let free = model.sse(&theta, 0, &ctx, &exp);
        assert_eq!(model.sse_ahead(&theta, 0, &ctx, &exp, exp.len()), free);
        assert_ne!(model.sse_ahead(&theta, 0, &ctx, &exp, 10), free);
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
