//! A muscle-model fit of one trace as `mckibben fit` runs it ([`FitRun`]):
//! its problem, its engine and its other starts, run on the evaluator the
//! caller hands it, every try settled by the edge rule; the one place a
//! fit's starts run. What a fresh fit runs (the algorithm, the plan, the
//! stop rules) is [`super::settings`].

use std::path::Path;
use std::sync::atomic::AtomicBool;

use anyhow::Context as _;
use serde::Serialize;

use super::agreement::Agreement;
use super::chart::ModelChart;
use super::edge::{Widening, settle_tries};
use super::objective::ModelObjective;
use super::problem::{Admission, FitProblem, Overshoot};
use super::records::{Validation, offset_note};
use super::settings::FitSettings;
use crate::data::{Trace, sources};
use crate::eval::Evaluator;
use crate::model::coords::gauge_fixed;
use crate::model::effects::Effect;
use crate::model::{Family, Flow, Loop, Model, Switching, UserBound};
use crate::optim::engine::{Engine, Observer, Outcome, Plan, StopReason, StopRules};

/// What a fit identifies on a trace: the family, its effects and its search
/// box (the joint flow's; the thesis' flow, `FitSettings::thesis_flow`,
/// takes its own).
#[derive(Debug, Clone, PartialEq)]
pub struct FitTarget {
    pub family: Family,
    /// Effect stages after the family, in chain order (`--effects`).
    pub effects: Vec<Effect>,
    /// Also fit the Bouc-Wen exponent n (`--free-n`).
    pub free_n: bool,
    /// Loop shapes the box admits (`--loop`).
    pub loop_shape: Loop,
    /// Where a generalized fit lets its sign terms switch (`--switch`);
    /// `None`, the default: searched from scratch, and a warm start's
    /// model's level held.
    pub switching: Option<Switching>,
    /// Whether a loop whose update overshoots is admitted (`--overshoot`);
    /// `None`: admitted ([`Overshoot`]'s default).
    pub overshoot: Option<Overshoot>,
    /// The user's bounds and fixed values (`--bound`, `--fix`), an effect's
    /// as `effect.param`.
    pub bounds: Vec<UserBound>,
}

impl FitTarget {
    /// `family` followed by `effects` in the box `fit --effects` searches
    /// by default: n held at 1, bounded loops, the default switching, no
    /// user bounds.
    pub fn chain(family: Family, effects: &[Effect]) -> FitTarget {
        FitTarget {
            family,
            effects: effects.to_vec(),
            free_n: false,
            loop_shape: Loop::Bounded,
            switching: None,
            overshoot: None,
            bounds: Vec::new(),
        }
    }
}

/// A fit of its traces as `mckibben fit` runs it: the problem, and the
/// engine that runs on it.
#[derive(Debug, Clone)]
pub struct FitRun {
    pub problem: FitProblem,
    pub engine: Engine<ModelChart>,
    /// The first start's plan, what the fit was asked to run (its
    /// algorithm, population and tries): the engine above is the kept
    /// start's, which may be the chain's warm start, of a smaller
    /// population and no global stage.
    pub asked: Plan,
    /// A warm start's model as it was, in the problem's gauge (same outputs):
    /// what the refit is measured against ([`FitRun::start_scores`]).
    pub start: Option<Vec<f64>>,
    /// A second start run after the engine ([`FitRun::also_from`]): the
    /// chain built one effect at a time, warm-started in a box widened to
    /// hold it.
    second: Option<ChainStart>,
    /// Seconds spent before the first start, building that chain (whether
    /// or not the build ended): counted in the fit's time and its budget.
    pub built_in_s: f64,
    /// Which of the two was kept, once [`FitRun::run`] has run both.
    pub built: Option<Built>,
    /// The default switching's second start ([`FitProblem::at_zero`]): the same
    /// fit with the generalized switching level held at the sensor's zero,
    /// run after the engine, before any [`FitRun::also_from`] start.
    zero: Option<Start>,
    /// Which of the switching starts was kept, once [`FitRun::run`] has run both.
    pub switched: Option<Switched>,
    /// How far the kept start's tries agree, once [`FitRun::run`] has run
    /// (`None` for a single try).
    pub agreement: Option<Agreement>,
}

