//! The fitting engine's stop rules on cheap synthetic objectives: a target
//! SSE and a time budget stop the whole fit, a stall ends a population
//! stage, and Ctrl-C (the interrupt flag) stops the fit keeping the best so
//! far. The staged fit on real models (interrupt and resume, thread counts,
//! backends) is in `optim_determinism.rs`; here each rule is checked alone
//! against a cost whose behaviour is known exactly.

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use mckibben::model::Measure;
use mckibben::optim::Algorithm;
use mckibben::optim::engine::{
    Engine, FreeRun, Objective, Outcome, Plan, Space, Stage, StageEnd, StopReason, StopRules,
};
use mckibben::search::{Params, Rows};

const DIM: usize = 3;

/// The box [-5, 5]³.
fn space() -> Space {
    Space::new(
        vec![-5.0; DIM],
        vec![5.0; DIM],
        (0..DIM).map(|i| format!("x{i}")).collect(),
    )
}

/// A DE search of `n` individuals over `g` generations, on one island.
fn plan(n: usize, g: usize) -> Plan {
    Plan::search(Algorithm::De.default_settings(), n, g)
}

fn sphere(row: &[f64]) -> f64 {
    row.iter().map(|x| x * x).sum()
}

/// What a test objective returns for one row; `calls` is the number of
/// `costs` calls before this one (one per generation).
type Cost = fn(row: &[f64], calls: usize) -> f64;

/// A synthetic objective: `cost` for every row, whatever the measure (the
/// engine may ask for the free run or a horizon), optionally sleeping
/// `pause` per call; it counts its calls and keeps the lowest cost it ever
/// returned with its row, to check what the engine reports as the best.
struct Synthetic {
    cost: Cost,
    pause: Duration,
    calls: usize,
    lowest: Option<(f32, Vec<f64>)>,
    /// Seconds of "evaluator" time it reports a call
    /// (`Objective::evaluator_seconds`); `None`: it reports none, and the
    /// engine times its calls whole.
    reported: Option<f64>,
}

impl Synthetic {
    fn new(cost: Cost) -> Synthetic {
        Synthetic {
            cost,
            pause: Duration::ZERO,
            calls: 0,
            lowest: None,
            reported: None,
        }
    }
}

impl Objective for Synthetic {
    fn describe(&self) -> String {
        "synthetic test objective".into()
    }

    fn costs(&mut self, rows: Rows<'_, Params>, _: Measure) -> anyhow::Result<Vec<f32>> {
        std::thread::sleep(self.pause);
        let costs: Vec<f32> = rows
            .iter()
            .map(|row| (self.cost)(row, self.calls) as f32)
            .collect();
        for (row, &c) in rows.iter().zip(&costs) {
            if self.lowest.as_ref().is_none_or(|(l, _)| c < *l) {
                self.lowest = Some((c, row.to_vec()));
            }
        }
        self.calls += 1;
        Ok(costs)
    }

    fn evaluator_seconds(&self) -> Option<f64> {
        self.reported.map(|per_call| per_call * self.calls as f64)
    }
}

fn run(engine: &mut Engine, objective: &mut Synthetic) -> Outcome {
    engine.run(objective, &mut [], None, None).unwrap()
}

/// The free-run best after each generation, as the history records it.
fn best_by_generation(engine: &Engine) -> Vec<f64> {
    engine
        .history
        .records
        .iter()
        .map(|r| r.best_sse.expect("a finite best after every generation"))
        .collect()
}

#[test]
fn a_target_sse_stops_the_fit_at_the_first_generation_that_reaches_it() {
    const TARGET: f64 = 1e-2;
    const G: usize = 200;
    let mut engine = Engine::new(
        plan(20, G),
        space(),
        3,
        StopRules {
            target_sse: Some(TARGET),
            ..StopRules::default()
        },
    )
    .unwrap();
    let mut objective = Synthetic::new(|row, _| sphere(row));
    let out = run(&mut engine, &mut objective);
    assert_eq!(out.stop, StopReason::TargetSse);
    assert!(out.sse <= TARGET, "sse {}", out.sse);
    assert!(out.generations < G, "{} generations", out.generations);
    // The reported best is a candidate that was scored, with its own cost.
    assert_eq!(out.sse, sphere(&out.params) as f32 as f64);
    // Not reached by the first population (the rule had to stop a search in
    // progress), and the fit stopped at once when it was reached.
    let bests = best_by_generation(&engine);
    assert_eq!(bests.len(), out.generations);
    assert!(bests[0] > TARGET, "first population best {}", bests[0]);
    assert!(bests[bests.len() - 2] > TARGET && bests[bests.len() - 1] <= TARGET);
    // Only the generations that ran were scored.
    assert_eq!(objective.calls, out.generations);
    // The stage it cut short is reported with what it did.
    assert_eq!(out.stages.len(), 1, "{:?}", out.stages);
    let stage = &out.stages[0];
    assert_eq!(stage.ended, StageEnd::CutShort);
    assert_eq!(stage.steps, out.generations);
    assert_eq!(stage.evaluations, out.evaluations);
    assert_eq!(stage.best_cost, out.sse);
}

