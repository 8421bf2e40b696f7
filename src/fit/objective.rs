//! The muscle models' objective — the batch evaluator on an estimation
//! problem — and the engine's defaults for fitting them.

use std::time::Instant;

use serde::Serialize;

use super::problem::{Admission, FitProblem, Overshoot, SETTLED_SHARE};
use crate::eval::{Evaluator, Pending, Problem};
use crate::model::coords::in_bounded_class;
use crate::model::{Flow, Loop, Measure};
use crate::optim::engine::plan::{FreeRun, Global, Plan, Polish, Refine, TrySize};
use crate::optim::engine::{Fork, Objective, Ticket};
use crate::optim::{AlgoSettings, Algorithm};
use crate::search::{Params, Rows};

/// A model family's fit to experiments, scored by a batch evaluator.
pub struct ModelObjective<'a> {
    evaluator: &'a mut dyn Evaluator,
    problem: Problem,
    /// A problem whose free-run cost a candidate must keep at or below the
    /// bound, or it scores +∞ on the free run ([`FitProblem::stress`]); a
    /// candidate outside the bounded class too, when the problem asks for it
    /// ([`crate::model::coords::in_bounded_class`]).
    stress: Option<(Problem, f64)>,
    /// Whether the loop must be in the bounded class.
    bounded_class: bool,
    /// A step a sample that every candidate's loop update must settle
    /// within on the free run ([`crate::model::Family::stable_step`]; a loop
    /// without such a step passes), where overshoots are refused
    /// ([`Overshoot`]).
    stable_floor: Option<f64>,
    /// Whether every row must have a bounded loop
    /// ([`crate::model::Family::loop_bounded`]), whatever the measure: the
    /// diagnosis' rule ([`ModelObjective::bounded_loops`]).
    loop_bounded: bool,
    /// What the evaluator's calls have spent so far.
    clock: Clock,
}

/// Time spent inside an evaluator's calls.
struct Clock {
    /// Wall time.
    seconds: f64,
    /// Of that, the kernels' on the device's clock; `None` once a call had
    /// no device time.
    kernel: Option<f64>,
}

impl Clock {
    fn new() -> Self {
        Clock {
            seconds: 0.0,
            kernel: Some(0.0),
        }
    }

    /// `call` on `evaluator`, its wall time and its kernels' device time added.
    fn timed<T>(
        &mut self,
        evaluator: &mut dyn Evaluator,
        call: impl FnOnce(&mut dyn Evaluator) -> T,
    ) -> T {
        let started = Instant::now();
        let out = call(evaluator);
        self.seconds += started.elapsed().as_secs_f64();
        self.kernel = self
            .kernel
            .zip(evaluator.kernel_seconds())
            .map(|(a, b)| a + b);
        out
    }
}

impl<'a> ModelObjective<'a> {
    /// Scores `problem` (whatever its measure: each call sets its own).
    pub fn new(evaluator: &'a mut dyn Evaluator, problem: Problem) -> Self {
        ModelObjective {
            evaluator,
            problem,
            stress: None,
            bounded_class: false,
            stable_floor: None,
            loop_bounded: false,
            clock: Clock::new(),
        }
    }

    /// Scores `problem`, every row with an unbounded loop costing `+∞` under
    /// every measure: the diagnosis' admission ([`Admission::BoundedLoops`],
    /// which says why).
    pub fn bounded_loops(evaluator: &'a mut dyn Evaluator, problem: Problem) -> Self {
        ModelObjective {
            loop_bounded: true,
            ..ModelObjective::new(evaluator, problem)
        }
    }

