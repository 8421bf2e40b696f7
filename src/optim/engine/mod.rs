//! The fitting engine: the one run loop every command fits parameters with
//! (`fit`, `compare`, `diagnose`, `validate boucwen`, the PID tuning).
//!
//! A fit is a [`Plan`] — a global population search, a free-run stage and a
//! Levenberg–Marquardt polish, each optional (see [`plan`] for why) — run
//! over an [`Objective`] that scores whole populations at once (the batch
//! evaluator, on the CPU or a GPU). The engine owns what every fit needs
//! around the update rules:
//!
//! - **Stopping**: each population stage ends after its generations `G`
//!   (populations evaluated, the initial one included) or when it stalls; the
//!   whole fit stops at a target SSE, a time budget or Ctrl-C, keeping the
//!   best so far.
//! - **Costs**: NaN and ±∞ rank as +∞ (a diverged candidate), never
//!   poisoning selection or statistics.
//! - **History**: one record per generation and per polish start.
//! - **Checkpoints**: an [`Engine`] holds everything its future depends on —
//!   the stage and its generation, the optimizer's state, the history, the
//!   best so far — and nothing else, so a checkpoint resumes to the
//!   bit-identical result. (A polish interrupted half-way is redone from
//!   its start: it is deterministic and short.)
//! - **Costs made visible**: each stage's summary holds the seconds spent
//!   inside the evaluator's calls beside its wall time, so the share of the
//!   engine's own work (updates, embedding, selection) can be read off any
//!   run.
//! - **Tries**: the plan runs as independent tries ([`Plan::tries`]), each
//!   with its own seed and state, in lock-step: every generation, the rows
//!   of every try that share a measure are scored in one call, and the
//!   polish's starts of every try share its calls where calls pay a round
//!   trip. A try's arithmetic does not depend on the others, so a run of
//!   more tries holds the tries of a run of fewer, bit for bit, and ends at
//!   an SSE no higher (the stop rules of the whole fit aside).
//!
//! Every random draw comes from the [`Streams`](super::Streams) of the try's seed, the stage
//! and its generation, one stream per individual: the update rules run row
//! by row in parallel (rayon), and a fit is a pure function of its seed
//! whatever the thread count or backend. No generator is part of the state:
//! the stage and its generation say where every stream stands.

/// The most generations a stage may plan: a search that long runs for
/// days on any population, so a larger count is a typo (a count near a
/// word's end wrapped once the initial population was added to it).
pub const MAX_GENERATIONS: usize = 1_000_000_000;

/// Why a stage cannot run `generations` generations (none where it can):
/// the one check of every flag and argument that counts them.
pub fn generations_refused(generations: usize) -> Option<String> {
    match generations {
        0 => Some("at least 1: the first generation is the drawn population".into()),
        g if g > MAX_GENERATIONS => Some(format!(
            "at most {MAX_GENERATIONS}: a search that long would run for days"
        )),
        _ => None,
    }
}

pub mod plan;
mod polish;
mod population;
pub mod space;
mod tries;

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::argmin;
use super::history::{GenerationRecord, History};
pub use super::stage::Stage;
use super::streams::try_seed;
use crate::data::write_atomic;
use crate::search::{Coords, Measure, Params, Population, Rows};
use polish::CutPolish;

pub use plan::{FreeRun, Global, Plan, Polish, Refine, TrySize};
pub use space::{Canonical, Chart, Space, Stepwise};
use tries::{Members, Scored, Step, Try, keep_lowest};

/// What a fit minimises: the costs of whole populations at once.
pub trait Objective {
    /// What scores, for the user ("cpu (32-lane batches on 2 threads)").
    fn describe(&self) -> String;