/// One start of a fit: the problem it searches (its box held or widened
/// where the start asks for it) and the engine that runs on it.
#[derive(Debug, Clone)]
struct Start {
    problem: FitProblem,
    engine: Engine<ModelChart>,
}

/// The chain's warm start ([`FitRun::also_from`]).
#[derive(Debug, Clone)]
struct ChainStart {
    start: Start,
}

/// A start run to its end with every try settled by the edge rule: its
/// outcome and the kept try's widenings.
struct Settled {
    outcome: Outcome,
    widened: Vec<Widening>,
}

impl Start {
    /// Runs the start on `evaluator` (no observer, no checkpoint: only the
    /// fit's first start reports its progress and is checkpointed), then
    /// settles its tries ([`settle_tries`]).
    fn run(
        &mut self,
        evaluator: &mut dyn Evaluator,
        stops: &StopRules,
        interrupt: Option<&AtomicBool>,
    ) -> anyhow::Result<Settled> {
        let hooks = Hooks {
            observers: &mut [],
            interrupt,
            checkpoint: None,
        };
        let outcome = run_on(&self.problem, &mut self.engine, evaluator, hooks)?;
        let (outcome, widened) =
            settle_tries(&mut self.problem, &self.engine, outcome, stops, evaluator)?;
        Ok(Settled { outcome, widened })
    }
}

/// A generalized fit run from the switching's two starts
/// ([`crate::model::Switching::Starts`]): the switching level held at the
/// estimation mean, and at the sensor's zero; the lower estimation SSE is
/// kept.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Switched {
    /// Estimation SSE with the level at the estimation mean.
    pub mean_sse: f64,
    /// Estimation SSE with the level at the sensor's zero.
    pub zero_sse: f64,
    /// `true` when the start at zero was kept.
    pub kept_zero: bool,
}

impl Switched {
    /// The two starts' outcomes compared: the one at zero is kept where it
    /// found a model at a lower estimation SSE.
    pub fn of(at_mean: &Outcome, at_zero: &Outcome) -> Switched {
        Switched {
            mean_sse: at_mean.sse,
            zero_sse: at_zero.sse,
            kept_zero: !at_zero.params.is_empty() && at_zero.sse < at_mean.sse,
        }
    }
}

/// A fit with effects run twice, from scratch and from the chain built one
/// effect at a time as the diagnosis builds it; the lower estimation SSE
/// is kept.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Built {
    /// Estimation SSE of the search from scratch.
    pub scratch_sse: f64,
    /// Estimation SSE of the warm start from the built chain.
    pub chain_sse: f64,
    /// `true` when the chain's fit was kept.
    pub kept_chain: bool,
}

