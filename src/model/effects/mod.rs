//! The effects catalogue (docs/DIAGNOSIS.md): parametric additions to the
//! nominal (baseline) model, in the units of the data.
//!
//! An [`ModelDescription`] model is a baseline [`Family`] plus a list of effects. Its
//! parameter vector is the baseline's canonical vector followed by each
//! effect's parameters in list order. The step reuses the model equations of
//! [`crate::model::sim`] (`linear_part`, `classic_w`, `generalized_w`) and only
//! changes what goes into them or what comes out of them, so that every effect
//! at its neutral value reproduces the baseline simulation bit for bit (the
//! tests check it): a neutral effect adds `+0`, multiplies by `1`, or never
//! binds.
//!
//! The catalogue (names, parameters, boxes, sizes, admission rules, start
//! hints) is one entry per realisation in `catalogue.rs`, from which
//! [`Effect`] is generated (`table.rs`); [`Effect`]'s methods here look the
//! entry up. The lane-wise step, [`Prepared::step`] in `step.rs`, is the
//! one definition every backend follows (docs/ARCHITECTURE.md, "The model
//! description"); each realisation's part of it is its stage in `stages/`
//! (`stage.rs` says what a stage is), placed by the catalogue's step order.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::model::Experiment;
use crate::model::Family;
use crate::names::UnknownName;

mod catalogue;
mod stage;
mod stages;
mod step;
mod table;
pub use catalogue::{Effect, STEP_ORDER, rings};
pub use stage::Side;
pub use step::{EffectState, Prepared};
pub use table::{EffectBox, Param, Params, StartHint, Unit};

/// One entry of the catalogue ([`Effect::entry`]).
pub type Realisation = table::Realisation<Effect>;

/// A realisation's place in the step order ([`STEP_ORDER`]).
pub type Placed = stage::Placed<Effect>;

/// Name and meaning of one effect parameter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EffectParam {
    pub name: String,
    pub meaning: &'static str,
    pub unit: Unit,
}

impl Effect {
    /// The physical effect this realises (one of [`Effect::PHYSICAL`],
    /// whose names flags, reports and the self-tests' confusion tables
    /// use): the first realisation of each is the physical effect itself.
    pub fn physical(self) -> Effect {
        self.entry().physical.unwrap_or(self)
    }