    /// The cost of every row under `measure`; lower is better, NaN and ±∞
    /// for a diverged candidate. An objective with a single measure ignores
    /// it.
    fn costs(&mut self, rows: Rows<'_, Params>, measure: Measure) -> anyhow::Result<Vec<f32>>;

    /// Starts [`Objective::costs`] of `rows` and returns before they are
    /// read where the scoring runs elsewhere (a device), so that the engine
    /// updates other islands meanwhile; [`Objective::collect`] then gives
    /// the costs, the same bits. By default it scores here.
    fn submit(&mut self, rows: Rows<'_, Params>, measure: Measure) -> anyhow::Result<Ticket> {
        Ok(Ticket::new(self.costs(rows, measure)?))
    }

    /// The costs of a [`Objective::submit`] of `rows` under `measure` (the
    /// same rows and measure it was handed).
    fn collect(
        &mut self,
        ticket: Ticket,
        rows: Rows<'_, Params>,
        measure: Measure,
    ) -> anyhow::Result<Vec<f32>> {
        let _ = (rows, measure);
        ticket.take()
    }

    /// The residuals of every row under `measure` (in `f32`, as the
    /// evaluators simulate), `None` where it diverges: what the polish
    /// differentiates. Only least-squares objectives have them.
    fn residuals(
        &mut self,
        rows: Rows<'_, Params>,
        measure: Measure,
    ) -> anyhow::Result<Vec<Option<Vec<f32>>>> {
        let _ = (rows, measure);
        anyhow::bail!(
            "{} is not a least-squares objective, so a fit of it cannot end with a polish",
            self.describe()
        )
    }

    /// Seconds spent so far inside the calls of the evaluator it scores on,
    /// where it does more than score (an objective may also admit rows or
    /// sum experiments); `None` where scoring is all it
    /// does, and the engine then counts its calls whole.
    fn evaluator_seconds(&self) -> Option<f64> {
        None
    }

    /// Seconds so far of the evaluator's kernels on the device's clock
    /// ([`crate::eval::Evaluator::kernel_seconds`], summed over its calls);
    /// `None` where a call had no device time (the CPU, an adapter without
    /// timestamp queries).
    fn kernel_seconds(&self) -> Option<f64> {
        None
    }

    /// Whether its calls pay a round trip each (a GPU evaluator's,
    /// [`crate::eval::Evaluator::round_trips`]): then the polish's starts
    /// share its calls, each round one call for all of them.
    fn round_trips(&self) -> bool {
        false
    }

    /// `n` objectives of their own that give the same numbers, one for each
    /// group of polish starts, so that the groups run side by side where
    /// the scoring is local (the CPU's evaluator forks,
    /// [`crate::eval::Evaluator::fork`]); `None` (the default) where the
    /// groups take turns on this one.
    fn forks(&self, n: usize) -> Option<Vec<Box<dyn Fork + '_>>> {
        let _ = n;
        None
    }
}

/// One thread's copy of an objective ([`Objective::forks`]).
pub trait Fork: Send {
    /// Runs `work` on an objective of its own that gives the same numbers
    /// as the one it was forked from.
    fn run(
        &mut self,
        work: &mut dyn FnMut(&mut dyn Objective) -> anyhow::Result<()>,
    ) -> anyhow::Result<()>;
}

/// Costs on their way ([`Objective::submit`]): whatever the objective needs
/// to finish them.
pub struct Ticket(Box<dyn std::any::Any>);

impl Ticket {
    pub fn new<T: 'static>(value: T) -> Ticket {
        Ticket(Box::new(value))
    }

    /// What [`Ticket::new`] was given, as the objective that made it knows it.
    pub fn take<T: 'static>(self) -> anyhow::Result<T> {
        self.0
            .downcast()
            .map(|b| *b)
            .map_err(|_| anyhow::anyhow!("a ticket of another objective"))
    }
}

/// When the whole fit stops early (each stage's own length is in the [`Plan`]).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct StopRules {
    /// Stop once the best free-run SSE is at or below this.
    pub target_sse: Option<f64>,
    /// Stop after this many seconds of wall-clock time (makes the result
    /// depend on the machine; off by default).
    pub time_budget_s: Option<f64>,
    /// End a population stage when its best cost has not improved by more
    /// than `stall_tolerance` (relative) for this many generations.
    pub stall_generations: Option<usize>,
    pub stall_tolerance: f64,
}

