//! A muscle-model fit as `mckibben fit` asks for it: the algorithm's
//! settings with the user's overrides laid over them, checked; the plan; the
//! stop rules; and where the run starts, fresh or resumed from a checkpoint.
//!
//! The settings carry `fit`'s flags one for one and every error names the
//! flag it is about, so that the command only parses, calls and prints.
//! [`FitRun`] is the whole run on one trace, which the command calls.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use anyhow::Context as _;
use serde::Serialize;

pub use super::edge::Switched;
use super::edge::{Widening, refit_off_edges};
use super::objective::{GENERATIONS, ModelObjective, POPULATION, staged_plan};
use super::problem::FitProblem;
use super::records::Validation;
use crate::data::Trace;
use crate::eval::Evaluator;
use crate::model::coords::gauge_fixed;
use crate::model::effects::Effect;
use crate::model::{Family, Flow, Loop, Measure, Model, Switching, UserBound};
use crate::optim::engine::{Engine, Observer, Outcome, Plan, Space, StopReason, StopRules};
use crate::optim::ga::{Crossover, Mutation};
use crate::optim::mfa::{self, Distance, Lambda0Schedule, Scale};
use crate::optim::stage::Stage;
use crate::optim::{AlgoSettings, Algorithm, Streams};

/// Settings of one algorithm laid over its base settings (`None`, `false`:
/// keep the base). Each acts on its own algorithm only, but every one given
/// is checked whatever the algorithm.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// GA crossover (`--crossover`).
    pub crossover: Option<Crossover>,
    /// GA: best individuals kept unchanged (`--elitism`).
    pub elitism: Option<usize>,
    /// GA: mutation probability (`--p-mut`).
    pub p_mut: Option<f64>,
    /// GA: mutation operator (`--mutation`).
    pub mutation: Option<Mutation>,
    /// MFA: Λ0 schedule (`--mfa-lambda0`).
    pub mfa_lambda0: Option<Lambda0Schedule>,
    /// MFA: attractiveness against distance (`--mfa-distance`).
    pub mfa_distance: Option<Distance>,
    /// MFA: units of distances and walk (`--mfa-scale`).
    pub mfa_scale: Option<Scale>,
    /// MFA: attractors a firefly moves towards, 0 for all (`--mfa-attractors`).
    pub mfa_attractors: Option<usize>,
    /// MFA: the brightest attractors instead of random ones (`--mfa-brightest`).
    pub mfa_brightest: bool,
    /// MFA: start of the random walk's schedule (`--mfa-rho0`).
    pub mfa_rho0: Option<f64>,
    /// DE: share of the population x_pbest is drawn from (`--de-p-best`).
    pub de_p_best: Option<f64>,
    /// PSO: one random number for the social term (`--pso-scalar-social`).
    pub pso_scalar_social: bool,
}

impl Overrides {
    /// The algorithm-specific flags given, each with the algorithm it tunes.
    fn given(&self) -> Vec<(&'static str, Algorithm)> {
        use Algorithm::{De, Ga, Mfa, Pso};
        [
            (self.crossover.is_some(), "--crossover", Ga),
            (self.elitism.is_some(), "--elitism", Ga),
            (self.p_mut.is_some(), "--p-mut", Ga),
            (self.mutation.is_some(), "--mutation", Ga),
            (self.mfa_lambda0.is_some(), "--mfa-lambda0", Mfa),
            (self.mfa_distance.is_some(), "--mfa-distance", Mfa),
            (self.mfa_scale.is_some(), "--mfa-scale", Mfa),
            (self.mfa_attractors.is_some(), "--mfa-attractors", Mfa),
            (self.mfa_brightest, "--mfa-brightest", Mfa),
            (self.mfa_rho0.is_some(), "--mfa-rho0", Mfa),
            (self.de_p_best.is_some(), "--de-p-best", De),
            (self.pso_scalar_social, "--pso-scalar-social", Pso),
        ]
        .into_iter()
        .filter(|(given, _, _)| *given)
        .map(|(_, flag, algo)| (flag, algo))
        .collect()
    }
}

