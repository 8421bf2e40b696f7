//! The one fitting problem `fit`, `compare`, the generated cases and the
//! diagnosis all work on: the records (each trace split as the thesis
//! splits it, §4.3.1, in one set of coordinates), each record's parts, the
//! model description that is fitted, its search box and which candidates
//! the fits admit: a plain value. The evaluator that scores its searches
//! and the flag that stops them are the searches' own
//! ([`super::searches::Searches`], [`super::run::FitRun::run`]).
//!
//! `fit` builds it on its traces, one per file ([`FitProblem::with_box`]):
//! the box in the data's own scale, their validation halves the one part
//! it reports on. The
//! diagnosis builds it on one trace per load ([`FitProblem::diagnosis`]):
//! the second halves cut into selection and test blocks, and every
//! candidate model in the diagnosis' box ([`FitProblem::with_model`]).
//! Either way one estimation cost is minimised ([`FitProblem::est_sse`]).

use std::ops::Range;
use std::sync::Arc;

use nalgebra::DVector;
use serde::Serialize;

use super::chart::ModelChart;
use super::records::{Records, Validation};
use crate::data::units::stated_length_in_mm;
use crate::data::{Trace, mixed_steps};
use crate::eval::Problem;
use crate::ident::fit::CHI2_1_95;
use crate::model::bounds::Origin;
use crate::model::coords::shape_range;
use crate::model::effects::{Context, Effect, EffectBox, ModelDescription, effect_box};
use crate::model::experiment::{Parts, halves};
use crate::model::file::Chain;
use crate::model::presets::ThesisBounds;
use crate::model::{
    Experiment, Family, FittedBaseline, Flow, LinearPrior, Loop, Model, SearchSpace, Switching,
    UserBound,
};
use crate::optim::engine::Space;

/// How far beyond the estimation output's largest deviation a bounded model
/// may go on the whole record's input ([`FitProblem::stress`]).
pub const STRESS_FACTOR: f64 = 10.0;

/// Whether `fit` admits a loop whose discrete update overshoots on the
/// steps its estimation records take (`--overshoot`;
/// [`Family::stable_step`]).
///
/// Such a loop is a property of the update, not of the continuous model,
/// and a record that turns back and forth at those steps pumps it. On the
/// Cavatappi records larger populations found classic fits of that kind
/// that lowered the estimation SSE and validated far worse (at `--pop
/// 4000`, 400 g: −827 % where ARX gives 69.8 %); refusing them kept a
/// larger population from hurting (docs/RESULTS.md, "Loops whose update
/// overshoots"). Admitted by default: on the rig twin with a stiff braid
/// friction at large populations, and for the generalized family on the
/// shipped stairs, the sharp loops that overshoot validated better.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Overshoot {
    /// Only loops that settle on all but the fastest 1 % of the estimation
    /// halves' output steps a sample.
    Refuse,
    /// Any loop, as the update runs it.
    #[default]
    Allow,
}

/// The share of the estimation halves' output steps a loop must settle
/// within where overshoots are refused: all but the fastest 1 %. Why not
/// all: on a record sampled coarsely for its loop (the Cavatappi long cycle
/// at 10 Hz, whose fastest sample steps 1.5 mm and whose 99th percentile
/// 0.11 mm) a loop that settles on every step is too soft to fit (36 %
/// against 71–81 % on its second half), and an overshoot on a rare fast
/// step is a glitch, not the pumping of a record that turns at such steps.
pub const SETTLED_SHARE: f64 = 0.99;

/// Which candidates a problem's fits admit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Admission {
    /// `fit`'s rule: on the free run, every candidate must stay within the
    /// stress bound on the whole record's input ([`FitProblem::stress`]),
    /// with bounded loops inside the bounded class, and, where overshoots
    /// are refused, its loop's update must settle on the estimation
    /// records' steps ([`Overshoot`]); the thesis' flow checks none of
    /// these (`fit::objective::ModelObjective::for_problem`).
    Fit(Overshoot),
    /// The diagnosis' rule: only models whose loop is bounded
    /// ([`Family::loop_bounded`]), under every measure. Why: a model fitted
    /// to one half with an unbounded loop (`β + γ < 0`) lets `w` run away
    /// once the input leaves the estimation half's range, and then diverges
    /// on its own validation half, leaving no gap to diagnose (as on the
    /// Cavatappi 500 g file: docs/lab/diagnosis.md, "Real data: the
    /// Cavatappi muscle").
    BoundedLoops,
}