#[test]
fn a_time_budget_stops_the_fit_between_generations() {
    const BUDGET_S: f64 = 0.3;
    const PAUSE_MS: u64 = 20;
    const G: usize = 1000;
    let mut engine = Engine::new(
        plan(8, G),
        space(),
        5,
        StopRules {
            time_budget_s: Some(BUDGET_S),
            ..StopRules::default()
        },
    )
    .unwrap();
    let mut objective = Synthetic::new(|row, _| sphere(row));
    objective.pause = Duration::from_millis(PAUSE_MS);
    let out = run(&mut engine, &mut objective);
    assert_eq!(out.stop, StopReason::TimeBudget);
    assert!(
        out.generations >= 1 && out.generations < G,
        "{} generations",
        out.generations
    );
    // The budget is checked before each generation and every generation
    // sleeps at least PAUSE_MS, so none starts once the budget is spent:
    // at most ⌈budget / pause⌉ ran, and the run lasted at least the budget.
    // (Both bounds hold however slow the machine is.)
    let most = (BUDGET_S * 1000.0 / PAUSE_MS as f64).ceil() as usize;
    assert!(out.generations <= most, "{} generations", out.generations);
    assert!(out.seconds >= BUDGET_S, "{} s", out.seconds);
    // The best so far is kept.
    assert!(out.sse.is_finite() && out.params.len() == DIM, "{out:?}");
    assert_eq!(objective.calls, out.generations);
}

/// Each stage's `evaluator_seconds` is what the objective says it spent in
/// its evaluator during the stage, where it says (here a made-up 0.25 s a
/// call, while it really sleeps 20 ms: the engine must take the objective's
/// word, not its own clock); where it does not, the engine counts its calls
/// whole, which take at least the 20 ms each sleeps and never more than the
/// stage's wall time.
#[test]
fn each_stage_counts_the_seconds_spent_in_the_evaluator() {
    const G: usize = 5;
    const PAUSE_MS: u64 = 20;
    for reported in [Some(0.25), None] {
        let mut engine = Engine::new(plan(8, G), space(), 2, StopRules::default()).unwrap();
        let mut objective = Synthetic::new(|row, _| sphere(row));
        objective.pause = Duration::from_millis(PAUSE_MS);
        objective.reported = reported;
        let out = run(&mut engine, &mut objective);
        assert_eq!((out.stages.len(), objective.calls), (1, G));
        let stage = &out.stages[0];
        match reported {
            Some(per_call) => assert_eq!(stage.evaluator_seconds, per_call * G as f64),
            None => {
                let slept = (G as u64 * PAUSE_MS) as f64 / 1000.0;
                assert!(
                    stage.evaluator_seconds >= slept && stage.evaluator_seconds <= stage.seconds,
                    "{stage:?}"
                );
            }
        }
    }
}

/// A population stage ends as stalled exactly `stall_generations` after its
/// best last improved (with no tolerance, any improvement counts), and not
/// before: on the sphere floored at 0.5, which no search can improve past,
/// so the stall is sure to come well before `G` (here DE reaches the floor
/// first; a plateau above it would end the stage the same way).
#[test]
fn a_stage_whose_best_stops_improving_ends_stalled_the_window_after_its_last_improvement() {
    const W: usize = 5;
    const G: usize = 200;
    let mut engine = Engine::new(
        plan(20, G),
        space(),
        7,
        StopRules {
            stall_generations: Some(W),
            stall_tolerance: 0.0,
            ..StopRules::default()
        },
    )
    .unwrap();
    // A floor the first population almost never holds (the ball of radius
    // 0.1 is 4·10⁻⁶ of the box; 20 draws), and DE reaches in tens of
    // generations: the stage improves, then stalls on it.
    let mut objective = Synthetic::new(|row, _| sphere(row).max(0.01));
    let out = run(&mut engine, &mut objective);
    // The stall ends the stage, not the fit: the plan has no other stage.
    assert_eq!(out.stop, StopReason::Completed);
    assert_eq!(out.stages.len(), 1);
    let stage = &out.stages[0];
    assert_eq!(
        (stage.stage, stage.ended),
        (Stage::Global, StageEnd::Stalled)
    );
    assert!(stage.steps < G, "{} steps", stage.steps);
    assert_eq!(stage.steps, out.generations);
    let bests: Vec<f64> = engine
        .history
        .records
        .iter()
        .map(|r| r.stage_best.unwrap())
        .collect();
    let last = *bests.last().unwrap();
    let improved_last = bests.iter().position(|&b| b == last).unwrap() + 1;
    assert!(
        improved_last > 1,
        "the first population already had the floor"
    );
    assert_eq!(stage.steps, improved_last + W, "{bests:?}");
}