    /// Scores `problem`'s estimation halves under its admission
    /// ([`Admission`]). `fit`'s rejects on the free run every candidate that
    /// leaves the problem's stress bound: what `fit` writes must stay
    /// bounded on the whole record's input. With bounded loops (the default)
    /// it also rejects every loop outside the class, which the data-scale
    /// box excludes anyway but a box on the canonical loop-shape parameters
    /// does not; where overshoots are refused ([`Overshoot`]), every loop
    /// whose update overshoots on the steps the estimation records take
    /// ([`SETTLED_SHARE`]). The thesis' flow is the thesis' experiment and
    /// runs without these checks. The diagnosis' admits bounded loops only,
    /// under every measure ([`ModelObjective::bounded_loops`]).
    pub fn for_problem(evaluator: &'a mut dyn Evaluator, problem: &FitProblem) -> Self {
        match problem.admission {
            Admission::BoundedLoops => {
                ModelObjective::bounded_loops(evaluator, problem.est_problem())
            }
            Admission::Fit(overshoot) => {
                let joint = problem.flow != Flow::Thesis;
                ModelObjective {
                    stress: joint.then(|| problem.stress()),
                    bounded_class: joint && problem.loop_shape == Loop::Bounded,
                    // With effects the loop steps on the baseline's own
                    // output, not the measured one.
                    stable_floor: (joint
                        && overshoot == Overshoot::Refuse
                        && problem.model.effects.is_empty())
                    .then(|| problem.records.measured_step_within(SETTLED_SHARE)),
                    ..ModelObjective::new(evaluator, problem.est_problem())
                }
            }
        }
    }

    /// Which rows have a bounded loop and stay within the stress bound (all,
    /// without a stress problem). Only rows with `finite` true are checked:
    /// the rest are rejected anyway.
    fn bounded(&mut self, rows: Rows<'_, Params>, finite: &[bool]) -> anyhow::Result<Vec<bool>> {
        let Some((problem, bound)) = &self.stress else {
            return Ok(vec![true; finite.len()]);
        };
        let family = problem.family;
        let admitted = |row: &[f64]| {
            let steady = self
                .stable_floor
                .is_none_or(|floor| family.stable_step(row).is_none_or(|s| s >= floor));
            steady
                && if self.bounded_class {
                    in_bounded_class(family, row)
                } else {
                    family.loop_bounded(row)
                }
        };
        let picked: Vec<usize> = (0..finite.len())
            .filter(|&i| finite[i] && admitted(rows.row(i)))
            .collect();
        let subset: Vec<f64> = picked
            .iter()
            .flat_map(|&i| rows.row(i).iter().copied())
            .collect();
        let mut ok = vec![false; finite.len()];
        if picked.is_empty() {
            return Ok(ok);
        }
        let energy = self
            .clock
            .timed(self.evaluator, |e| {
                e.evaluate(problem, Rows::new(&subset, rows.dim()))
            })?
            .total;
        for (&i, &e) in picked.iter().zip(&energy) {
            ok[i] = (e as f64) <= *bound;
        }
        Ok(ok)
    }
}

impl ModelObjective<'_> {
    /// Which rows the fits admit whatever the measure: their effect
    /// parameters ([`crate::model::effects::ModelDescription::effects_admit`]; all,
    /// without effects) and, with [`ModelObjective::bounded_loops`], their
    /// loop.
    fn admitted(&self, rows: Rows<'_, Params>) -> Vec<bool> {
        let family = self.problem.family;
        let loop_ok = |row: &[f64]| !self.loop_bounded || family.loop_bounded(row);
        if self.problem.effects.is_empty() {
            return rows.iter().map(loop_ok).collect();
        }
        let model = self.problem.model();
        rows.iter()
            .map(|row| loop_ok(row) && model.effects_admit(row))
            .collect()
    }
}