/// The records, their parts, the model fitted to them and its box: see the
/// module's documentation.
#[derive(Debug, Clone)]
pub struct FitProblem {
    /// The traces, split and in one set of coordinates ([`Records::of`]).
    pub records: Arc<Records>,
    /// Each record's estimation, selection and test samples. `fit`'s
    /// records have no selection blocks and their validation half as the
    /// test part; the diagnosis' parts keep it honest: the fits read the
    /// estimation half, every choice (which effect, which realisation, which
    /// seed, when to stop, the noise floor) reads the selection part, and
    /// the test part is read once, by [`FitProblem::test`], after the model
    /// is final.
    pub parts: Vec<Parts>,
    /// What is fitted: the family and its effect stages, in chain order;
    /// their parameters follow the family's in every vector.
    pub model: ModelDescription,
    /// The box the fit searches.
    pub space: SearchSpace,
    pub flow: Flow,
    /// Which loop shapes the box admits (the joint flow's; the thesis' flow
    /// searches its own tables, of either sign).
    pub loop_shape: Loop,
    /// Where a generalized fit lets its sign terms switch (the joint
    /// flow's; the thesis' flow holds the level at the estimation mean).
    pub switching: Switching,
    pub admission: Admission,
    pub input_name: String,
    pub output_name: String,
}

/// How long after an input step a first-order model is still in its
/// transient: three time constants of the pole `a` (95 % settled), at least
/// one sample, at most a quarter of `len`.
pub fn settle_samples(a: f64, len: usize) -> usize {
    let a = a.clamp(1e-6, 1.0 - 1e-9);
    ((3.0 / -a.ln()).ceil() as usize).clamp(1, (len / 4).max(1))
}

/// The prediction horizon for data whose ARX pole is `a`: a
/// third of its time constant `1/(1 − a)` in samples, so that errors cannot
/// pile up through the slow pole, yet the prediction depends on the
/// dynamics rather than on the last measurement alone; at least 2, at most
/// a quarter of the shortest experiment.
pub fn horizon(arx_pole: f64, shortest: usize) -> usize {
    let tau = 1.0 / (1.0 - arx_pole).max(1e-3);
    ((tau / 3.0).round() as usize).clamp(2, (shortest / 4).max(2))
}

/// What the thesis' loop-shape bounds, which are per mm of stroke, are
/// multiplied by in a box for a record whose output column is
/// `output_name`: with `n = 1`, `β·|w|` is a pure number, so a loop-shape
/// parameter scales as one over the output's unit, and the same loops in
/// metres need bounds a thousand times larger. A column that names no
/// length ([`stated_length_in_mm`]) is taken to be in mm, as the
/// thesis' data and the shipped data are.
pub fn shape_per_output_unit(output_name: &str) -> f64 {
    stated_length_in_mm(output_name).unwrap_or(1.0)
}

/// `space`, the diagnosis' box in native coordinates, widened to hold a
/// start model's baseline parameters `start` (`diagnose --from`): a model
/// `fit` fitted in its own box, such as a braid's sharp friction loop far
/// past the thesis' loop shapes, then starts the diagnosis as it is, not
/// as its clamped image. Each bound `start` passes moves past it by half
/// the distance again, so that the start is not on the new edge.
/// (`SearchSpace::widen_to_hold`, `fit --from`'s, widens only the bounds
/// the data set, in steps; every bound of this box is the class's.)
fn hold_start(space: &mut SearchSpace, start: &[f64]) {
    for (j, &v) in start.iter().enumerate() {
        if v > space.upper[j] {
            space.upper[j] = v + 0.5 * (v - space.upper[j]);
        }
        if v < space.lower[j] {
            space.lower[j] = v - 0.5 * (space.lower[j] - v);
        }
    }
}

/// `space`, a box of the thesis' loop shapes ([`SearchSpace::from_prior`]),
/// with those shapes in the unit of `output_name`
/// ([`shape_per_output_unit`]; exact at `n = 1`, where every box but a
/// `--free-n` one holds `n`).
fn thesis_shapes_in_unit_of(mut space: SearchSpace, output_name: &str) -> SearchSpace {
    let per_unit = shape_per_output_unit(output_name);
    for i in shape_range(space.family) {
        space.lower[i] *= per_unit;
        space.upper[i] *= per_unit;
    }
    space
}

impl FitProblem {
    /// `fit`'s problem on `trace` ([`FitProblem::with_box`] on the one
    /// record): split in halves, the ARX prior identified on the estimation
    /// half, and the box of `flow`: the joint flow's in the data's own
    /// scale, bounded loops ([`SearchSpace::scaled`]) and,
    /// for the generalized family, the default switching
    /// ([`Switching::Search`]); the thesis' flow's from `hysteresis` (the
    /// hull of its tables when `None`), its loop shapes in the output's unit
    /// ([`shape_per_output_unit`]), with the linear part fixed at ARX's.
    /// `n` is fixed at 1 unless `free_n`.
    pub fn new(
        trace: &Trace,
        family: Family,
        flow: Flow,
        hysteresis: Option<&ThesisBounds>,
        free_n: bool,
    ) -> anyhow::Result<FitProblem> {
        let shape = (Loop::Bounded, Switching::default());
        let traces = std::slice::from_ref(trace);
        FitProblem::with_box(traces, family, flow, hysteresis, free_n, shape, &[])
    }