/// What a fresh fit runs: the algorithm, its size and seed, the flow, the
/// staged fit's knobs and the stop rules.
#[derive(Debug, Clone, PartialEq)]
pub struct FitSettings {
    /// Update rule of the population search (`--algo`).
    pub algo: Algorithm,
    /// Population of the global stage (`--pop`).
    pub pop: usize,
    /// Generations of the global stage (`--gens`).
    pub gens: usize,
    pub seed: u64,
    /// The thesis' flow: one search on the free run with the thesis'
    /// settings (`--thesis-flow`), instead of the staged fit.
    pub thesis_flow: bool,
    /// Islands of the staged fit's global stage (`--islands`).
    pub islands: Option<usize>,
    /// Prediction horizon of the staged fit's global stage (`--horizon`).
    pub horizon: Option<usize>,
    pub overrides: Overrides,
    /// `--target-sse`, `--time-budget`, `--stall`.
    pub stops: StopRules,
}

impl FitSettings {
    /// `mckibben fit`'s defaults: the staged fit with differential
    /// evolution at [`POPULATION`] and [`GENERATIONS`], no overrides, no
    /// early stop.
    pub fn staged(seed: u64) -> FitSettings {
        FitSettings {
            algo: Algorithm::De,
            pop: POPULATION,
            gens: GENERATIONS,
            seed,
            thesis_flow: false,
            islands: None,
            horizon: None,
            overrides: Overrides::default(),
            stops: StopRules::default(),
        }
    }

    /// The base settings (the thesis' or the staged fit's) with the
    /// overrides laid over them; `note` hears of a rule applied unasked.
    fn algo_settings(&self, family: Family, note: &dyn Fn(String)) -> anyhow::Result<AlgoSettings> {
        let o = &self.overrides;
        let mut s = if self.thesis_flow {
            self.algo.thesis_settings(family)
        } else {
            self.algo.staged_settings(self.pop)
        };
        // Every override is checked whatever the algorithm; each only acts on its own.
        if let Some(p) = o.p_mut {
            anyhow::ensure!(
                (0.0..=1.0).contains(&p),
                "--p-mut must be a probability in [0, 1] (got {p})"
            );
        }
        if let Some(e) = o.elitism {
            anyhow::ensure!(e < self.pop, "--elitism must be below --pop (got {e})");
        }
        if let Some(r) = o.mfa_rho0 {
            anyhow::ensure!(
                r.is_finite() && r >= 0.0,
                "--mfa-rho0 must be a finite step size ≥ 0 (got {r})"
            );
        }
        if let Some(p) = o.de_p_best {
            anyhow::ensure!(
                p > 0.0 && p <= 1.0,
                "--de-p-best must be in (0, 1] (got {p})"
            );
        }
        // A flag of another algorithm would be ignored: say so rather than
        // run something other than what the user asked for.
        if let Some((flag, algo)) = o.given().into_iter().find(|&(_, a)| a != self.algo) {
            anyhow::bail!(
                "{flag} tunes --algo {algo}, but this fit runs --algo {}: drop {flag} \
                 or add --algo {algo}",
                self.algo
            );
        }
        if let AlgoSettings::Ga(ga) = &mut s {
            if let Some(p) = o.p_mut {
                ga.p_mut = p;
            }
            if let Some(c) = o.crossover {
                ga.crossover = c;
            }
            if let Some(e) = o.elitism {
                ga.elitism = e;
            }
            if let Some(m) = o.mutation {
                ga.mutation = m;
            }
        }
        if let AlgoSettings::Mfa(m) = &mut s {
            if let Some(l) = o.mfa_lambda0 {
                m.lambda0 = l;
            }
            if let Some(d) = o.mfa_distance {
                m.distance = d;
            }
            if let Some(sc) = o.mfa_scale {
                m.scale = sc;
            }
            if let Some(k) = o.mfa_attractors {
                m.max_attractors = (k > 0).then_some(k);
            } else if self.thesis_flow && self.pop > mfa::ALL_PAIRS_MAX {
                m.towards_brightest();
                note(format!(
                    "the MFA's all-pairs move is O(N²·d) and takes over a second a \
                     generation above N = {}; moving each firefly towards the {} \
                     brightest instead (--mfa-attractors 0 for all pairs)",
                    mfa::ALL_PAIRS_MAX,
                    mfa::BRIGHTEST
                ));
            }
            if o.mfa_brightest {
                m.attractors = mfa::Attractors::Brightest;
            }
            if let Some(r) = o.mfa_rho0 {
                m.rho0 = r;
            }
        }
        if let AlgoSettings::Pso(pso) = &mut s
            && o.pso_scalar_social
        {
            pso.scalar_social = true;
        }
        if let (AlgoSettings::De(de), Some(p)) = (&mut s, o.de_p_best) {
            de.p_best = p;
        }
        Ok(s)
    }