impl FitRun {
    /// The problem of `what` on `traces` (one model for all, each split
    /// in halves: [`FitProblem::with_box`]; its box widened on return of
    /// [`FitRun::run`]) and the engine `settings` start on it: a warm start
    /// from `start` ([`FitSettings::start_warm`], the generalized switching
    /// level held at the start's own unless `what` says otherwise), else
    /// fresh or resumed from `checkpoint` ([`FitSettings::start`]), and a
    /// fresh second start where the default switching has one
    /// ([`FitProblem::at_zero`]).
    pub fn new(
        traces: &[Trace],
        what: &FitTarget,
        settings: &FitSettings,
        start: Option<&Model>,
        checkpoint: Option<&Path>,
        note: &dyn Fn(String),
    ) -> anyhow::Result<FitRun> {
        anyhow::ensure!(
            checkpoint.is_none() || start.is_none(),
            "--checkpoint resumes a fit from its own state: not with --from"
        );
        let flow = if settings.thesis_flow {
            Flow::Thesis
        } else {
            Flow::Joint
        };
        for trace in traces {
            if let Some(m) = start {
                m.check_data(trace).context("the start model")?;
            }
            if let Some(far) = offset_note(trace) {
                note(far);
            }
        }
        let problem = FitProblem::with_box(
            traces,
            what.family,
            flow,
            None,
            what.free_n,
            (what.loop_shape, what.switching.unwrap_or_default()),
            &what.bounds,
        )
        .and_then(|t| match start {
            Some(m) => t.in_coordinates_of(traces, m),
            None => Ok(t),
        })
        .and_then(|t| t.with_effects(&what.effects, &what.bounds))
        .with_context(|| format!("cannot fit {}", sources(traces)))?;
        let mut problem = problem;
        if let Some(overshoot) = what.overshoot {
            problem.admission = Admission::Fit(overshoot);
        }
        let start = start.map(|m| warm_start(&problem, m));
        // A warm start keeps its model's level unless another was asked.
        if let (Some(theta), Some(is), None) = (&start, what.family.switch_index(), what.switching)
        {
            problem.hold_switch_at(theta[is]);
        }
        if let Some(theta) = &start {
            let widened = problem.space.widen_to_hold(theta);
            if !widened.is_empty() {
                note(format!(
                    "the start model lies outside the box the data set; widened {}",
                    widened.join(", ")
                ));
            }
            if !problem.space.contains(theta) {
                note(
                    "the start model lies outside this fit's box on bounds that cannot widen \
                     (its class, your --bound, or a small-signal pole of 1 or more): the fit \
                     starts from the nearest point inside"
                        .to_string(),
                );
            }
        }
        match &start {
            Some(theta) => {
                let engine = settings.start_warm(&problem, theta)?;
                let mut fit = FitRun::of(problem, engine)?;
                fit.start = start;
                Ok(fit)
            }
            None => {
                let engine = settings.start(&problem, checkpoint, note)?;
                FitRun::of(problem, engine)
            }
        }
    }

    /// A fit of `problem` by `engine`, and, where `--switch starts` gives the
    /// problem a second start ([`FitProblem::at_zero`]), a fresh engine of
    /// the same plan and seed on it (a checkpoint holds the first start's
    /// engine only). `mckibben compare` and the generated cases fit so
    /// ([`run_fit`]); [`FitRun::new`] builds its fresh fits so.
    pub fn of(problem: FitProblem, engine: Engine<ModelChart>) -> anyhow::Result<FitRun> {
        let zero = match problem.at_zero() {
            Some(zero) if engine.plan.global.is_some() => {
                let second = Engine::new(
                    engine.plan.clone(),
                    zero.engine_space(),
                    engine.seed,
                    engine.stops.clone(),
                )?;
                Some(Start {
                    problem: zero,
                    engine: second,
                })
            }
            _ => None,
        };
        Ok(FitRun {
            problem,
            asked: engine.plan.clone(),
            engine,
            start: None,
            second: None,
            built_in_s: 0.0,
            built: None,
            zero,
            switched: None,
            agreement: None,
        })
    }

    /// Runs, after the engine, a warm start from `model` ([`FitSettings::start_warm`]
    /// on the problem's box widened to hold it) and keeps whichever ends at the
    /// lower estimation SSE ([`Built`]). `model` must be in the problem's
    /// coordinates: fitted on the same record, split the same way
    /// (`diagnose::chain::fit_chain` gives one). For `fit --effects`: a
    /// search of the whole chain's box from scratch is a lottery the
    /// diagnosis' warm-started rounds do not play (docs/ARCHITECTURE.md,
    /// "Warm starts"). `built_in_s`, the seconds `model` took to build, is
    /// counted in the fit's time.
    pub fn also_from(
        mut self,
        model: &Model,
        built_in_s: f64,
        settings: &FitSettings,
    ) -> anyhow::Result<FitRun> {
        let est = self.problem.estimation();
        anyhow::ensure!(
            model.effects() == self.problem.model.effects.as_slice()
                && model.base.family == self.problem.model.family
                && (model.base.input_mean, model.base.output_mean) == (est.u_mean, est.y_mean),
            "the second start must be the fit's own model, in the fit's coordinates"
        );
        let theta = warm_start(&self.problem, model);
        let mut problem = self.problem.clone();
        if let Some(is) = problem.model.family.switch_index() {
            problem.hold_switch_at(theta[is]);
        }
        problem.space.widen_to_hold(&theta);
        let engine = settings.start_warm(&problem, &theta)?;
        self.second = Some(ChainStart {
            start: Start { problem, engine },
        });
        self.built_in_s = built_in_s;
        Ok(self)
    }