/// Why the fit ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StopReason {
    /// Every stage of the plan ran.
    Completed,
    TargetSse,
    TimeBudget,
    /// The stop flag was raised (Ctrl-C).
    Interrupted,
}

impl StopReason {
    /// Why a run of several parts ended: this part's reason where it ended
    /// early, else `then`'s, so that a run cut short anywhere says so.
    pub fn earliest(self, then: StopReason) -> StopReason {
        match self {
            StopReason::Completed => then,
            early => early,
        }
    }
}

/// Why a stage ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StageEnd {
    Generations,
    Stalled,
    /// The polish ran every start.
    Polished,
    /// A stop rule of the whole fit ended this population stage early
    /// (`Outcome::stop` says which).
    CutShort,
}

/// What one stage did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageSummary {
    pub stage: Stage,
    pub measure: Measure,
    /// Generations (population stages) or starts (polish).
    pub steps: usize,
    pub evaluations: u64,
    pub seconds: f64,
    /// Of `seconds`, those spent inside the evaluator's scoring calls: the
    /// rest is the engine's own work (updates, embedding, selection, the
    /// polish's linear algebra).
    #[serde(default)]
    pub evaluator_seconds: f64,
    /// Of `evaluator_seconds`, the kernels' own time on the device's clock;
    /// `None` where the evaluator has no device clock.
    #[serde(default)]
    pub kernel_seconds: Option<f64>,
    /// The stage's best cost under its measure.
    #[serde(with = "super::inf_serde::one_f64")]
    pub best_cost: f64,
    pub ended: StageEnd,
}

/// The result of a fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    /// Canonical parameter vector of the best candidate (empty if every
    /// candidate diverged).
    pub params: Vec<f64>,
    /// Its free-run SSE (`+∞` if every candidate diverged).
    pub sse: f64,
    pub evaluations: u64,
    /// Generations of the population stages.
    pub generations: usize,
    pub seconds: f64,
    pub stop: StopReason,
    pub stages: Vec<StageSummary>,
    /// Each try's best, in the order of the tries (one for a plan of one
    /// try): canonical parameters (empty where every candidate of the try
    /// diverged) and free-run SSE.
    #[serde(default)]
    pub tries: Vec<TryEnd>,
    /// Why the last checkpoint could not be written, where it could not
    /// (a full disk): the fit ran on, its result whole, but it cannot be
    /// resumed from there.
    #[serde(skip)]
    pub checkpoint_error: Option<String>,
}

/// Where one try ended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TryEnd {
    pub params: Vec<f64>,
    #[serde(with = "super::inf_serde::one_f64")]
    pub sse: f64,
    /// Where the plan's refining rounds ran out while this try's last
    /// round still lowered its SSE by more than [`Refine::gain`]: that
    /// round's share. More rounds would have gone on.
    #[serde(default)]
    pub cut_gain: Option<f64>,
}

/// Sees every record as it is made (progress bars, logs).
pub trait Observer {
    /// `planned` is the plan's number of generations.
    fn record(&mut self, record: &GenerationRecord, planned: usize);
}

/// The observers of a step and how far into the history they have heard:
/// a long step (a polish of many starts, in waves) tells them as it goes,
/// so that a progress bar moves and an observer that watches for Ctrl-C
/// (Python's) is asked between waves, not only once the step is done.
struct Heard<'a, 'b> {
    observers: &'a mut [&'b mut dyn Observer],
    planned: usize,
    upto: usize,
}

impl Heard<'_, '_> {
    /// Tells every observer the history's records it has not heard yet.
    fn tell(&mut self, history: &History) {
        let records = &history.records;
        // A polish cut short rolls its records back: nothing new then.
        for record in records.get(self.upto..).unwrap_or_default() {
            for o in self.observers.iter_mut() {
                o.record(record, self.planned);
            }
        }
        self.upto = self.upto.max(records.len());
    }
}