    /// As [`FitProblem::new`] on every one of `traces` (`fit a.csv b.csv`:
    /// several experiments on one muscle, each split in halves, one model
    /// for all; the box from the first record's ARX estimate and every
    /// record's ranges, [`Records::of`]), with
    /// the joint flow's loop class, switching and user bounds (`--loop`,
    /// `--switch`, `--bound`, `--fix`); the thesis' flow takes none of them.
    pub fn with_box(
        traces: &[Trace],
        family: Family,
        flow: Flow,
        hysteresis: Option<&ThesisBounds>,
        free_n: bool,
        (loop_shape, switching): (Loop, Switching),
        bounds: &[UserBound],
    ) -> anyhow::Result<FitProblem> {
        anyhow::ensure!(
            family != Family::Linear,
            "the linear model is fitted by least squares: use `mckibben identify`"
        );
        if let Some(why) = mixed_steps(traces) {
            anyhow::bail!(why);
        }
        if let Some(why) = crate::data::unlike_records(traces) {
            anyhow::bail!(why);
        }
        let records = Records::of(traces, None)?;
        let first = &traces[0];
        let space = match flow {
            Flow::Thesis => {
                anyhow::ensure!(
                    bounds.is_empty(),
                    "the thesis' flow searches its own tables: --bound and --fix need the joint flow"
                );
                thesis_shapes_in_unit_of(
                    SearchSpace::from_prior(family, hysteresis, records.prior, flow, free_n),
                    &first.output_name,
                )
            }
            Flow::Joint => SearchSpace::scaled(
                family,
                records.prior,
                (loop_shape, switching),
                free_n,
                bounds,
            )?,
        };
        let parts = traces
            .iter()
            .map(|t| {
                let (estimation, validation) = halves(t.len());
                Parts {
                    estimation,
                    selection: Vec::new(),
                    test: vec![validation],
                }
            })
            .collect();
        Ok(FitProblem {
            records: Arc::new(records),
            parts,
            model: ModelDescription::new(family, Vec::new(), traces.len()),
            space,
            flow,
            loop_shape,
            switching,
            admission: Admission::Fit(Overshoot::default()),
            input_name: first.input_name.clone(),
            output_name: first.output_name.clone(),
        })
    }

    /// The diagnosis' problem on `traces` with `family` as its baseline:
    /// every trace split in halves as `fit` splits it, in `model`'s
    /// coordinates when one is given (`diagnose --from`, as `fit --from`:
    /// [`Records::of`]), the second halves in `blocks` blocks
    /// ([`Parts::of`]), or in as many as each record's input asks for
    /// ([`Parts::chosen`]) when `None`; the diagnosis' box and admission.
    pub fn diagnosis(
        traces: &[Trace],
        family: Family,
        model: Option<&Model>,
        blocks: Option<usize>,
    ) -> anyhow::Result<FitProblem> {
        if let Some(why) = mixed_steps(traces).or_else(|| crate::data::unlike_records(traces)) {
            anyhow::bail!(why);
        }
        let records = Records::of(traces, model)?;
        let settle = FitProblem::settle_of(&records);
        let parts = traces
            .iter()
            .map(|t| match blocks {
                // Checked before the blocks are laid out: a count no
                // record holds would otherwise be laid out first.
                Some(b) => match Parts::too_short(t.len(), b, settle) {
                    Some(e) => Err(anyhow::anyhow!("{}: {e}", t.source)),
                    None => Ok(Parts::of(t.len(), b, settle)),
                },
                None => Ok(Parts::chosen(&t.input, settle)),
            })
            .collect::<anyhow::Result<_>>()?;
        let first = &traces[0];
        let records = Arc::new(records);
        let baseline = ModelDescription::new(family, Vec::new(), traces.len());
        let mut space = FitProblem::diagnosis_box(&records, &baseline, &first.output_name);
        // A start of another family is refused with its reason later
        // (`diagnose::start_of`).
        if let Some(m) = model.filter(|m| m.base.family == family) {
            hold_start(&mut space, &m.theta()[..family.dim()]);
        }
        Ok(FitProblem {
            space,
            records,
            parts,
            model: baseline,
            flow: Flow::Joint,
            loop_shape: Loop::Bounded,
            switching: Switching::Search,
            admission: Admission::BoundedLoops,
            input_name: first.input_name.clone(),
            output_name: first.output_name.clone(),
        })
    }

    /// The same records, parts, rules and evaluator with `model` fitted, in
    /// the diagnosis' box (`FitProblem::diagnosis_box`): the diagnosis'
    /// candidates.
    pub fn with_model(&self, model: &ModelDescription) -> FitProblem {
        let mut space = FitProblem::diagnosis_box(&self.records, model, &self.output_name);
        // The baseline's bounds as this problem has them: widened to hold
        // a start model's (`FitProblem::diagnosis`).
        if model.family == self.model.family {
            let d = model.family.dim();
            space.lower[..d].copy_from_slice(&self.space.lower[..d]);
            space.upper[..d].copy_from_slice(&self.space.upper[..d]);
        }
        FitProblem {
            model: model.clone(),
            space,
            ..self.clone()
        }
    }