impl Objective for ModelObjective<'_> {
    fn describe(&self) -> String {
        self.evaluator.describe()
    }

    fn evaluator_seconds(&self) -> Option<f64> {
        Some(self.clock.seconds)
    }

    fn kernel_seconds(&self) -> Option<f64> {
        self.clock.kernel
    }

    fn round_trips(&self) -> bool {
        self.evaluator.round_trips()
    }

    fn forks(&self, n: usize) -> Option<Vec<Box<dyn Fork + '_>>> {
        (0..n)
            .map(|_| {
                let evaluator = self.evaluator.fork()?;
                Some(Box::new(ModelFork {
                    evaluator,
                    problem: &self.problem,
                    stress: &self.stress,
                    bounded_class: self.bounded_class,
                    stable_floor: self.stable_floor,
                    loop_bounded: self.loop_bounded,
                }) as Box<dyn Fork + '_>)
            })
            .collect()
    }

    fn costs(&mut self, rows: Rows<'_, Params>, measure: Measure) -> anyhow::Result<Vec<f32>> {
        let ticket = self.submit(rows, measure)?;
        self.collect(ticket, rows, measure)
    }

    fn submit(&mut self, rows: Rows<'_, Params>, measure: Measure) -> anyhow::Result<Ticket> {
        self.problem.measure = measure;
        let pending = self
            .clock
            .timed(self.evaluator, |e| e.submit(&self.problem, rows))?;
        Ok(Ticket::new(pending))
    }

    /// The scores summed over the experiments, then the admission's checks.
    fn collect(
        &mut self,
        ticket: Ticket,
        rows: Rows<'_, Params>,
        measure: Measure,
    ) -> anyhow::Result<Vec<f32>> {
        let pending: Pending = ticket.take()?;
        let scores = self.clock.timed(self.evaluator, |e| e.collect(pending))?;
        // Summed over the experiments in `f64`, as the diagnosis' SSEs are
        // (one experiment, as `fit`'s: the evaluator's own number).
        let mut costs: Vec<f32> = (0..scores.total.len())
            .map(|i| {
                let sum: f64 = scores.per_experiment.iter().map(|e| e[i] as f64).sum();
                sum as f32
            })
            .collect();
        for (c, ok) in costs.iter_mut().zip(self.admitted(rows)) {
            if !ok {
                *c = f32::INFINITY;
            }
        }
        if measure == Measure::FreeRun && self.stress.is_some() {
            let finite: Vec<bool> = costs.iter().map(|c| c.is_finite()).collect();
            let bounded = self.bounded(rows, &finite)?;
            for (c, ok) in costs.iter_mut().zip(bounded) {
                if !ok {
                    *c = f32::INFINITY;
                }
            }
        }
        Ok(costs)
    }

    fn residuals(
        &mut self,
        rows: Rows<'_, Params>,
        measure: Measure,
    ) -> anyhow::Result<Vec<Option<Vec<f32>>>> {
        self.problem.measure = measure;
        let mut residuals = self
            .clock
            .timed(self.evaluator, |e| e.residuals(&self.problem, rows))?;
        for (r, ok) in residuals.iter_mut().zip(self.admitted(rows)) {
            if !ok {
                *r = None;
            }
        }
        if measure == Measure::FreeRun && self.stress.is_some() {
            let finite: Vec<bool> = residuals.iter().map(Option::is_some).collect();
            let bounded = self.bounded(rows, &finite)?;
            for (r, ok) in residuals.iter_mut().zip(bounded) {
                if !ok {
                    *r = None;
                }
            }
        }
        Ok(residuals)
    }
}

/// A [`ModelObjective`]'s copy for one thread: a forked evaluator, and the
/// problem and admission of the objective it was forked from.
struct ModelFork<'o> {
    evaluator: Box<dyn Evaluator + Send>,
    problem: &'o Problem,
    stress: &'o Option<(Problem, f64)>,
    bounded_class: bool,
    stable_floor: Option<f64>,
    loop_bounded: bool,
}

impl Fork for ModelFork<'_> {
    fn run(
        &mut self,
        work: &mut dyn FnMut(&mut dyn Objective) -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        work(&mut ModelObjective {
            evaluator: &mut *self.evaluator,
            problem: self.problem.clone(),
            stress: self.stress.clone(),
            bounded_class: self.bounded_class,
            stable_floor: self.stable_floor,
            loop_bounded: self.loop_bounded,
            clock: Clock::new(),
        })
    }
}