/// A fit in progress (serialisable: a checkpoint is this value as JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Engine<C = Canonical> {
    pub plan: Plan,
    pub space: Space<C>,
    pub seed: u64,
    pub stops: StopRules,
    /// What the caller fits, as it names it (a digest of its data): the
    /// engine never reads it; a caller resuming a checkpoint compares it
    /// with its own. `None` in checkpoints written before it was kept.
    #[serde(default)]
    pub subject: Option<String>,
    /// Free-coordinate rows the first try's first stage starts from.
    initial: Vec<f64>,
    /// Index of the current step in [`Engine::steps`].
    cursor: usize,
    /// The tries, each with its own seed.
    tries: Vec<Try>,
    /// Generations of the current stage so far (the most of any try).
    stage_steps: usize,
    stage_start_evaluations: u64,
    stage_start_seconds: f64,
    #[serde(default)]
    stage_start_evaluator_seconds: f64,
    #[serde(default)]
    stage_start_kernel_seconds: Option<f64>,
    pub history: History,
    evaluations: u64,
    /// Seconds spent before the last resume.
    seconds_before: f64,
    /// Seconds spent inside the evaluator's calls, all stages.
    #[serde(default)]
    evaluator_seconds: f64,
    /// Of those, the kernels' on the device's clock; `None` once a call had
    /// no device time.
    #[serde(default)]
    kernel_seconds: Option<f64>,
    summaries: Vec<StageSummary>,
    #[serde(skip)]
    started: Option<Instant>,
    /// The canonical rows of the generation being scored, every island's in
    /// turn: one buffer, refilled in place every generation. Scratch, not state.
    #[serde(skip)]
    canonical: Option<Population<Params>>,
    /// The free coordinates the islands ask for, the same way.
    #[serde(skip)]
    asked: Option<Population<Coords>>,
}

impl<C: Chart> Engine<C> {
    /// A fit of `plan` over `space`.
    pub fn new(plan: Plan, space: Space<C>, seed: u64, stops: StopRules) -> anyhow::Result<Self> {
        anyhow::ensure!(
            !space.free().is_empty(),
            "the search space has no free parameter (every lower bound equals its upper bound)"
        );
        anyhow::ensure!(plan.tries >= 1, "a plan runs at least one try");
        if let Some(g) = &plan.global {
            let min = g.algorithm().min_population();
            anyhow::ensure!(
                g.population >= min,
                "{} needs a population of at least {min} (got {})",
                g.algorithm(),
                g.population
            );
            if let Some(why) = generations_refused(g.generations) {
                anyhow::bail!("{} generations: {why}", g.generations);
            }
            anyhow::ensure!(
                g.islands >= 1 && g.population / g.islands >= min,
                "{} islands of a population of {} leave fewer than {min} individuals an island ({}'s minimum)",
                g.islands,
                g.population,
                g.algorithm()
            );
        }
        let min = FreeRun::ALGORITHM.min_population();
        if let Some(f) = &plan.free_run {
            anyhow::ensure!(
                f.population / plan.islands() >= min && f.generations >= 1,
                "the free-run stage ({}) needs at least {min} individuals an island and one generation",
                FreeRun::ALGORITHM
            );
        }
        if let Some(r) = &plan.refine {
            anyhow::ensure!(
                r.population >= min && r.generations >= 1,
                "a refining round ({}) needs at least {min} individuals and one generation",
                FreeRun::ALGORITHM
            );
        }
        anyhow::ensure!(
            plan.sizes.is_empty() || plan.sizes.len() == plan.tries,
            "a plan that sizes its tries sizes each of them ({} sizes for {} tries)",
            plan.sizes.len(),
            plan.tries
        );
        for size in &plan.sizes {
            anyhow::ensure!(
                plan.global
                    .as_ref()
                    .is_none_or(|g| { size.global / g.islands >= g.algorithm().min_population() })
                    && plan
                        .free_run
                        .as_ref()
                        .is_none_or(|_| size.free_run / plan.islands() >= min)
                    && plan.refine.as_ref().is_none_or(|_| size.refine >= min),
                "a try of {} ({} in the free-run stage, {} a refining round) leaves an island or \
                 a round below its algorithm's smallest population",
                size.global,
                size.free_run,
                size.refine
            );
        }
        anyhow::ensure!(
            plan.global.is_some() || plan.free_run.is_some() || plan.polish.is_some(),
            "the plan has no stage"
        );
        Ok(Engine {
            history: History::new(space.canonical_names()),
            tries: (0..plan.tries)
                .map(|t| Try::new(try_seed(seed, t)))
                .collect(),
            plan,
            space,
            seed,
            stops,
            subject: None,
            initial: Vec::new(),
            cursor: 0,
            stage_steps: 0,
            stage_start_evaluations: 0,
            stage_start_seconds: 0.0,
            stage_start_evaluator_seconds: 0.0,
            stage_start_kernel_seconds: Some(0.0),
            evaluations: 0,
            seconds_before: 0.0,
            evaluator_seconds: 0.0,
            kernel_seconds: Some(0.0),
            summaries: Vec::new(),
            started: None,
            canonical: None,
            asked: None,
        })
    }