    /// The diagnosis' box of `model`: the joint flow's box around the ARX
    /// estimate ([`SearchSpace::from_prior`]: thesis hull, `a`, `b`, `c` around
    /// the ARX estimate), its loop shapes in the unit of `output_name`
    /// ([`shape_per_output_unit`]), plus each effect's box.
    fn diagnosis_box(
        records: &Records,
        model: &ModelDescription,
        output_name: &str,
    ) -> SearchSpace {
        let mut base = thesis_shapes_in_unit_of(
            SearchSpace::from_prior(model.family, None, records.prior, Flow::Joint, false),
            output_name,
        );
        // Least squares on hysteretic data underestimates the input gain: the
        // hysteretic model's `b` relates to the ARX static gain
        // `G = b_ARX/(1 − a_ARX)` through `1 − a·α`, not `1 − a`. Widen the
        // box to reach `G` itself.
        let ib = model.family.linear_indices()[1];
        let g = records.prior.b / (1.0 - records.prior.a).abs().max(1e-3);
        if g.abs() > base.upper[ib].abs().max(base.lower[ib].abs()) {
            if g > 0.0 {
                base.upper[ib] = g;
            } else {
                base.lower[ib] = g;
            }
        }
        // The classic loop stays bounded for every input only when β ≥ 0 (and
        // β + γ > 0, else w grows without bound and the fit diverges anyway):
        // with β < 0 the loading branch settles at A/(β+γ), above the level
        // A/(γ−β) past which the unloading branch drives w away. A baseline
        // fitted there follows the data but turns wild under any change of
        // input or parameters, so it is no base to attribute effects to.
        if model.family == Family::Classic {
            let beta = Family::Classic
                .index_of("beta")
                .expect("the classic family has β");
            base.lower[beta] = base.lower[beta].max(0.0);
        }
        let names = model.param_names()[model.family.dim()..].to_vec();
        let (mut lower, mut upper) = (Vec::new(), Vec::new());
        for &e in &model.effects {
            let EffectBox {
                lower: l, upper: h, ..
            } = effect_box(e, &records.ctx[0], model.datasets);
            lower.extend(l);
            upper.extend(h);
        }
        base.with_extra(names, lower, upper, &[])
            .expect("no user bounds to refuse")
    }

    /// The start of a search from scratch in the diagnosis' box: the middle
    /// of the family's box, every effect at its neutral value.
    pub fn centre(&self) -> Vec<f64> {
        let d = self.model.family.dim();
        let mid: Vec<f64> = self.space.lower[..d]
            .iter()
            .zip(&self.space.upper[..d])
            .map(|(l, u)| 0.5 * (l + u))
            .collect();
        self.neutral_effects(&mid)
    }

    /// The settling gap between blocks: three time constants of the ARX
    /// pole (95 % settled), at least one sample.
    fn settle_of(records: &Records) -> usize {
        let shortest = records.whole.iter().map(|w| w.len()).min().unwrap_or(0);
        settle_samples(records.prior.a, shortest)
    }

    /// An error naming the record and the length it needs when a record is
    /// too short for useful selection and test blocks: the diagnosis then
    /// refuses to run rather than choose and report on the same samples.
    pub fn check_parts(&self) -> anyhow::Result<()> {
        let settle = FitProblem::settle_of(&self.records);
        for (w, p) in self.records.whole.iter().zip(&self.parts) {
            let blocks = p.selection.len() + p.test.len();
            if let Some(e) = Parts::too_short(w.len(), blocks, settle) {
                anyhow::bail!("{}: {e}", w.name);
            }
        }
        Ok(())
    }

    /// The second start of [`Switching::Starts`]: the same problem with the
    /// generalized switching level held at the sensor's zero instead of the
    /// estimation mean. `None` where a fit has one start: another family or
    /// switching, the thesis' flow, a level the user bounds or fixes, or an
    /// estimation mean of 0 (the two starts would be one).
    pub fn at_zero(&self) -> Option<FitProblem> {
        let is = self.model.family.switch_index()?;
        let mean = self.estimation().y_mean;
        let held_at_mean = (self.space.lower[is], self.space.upper[is]) == (mean, mean)
            && self.space.origin[is] == [Origin::Class; 2];
        let two = self.flow == Flow::Joint
            && self.switching == Switching::Starts
            && held_at_mean
            && mean != 0.0;
        two.then(|| {
            let mut zero = self.clone();
            (zero.space.lower[is], zero.space.upper[is]) = (0.0, 0.0);
            zero
        })
    }

    /// Holds the generalized switching level at `x_s` under the default
    /// switching ([`Switching::Search`]; not `--switch mean`, `zero` or
    /// `starts`, nor a level the user bounds or fixes): a warm start keeps
    /// its model's own level, as it keeps the basin it is given.
    pub fn hold_switch_at(&mut self, x_s: f64) {
        let Some(is) = self.model.family.switch_index() else {
            return;
        };
        if self.switching == Switching::default() && self.space.origin[is] == [Origin::Class; 2] {
            (self.space.lower[is], self.space.upper[is]) = (x_s, x_s);
        }
    }

    /// The same problem in `model`'s coordinates ([`Records::of`]): a warm
    /// start then starts at the saved model itself.
    pub fn in_coordinates_of(
        mut self,
        traces: &[Trace],
        model: &Model,
    ) -> anyhow::Result<FitProblem> {
        self.records = Arc::new(Records::of(traces, Some(model))?);
        Ok(self)
    }