    /// Why a run that scored no candidate ended, for its message: a stop
    /// while the chain was built says so (its searches scored candidates,
    /// the fit's did not).
    pub fn unscored(&self, stop: StopReason) -> String {
        if self.built_in_s > 0.0 {
            format!(
                "stopped ({stop:?}) while the chain was built ({:.1} s), before the fit's first \
                 start scored a candidate",
                self.built_in_s
            )
        } else {
            format!("stopped ({stop:?}) before any candidate was scored")
        }
    }

    /// A warm start's model as it was, scored as the refit is: its
    /// estimation SSE and its validation on this record. Where the refit
    /// fits the estimation half better and validates clearly worse, the
    /// estimation half does not settle the model, and the user should see
    /// both.
    pub fn start_scores(&self) -> Option<StartScores> {
        self.start.as_ref().map(|theta| StartScores {
            est_sse: self.problem.est_sse(theta),
            validation: self.problem.validate(theta),
        })
    }

    /// Runs the engine on `evaluator` to its end or a stop rule
    /// (`interrupt` raised: after the current generation), then the other
    /// starts (the switching's start at zero, the chain's warm start) where
    /// there are, every start's tries settled by the edge rule
    /// ([`settle_tries`]) before the lowest estimation SSE is kept;
    /// `checkpoint` as [`Engine::run`]. A time budget covers the whole fit,
    /// the chain's build included: each start runs in what the ones before
    /// it left, and one with nothing left does not run. The outcome's
    /// `stop` is the first start's that ended early (a budget, a target,
    /// Ctrl-C), `completed` only where every start ran to its end. Returns
    /// the outcome and the kept try's widenings. The one place a fit's starts, tries, switching
    /// levels and edge refits run: `mckibben fit`, Python's `fit`, the
    /// diagnosis' fits as `fit` makes them, `compare` and the generated
    /// cases all run their fits here.
    pub fn run(
        &mut self,
        evaluator: &mut dyn Evaluator,
        observers: &mut [&mut dyn Observer],
        interrupt: Option<&AtomicBool>,
        checkpoint: Option<&Path>,
    ) -> anyhow::Result<(Outcome, Vec<Widening>)> {
        let stops = self.engine.stops.clone();
        let left = |spent: f64| stops.time_budget_s.map(|b| (b - spent).max(0.0));
        self.engine.stops.time_budget_s = left(self.built_in_s);
        let hooks = Hooks {
            observers,
            interrupt,
            checkpoint,
        };
        let outcome = run_on(&self.problem, &mut self.engine, evaluator, hooks)?;
        // Only the first start is checkpointed: its failure to be is the fit's.
        let checkpoint_error = outcome.checkpoint_error.clone();
        let (mut outcome, mut widened) =
            settle_tries(&mut self.problem, &self.engine, outcome, &stops, evaluator)?;
        outcome.seconds += self.built_in_s;
        let mut stop = outcome.stop;
        // A later start runs where the fit was not stopped and time is left.
        let runs_on = |stop: StopReason, spent: f64| {
            if stop == StopReason::Interrupted {
                return Err(StopReason::Interrupted);
            }
            match left(spent) {
                Some(t) if t <= 0.0 => Err(StopReason::TimeBudget),
                t => Ok(t),
            }
        };
        if let Some(mut start) = self.zero.take() {
            match runs_on(stop, outcome.seconds) {
                Ok(budget) => start.engine.stops.time_budget_s = budget,
                Err(why) => {
                    let stop = stop.earliest(why);
                    return Ok(self.ended(outcome, widened, stop, checkpoint_error));
                }
            }
            let zero = start.run(evaluator, &stops, interrupt)?;
            stop = stop.earliest(zero.outcome.stop);
            let switched = Switched::of(&outcome, &zero.outcome);
            self.switched = Some(switched);
            let (evaluations, seconds) = (
                outcome.evaluations + zero.outcome.evaluations,
                outcome.seconds + zero.outcome.seconds,
            );
            if switched.kept_zero {
                (self.problem, self.engine) = (start.problem, start.engine);
                (outcome, widened) = (zero.outcome, zero.widened);
            }
            (outcome.evaluations, outcome.seconds) = (evaluations, seconds);
        }
        if let Some(ChainStart { mut start }) = self.second.take() {
            match runs_on(stop, outcome.seconds) {
                Ok(budget) => start.engine.stops.time_budget_s = budget,
                Err(why) => {
                    let stop = stop.earliest(why);
                    return Ok(self.ended(outcome, widened, stop, checkpoint_error));
                }
            }
            let Settled {
                outcome: chain,
                widened: chain_widened,
            } = start.run(evaluator, &stops, interrupt)?;
            stop = stop.earliest(chain.stop);
            let kept_chain = !chain.params.is_empty() && chain.sse < outcome.sse;
            self.built = Some(Built {
                scratch_sse: outcome.sse,
                chain_sse: chain.sse,
                kept_chain,
            });
            if kept_chain {
                (self.problem, self.engine, widened) = (start.problem, start.engine, chain_widened);
                let evaluations = outcome.evaluations + chain.evaluations;
                let seconds = outcome.seconds + chain.seconds;
                outcome = Outcome {
                    evaluations,
                    seconds,
                    ..chain
                };
            } else {
                outcome.evaluations += chain.evaluations;
                outcome.seconds += chain.seconds;
            }
        }
        Ok(self.ended(outcome, widened, stop, checkpoint_error))
    }