    /// The plan of a fresh fit of `problem`.
    fn plan(&self, problem: &FitProblem, note: &dyn Fn(String)) -> anyhow::Result<Plan> {
        let min = self.algo.min_population();
        anyhow::ensure!(
            self.pop >= min,
            "--pop must be at least {min} for --algo {} (got {})",
            self.algo,
            self.pop
        );
        let settings = self.algo_settings(problem.model.family, note)?;
        if self.thesis_flow {
            return Ok(Plan::thesis(settings, self.pop, self.gens));
        }
        let mut plan = staged_plan(problem, settings, self.pop, self.gens);
        if let Some(global) = plan.global.as_mut() {
            if let Some(k) = self.islands {
                anyhow::ensure!(k >= 1, "--islands must be at least 1");
                anyhow::ensure!(
                    self.pop / k >= min,
                    "--islands {k} leaves {} individuals an island of --pop {}; --algo {} needs at least {min}",
                    self.pop / k,
                    self.pop,
                    self.algo
                );
                global.islands = k;
            }
            if let Some(h) = self.horizon {
                anyhow::ensure!(h >= 1, "--horizon must be at least 1 sample");
                global.measure = Measure::Ahead { horizon: h };
            }
        }
        Ok(plan)
    }

    /// A warm start from the canonical `start`: the free-run stage from
    /// `start` and a cloud around it ([`Space::around`]), then the polish;
    /// no global search, so the fit refines the basin it is given (a global
    /// search finds other basins, and where the estimation data do not
    /// settle the model some of those fit the estimation half better and
    /// validate worse: docs/ARCHITECTURE.md, "Warm starts").
    pub fn start_warm(&self, problem: &FitProblem, start: &[f64]) -> anyhow::Result<Engine> {
        let mut plan = self.plan(problem, &|_| ())?;
        plan.global = None;
        let space = Space::from(&problem.space);
        let n = plan.free_run.as_ref().map_or(1, |f| f.population);
        // The cloud is the free-run stage's first population: its draws
        // before the first generation.
        let streams = Streams::new(self.seed, Stage::FreeRun, 0);
        let rows = space.around(start, n, &streams);
        Ok(Engine::new(plan, space, self.seed, self.stops()?)?.with_initial(&rows))
    }

    /// The stop rules, checked.
    fn stops(&self) -> anyhow::Result<StopRules> {
        if let Some(t) = self.stops.time_budget_s {
            anyhow::ensure!(
                t >= 0.0,
                "--time-budget must be at least 0 seconds (got {t})"
            );
        }
        Ok(self.stops.clone())
    }

    /// The engine to run on `problem`: resumed from `checkpoint` when that file
    /// exists, else fresh. A checkpoint holds the whole future of its run,
    /// so its plan, N, G, seed and settings win over these and it resumes to
    /// the identical result; only the stop rules are taken from here, since
    /// when to stop is the caller's to choose again. `note` hears of the
    /// resumption and of rules applied unasked.
    pub fn start(
        &self,
        problem: &FitProblem,
        checkpoint: Option<&Path>,
        note: &dyn Fn(String),
    ) -> anyhow::Result<Engine> {
        let space = Space::from(&problem.space);
        if let Some(path) = checkpoint.filter(|p| p.exists()) {
            let mut engine = Engine::load(path)?;
            anyhow::ensure!(
                engine.space.names == space.names,
                "checkpoint {} fits the parameters {:?}, not those of a {} model: pass the --model it was made with",
                path.display(),
                engine.space.names,
                problem.model.family
            );
            engine.stops = self.stops()?;
            note(format!(
                "resuming at generation {} of {} from {} (its plan, N, G, seed and settings win)",
                engine.generation(),
                engine.plan.generations(),
                path.display()
            ));
            return Ok(engine);
        }
        Engine::new(self.plan(problem, note)?, space, self.seed, self.stops()?)
    }
}