    /// The same problem with `effects` after the family: their parameters
    /// join the box in their own units (each effect's box from the record,
    /// [`effect_box`]); `bounds` may name them (`creep.kappa=0:1`).
    pub fn with_effects(
        mut self,
        effects: &[Effect],
        bounds: &[UserBound],
    ) -> anyhow::Result<FitProblem> {
        anyhow::ensure!(
            effects.is_empty() || self.flow == Flow::Joint,
            "the thesis' flow fits the thesis' models: --effects needs the joint flow"
        );
        if let Some(why) = Effect::chain_conflict(effects) {
            anyhow::bail!("--effects {why}");
        }
        for e in effects {
            // Its parameters would tell the records apart (one per load),
            // and a model file is one model for any record.
            anyhow::ensure!(
                e.applicable(1),
                "--effects: `{e}` needs several datasets (one per load) and fits a parameter \
                 for each; `fit` fits one model for all its records: use `mckibben diagnose`"
            );
        }
        let datasets = self.datasets();
        self.model = ModelDescription::new(self.model.family, effects.to_vec(), datasets);
        let names = self.model.param_names();
        let d = self.model.family.dim();
        let (mut lower, mut upper) = (Vec::new(), Vec::new());
        for &e in effects {
            let EffectBox {
                lower: lo,
                upper: hi,
                ..
            } = effect_box(e, self.context(), datasets);
            lower.extend(lo);
            upper.extend(hi);
        }
        self.space = self
            .space
            .with_extra(names[d..].to_vec(), lower, upper, bounds)?;
        Ok(self)
    }

    /// The engine's box of this problem: its search box, with a searched
    /// switching level's preferred levels kept where they score within
    /// the likelihood-ratio threshold of the lowest (the estimation data
    /// cannot tell them apart at 95 %).
    pub fn engine_space(&self) -> Space<ModelChart> {
        let mut space = Space::from(&self.space);
        let share = CHI2_1_95 / self.est_samples().max(1) as f64;
        for s in &mut space.stepwise {
            s.tolerance = share;
        }
        space
    }

    /// A digest of the records this problem fits: every record's samples as
    /// the fit reads them, its sample time, means and column names. A
    /// checkpoint keeps it ([`Engine::subject`](crate::optim::engine::Engine))
    /// so that a fit on other data (another file, column or resampling)
    /// cannot resume it and report another record's parameters as its own.
    pub fn data_digest(&self) -> String {
        use sha2::{Digest, Sha256};
        let mut hash = Sha256::new();
        for name in [&self.input_name, &self.output_name] {
            hash.update((name.len() as u64).to_le_bytes());
            hash.update(name.as_bytes());
        }
        for record in &self.records.whole {
            hash.update((record.u.len() as u64).to_le_bytes());
            for v in [record.dt, record.u_mean, record.y_mean] {
                hash.update(v.to_le_bytes());
            }
            for v in record.u.iter().chain(&record.y) {
                hash.update(v.to_le_bytes());
            }
        }
        format!("{:x}", hash.finalize())
    }

    /// The first record's estimation half.
    pub fn estimation(&self) -> &Experiment {
        &self.records.est[0]
    }

    /// The ARX prior the box is built on.
    pub fn prior(&self) -> LinearPrior {
        self.records.prior
    }

    /// The effects' constants of the first record: its estimation half's,
    /// in its coordinates.
    pub fn context(&self) -> &Context {
        &self.records.ctx[0]
    }

    pub fn datasets(&self) -> usize {
        self.records.whole.len()
    }

    /// The family's parameters of `params` followed by every effect of the
    /// chain at its neutral value (the baseline's output, bit for bit).
    pub fn neutral_effects(&self, params: &[f64]) -> Vec<f64> {
        let mut theta = params[..self.model.family.dim()].to_vec();
        for &e in &self.model.effects {
            theta.extend(effect_box(e, self.context(), self.model.datasets).neutral);
        }
        theta
    }

    /// The estimation problem the optimizer scores: the model description
    /// on every record's estimation half.
    pub fn est_problem(&self) -> Problem {
        Problem::new(self.model.family, self.records.est.clone())
            .with_effects(self.model.effects.clone(), self.records.ctx.clone())
    }