    /// The kept start's outcome as the fit's: why the fit ended, whether
    /// its checkpoint was written, and how far the kept start's tries agree.
    fn ended(
        &mut self,
        mut outcome: Outcome,
        widened: Vec<Widening>,
        stop: StopReason,
        checkpoint_error: Option<String>,
    ) -> (Outcome, Vec<Widening>) {
        outcome.stop = stop;
        outcome.checkpoint_error = checkpoint_error;
        let problem = &self.problem;
        self.agreement = Agreement::of(&outcome.tries, problem.est_samples()).map(|a| {
            a.with_runner_up(&outcome.tries, &outcome.params, |other, best| {
                problem.apart_on_validation(other, best)
            })
        });
        (outcome, widened)
    }
}

/// What watches a run of the engine ([`Engine::run`]): its observers, the
/// flag that interrupts it and the file it checkpoints to.
struct Hooks<'a, 'o> {
    observers: &'a mut [&'o mut dyn Observer],
    interrupt: Option<&'a AtomicBool>,
    checkpoint: Option<&'a Path>,
}

/// Runs `engine` on `problem`'s objective, scored on `evaluator`, watched
/// by `hooks`.
fn run_on(
    problem: &FitProblem,
    engine: &mut Engine<ModelChart>,
    evaluator: &mut dyn Evaluator,
    hooks: Hooks<'_, '_>,
) -> anyhow::Result<Outcome> {
    let mut objective = ModelObjective::for_problem(evaluator, problem);
    engine.run(
        &mut objective,
        hooks.observers,
        hooks.interrupt,
        hooks.checkpoint,
    )
}

/// Fits `problem` with `plan` from `seed` on `evaluator`, with no observer,
/// interrupt or checkpoint (the studies of `compare` and the generated
/// cases), as [`FitRun::run`] fits: both starts of `--switch starts` where
/// the problem has two, every try settled by the edge rule, the lowest
/// estimation SSE kept. Returns the kept start's engine and the outcome.
pub fn run_fit(
    problem: &FitProblem,
    plan: Plan,
    seed: u64,
    stops: StopRules,
    evaluator: &mut dyn Evaluator,
) -> anyhow::Result<(Engine<ModelChart>, Outcome)> {
    let engine = Engine::new(plan, problem.engine_space(), seed, stops)?;
    let mut fit = FitRun::of(problem.clone(), engine)?;
    let (outcome, _) = fit.run(evaluator, &mut [], None, None)?;
    Ok((fit.engine, outcome))
}