/// A constant cost never improves: with stall rules each population stage
/// (the window restarts with the stage) ends after `W + 1` generations, the
/// first population and `W` without improvement; without them each runs
/// its full length.
#[test]
fn a_constant_cost_stalls_every_population_stage_and_only_with_stall_rules() {
    const W: usize = 4;
    const G: usize = 40;
    let two_stages = || {
        let mut p = plan(8, G);
        p.free_run = Some(FreeRun {
            population: 8,
            generations: G,
        });
        p
    };
    let stalling = StopRules {
        stall_generations: Some(W),
        stall_tolerance: 1e-6,
        ..StopRules::default()
    };
    let constant: Cost = |_, _| 1.0;

    let mut engine = Engine::new(two_stages(), space(), 1, stalling).unwrap();
    let out = run(&mut engine, &mut Synthetic::new(constant));
    assert_eq!(out.stop, StopReason::Completed);
    let ends: Vec<(Stage, StageEnd, usize)> = out
        .stages
        .iter()
        .map(|s| (s.stage, s.ended, s.steps))
        .collect();
    assert_eq!(
        ends,
        [
            (Stage::Global, StageEnd::Stalled, W + 1),
            (Stage::FreeRun, StageEnd::Stalled, W + 1)
        ]
    );
    assert_eq!(out.generations, 2 * (W + 1));

    let mut engine = Engine::new(two_stages(), space(), 1, StopRules::default()).unwrap();
    let out = run(&mut engine, &mut Synthetic::new(constant));
    let ends: Vec<(StageEnd, usize)> = out.stages.iter().map(|s| (s.ended, s.steps)).collect();
    assert_eq!(
        ends,
        [(StageEnd::Generations, G), (StageEnd::Generations, G)]
    );
}

/// The tolerance is relative: a best that improves by 0.1 % a generation
/// (0.5 % over a window of 5) has stalled for a tolerance of 1 % and has
/// not for one of 0.1 %.
#[test]
fn the_stall_tolerance_counts_improvements_smaller_than_it_as_none() {
    const W: usize = 5;
    const G: usize = 60;
    // Every row alike, lower by 0.1 % each generation.
    let creeping: Cost = |_, calls| 0.999f64.powi(calls as i32);
    let ended = |tolerance: f64| {
        let stops = StopRules {
            stall_generations: Some(W),
            stall_tolerance: tolerance,
            ..StopRules::default()
        };
        let mut engine = Engine::new(plan(8, G), space(), 2, stops).unwrap();
        let out = run(&mut engine, &mut Synthetic::new(creeping));
        (out.stages[0].ended, out.stages[0].steps)
    };
    assert_eq!(ended(1e-2), (StageEnd::Stalled, W + 1));
    assert_eq!(ended(1e-3), (StageEnd::Generations, G));
}

/// Ctrl-C before the first generation: the fit stops before scoring
/// anything, so there is no best to keep (empty parameters, infinite SSE),
/// and it leaves no trace: run again without the flag, the same engine
/// gives exactly what a fresh one does.
#[test]
fn an_interrupt_raised_before_the_run_stops_it_before_any_evaluation() {
    let fresh = || Engine::new(plan(8, 10), space(), 4, StopRules::default()).unwrap();
    let flag = AtomicBool::new(true);
    let mut engine = fresh();
    let mut objective = Synthetic::new(|row, _| sphere(row));
    let cut = engine
        .run(&mut objective, &mut [], Some(&flag), None)
        .unwrap();
    assert_eq!(cut.stop, StopReason::Interrupted);
    assert_eq!((cut.generations, cut.evaluations), (0, 0));
    assert!(cut.params.is_empty() && cut.sse == f64::INFINITY, "{cut:?}");
    assert!(cut.stages.is_empty());
    assert_eq!(objective.calls, 0);

    flag.store(false, Ordering::SeqCst);
    let resumed = engine
        .run(&mut objective, &mut [], Some(&flag), None)
        .unwrap();
    let straight = run(&mut fresh(), &mut Synthetic::new(|row, _| sphere(row)));
    assert_eq!(resumed.stop, StopReason::Completed);
    assert_eq!(
        (&resumed.params, resumed.sse, resumed.evaluations),
        (&straight.params, straight.sse, straight.evaluations)
    );
}