    /// Starts the first try's first stage from these canonical rows (a warm
    /// start from known models): the first members of the first population,
    /// or the polish's starts when the plan is a polish alone. Clamped into
    /// the box.
    pub fn with_initial(mut self, canonical: Rows<'_, Params>) -> Self {
        let mut rows = self.space.project(canonical);
        let bounds = self.space.bounds();
        for row in rows.iter_mut() {
            bounds.clamp(row);
        }
        self.initial = rows.into_flat();
        self
    }

    /// Generations of the population stages so far.
    pub fn generation(&self) -> usize {
        self.history
            .records
            .iter()
            .filter(|r| r.stage != Stage::Polish)
            .count()
    }

    /// Best free-run SSE so far over every try, and its canonical parameters.
    pub fn best(&self) -> Option<(&[f64], f64)> {
        self.overall_best().map(|b| (b.params.as_slice(), b.cost))
    }

    fn elapsed(&self) -> f64 {
        self.seconds_before + self.started.map_or(0.0, |t| t.elapsed().as_secs_f64())
    }

    /// What island `i` of `stage` minimises: with a horizon ladder, the
    /// global stage's horizon times 4^i, the free run once that reaches the
    /// longest experiment, and the free run on the last island.
    fn island_measure(&self, stage: Stage, i: usize) -> Measure {
        match (stage, &self.plan.global, self.measure(stage)) {
            (Stage::Global, Some(g), Measure::Ahead { horizon }) if g.ladder => {
                let h = horizon.saturating_mul(4usize.saturating_pow(i as u32));
                if h >= g.longest || (i > 0 && i + 1 == g.islands) {
                    Measure::FreeRun
                } else {
                    Measure::Ahead { horizon: h }
                }
            }
            (_, _, m) => m,
        }
    }

    fn measure(&self, stage: Stage) -> Measure {
        match (stage, &self.plan.global) {
            (Stage::Global, Some(g)) => g.measure,
            _ => Measure::FreeRun,
        }
    }