/// A warm start's model as it was, on the record it is refitted to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StartScores {
    /// Free-run SSE on the estimation half (`+∞` if it diverged there).
    pub est_sse: f64,
    pub validation: Validation,
}

/// The start of a warm start from `model`: its baseline's parameters in the
/// box's gauge (same outputs), and for each of the problem's effects the
/// model's value where it has that effect, else the effect's neutral value.
fn warm_start(problem: &FitProblem, model: &Model) -> Vec<f64> {
    let base = gauge_fixed(model.base.family, &model.base.params);
    let mut theta = problem.neutral_effects(&base);
    let ours = problem.model.clone();
    let theirs = model.augmented();
    let values = model.theta();
    for &e in &problem.model.effects {
        if let (Some(to), Some(from)) = (ours.offset_of(e), theirs.offset_of(e)) {
            let k = e.dim(1);
            theta[to..to + k].copy_from_slice(&values[from..from + k]);
        }
    }
    theta
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::synthetic::Synthetic;
    use crate::optim::Algorithm;
    use crate::search::{Params, Rows};

    fn settings(algo: Algorithm, pop: usize) -> FitSettings {
        FitSettings {
            algo,
            pop,
            gens: 10,
            ..FitSettings::staged(1)
        }
    }

    /// The CPU evaluator, counting the rows it scores in every fork.
    #[derive(Clone)]
    struct Counting {
        cpu: crate::eval::cpu::CpuEvaluator,
        rows: std::sync::Arc<std::sync::atomic::AtomicUsize>,
    }

    impl Evaluator for Counting {
        fn describe(&self) -> String {
            "counting".into()
        }

        fn fork(&self) -> Option<Box<dyn Evaluator + Send>> {
            Some(Box::new(self.clone()))
        }

        fn evaluate(
            &mut self,
            problem: &crate::eval::Problem,
            population: Rows<'_, Params>,
        ) -> anyhow::Result<crate::eval::Scores> {
            self.rows
                .fetch_add(population.len(), std::sync::atomic::Ordering::SeqCst);
            self.cpu.evaluate(problem, population)
        }

        fn residuals(
            &mut self,
            problem: &crate::eval::Problem,
            population: Rows<'_, Params>,
        ) -> anyhow::Result<Vec<Option<Vec<f32>>>> {
            self.rows
                .fetch_add(population.len(), std::sync::atomic::Ordering::SeqCst);
            self.cpu.residuals(problem, population)
        }
    }

    #[test]
    fn a_fit_scores_every_start_on_the_evaluator_it_is_given() {
        let data = Synthetic::new(Family::Generalized, 600, 0.05, 2);
        let what = FitTarget {
            switching: Some(Switching::Starts),
            ..FitTarget::chain(Family::Generalized, &[])
        };
        let fit = FitRun::new(
            std::slice::from_ref(&data.trace),
            &what,
            &settings(Algorithm::De, 24),
            None,
            None,
            &|_| (),
        )
        .unwrap();
        assert!(fit.zero.is_some(), "--switch starts' second start");
        let rows = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let mut counting = Counting {
            cpu: crate::eval::cpu::CpuEvaluator::new(),
            rows: rows.clone(),
        };
        let mut fit = fit;
        let (outcome, _) = fit.run(&mut counting, &mut [], None, None).unwrap();
        assert!(fit.switched.is_some(), "both starts ran");
        // Every row the engines counted, both starts', passed through it
        // (and the rows scored again that they do not count).
        let scored = rows.load(std::sync::atomic::Ordering::SeqCst) as u64;
        assert!(
            scored >= outcome.evaluations,
            "{scored} < {}",
            outcome.evaluations
        );
    }
}