    /// The check that a candidate stays bounded on every input of the
    /// records: each whole record's input (estimation and validation
    /// halves) with the measured output replaced by its first sample and
    /// zeros, so that a candidate's free-run "SSE" on them is the energy of
    /// its own output, and the largest energy a bounded model may have.
    ///
    /// Why: a model fitted to one half can be unstable on the other. An
    /// estimation optimum with β + γ < 0 lets `w` grow without bound once
    /// the input leaves the estimation half's range, and the fit then writes
    /// a model that diverges on its own validation half (as on the
    /// Cavatappi muscle: docs/ARCHITECTURE.md, "Decisions of the fitting
    /// engine"). The check uses the validation halves' input, never their
    /// output; the bound is ten times the estimation outputs' largest
    /// deviation, on every sample.
    pub fn stress(&self) -> (Problem, f64) {
        let quiet: Vec<Experiment> = self
            .records
            .whole
            .iter()
            .map(|record| {
                let mut whole = record.clone();
                let start = whole.y.first().copied().unwrap_or(0.0);
                whole.y = vec![0.0; whole.u.len()];
                if let Some(first) = whole.y.first_mut() {
                    *first = start;
                }
                whole
            })
            .collect();
        let largest = self
            .records
            .est
            .iter()
            .flat_map(|e| &e.y)
            .fold(0.0f64, |m, &v| m.max((v as f64).abs()));
        let samples: usize = quiet.iter().map(|w| w.u.len()).sum();
        let bound = samples as f64 * (STRESS_FACTOR * largest).powi(2);
        let problem = Problem::new(self.model.family, quiet)
            .with_effects(self.model.effects.clone(), self.records.ctx.clone());
        (problem, bound)
    }

    /// Whether the problem's fits admit `theta` whatever the measure: every
    /// effect admitted ([`ModelDescription::effects_admit`]: a ringing must ring)
    /// and, under [`Admission::BoundedLoops`], a bounded loop.
    pub fn admits(&self, theta: &[f64]) -> bool {
        let loop_ok =
            self.admission != Admission::BoundedLoops || self.model.family.loop_bounded(theta);
        loop_ok && self.model.effects_admit(theta)
    }

    /// The free-run SSE of `theta` on the estimation halves, the cost every
    /// fit minimises, summed over the records (`+∞` where a run diverges or
    /// the problem does not admit `theta`).
    pub fn est_sse(&self, theta: &[f64]) -> f64 {
        let model = &self.model;
        self.est_sum(theta, |t, i, c, e| model.sse(t, i, c, e))
    }

    /// Estimation SSE of the `horizon`-step-ahead prediction (see
    /// [`ModelDescription::sse_ahead`]).
    pub fn est_sse_ahead(&self, theta: &[f64], horizon: usize) -> f64 {
        let model = &self.model;
        self.est_sum(theta, |t, i, c, e| model.sse_ahead(t, i, c, e, horizon))
    }

    /// `cost(θ, record, context, estimation half)` summed over the records.
    fn est_sum(
        &self,
        theta: &[f64],
        cost: impl Fn(&[f32], usize, &Context, &Experiment) -> f32,
    ) -> f64 {
        if !self.admits(theta) {
            return f64::INFINITY;
        }
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        let sum: f64 = self
            .records
            .est
            .iter()
            .zip(&self.records.ctx)
            .enumerate()
            .map(|(i, (e, c))| cost(&t, i, c, e) as f64)
            .sum();
        if sum.is_finite() { sum } else { f64::INFINITY }
    }

    /// Estimation residuals over all records (the first sample of each is
    /// the start, not a residual).
    pub fn est_samples(&self) -> usize {
        self.records
            .est
            .iter()
            .map(|e| e.len().saturating_sub(1))
            .sum()
    }

    /// Free-run residuals `ŷ − y` of the estimation halves, every record
    /// from its second sample on; `None` if the simulation diverged or the
    /// problem does not admit `theta`.
    pub fn est_residuals(&self, theta: &[f64]) -> Option<DVector<f64>> {
        if !self.admits(theta) {
            return None;
        }
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        let mut r = Vec::with_capacity(self.records.est.iter().map(|e| e.len()).sum());
        for (i, (e, c)) in self.records.est.iter().zip(&self.records.ctx).enumerate() {
            let p = self.model.simulate(&t, i, c, e);
            r.extend(p.iter().zip(&e.y).skip(1).map(|(&a, &b)| (a - b) as f64));
        }
        r.iter()
            .all(|v| v.is_finite())
            .then(|| DVector::from_vec(r))
    }

    /// The prediction horizon of a search on the multi-step-ahead
    /// prediction error (the fit's global stage's, the diagnosis' `Ahead`
    /// start's): [`horizon`] from the ARX pole and the shortest estimation
    /// half.
    pub fn horizon(&self) -> usize {
        let shortest = self.records.est.iter().map(|e| e.len()).min().unwrap_or(8);
        horizon(self.records.prior.a, shortest)
    }

    /// Predicted output (deviation coordinates) over each whole record: the
    /// free run from the first sample, so the second half starts from a
    /// warmed-up state rather than `w = 0`.
    pub fn predict(&self, theta: &[f64]) -> Vec<Vec<f32>> {
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        self.records
            .whole
            .iter()
            .zip(&self.records.ctx)
            .enumerate()
            .map(|(i, (e, c))| self.model.simulate(&t, i, c, e))
            .collect()
    }

    /// Selection samples over all records.
    pub fn selection_samples(&self) -> usize {
        self.parts.iter().map(Parts::selection_len).sum()
    }

    /// Each record's selection blocks.
    pub fn selection_ranges(&self) -> Vec<Vec<Range<usize>>> {
        self.parts.iter().map(|p| p.selection.clone()).collect()
    }