    /// Runs until every stage ran or a stop rule holds. `interrupt` (Ctrl-C)
    /// stops cleanly after the current generation or polish iteration;
    /// `checkpoint` is rewritten every ten seconds and when the fit stops;
    /// a write that fails does not stop the fit (its result is whole) and
    /// is reported in [`Outcome::checkpoint_error`] where the last one failed.
    pub fn run(
        &mut self,
        objective: &mut dyn Objective,
        observers: &mut [&mut dyn Observer],
        interrupt: Option<&AtomicBool>,
        checkpoint: Option<&Path>,
    ) -> anyhow::Result<Outcome> {
        const CHECKPOINT_EVERY_S: f64 = 10.0;
        self.started.get_or_insert_with(Instant::now);
        let planned = self.planned_generations();
        let mut last_save = Instant::now();
        let mut checkpoint_error = None;
        // What a polish cut short did: not part of the state (see `polish`).
        let mut interim: Option<CutPolish> = None;
        let stop = loop {
            let cut_best = interim.as_ref().and_then(|c| c.best.as_ref());
            if let Some(reason) = self.should_stop(interrupt, cut_best.map(|(_, s)| s)) {
                break reason;
            }
            let Some(step) = self.step() else {
                break StopReason::Completed;
            };
            let mut heard = Heard {
                observers: &mut *observers,
                planned,
                upto: self.history.records.len(),
            };
            match step {
                Step::Global | Step::FreeRun | Step::Refine(_) | Step::Level(_) => {
                    self.step_population(objective, step)?
                }
                Step::Polish | Step::RefinePolish(_) | Step::LevelPolish(_) => {
                    interim = self.polish(objective, step, interrupt, &mut heard)?
                }
            }
            heard.tell(&self.history);
            if let Some(path) = checkpoint
                && last_save.elapsed().as_secs_f64() >= CHECKPOINT_EVERY_S
            {
                checkpoint_error = self.save(path).err().map(|e| format!("{e:#}"));
                last_save = Instant::now();
            }
        };
        if let Some(path) = checkpoint {
            checkpoint_error = self.save(path).err().map(|e| format!("{e:#}"));
        }
        let mut best = self.overall_best().cloned();
        if stop != StopReason::Completed {
            let cut_polish = interim.as_ref().and_then(|c| c.best.as_ref());
            for candidate in [
                cut_polish.map(|(_, s)| s.clone()),
                self.best_so_far(objective)?,
            ]
            .into_iter()
            .flatten()
            {
                if best.as_ref().is_none_or(|b| candidate.cost < b.cost) {
                    best = Some(candidate);
                }
            }
        }
        // A population stage a stop rule cut short is reported too, but not
        // kept in the state: a resumed fit goes on with it. (A polish cut
        // short is not: its steps are rolled back, to be redone on resume,
        // and only its best point is kept, in `interim`.)
        let mut stages = self.summaries.clone();
        if let Some(stage) = self.stage()
            && stage != Stage::Polish
            && self.tries.iter().any(|t| !t.optimizers.is_empty())
        {
            stages.push(self.summary(stage, StageEnd::CutShort));
        }
        let finished = stop == StopReason::Completed;
        Ok(Outcome {
            params: best.as_ref().map_or(Vec::new(), |b| b.params.clone()),
            sse: best.as_ref().map_or(f64::INFINITY, |b| b.cost),
            evaluations: self.evaluations + interim.as_ref().map_or(0, |c| c.evaluations),
            generations: self.generation(),
            seconds: self.elapsed(),
            stop,
            stages,
            tries: self
                .tries
                .iter()
                .enumerate()
                .map(|(i, t)| {
                    // A try's end is its best, or the polish cut short
                    // found better.
                    let best = match interim.as_ref().and_then(|c| c.best.as_ref()) {
                        Some((k, s))
                            if *k == i && t.best.as_ref().is_none_or(|b| s.cost < b.cost) =>
                        {
                            Some(s)
                        }
                        _ => t.best.as_ref(),
                    };
                    TryEnd {
                        params: best.map_or(Vec::new(), |b| b.params.clone()),
                        sse: best.map_or(f64::INFINITY, |b| b.cost),
                        // Still refining once every step ran: the cap ended it.
                        cut_gain: t
                            .round_gain
                            .filter(|_| t.refining && self.plan.refine.is_some() && finished),
                    }
                })
                .collect(),
            checkpoint_error,
        })
    }

    /// Whether the whole fit should stop now, and why; `interim` is the
    /// best of a polish cut short, which the state does not hold.
    fn should_stop(
        &self,
        interrupt: Option<&AtomicBool>,
        interim: Option<&Scored>,
    ) -> Option<StopReason> {
        if interrupt.is_some_and(|f| f.load(Ordering::SeqCst)) {
            return Some(StopReason::Interrupted);
        }
        if let Some(t) = self.stops.target_sse
            && [self.overall_best(), interim]
                .into_iter()
                .flatten()
                .any(|b| b.cost <= t)
        {
            return Some(StopReason::TargetSse);
        }
        if self
            .stops
            .time_budget_s
            .is_some_and(|t| self.elapsed() >= t)
        {
            return Some(StopReason::TimeBudget);
        }
        None
    }