/// Default population of the global stage, all tries together.
pub const POPULATION: usize = 1000;
/// A try's population: a population of at least twice this runs tries of
/// this size and of [`SMALL_TRY_POPULATION`] ([`try_populations`]), a
/// smaller one a single try of its own size.
pub const TRY_POPULATION: usize = 1000;
/// A small try's population: on some records a population this small
/// converges before its loop saturates, where every try of
/// [`TRY_POPULATION`] converges into a saturated loop (measured on the
/// generated cases: docs/RESULTS.md, "Larger populations").
pub const SMALL_TRY_POPULATION: usize = 100;
/// Small tries that follow each large one after the first two.
const SMALL_TRIES_A_BLOCK: usize = TRY_POPULATION / SMALL_TRY_POPULATION;
/// Default islands of a try (fewer when its population is too small for four).
pub const ISLANDS: usize = 4;
/// The fewest individuals an island of the default plan holds, unless its
/// algorithm needs more ([`Algorithm::min_population`]): a choice of the
/// plan, so that a small population is split into fewer islands rather than
/// into handfuls.
pub const ISLAND_MIN: usize = 4;
/// Default generations of the global stage.
pub const GENERATIONS: usize = 300;

/// Each try's population when a population of `n` is run: the prefix of
/// one fixed sequence (two tries of [`TRY_POPULATION`], then blocks of ten
/// tries of [`SMALL_TRY_POPULATION`] and one large try, so that both sizes
/// get about half the budget, as BIPOP gives them: Hansen, 2009) that `n`
/// holds, what is left over not searched; below two large tries, a single
/// try of `n`. Fixed, so that with the same seed a larger population runs
/// the tries of a smaller one and more, and never ends at a higher
/// estimation SSE.
pub fn try_populations(n: usize) -> Vec<usize> {
    if n < 2 * TRY_POPULATION {
        return vec![n];
    }
    let sequence = [TRY_POPULATION; 2].into_iter().chain(
        std::iter::repeat(
            std::iter::repeat_n(SMALL_TRY_POPULATION, SMALL_TRIES_A_BLOCK).chain([TRY_POPULATION]),
        )
        .flatten(),
    );
    let mut left = n;
    sequence
        .map_while(|size| {
            left = left.checked_sub(size)?;
            Some(size)
        })
        .collect()
}

/// Tries of one population: how a fit's tries are told (a fit of
/// `--pop 10000` runs 6 tries of 1000 and 40 of 100).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct TryGroup {
    pub population: usize,
    pub tries: usize,
}

/// The tries of `plan`, by population (the global stage's, or the
/// free-run stage's in a plan from a known point), in the order they first
/// run.
pub fn try_groups(plan: &Plan) -> Vec<TryGroup> {
    let populations: Vec<usize> = (0..plan.tries).map(|t| try_population(plan, t)).collect();
    groups_of(&populations)
}

/// Try `t`'s population: its global stage's, or its free-run stage's in a
/// plan from a known point (0 in a plan with neither).
pub fn try_population(plan: &Plan, t: usize) -> usize {
    let size = plan.try_size(t);
    if plan.global.is_some() {
        size.global
    } else {
        size.free_run
    }
}

/// Tries of these populations, by population, in the order they first run.
pub fn groups_of(populations: &[usize]) -> Vec<TryGroup> {
    let mut groups: Vec<TryGroup> = Vec::new();
    for &population in populations {
        match groups.iter_mut().find(|g| g.population == population) {
            Some(g) => g.tries += 1,
            None => groups.push(TryGroup {
                population,
                tries: 1,
            }),
        }
    }
    groups
}

/// How `groups` read: "6 tries of 1000 and 40 of 100".
pub fn tries_text(groups: &[TryGroup]) -> String {
    groups
        .iter()
        .enumerate()
        .map(|(i, g)| match (i, g.tries) {
            (0, 1) => format!("1 try of {}", g.population),
            (0, k) => format!("{k} tries of {}", g.population),
            (_, k) => format!("{k} of {}", g.population),
        })
        .collect::<Vec<_>>()
        .join(" and ")
}