    /// Each record's test blocks.
    pub fn test_ranges(&self) -> Vec<Vec<Range<usize>>> {
        self.parts.iter().map(|p| p.test.clone()).collect()
    }

    /// Residuals `y − ŷ` of the free run on each selection block, with the
    /// record each belongs to and its range.
    pub fn selection_residuals(&self, theta: &[f64]) -> Vec<(usize, Range<usize>, Vec<f64>)> {
        let runs = self.predict(theta);
        let mut blocks = Vec::new();
        for (i, (p, w)) in runs.iter().zip(&self.records.whole).enumerate() {
            for r in &self.parts[i].selection {
                let res = r.clone().map(|k| w.y[k] as f64 - p[k] as f64).collect();
                blocks.push((i, r.clone(), res));
            }
        }
        blocks
    }

    /// Scores on the selection part, every record pooled (infinite RMSE
    /// where the simulation diverged): what every choice reads.
    pub fn selection(&self, theta: &[f64]) -> Validation {
        self.records
            .score_on(&self.model, theta, &self.selection_ranges())
    }

    /// [`FitProblem::selection`]'s RMSE.
    pub fn selection_rmse(&self, theta: &[f64]) -> f64 {
        self.selection(theta).rmse
    }

    /// Scores on the test part, every record pooled: read once the model is
    /// final, and by nothing that chooses.
    pub fn test(&self, theta: &[f64]) -> Validation {
        self.records
            .score_on(&self.model, theta, &self.test_ranges())
    }

    /// The SSE of the free run on each selection block of every record, in
    /// order (`+∞` where it diverged): whether a gain holds across the part,
    /// not only pooled.
    pub fn block_sse(&self, theta: &[f64]) -> Vec<f64> {
        self.selection_residuals(theta)
            .iter()
            .map(|(_, _, r)| {
                let sse: f64 = r.iter().map(|v| v * v).sum();
                if sse.is_finite() { sse } else { f64::INFINITY }
            })
            .collect()
    }

    /// Validation scores on each record's second half
    /// ([`Records::validate`]): `fit`'s figure.
    pub fn validate(&self, theta: &[f64]) -> Validation {
        self.records.validate(&self.model, theta)
    }

    /// [`Records::apart_on_validation`]: how far the fits `a` and `b` part
    /// over the validation halves, on the inputs alone.
    pub fn apart_on_validation(&self, a: &[f64], b: &[f64]) -> f64 {
        self.records.apart_on_validation(&self.model, a, b)
    }