    /// Scores `rows` (free coordinates) under `measure`, counting the
    /// evaluations: their canonical rows and costs, NaN and −∞ made +∞.
    fn score(
        &mut self,
        objective: &mut dyn Objective,
        rows: Rows<'_, Coords>,
        measure: Measure,
    ) -> anyhow::Result<(Population<Params>, Vec<f32>)> {
        let canonical = self.space.embed(rows);
        let costs = self.score_canonical(objective, canonical.rows(), measure)?;
        Ok((canonical, costs))
    }

    /// Scores canonical rows under `measure`, counting the evaluations and
    /// the evaluator's seconds: their costs, NaN and −∞ made +∞.
    fn score_canonical(
        &mut self,
        objective: &mut dyn Objective,
        canonical: Rows<'_, Params>,
        measure: Measure,
    ) -> anyhow::Result<Vec<f32>> {
        let (costs, spent) = timed(objective, |o| o.costs(canonical, measure));
        self.spent(spent);
        let costs = sanitized(costs?, canonical.len(), &*objective)?;
        self.evaluations += costs.len() as u64;
        Ok(costs)
    }

    /// [`Engine::score`] without touching the state.
    fn costs_of(
        &self,
        objective: &mut dyn Objective,
        rows: Rows<'_, Coords>,
        measure: Measure,
    ) -> anyhow::Result<(Population<Params>, Vec<f32>)> {
        let canonical = self.space.embed(rows);
        let n = canonical.len();
        let costs = sanitized(objective.costs(canonical.rows(), measure)?, n, &*objective)?;
        Ok((canonical, costs))
    }

    /// Appends the history record of the generation (`costs`: the ranked
    /// costs of every try that stepped) or polish start (`None`) just made.
    fn record(&mut self, stage: Stage, measure: Measure, costs: Option<&[f32]>) {
        let (gbest, mean, std, diverged) =
            costs.map_or((None, None, None, 0), GenerationRecord::stats);
        let stage_best = self
            .tries
            .iter()
            .filter_map(|t| t.stage_best.as_ref())
            .fold(None, |b: Option<&Scored>, s| match b {
                Some(b) if b.cost <= s.cost => Some(b),
                _ => Some(s),
            });
        let best = self.overall_best();
        let leader = stage_best.or(best);
        let record = GenerationRecord {
            generation: self.history.records.len() + 1,
            stage,
            measure,
            evaluations: self.evaluations,
            seconds: self.elapsed(),
            best_sse: best.map(|b| b.cost),
            stage_best: stage_best.map(|b| b.cost),
            generation_best_sse: gbest,
            mean_sse: mean,
            std_sse: std,
            diverged,
            best_params: leader.map_or(Vec::new(), |b| b.params.clone()),
        };
        self.history.records.push(record);
    }

    /// Marks the start of a stage: its steps, best, evaluations and seconds
    /// count from here.
    fn start_stage(&mut self) {
        self.stage_steps = 0;
        for t in &mut self.tries {
            t.steps = 0;
            t.done = false;
            t.stage_best = None;
            t.stage_bests.clear();
        }
        self.stage_start_evaluations = self.evaluations;
        self.stage_start_seconds = self.elapsed();
        self.stage_start_evaluator_seconds = self.evaluator_seconds;
        self.stage_start_kernel_seconds = self.kernel_seconds;
    }

    /// Counts what a call spent in the evaluator.
    fn spent(&mut self, spent: Spent) {
        self.evaluator_seconds += spent.seconds;
        self.kernel_seconds = self.kernel_seconds.zip(spent.kernel).map(|(a, b)| a + b);
    }

    /// What the current stage, `stage`, has done so far.
    fn summary(&self, stage: Stage, ended: StageEnd) -> StageSummary {
        let best = self
            .tries
            .iter()
            .filter_map(|t| t.stage_best.as_ref())
            .map(|b| b.cost)
            .fold(f64::INFINITY, f64::min);
        StageSummary {
            stage,
            measure: self.measure(stage),
            steps: self.stage_steps,
            evaluations: self.evaluations - self.stage_start_evaluations,
            seconds: self.elapsed() - self.stage_start_seconds,
            evaluator_seconds: self.evaluator_seconds - self.stage_start_evaluator_seconds,
            kernel_seconds: self
                .kernel_seconds
                .zip(self.stage_start_kernel_seconds)
                .map(|(now, start)| now - start),
            best_cost: best,
            ended,
        }
    }

