//! A larger population buys independent tries: with the same seed a run of
//! more tries runs the tries of a run of fewer, bit for bit, and ends at an
//! estimation SSE no higher; every try's candidates are scored in the same
//! evaluator calls, and the result does not depend on the thread count, the
//! backend (lavapipe) or an interrupt and resume. Checked on the generalized
//! family in the data-scale box, whose switching level is searched as a
//! level (held by the polish, moved by a scan, tried at its preferred
//! values), so that every step of the plan runs: the global stage, the
//! free-run stage, the polish, the refining rounds and the level rounds.

mod common;

use std::sync::atomic::AtomicBool;

use mckibben::eval::Evaluator;
use mckibben::eval::cpu::CpuEvaluator;
use mckibben::fit::chart::ModelChart;
use mckibben::fit::objective::{ModelObjective, staged_plan};
use mckibben::fit::problem::FitProblem;
use mckibben::fit::run::run_fit;
use mckibben::fit::synthetic::Synthetic;
use mckibben::model::{Family, Flow};
use mckibben::optim::Algorithm;
use mckibben::optim::engine::{Engine, Outcome, Plan, Stage, StopReason, StopRules, TrySize};
use mckibben::optim::streams::try_seed;

/// A generalized record of 600 samples and its fitting problem (the
/// switching level searched, the default).
fn problem() -> FitProblem {
    let s = Synthetic::new(Family::Generalized, 600, 0.05, 6);
    FitProblem::new(&s.trace, Family::Generalized, Flow::Joint, None, false).unwrap()
}

/// The default plan at a small size: `tries` tries of 40 for 12
/// generations, refining rounds of 8 for 6 generations, short polishes.
fn plan(problem: &FitProblem, tries: usize) -> Plan {
    let mut plan = staged_plan(problem, Algorithm::De.staged_settings(40), 40, 12);
    plan.tries = tries;
    let polish = plan.polish.as_mut().unwrap();
    polish.starts = 2;
    polish.iterations = 4;
    let refine = plan.refine.as_mut().unwrap();
    (refine.population, refine.generations, refine.rounds) = (8, 6, 2);
    plan
}

fn run(
    problem: &FitProblem,
    plan: Plan,
    evaluator: &mut dyn Evaluator,
) -> (Engine<ModelChart>, Outcome) {
    run_seeded(problem, plan, 3, evaluator)
}

fn run_seeded(
    problem: &FitProblem,
    plan: Plan,
    seed: u64,
    evaluator: &mut dyn Evaluator,
) -> (Engine<ModelChart>, Outcome) {
    let mut engine = Engine::new(plan, problem.engine_space(), seed, StopRules::default()).unwrap();
    let mut objective = ModelObjective::for_problem(evaluator, problem);
    let outcome = engine.run(&mut objective, &mut [], None, None).unwrap();
    (engine, outcome)
}

#[test]
fn more_tries_run_the_tries_of_fewer_and_never_end_higher() {
    let problem = problem();
    let mut cpu = CpuEvaluator::new();
    let (one_engine, one) = run(&problem, plan(&problem, 1), &mut cpu);
    let (_, three) = run(&problem, plan(&problem, 3), &mut cpu);
    // Every step of the plan ran, the level rounds included.
    let stages = one_engine.stages();
    assert!(stages.contains(&Stage::Refine), "{stages:?}");
    assert!(
        stages.len() > 5,
        "refining and level rounds follow the polish: {stages:?}"
    );
    assert_eq!(one.tries.len(), 1);
    assert_eq!(three.tries.len(), 3);
    assert_eq!(
        three.tries[0], one.tries[0],
        "the first try is the run of one"
    );
    assert_ne!(three.tries[1], three.tries[0], "each try its own seed");
    // Each try is the run of one from its own seed: nothing passes between
    // them.
    for t in 1..3 {
        let (_, alone) = run_seeded(&problem, plan(&problem, 1), try_seed(3, t), &mut cpu);
        assert_eq!(three.tries[t], alone.tries[0], "try {t}");
    }
    assert!(three.sse <= one.sse, "{} > {}", three.sse, one.sse);
    let lowest = three
        .tries
        .iter()
        .map(|t| t.sse)
        .fold(f64::INFINITY, f64::min);
    assert_eq!(three.sse, lowest, "the lowest try is kept");
    // Settled by the edge rule, each in its own box: still nested.
    let (_, settled_one) = run_fit(
        &problem,
        plan(&problem, 1),
        3,
        StopRules::default(),
        &mut cpu,
    )
    .unwrap();
    let (_, settled_three) = run_fit(
        &problem,
        plan(&problem, 3),
        3,
        StopRules::default(),
        &mut cpu,
    )
    .unwrap();
    assert_eq!(settled_three.tries[0], settled_one.tries[0]);
    assert!(settled_three.sse <= settled_one.sse);
}

/// `plan` with tries of these global populations (a fifth of each, at
/// least four an island, in the free-run stage; eight in a refining round;
/// a polish start for each 20 of the population).
fn sized(mut plan: Plan, populations: &[usize]) -> Plan {
    plan.tries = populations.len();
    plan.sizes = populations
        .iter()
        .map(|&global| TrySize {
            global,
            free_run: (global / 5).max(16),
            refine: 8,
            polish: (global / 20).max(1),
        })
        .collect();
    plan
}