    /// The fitted model as a model file holds it: in the first record's
    /// estimation coordinates, with its effect constants.
    pub fn fitted_model(&self, params: &[f64]) -> Model {
        let family = self.model.family;
        let d = family.dim();
        let base = FittedBaseline {
            family,
            params: params[..d].to_vec(),
            input_mean: self.estimation().u_mean,
            output_mean: self.estimation().y_mean,
            dt: self.estimation().dt,
            input_name: self.input_name.clone(),
            output_name: self.output_name.clone(),
        };
        let chain = (!self.model.effects.is_empty()).then(|| Chain {
            effects: self.model.effects.clone(),
            params: params[d..].to_vec(),
            context: *self.context(),
            datasets: self.model.datasets,
        });
        Model { base, chain }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::synthetic::Synthetic;
    use crate::ident::fit_percent;

    #[test]
    fn a_fits_test_part_is_its_validation_half() {
        let s = Synthetic::new(Family::Classic, 600, 0.05, 4);
        let problem = FitProblem::new(&s.trace, Family::Classic, Flow::Joint, None, false).unwrap();
        assert!(problem.parts[0].selection.is_empty());
        assert_eq!(
            problem.parts[0].test,
            vec![problem.records.val_start[0]..600]
        );
        assert_eq!(problem.test(&s.truth), problem.validate(&s.truth));
    }

    /// A fit of several records splits each, and what it admits must stay
    /// bounded on every record's input, not the first's alone.
    #[test]
    fn a_fit_of_several_records_splits_and_stresses_each() {
        let (a, b) = (
            Synthetic::new(Family::Classic, 400, 0.05, 6),
            Synthetic::new(Family::Classic, 700, 0.05, 7),
        );
        let shape = (Loop::Bounded, Switching::default());
        let problem_of = |traces: &[Trace]| {
            FitProblem::with_box(
                traces,
                Family::Classic,
                Flow::Joint,
                None,
                false,
                shape,
                &[],
            )
        };
        let problem = problem_of(&[a.trace.clone(), b.trace.clone()]).unwrap();
        assert_eq!(problem.datasets(), 2);
        assert_eq!(problem.parts[1].test, vec![halves(700).1]);
        let (stress, bound) = problem.stress();
        assert_eq!(stress.experiments.len(), 2);
        for (quiet, record) in stress.experiments.iter().zip(&problem.records.whole) {
            assert_eq!(quiet.u, record.u);
            assert_eq!(quiet.y[0], record.y[0]);
            assert!(quiet.y[1..].iter().all(|&y| y == 0.0));
        }
        let largest = problem
            .records
            .est
            .iter()
            .flat_map(|e| &e.y)
            .fold(0.0f64, |m, &v| m.max(f64::from(v).abs()));
        assert_eq!(bound, 1100.0 * (STRESS_FACTOR * largest).powi(2));
        // One record twice, or records of other columns, one model cannot take.
        let fit = |traces: &[Trace]| problem_of(traces).unwrap_err().to_string();
        let twice = fit(&[a.trace.clone(), b.trace.clone(), a.trace.clone()]);
        assert!(twice.contains("hold the same samples"), "{twice}");
        let metres = Trace {
            output_name: "x_m".into(),
            ..b.trace.clone()
        };
        let named = fit(&[a.trace.clone(), metres]);
        assert!(
            named.contains("give the records the same columns"),
            "{named}"
        );
    }

    #[test]
    fn a_diagnosis_candidate_searches_the_baselines_box_then_each_effects() {
        let s = Synthetic::new(Family::Classic, 600, 0.05, 5);
        let data = FitProblem::diagnosis(&[s.trace], Family::Classic, None, Some(2)).unwrap();
        let d = Family::Classic.dim();
        // The classic loop's β held non-negative, the gain's box reaching
        // the ARX static gain.
        assert!(data.space.lower[Family::Classic.index_of("beta").unwrap()] >= 0.0);
        let prior = data.prior();
        let gain = prior.b / (1.0 - prior.a);
        let ib = Family::Classic.linear_indices()[1];
        assert!(data.space.lower[ib] <= gain && gain <= data.space.upper[ib]);
        let model = data.model.with(Effect::Creep).with(Effect::Asymmetry);
        let candidate = data.with_model(&model);
        assert_eq!(candidate.space.lower[..d], data.space.lower[..]);
        assert_eq!(candidate.space.upper[..d], data.space.upper[..]);
        let mut at = d;
        for e in [Effect::Creep, Effect::Asymmetry] {
            let b = effect_box(e, data.context(), 1);
            let n = b.neutral.len();
            assert_eq!(candidate.space.lower[at..at + n], b.lower[..], "{e}");
            assert_eq!(candidate.space.upper[at..at + n], b.upper[..], "{e}");
            assert_eq!(candidate.centre()[at..at + n], b.neutral[..], "{e}");
            at += n;
        }
        assert_eq!(candidate.space.names(), model.param_names());
        // The neutral chain is the baseline, bit for bit.
        let base = data.centre();
        assert_eq!(
            candidate.est_sse(&candidate.neutral_effects(&base)),
            data.est_sse(&base)
        );
    }

    #[test]
    fn the_truth_validates_near_the_noise() {
        let s = Synthetic::new(Family::Classic, 600, 0.05, 1);
        let problem = FitProblem::new(&s.trace, Family::Classic, Flow::Joint, None, false).unwrap();
        // The box holds the truth's twin in its gauge A = 1.
        let twin = crate::model::coords::gauge_fixed(Family::Classic, &s.truth);
        assert!(problem.space.contains(&twin), "{twin:?}");
        assert!(!problem.space.contains(&s.truth), "A is held at 1");
        let v = problem.validate(&s.truth);
        assert!(v.rmse < 0.2 && v.fit_percent > 95.0, "{v:?}");
        let thesis = FitProblem::new(&s.trace, Family::Classic, Flow::Thesis, None, false).unwrap();
        assert_eq!(thesis.space.free(), vec![0, 1, 2, 3]);
        assert!(FitProblem::new(&s.trace, Family::Linear, Flow::Joint, None, false).is_err());
    }

    #[test]
    fn in_a_models_coordinates_its_parameters_are_that_model_on_another_record() {
        for family in [Family::Classic, Family::Generalized] {
            let s = Synthetic::new(family, 600, 0.05, 3);
            let fitted_on = FitProblem::new(&s.trace, family, Flow::Joint, None, false).unwrap();
            let model = fitted_on.fitted_model(&s.truth);
            // Another record of the same muscle: its means are not the model's.
            let t = &s.trace;
            let later = Trace::uniform(
                "later",
                t.dt(),
                t.input[150..].to_vec(),
                t.output[150..].to_vec(),
            );
            let problem = FitProblem::new(&later, family, Flow::Joint, None, false).unwrap();
            assert!((problem.estimation().y_mean - model.base.output_mean).abs() > 0.1);
            let saved = model.simulate_trace(&later);
            let val_start = problem.records.val_start[0];
            let expected = fit_percent(&later.output[val_start..], &saved[val_start..]);
            let here = problem
                .clone()
                .in_coordinates_of(std::slice::from_ref(&later), &model)
                .unwrap()
                .validate(&s.truth);
            assert!(
                (here.fit_percent - expected).abs() < 1e-6,
                "{family}: {} against the model's own {expected}",
                here.fit_percent
            );
            // In the record's own coordinates the same numbers are another model.
            let moved = problem.validate(&s.truth).fit_percent;
            assert!((moved - expected).abs() > 1e-3, "{family}: {moved}");
        }
    }
}