/// What a fit identifies on a trace: the family, its effects and its search
/// box (the joint flow's; the thesis' flow, `FitSettings::thesis_flow`,
/// takes its own).
#[derive(Debug, Clone, PartialEq)]
pub struct FitBox {
    pub family: Family,
    /// Effect stages after the family, in chain order (`--effects`).
    pub effects: Vec<Effect>,
    /// Also fit the Bouc-Wen exponent n (`--free-n`).
    pub free_n: bool,
    /// Loop shapes the box admits (`--loop`).
    pub loop_shape: Loop,
    /// Where a generalized fit lets its sign terms switch (`--switch`).
    pub switching: Switching,
    /// The user's bounds and fixed values (`--bound`, `--fix`), an effect's
    /// as `effect.param`.
    pub bounds: Vec<UserBound>,
}

impl FitBox {
    /// `family` followed by `effects` in the box `fit --effects` searches
    /// by default: n held at 1, bounded loops, the default switching, no
    /// user bounds.
    pub fn chain(family: Family, effects: &[Effect]) -> FitBox {
        FitBox {
            family,
            effects: effects.to_vec(),
            free_n: false,
            loop_shape: Loop::Bounded,
            switching: Switching::default(),
            bounds: Vec::new(),
        }
    }
}

/// A fit of one trace as `mckibben fit` runs it: the problem, and the engine
/// that runs on it.
#[derive(Debug, Clone)]
pub struct FitRun {
    pub problem: FitProblem,
    pub engine: Engine,
    /// A warm start's model as it was, in the problem's gauge (same outputs):
    /// what the refit is measured against ([`FitRun::start_scores`]).
    pub start: Option<Vec<f64>>,
    /// A second start run after the engine ([`FitRun::also_from`]): its problem
    /// (the box widened to hold it), its warm-start engine and the seconds
    /// its model took to build.
    second: Option<(FitProblem, Engine, f64)>,
    /// Which of the two was kept, once [`FitRun::run`] has run both.
    pub built: Option<Built>,
    /// The default switching's second start ([`FitProblem::at_zero`]): the same
    /// fit with the generalized switching level held at the sensor's zero,
    /// run after the engine, before any [`FitRun::also_from`] start.
    zero: Option<(FitProblem, Engine)>,
    /// Which of the switching starts was kept, once [`FitRun::run`] has run both.
    pub switched: Option<Switched>,
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
    /// The problem of `what` on `trace` (its box widened on return of
    /// [`FitRun::run`]) and the engine `settings` start on it: a warm start
    /// from `start` ([`FitSettings::start_warm`], the generalized switching
    /// level held at the start's own unless `what` says otherwise), else
    /// fresh or resumed from `checkpoint` ([`FitSettings::start`]), and a
    /// fresh second start where the default switching has one
    /// ([`FitProblem::at_zero`]).
    pub fn new(
        trace: &Trace,
        what: &FitBox,
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
        if let Some(m) = start {
            m.check_data(trace).context("the start model")?;
        }
        let problem = FitProblem::with_box(
            trace,
            what.family,
            flow,
            None,
            what.free_n,
            (what.loop_shape, what.switching),
            &what.bounds,
        )
        .and_then(|t| match start {
            Some(m) => t.in_coordinates_of(trace, m),
            None => Ok(t),
        })
        .and_then(|t| t.with_effects(&what.effects, &what.bounds))
        .with_context(|| format!("cannot fit {}", trace.source))?;
        let mut problem = problem;
        let start = start.map(|m| warm_start(&problem, m));
        if let (Some(theta), Some(is)) = (&start, what.family.switch_index()) {
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
        let engine = match &start {
            Some(theta) => settings.start_warm(&problem, theta)?,
            None => settings.start(&problem, checkpoint, note)?,
        };
        // A fresh fit of its own (the checkpoint holds the first start's).
        let zero = match (&start, problem.at_zero()) {
            (None, Some(zero)) => {
                let engine = settings.start(&zero, None, &|_| ())?;
                Some((zero, engine))
            }
            _ => None,
        };
        Ok(FitRun {
            problem,
            engine,
            start,
            second: None,
            built: None,
            zero,
            switched: None,
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
        self.second = Some((problem, engine, built_in_s));
        Ok(self)
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

    /// The same fit, every start of it scored on `evaluator` (the CPU
    /// batch path until then): the backend the command asked for.
    pub fn scored_on(mut self, evaluator: Box<dyn Evaluator + Send>) -> FitRun {
        self.problem = self.problem.scored_on(evaluator);
        if let Some((zero, _)) = self.zero.as_mut() {
            zero.score_like(&self.problem);
        }
        if let Some((second, _, _)) = self.second.as_mut() {
            second.score_like(&self.problem);
        }
        self
    }

    /// Runs the engine on the problem's evaluator ([`FitRun::scored_on`]) to
    /// its end or a stop rule (`interrupt` raised: after the current
    /// generation), then the edge rule ([`refit_off_edges`]); `checkpoint`
    /// as [`Engine::run`]. Returns the outcome and the widenings.
    pub fn run(
        &mut self,
        observers: &mut [&mut dyn Observer],
        interrupt: Option<&AtomicBool>,
        checkpoint: Option<&Path>,
    ) -> anyhow::Result<(Outcome, Vec<Widening>)> {
        let mut outcome = run_on(
            &self.problem,
            &mut self.engine,
            observers,
            interrupt,
            checkpoint,
        )?;
        if let Some((problem, mut engine)) = self.zero.take()
            && outcome.stop != StopReason::Interrupted
        {
            let zero = run_on(&problem, &mut engine, &mut [], interrupt, None)?;
            let switched = Switched::of(&outcome, &zero);
            self.switched = Some(switched);
            let (evaluations, seconds) = (
                outcome.evaluations + zero.evaluations,
                outcome.seconds + zero.seconds,
            );
            if switched.kept_zero {
                (self.problem, self.engine, outcome) = (problem, engine, zero);
            }
            (outcome.evaluations, outcome.seconds) = (evaluations, seconds);
        }
        if let Some((problem, mut engine, built_in_s)) = self.second.take()
            && outcome.stop != StopReason::Interrupted
        {
            outcome.seconds += built_in_s;
            let chain = run_on(&problem, &mut engine, &mut [], interrupt, None)?;
            let kept_chain = !chain.params.is_empty() && chain.sse < outcome.sse;
            self.built = Some(Built {
                scratch_sse: outcome.sse,
                chain_sse: chain.sse,
                kept_chain,
            });
            if kept_chain {
                (self.problem, self.engine) = (problem, engine);
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
        let stops = self.engine.stops.clone();
        self.problem.scorer().run(|evaluator| {
            refit_off_edges(&mut self.problem, &self.engine, outcome, &stops, evaluator)
        })
    }
}

/// Runs `engine` on `problem`'s objective and evaluator.
fn run_on(
    problem: &FitProblem,
    engine: &mut Engine,
    observers: &mut [&mut dyn Observer],
    interrupt: Option<&AtomicBool>,
    checkpoint: Option<&Path>,
) -> anyhow::Result<Outcome> {
    problem.with_evaluator(|evaluator| {
        let mut objective = ModelObjective::for_problem(evaluator, problem);
        engine.run(&mut objective, observers, interrupt, checkpoint)
    })
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
    use std::cell::RefCell;

    use super::*;
    use crate::fit::synthetic::Synthetic;
    use crate::model::Flow;

    fn settings(algo: Algorithm, pop: usize) -> FitSettings {
        FitSettings {
            algo,
            pop,
            gens: 10,
            ..FitSettings::staged(1)
        }
    }

    #[test]
    fn every_override_is_checked_whatever_the_algorithm_and_errors_name_the_flag() {
        let mut s = settings(Algorithm::De, 40);
        s.overrides.p_mut = Some(2.0);
        let e = s.algo_settings(Family::Classic, &|_| ()).unwrap_err();
        assert!(e.to_string().starts_with("--p-mut"), "{e}");
        let mut s = settings(Algorithm::Ga, 40);
        s.stops.time_budget_s = Some(-1.0);
        assert!(
            s.stops()
                .unwrap_err()
                .to_string()
                .starts_with("--time-budget")
        );
    }

    #[test]
    fn a_flag_of_another_algorithm_is_an_error_that_names_both() {
        let mut s = settings(Algorithm::Pso, 40);
        s.overrides.p_mut = Some(0.3);
        let e = s.algo_settings(Family::Classic, &|_| ()).unwrap_err();
        let e = e.to_string();
        assert!(e.starts_with("--p-mut tunes --algo ga"), "{e}");
        assert!(e.contains("runs --algo pso"), "{e}");
        let mut s = settings(Algorithm::Ga, 40);
        s.overrides.p_mut = Some(0.3);
        s.overrides.mfa_brightest = true;
        let e = s.algo_settings(Family::Classic, &|_| ()).unwrap_err();
        assert!(e.to_string().starts_with("--mfa-brightest"), "{e}");
        s.overrides.mfa_brightest = false;
        let Ok(AlgoSettings::Ga(ga)) = s.algo_settings(Family::Classic, &|_| ()) else {
            panic!("a GA with its own flag");
        };
        assert_eq!(ga.p_mut, 0.3);
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
            population: &[f64],
        ) -> anyhow::Result<crate::eval::Scores> {
            let rows = population.len() / problem.dim();
            self.rows
                .fetch_add(rows, std::sync::atomic::Ordering::SeqCst);
            self.cpu.evaluate(problem, population)
        }

        fn residuals(
            &mut self,
            problem: &crate::eval::Problem,
            population: &[f64],
        ) -> anyhow::Result<Vec<Option<Vec<f32>>>> {
            let rows = population.len() / problem.dim();
            self.rows
                .fetch_add(rows, std::sync::atomic::Ordering::SeqCst);
            self.cpu.residuals(problem, population)
        }
    }

    #[test]
    fn a_fit_scores_every_start_on_the_evaluator_it_is_given() {
        let data = Synthetic::new(Family::Generalized, 600, 0.05, 2);
        let what = FitBox::chain(Family::Generalized, &[]);
        let fit = FitRun::new(
            &data.trace,
            &what,
            &settings(Algorithm::De, 24),
            None,
            None,
            &|_| (),
        )
        .unwrap();
        assert!(fit.zero.is_some(), "the default switching's second start");
        let rows = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let counting = Counting {
            cpu: crate::eval::cpu::CpuEvaluator::new(),
            rows: rows.clone(),
        };
        let mut fit = fit.scored_on(Box::new(counting));
        let (outcome, _) = fit.run(&mut [], None, None).unwrap();
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

    #[test]
    fn the_thesis_flow_caps_a_large_swarm_and_says_so() {
        let data = Synthetic::new(Family::Classic, 600, 0.05, 1);
        let problem =
            FitProblem::new(&data.trace, Family::Classic, Flow::Thesis, None, false).unwrap();
        let mut s = settings(Algorithm::Mfa, mfa::ALL_PAIRS_MAX + 1);
        s.thesis_flow = true;
        let notes = RefCell::new(Vec::new());
        let plan = s.plan(&problem, &|n| notes.borrow_mut().push(n)).unwrap();
        let Some(AlgoSettings::Mfa(m)) = plan.global.map(|g| g.settings) else {
            panic!("an MFA plan");
        };
        assert_eq!(m.max_attractors, Some(mfa::BRIGHTEST));
        assert_eq!(notes.borrow().len(), 1);
        s.overrides.mfa_attractors = Some(0);
        notes.borrow_mut().clear();
        s.plan(&problem, &|n| notes.borrow_mut().push(n)).unwrap();
        assert!(notes.borrow().is_empty());
    }
}