#[test]
fn tries_of_different_sizes_each_run_as_alone() {
    let problem = problem();
    let mut cpu = CpuEvaluator::new();
    let populations = [40, 40, 16, 16, 40];
    let (_, mixed) = run(&problem, sized(plan(&problem, 1), &populations), &mut cpu);
    assert_eq!(mixed.tries.len(), populations.len());
    for (t, &n) in populations.iter().enumerate() {
        let (_, alone) = run_seeded(
            &problem,
            sized(plan(&problem, 1), &[n]),
            try_seed(3, t),
            &mut cpu,
        );
        assert_eq!(mixed.tries[t], alone.tries[0], "try {t} of {n}");
    }
    assert_ne!(mixed.tries[2], mixed.tries[0]);
    // The first try of a sized plan is the unsized plan's run of one.
    let (_, one) = run(&problem, plan(&problem, 1), &mut cpu);
    assert_eq!(mixed.tries[0], one.tries[0]);
    // Every size is checked against its algorithm's smallest island.
    let tiny = sized(plan(&problem, 1), &[40, 8]);
    let refused = Engine::new(tiny, problem.engine_space(), 3, StopRules::default());
    assert!(refused.is_err());
}

#[test]
fn tries_do_not_depend_on_the_thread_count() {
    let problem = problem();
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let plan = sized(plan(&problem, 1), &[40, 16, 40]);
                run(&problem, plan, &mut CpuEvaluator::new()).1
            })
    };
    let one = on(1);
    for threads in [2, 3] {
        let other = on(threads);
        assert_eq!(other.tries, one.tries, "{threads} threads");
        assert_eq!(other.params, one.params, "{threads} threads");
    }
}

/// Cut in the global stage, the polish and a refining round, each run
/// resumes from its checkpoint to the uninterrupted result.
#[test]
fn an_interrupted_run_of_tries_resumes_to_the_identical_result() {
    let problem = problem();
    let dir = tempfile::tempdir().unwrap();
    let (straight, full) = run(&problem, plan(&problem, 3), &mut CpuEvaluator::new());
    let records = straight.history.records.len();
    let refine_at = straight
        .history
        .records
        .iter()
        .position(|r| r.stage == Stage::Refine)
        .unwrap()
        + 2;
    for at in [4, 20, refine_at] {
        assert!(at < records);
        let path = dir.path().join(format!("{at}.json"));
        let flag = AtomicBool::new(false);
        let mut first = Engine::new(
            plan(&problem, 3),
            problem.engine_space(),
            3,
            StopRules::default(),
        )
        .unwrap();
        let mut cpu = CpuEvaluator::new();
        let mut objective = ModelObjective::for_problem(&mut cpu, &problem);
        let cut = first
            .run(
                &mut objective,
                &mut [&mut common::InterruptAt(at, &flag)],
                Some(&flag),
                Some(&path),
            )
            .unwrap();
        assert_eq!(cut.stop, StopReason::Interrupted, "at {at}");
        let mut resumed = Engine::<ModelChart>::load(&path).unwrap();
        let mut cpu = CpuEvaluator::new();
        let mut objective = ModelObjective::for_problem(&mut cpu, &problem);
        let out = resumed.run(&mut objective, &mut [], None, None).unwrap();
        assert_eq!(out.tries, full.tries, "at {at}");
        assert_eq!(out.evaluations, full.evaluations, "at {at}");
    }
}

/// The same tries, bit for bit, on lavapipe, where the polish's starts of
/// every try share its calls; a hardware GPU agrees within 1e-3.
#[test]
fn cpu_and_gpu_backends_give_the_same_tries() {
    use mckibben::eval::gpu::GpuEvaluator;
    let Some(mut gpu) = common::require_gpu(GpuEvaluator::open(Default::default())) else {
        return;
    };
    let software = common::is_lavapipe(gpu.adapter_info());
    let problem = problem();
    let mixed = || sized(plan(&problem, 1), &[40, 16, 40]);
    let (_, a) = run(&problem, mixed(), &mut CpuEvaluator::new());
    let (_, b) = run(&problem, mixed(), &mut gpu);
    if software {
        assert_eq!(a.tries, b.tries);
    } else {
        assert!(
            (a.sse - b.sse).abs() <= 1e-3 * a.sse,
            "{} vs {}",
            a.sse,
            b.sse
        );
    }
}

/// A larger cap on the refining rounds only adds rounds: a try that stopped
/// refining on the gain rule within the smaller cap ends bit for bit as
/// under it (the level rounds draw the same numbers whatever the cap), and
/// a try the smaller cap cut short says by how much its last round still
/// gained.
#[test]
fn a_larger_refining_cap_only_adds_rounds() {
    let problem = problem();
    let mut cpu = CpuEvaluator::new();
    let capped = |rounds: usize| {
        let mut p = plan(&problem, 6);
        p.refine.as_mut().unwrap().rounds = rounds;
        p
    };
    let (_, small) = run(&problem, capped(1), &mut cpu);
    let (_, large) = run(&problem, capped(6), &mut cpu);
    let gain = plan(&problem, 1).refine.unwrap().gain;
    let (mut stopped, mut cut) = (0, 0);
    for (t, (s, l)) in small.tries.iter().zip(&large.tries).enumerate() {
        match s.cut_gain {
            None => {
                stopped += 1;
                assert_eq!(s, l, "try {t} stopped refining within the smaller cap");
            }
            Some(g) => {
                cut += 1;
                assert!(g > gain, "try {t}: a cut try's last round gained {g}");
            }
        }
    }
    assert!(stopped > 0 && cut > 0, "{stopped} stopped, {cut} cut");
}