/// Ctrl-C during the search: the current generation finishes, and the fit
/// reports the lowest cost of every candidate scored so far, with its row.
#[test]
fn an_interrupt_during_the_search_keeps_the_best_candidate_scored_so_far() {
    const AT: usize = 3;
    let flag = AtomicBool::new(false);
    let mut engine = Engine::new(plan(8, 50), space(), 6, StopRules::default()).unwrap();
    let mut objective = Synthetic::new(|row, _| sphere(row));
    let out = engine
        .run(
            &mut objective,
            &mut [&mut common::InterruptAt(AT, &flag)],
            Some(&flag),
            None,
        )
        .unwrap();
    assert_eq!(out.stop, StopReason::Interrupted);
    assert_eq!(out.generations, AT);
    assert_eq!(objective.calls, AT);
    let (lowest, row) = objective.lowest.expect("candidates were scored");
    assert_eq!((out.sse, &out.params), (lowest as f64, &row));
}

/// A time budget covers a whole fit: the chain's build (`built_in_s`) and
/// every start. A fit whose build spent it runs no start, not even the
/// switching's second one, and says where the time went; with time left,
/// both starts run and the fit completes.
#[test]
fn a_time_budget_covers_every_start_of_a_fit() {
    use mckibben::fit::run::FitTarget;
    use mckibben::fit::settings::FitSettings;
    use mckibben::fit::synthetic::Synthetic;
    use mckibben::model::{Family, Switching};

    let trace = Synthetic::new(Family::Generalized, 400, 0.05, 3).trace;
    let what = FitTarget {
        switching: Some(Switching::Starts),
        ..FitTarget::chain(Family::Generalized, &[])
    };
    let settings = |budget: f64| FitSettings {
        pop: 20,
        gens: 3,
        stops: StopRules {
            time_budget_s: Some(budget),
            ..StopRules::default()
        },
        ..FitSettings::staged(1)
    };
    let fit = |budget: f64, built_in_s: f64| fit_on(&trace, &what, &settings(budget), built_in_s);
    let (spent, out) = fit(2.0, 2.0);
    assert_eq!((out.stop, out.evaluations), (StopReason::TimeBudget, 0));
    assert!(spent.switched.is_none(), "the second start ran");
    assert_eq!(
        spent.unscored(out.stop),
        "stopped (TimeBudget) while the chain was built (2.0 s), before the fit's first start \
         scored a candidate"
    );
    let (left, out) = fit(600.0, 2.0);
    assert_eq!(out.stop, StopReason::Completed);
    assert!(left.switched.is_some(), "both starts ran");
    assert!(
        out.seconds >= 2.0,
        "the build's seconds are the fit's: {}",
        out.seconds
    );
}

/// The budget covers the edge rule's refits of every try too: a fit of
/// many tries whose run spent the budget refits none of them, and says it
/// was the budget (the refits ran on a fresh budget each, and the last
/// one's `completed` stood for the fit's reason: on the shipped stair, a
/// 0.5 s budget at N = 20 000 ended `completed`).
#[test]
fn a_time_budget_covers_the_refits_of_every_try() {
    use mckibben::data::csv::{ReadOptions, read_traces};
    use mckibben::fit::run::FitTarget;
    use mckibben::fit::settings::FitSettings;
    use mckibben::model::Family;

    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/stair_4.5kg.csv");
    let trace = read_traces(&path, &ReadOptions::default())
        .unwrap()
        .remove(0);
    let settings = FitSettings {
        // Tries of 1000 and 100, 101 of them, of 300 generations each: more
        // than any machine runs in the budget, which cuts them all with a
        // best point each, some of them on an edge of the data's box.
        pop: 20_000,
        stops: StopRules {
            time_budget_s: Some(0.3),
            ..StopRules::default()
        },
        ..FitSettings::staged(1)
    };
    let (_, out) = fit_on(
        &trace,
        &FitTarget::chain(Family::Classic, &[]),
        &settings,
        0.0,
    );
    assert_eq!(out.stop, StopReason::TimeBudget);
    assert!(out.tries.len() > 1, "{} tries", out.tries.len());
    assert!(
        out.stages
            .iter()
            .all(|s| s.stage == mckibben::optim::stage::Stage::Global),
        "a refit ran: {:?}",
        out.stages
    );
}

/// `fit`'s run of `what` on `trace` with `settings` on the CPU, its chain's
/// build said to have taken `built_in_s` of the budget: the run and its
/// outcome.
fn fit_on(
    trace: &mckibben::data::Trace,
    what: &mckibben::fit::run::FitTarget,
    settings: &mckibben::fit::settings::FitSettings,
    built_in_s: f64,
) -> (mckibben::fit::run::FitRun, mckibben::optim::engine::Outcome) {
    let mut fit = mckibben::fit::run::FitRun::new(
        std::slice::from_ref(trace),
        what,
        settings,
        None,
        None,
        &|_| (),
    )
    .unwrap();
    fit.built_in_s = built_in_s;
    let (out, _) = fit
        .run(
            &mut mckibben::eval::cpu::CpuEvaluator::new(),
            &mut [],
            None,
            None,
        )
        .unwrap();
    (fit, out)
}