    /// The best candidate known when the fit stops early, scored on the free
    /// run (the global stage may search another measure): the best free-run
    /// candidate so far, or else the best of the members in hand. It leaves
    /// the state untouched, so that a checkpoint resumes to the result of an
    /// uninterrupted fit.
    fn best_so_far(&self, objective: &mut dyn Objective) -> anyhow::Result<Option<Scored>> {
        if self.overall_best().is_some() {
            return Ok(None);
        }
        let members: Vec<f64> = self
            .tries
            .iter()
            .flat_map(|t| {
                if t.optimizers.is_empty() {
                    t.carried
                        .iter()
                        .flat_map(|m| m.rows.clone())
                        .collect::<Vec<_>>()
                } else {
                    t.optimizers
                        .iter()
                        .flat_map(|o| o.members().0.into_flat())
                        .collect()
                }
            })
            .collect();
        if members.is_empty() {
            return Ok(None);
        }
        let members = Rows::new(&members, self.space.free_dim());
        let (canonical, costs) = self.costs_of(objective, members, Measure::FreeRun)?;
        Ok(argmin(&costs).map(|i| Scored {
            params: canonical.rows().row(i).to_vec(),
            cost: costs[i] as f64,
        }))
    }

    /// Writes the checkpoint (JSON) atomically.
    pub fn save(&mut self, path: &Path) -> anyhow::Result<()> {
        self.seconds_before = self.elapsed();
        self.started = Some(Instant::now());
        let json = serde_json::to_vec(self)?;
        write_atomic(path, &json)
            .map_err(|e| anyhow::anyhow!("cannot write checkpoint {}: {e}", path.display()))
    }

    /// Reads a checkpoint written by [`Engine::save`].
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let bytes = crate::data::input::read(path)
            .map_err(|e| anyhow::anyhow!("cannot read checkpoint {}: {e}", path.display()))?;
        serde_json::from_slice(&bytes).map_err(|e| {
            anyhow::anyhow!(
                "{} is not a mckibben checkpoint of this version (or a damaged one): {e}",
                path.display()
            )
        })
    }
}

/// What a call spent inside the evaluator.
#[derive(Debug, Clone, Copy, Default)]
struct Spent {
    /// Wall time.
    seconds: f64,
    /// The kernels' device time, where the evaluator has a device clock.
    kernel: Option<f64>,
}

/// Runs `call` on `objective` and says how long it spent inside the
/// evaluator: what the objective counts ([`Objective::evaluator_seconds`]),
/// or else the whole call; and of that the kernels' device time
/// ([`Objective::kernel_seconds`]).
fn timed<T>(
    objective: &mut dyn Objective,
    call: impl FnOnce(&mut dyn Objective) -> T,
) -> (T, Spent) {
    let before = objective.evaluator_seconds();
    let kernel_before = objective.kernel_seconds();
    let started = Instant::now();
    let out = call(objective);
    let whole = started.elapsed().as_secs_f64();
    let seconds = match (before, objective.evaluator_seconds()) {
        (Some(a), Some(b)) => b - a,
        _ => whole,
    };
    let kernel = kernel_before
        .zip(objective.kernel_seconds())
        .map(|(a, b)| b - a);
    (out, Spent { seconds, kernel })
}

/// `costs` with NaN and −∞ made +∞, checked to hold one cost per each of
/// the `n` candidates.
fn sanitized(mut costs: Vec<f32>, n: usize, objective: &dyn Objective) -> anyhow::Result<Vec<f32>> {
    anyhow::ensure!(
        costs.len() == n,
        "{} returned {} costs for {n} candidates",
        objective.describe(),
        costs.len()
    );
    for c in &mut costs {
        if c.is_nan() || *c < 0.0 && c.is_infinite() {
            *c = f32::INFINITY;
        }
    }
    Ok(costs)
}