/// The engine's default plan for a muscle model of a population `n` (all
/// tries together, [`try_populations`]): each try's global stage with `algorithm`
/// (its [`Algorithm::staged_settings`]) on the `horizon`-step-ahead
/// prediction, for `g` generations; a free-run stage of a fifth of the
/// try's population for a quarter of the generations; the default polish,
/// with continuation up to `longest` samples (the longest experiment); and
/// refining rounds of the free-run stage's size for `g` generations each.
pub fn default_plan(
    algorithm: Algorithm,
    n: usize,
    g: usize,
    horizon: usize,
    longest: usize,
) -> Plan {
    let populations = try_populations(n);
    let n = populations[0];
    let per_island = ISLAND_MIN.max(algorithm.min_population());
    let islands = (n / per_island).clamp(1, ISLANDS);
    // A try's free-run stage and refining rounds hold a fifth of its
    // global population; its polish takes starts in proportion to its
    // population (the first try's sixteen), one an island at least: a
    // polish start costs the same whatever the try's size, and sixteen
    // would take most of a small try's time.
    let polish = Polish::default().starts;
    let size = |global: usize| {
        let fifth = (global / 5).max(FreeRun::ALGORITHM.min_population() * islands);
        TrySize {
            global,
            free_run: fifth,
            refine: fifth,
            polish: (polish * global).div_ceil(n).max(islands),
        }
    };
    let free_run = size(n).free_run;
    Plan {
        global: Some(Global {
            settings: algorithm.staged_settings(n),
            population: n,
            generations: g,
            measure: Measure::Ahead { horizon },
            islands,
            ladder: true,
            longest,
        }),
        free_run: Some(FreeRun {
            population: free_run,
            generations: (g / 4).max(1),
        }),
        polish: Some(Polish {
            longest,
            ..Polish::default()
        }),
        refine: Some(Refine {
            population: free_run,
            generations: g,
            ..Refine::default()
        }),
        tries: populations.len(),
        sizes: if populations.iter().all(|&p| p == n) {
            Vec::new()
        } else {
            populations.into_iter().map(size).collect()
        },
    }
}

/// The engine's default plan for `problem` with `settings`' algorithm and
/// those settings, `n × g`, its horizon from the problem's ARX pole and its
/// polish's continuation up to the estimation data's length.
///
/// Only a family whose state switches where the output crosses a level
/// (the generalized family's sign terms in `x`) is refined: its free run
/// jumps where a sample crosses the level, and the polish stops on such
/// ledges, which a round of refining steps over. A smooth family's polish
/// ends in its valley's floor, and there refining only finds, on a record
/// the model cannot fit exactly, another optimum of the estimation half
/// that validates worse (both measured: docs/ARCHITECTURE.md, "Decisions
/// of the fitting engine").
pub fn staged_plan(problem: &FitProblem, settings: AlgoSettings, n: usize, g: usize) -> Plan {
    let longest = problem.estimation().len();
    let mut plan = default_plan(settings.algorithm(), n, g, problem.horizon(), longest);
    if let Some(global) = plan.global.as_mut() {
        global.settings = settings;
    }
    if problem.model.family.switch_index().is_none() {
        plan.refine = None;
    }
    plan
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_larger_population_runs_a_smaller_ones_tries_first() {
        assert_eq!(try_populations(1000), [1000]);
        assert_eq!(try_populations(1999), [1999]);
        assert_eq!(try_populations(2000), [1000, 1000]);
        let ten = try_populations(10_000);
        assert_eq!(ten.iter().sum::<usize>(), 10_000);
        assert_eq!(
            groups_of(&ten),
            [
                TryGroup {
                    population: 1000,
                    tries: 6
                },
                TryGroup {
                    population: 100,
                    tries: 40
                }
            ]
        );
        assert_eq!(
            tries_text(&groups_of(&ten)),
            "6 tries of 1000 and 40 of 100"
        );
        // Every population from two large tries on holds the tries of every
        // smaller one as its first, and what it leaves is less than the
        // next try of the sequence.
        let mut before = try_populations(2000);
        for n in (2000..=30_000).step_by(50) {
            let now = try_populations(n);
            assert_eq!(now[..before.len()], before[..], "{n}");
            let left = n - now.iter().sum::<usize>();
            let next = try_populations(n + TRY_POPULATION)[now.len()];
            assert!(left < next, "{n} leaves {left}, the next try holds {next}");
            before = now;
        }
    }
}