    /// How the physical effect is realised, for reports.
    pub fn realisation(self) -> &'static str {
        self.entry().realisation
    }

    /// The realisation's size in words a person reads, where its parameters
    /// do not say it directly (`params`: the effect's own, `dt` the sample
    /// time): a lag's time constant, a mode's frequency and damping.
    pub fn size_text(self, params: &[f64], dt: f64) -> Option<String> {
        self.entry().size_text.map(|text| text(params, dt))
    }

    /// Its flag and JSON name.
    pub fn name(self) -> &'static str {
        self.entry().name
    }

    /// The realisations the diagnosis tries when `--effects` names none:
    /// the catalogue less those tried only on request.
    pub fn by_default() -> Vec<Effect> {
        Effect::ALL
            .into_iter()
            .filter(|e| !e.entry().on_request)
            .collect()
    }

    /// Why `effects` cannot be one chain, if they cannot: an effect named
    /// twice, or two realisations of one physical effect (`creep` and
    /// `creep:output`), where a model holds one of each.
    pub fn chain_conflict(effects: &[Effect]) -> Option<String> {
        for (k, e) in effects.iter().enumerate() {
            if let Some(other) = effects[..k].iter().find(|o| o.physical() == e.physical()) {
                return Some(if other == e {
                    format!("names `{e}` twice: each effect enters a chain once")
                } else {
                    format!(
                        "names `{other}` and `{e}`, two realisations of `{}`: a model holds one \
                         realisation of each physical effect (`diagnose --effects` tries them \
                         against each other)",
                        e.physical()
                    )
                });
            }
        }
        None
    }

    /// Whether the effect can be fitted on `datasets` datasets (`load` needs two).
    pub fn applicable(self, datasets: usize) -> bool {
        datasets >= self.entry().min_datasets
    }

    /// Whether the effect has a parameter for each dataset after the first
    /// (`load`) rather than a fixed list.
    pub fn per_later_dataset(self) -> bool {
        matches!(self.entry().params, Params::PerLaterDataset { .. })
    }

    /// Parameters of the effect for `datasets` datasets, in vector order.
    pub fn params(self, datasets: usize) -> Vec<EffectParam> {
        match self.entry().params {
            Params::Fixed(list) => list
                .iter()
                .map(|p| EffectParam {
                    name: p.name.into(),
                    meaning: p.meaning,
                    unit: p.unit,
                })
                .collect(),
            Params::PerLaterDataset {
                name,
                meaning,
                unit,
            } => (1..datasets.max(1))
                .map(|e| EffectParam {
                    name: format!("{name}{e}"),
                    meaning,
                    unit,
                })
                .collect(),
        }
    }

    /// Whether its parameter `name` says how it evolves in time (a pole, a
    /// delay, how fast its steps fall) rather than how large it is: what a
    /// chain carried to another record of the muscle holds
    /// (`Realisation::dynamics`).
    pub fn is_dynamics(self, name: &str) -> bool {
        self.entry().dynamics.contains(&name)
    }

    pub fn dim(self, datasets: usize) -> usize {
        self.params(datasets).len()
    }

    /// Index (within the effect's parameters) of the one that measures its
    /// size, which the self-test recovers.
    pub fn primary(self) -> usize {
        self.entry().primary
    }

    /// The residual signature that points to this effect, for the report.
    pub fn signature(self) -> &'static str {
        self.entry().signature
    }

    /// Whether the diagnosis admits the effect's parameters `params` (its
    /// own, in vector order): a ringing must ring.
    pub fn admits(self, params: &[f64]) -> bool {
        self.entry().admits.is_none_or(|admits| admits(params))
    }

    /// Where the diagnosis starts its fit beyond the uniform draws.
    pub fn hint(self) -> StartHint {
        self.entry().hint
    }

    /// The catalogue for a flag's help: every realisation, grouped by the
    /// physical effect it realises, and which need several datasets.
    pub fn help_list() -> String {
        let names: Vec<&str> = Effect::PHYSICAL
            .iter()
            .flat_map(|&p| Effect::ALL.into_iter().filter(move |e| e.physical() == p))
            .map(Effect::name)
            .collect();
        let several: Vec<String> = Effect::ALL
            .into_iter()
            .filter(|e| !e.applicable(1))
            .map(|e| format!("`{e}`"))
            .collect();
        let on_request: Vec<String> = Effect::ALL
            .into_iter()
            .filter(|e| e.entry().on_request)
            .map(|e| format!("`{e}`"))
            .collect();
        format!(
            "{}; {} only applies with several DATA files, e.g. one per hanging load; {} only \
             when named",
            names.join(", "),
            several.join(", "),
            on_request.join(", ")
        )
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
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Effect::ALL
            .iter()
            .copied()
            .find(|e| e.name() == s.trim().to_ascii_lowercase())
            .ok_or_else(|| {
                let names: Vec<_> = Effect::ALL.iter().map(|e| e.name()).collect();
                UnknownName {
                    what: "effect",
                    got: s.to_string(),
                    expected: format!("one of {}", names.join(", ")),
                }
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

    /// The same context for an input read in units `per_input` times the
    /// fitted ones and an output `per_output` times (`Model::rescaled`).
    pub fn rescaled(&self, per_input: f64, per_output: f64) -> Context {
        Context {
            u_mean: self.u_mean * per_input,
            y_mean: self.y_mean * per_output,
            dt: self.dt,
            branch_tol: self.branch_tol * per_input,
            drives_up: self.drives_up,
            input_min: self.input_min * per_input,
            input_max: self.input_max * per_input,
            output_min: self.output_min * per_output,
            output_max: self.output_max * per_output,
            max_step: self.max_step * per_input,
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
pub fn effect_box(effect: Effect, ctx: &Context, datasets: usize) -> EffectBox {
    (effect.entry().bounds)(ctx, datasets)
}

/// A baseline family plus effects: the model a candidate of the diagnosis is.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelDescription {
    pub family: Family,
    pub effects: Vec<Effect>,
    /// Number of datasets scored together (the `load` effect has one gain per
    /// dataset after the first).
    pub datasets: usize,
}

impl ModelDescription {
    pub fn new(family: Family, effects: Vec<Effect>, datasets: usize) -> Self {
        ModelDescription {
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
    /// ones the fits admit, each by its own rule ([`Effect::admits`]: a
    /// ringing must ring).
    pub fn effects_admit(&self, theta: &[f64]) -> bool {
        let mut at = self.family.dim();
        self.effects.iter().all(|e| {
            let dim = e.dim(self.datasets);
            at += dim;
            e.admits(&theta[at - dim..at])
        })
    }

    /// This model with one more effect.
    pub fn with(&self, effect: Effect) -> ModelDescription {
        let mut effects = self.effects.clone();
        effects.push(effect);
        ModelDescription::new(self.family, effects, self.datasets)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain holds one realisation of each physical effect: `fit
    /// --effects creep,creep:output` built two creeps, where the diagnosis
    /// tries them against each other.
    #[test]
    fn a_chain_holds_one_realisation_of_each_physical_effect() {
        let parse =
            |names: &[&str]| -> Vec<Effect> { names.iter().map(|n| n.parse().unwrap()).collect() };
        assert_eq!(
            Effect::chain_conflict(&parse(&["creep", "delay:input-lag"])),
            None
        );
        let both = Effect::chain_conflict(&parse(&["creep", "delay", "creep:output"])).unwrap();
        assert!(
            both.contains("`creep` and `creep:output`, two realisations of `creep`"),
            "{both}"
        );
        let twice = Effect::chain_conflict(&parse(&["delay", "delay"])).unwrap();
        assert!(twice.starts_with("names `delay` twice"), "{twice}");
    }

    #[test]
    fn the_default_catalogue_leaves_out_only_what_is_tried_on_request() {
        let default = Effect::by_default();
        assert!(!default.contains(&Effect::LogCreep));
        assert_eq!(default.len(), Effect::ALL.len() - 1);
        assert!(Effect::help_list().contains("`creep:log` only when named"));
    }

    #[test]
    fn an_effects_dynamics_are_its_own_parameters_and_never_its_size() {
        for effect in Effect::ALL {
            let names: Vec<String> = effect.params(1).into_iter().map(|p| p.name).collect();
            for d in effect.entry().dynamics {
                assert!(
                    names.iter().any(|n| n == d),
                    "{effect}: {d} is not a parameter"
                );
            }
            // The size the self-tests recover is refitted on another
            // record, but where the size is itself a time.
            let sized_by_a_time = [
                Effect::Delay,
                Effect::InputLag,
                Effect::OutputLag,
                Effect::Inertia,
                Effect::LoadMode,
                Effect::DrainLag,
            ];
            if let Some(primary) = names.get(effect.primary()) {
                let held = effect.is_dynamics(primary);
                assert_eq!(
                    held,
                    sized_by_a_time.contains(&effect),
                    "{effect}: {primary}"
                );
            }
        }
        assert!(Effect::TwoPoleCreep.is_dynamics("rho_slow"));
        assert!(!Effect::TwoPoleCreep.is_dynamics("kappa"));
        assert!(!Effect::Backlash.is_dynamics("r"));
        assert!(Effect::CyclicSoftening.is_dynamics("r"));
    }
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

    fn neutral_vector(model: &ModelDescription, base: &[f64], ctx: &Context) -> Vec<f32> {
        let mut theta: Vec<f64> = base.to_vec();
        for &e in &model.effects {
            theta.extend(effect_box(e, ctx, model.datasets).neutral);
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
            exp.y = simulate(fam, &base32, exp.y_mean as f32, &exp.u, 0.5).x;
            let ctx = Context::of(&exp, true);
            let reference = simulate(fam, &base32, exp.y_mean as f32, &exp.u, exp.y[0]);
            let ref_sse = sse(fam, &base32, exp.y_mean as f32, &exp.u, &exp.y);
            for effect in Effect::ALL {
                for datasets in [1, 3] {
                    let model = ModelDescription::new(fam, vec![effect], datasets);
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
                            measured_sse(fam, &base32, exp.y_mean as f32, &exp.u, &exp.y, measure)
                                .to_bits(),
                            "{fam} + {effect}, {measure}"
                        );
                    }
                    // Also for the other datasets (the load gains are per dataset).
                    let got = model.simulate(&theta, datasets - 1, &ctx, &exp);
                    assert_eq!(got, reference.x, "{fam} + {effect}, last dataset");
                }
            }
            // All effects at once, neutral, are still the baseline.
            let model = ModelDescription::new(fam, Effect::ALL.to_vec(), 2);
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
        let reference = simulate(fam, &base32, exp.y_mean as f32, &exp.u, exp.y[0]).x;
        for effect in Effect::ALL {
            let model = ModelDescription::new(fam, vec![effect], 2);
            let EffectBox {
                neutral,
                lower: lo,
                upper: hi,
            } = effect_box(effect, &ctx, 2);
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
        let model = ModelDescription::new(fam, vec![Effect::Delay], 1);
        let theta = [0.9f32, 2.0, 0.1, 0.0, 3.0];
        let got = model.simulate(&theta, 0, &ctx, &exp);
        // The same model on the input shifted by three samples (u(0) held).
        let mut shifted = vec![exp.u[0]; 3];
        shifted.extend_from_slice(&exp.u[..exp.len() - 3]);
        let reference = simulate(
            fam,
            &[0.9, 2.0, 0.1, 0.0],
            exp.y_mean as f32,
            &shifted,
            exp.y[0],
        );
        assert_eq!(got, reference.x);
    }

    #[test]
    fn one_step_ahead_prediction_error_is_the_equation_error() {
        // For the linear family, the 1-step-ahead predictor restarts from
        // every measurement: ŷ(k) = a·y(k−1) + b·u(k−1) + c.
        let exp = experiment();
        let ctx = Context::of(&exp, true);
        let model = ModelDescription::new(Family::Linear, Vec::new(), 1);
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
        let model = ModelDescription::new(Family::Classic, vec![Effect::Creep, Effect::Inertia], 1);
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
        let baseline = neutral_vector(&ModelDescription::new(fam, vec![], 1), &base, &ctx);
        let reference = ModelDescription::new(fam, vec![], 1).simulate(&baseline, 0, &ctx, &exp);
        for (effect, slow_pole) in [
            (Effect::Creep, 0),
            (Effect::OutputCreep, 0),
            (Effect::TwoPoleCreep, 1),
            (Effect::LogCreep, 0),
        ] {
            let model = ModelDescription::new(fam, vec![effect], 1);
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
        let model = ModelDescription::new(fam, vec![Effect::TwoPoleCreep], 1);
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

    /// The log-time creep after an input step: about `κ·Δu` more for each
    /// decade of time between its fastest and slowest time constants, and
    /// `3·κ·Δu` in all once the slowest has settled.
    #[test]
    fn the_log_creep_creeps_a_gain_per_decade() {
        let mut exp = experiment();
        exp.u = vec![0.5; 20_000];
        exp.y = vec![0.0; 20_000];
        let ctx = Context::of(&exp, true);
        let fam = Family::Linear;
        let base = thesis_params(fam);
        let model = ModelDescription::new(fam, vec![Effect::LogCreep], 1);
        let neutral = neutral_vector(&model, &base, &ctx);
        let reference = model.simulate(&neutral, 0, &ctx, &exp);
        let mut theta = neutral.clone();
        let at = fam.dim();
        // Time constants of 20, 200 and 2 000 samples.
        theta[at..at + 2].copy_from_slice(&[0.9995, 2.0]);
        let y = model.simulate(&theta, 0, &ctx, &exp);
        let creep = |k: usize| (y[k] - reference[k]) as f64;
        let per_decade = 2.0 * 0.5;
        for (from, to) in [(20, 200), (200, 2000)] {
            let grown = creep(to) - creep(from);
            assert!(
                (0.8..1.1).contains(&(grown / per_decade)),
                "{from} to {to}: {grown}"
            );
        }
        assert!(
            (creep(19_999) - 3.0 * per_decade).abs() < 1e-3,
            "{}",
            creep(19_999)
        );
    }

    /// Pulses of `levels` (absolute input, 20 samples each) between rests
    /// at 0, and what `effect` at `params` moves a static linear
    /// baseline's output `x(k) = u(k−1)` by at every sample: the input's
    /// move where the effect moves the input, read back at the sample it
    /// moved, and the output's one sample later where it moves the output.
    fn moved_input(levels: &[f64], effect: Effect, params: &[f32]) -> Vec<f64> {
        moved_output(levels, 1.0, effect, params)
    }

    /// The same for a muscle of gain `gain` (`x(k) = gain·u(k−1)`), whose
    /// displacement is not its input.
    fn moved_output(levels: &[f64], gain: f32, effect: Effect, params: &[f32]) -> Vec<f64> {
        let mut p = vec![0.0; 10];
        for &level in levels {
            p.extend([level; 20]);
            p.extend([0.0; 20]);
        }
        let y = vec![0.0; p.len()];
        let trace = crate::data::Trace::uniform("pulses", 0.1, p.clone(), y);
        let exp = Experiment::with_means_of(&trace, 0..p.len());
        let ctx = Context::of(&exp, true);
        let plain = ModelDescription::new(Family::Linear, vec![], 1);
        let reference = plain.simulate(&[0.0, gain, 0.0, 0.0], 0, &ctx, &exp);
        let model = plain.with(effect);
        let mut theta = vec![0.0f32, gain, 0.0, 0.0];
        theta.extend_from_slice(params);
        let got = model.simulate(&theta, 0, &ctx, &exp);
        (0..p.len() - 1)
            .map(|k| (got[k + 1] - reference[k + 1]) as f64)
            .collect()
    }

    /// The move at the middle of pulse `i` and of the rest after it.
    fn at_pulse(moved: &[f64], i: usize) -> (f64, f64) {
        (moved[10 + 40 * i + 10], moved[10 + 40 * i + 30])
    }

    #[test]
    fn a_mullins_softening_grows_with_the_largest_input_only() {
        let s = 0.5;
        let moved = moved_input(&[0.6, 0.8, 1.0, 1.0, 0.6], Effect::Softening, &[s]);
        let close = |a: f64, b: f64| (a - b).abs() < 1e-5;
        for (i, (level, peak)) in [(0.6, 0.6), (0.8, 0.8), (1.0, 1.0), (1.0, 1.0), (0.6, 1.0)]
            .into_iter()
            .enumerate()
        {
            let (pulse, rest) = at_pulse(&moved, i);
            assert!(close(pulse, s as f64 * peak * level), "pulse {i}: {pulse}");
            assert!(close(rest, 0.0), "rest after pulse {i}: {rest}");
        }
    }

    #[test]
    fn a_cyclic_softening_deepens_equal_pulses_by_less_each_time_and_keeps_it() {
        let (s, r) = (0.4, 0.5);
        let moved = moved_input(&[1.0; 4], Effect::CyclicSoftening, &[s, r]);
        for i in 0..4 {
            let (pulse, rest) = at_pulse(&moved, i);
            let want = s as f64 * (1.0 - (r as f64).powi(i as i32 + 1));
            assert!(
                (pulse - want).abs() < 1e-5,
                "pulse {i}: {pulse} against {want}"
            );
            assert!(rest.abs() < 1e-6, "rest after pulse {i}: {rest}");
        }
    }

    #[test]
    fn a_permanent_set_grows_with_each_new_largest_displacement_and_never_shrinks() {
        // A muscle of gain 2: the set follows its displacement, twice the
        // input.
        let (share, gain) = (-0.3, 2.0);
        let moved = moved_output(&[0.5, 1.0, 0.5], gain, Effect::Set, &[share]);
        let mut rests = Vec::new();
        for (i, (level, peak)) in [(0.5, 0.5), (1.0, 1.0), (0.5, 1.0)].into_iter().enumerate() {
            let (pulse, rest) = at_pulse(&moved, i);
            let g = gain as f64;
            assert!(
                (pulse - share as f64 * g * (peak - level)).abs() < 1e-5,
                "pulse {i}: {pulse}"
            );
            assert!(
                (rest - share as f64 * g * peak).abs() < 1e-5,
                "rest after pulse {i}: {rest}"
            );
            rests.push(rest);
        }
        // The rest only moves further the set's way.
        assert!(rests.windows(2).all(|w| w[1] <= w[0]), "{rests:?}");
    }

    #[test]
    fn a_ratchet_walks_with_every_loading() {
        // A steady walk, one that slows as the log of the count, and one
        // that settles: the n-th step is the one before times 1 − q/n.
        for (a, q) in [(0.2f32, 0.0f32), (0.2, 1.0), (0.2, 1.5)] {
            let moved = moved_input(&[1.0; 4], Effect::Ratchet, &[a, q]);
            let (mut step, mut want) = (a as f64, 0.0);
            for i in 0..4 {
                let n = (i + 1) as f64;
                if i > 0 {
                    step *= 1.0 - q as f64 / n;
                }
                want += step;
                let (pulse, rest) = at_pulse(&moved, i);
                assert!(
                    (pulse - want).abs() < 1e-5 && (rest - want).abs() < 1e-5,
                    "q {q}, cycle {i}: pulse {pulse}, rest {rest}, want {want}"
                );
            }
        }
    }

    /// A realisation the model lacks holds zeros, not unset memory: the
    /// step may compute with its constants before it tests whether it is
    /// on (docs/PERFORMANCE.md, "Absent stages hold zeros").
    #[test]
    fn a_model_without_a_realisation_holds_zeros_for_it() {
        let none = format!("{:?}", catalogue::Stages::<2>::none());
        assert_eq!(
            none.matches("on: false").count(),
            Effect::ALL.len(),
            "{none}"
        );
        let rest = none.replace("0.0", "").replace('0', "");
        assert!(!rest.contains(|c: char| c.is_ascii_digit()), "{none}");
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
        let err = "friction".parse::<Effect>().unwrap_err().to_string();
        assert!(err.contains("delay") && err.contains("load"), "{err}");
    }
}
