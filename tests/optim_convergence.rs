//! The default staged fit reaches the noise floor on generated cases with a
//! known truth: the validation RMSE within 5 % of the truth's own, whatever
//! the algorithm of the global stage; or, where the data cannot reach the
//! truth (its own polished optimum validates worse than that), an
//! estimation SSE within the likelihood-ratio threshold of that optimum's
//! ([`Case::judge`]).
//!
//! The cases come from `fit::cases`: truths of the bounded class drawn on
//! their own priors (slow poles, fast linear poles with a slow loop, both
//! classic classes), records in MPa→mm, kPa→m and psi→mm, stair / multisine
//! / mixed inputs, 0.02–0.1 mm of noise. A cheap subset runs in CI; the full
//! 20-case matrix per family is ignored for its time (`cargo test --release
//! --test optim_convergence -- --ignored --nocapture`), and its results are
//! in docs/RESULTS.md. The classic matrix meets the bar; the generalized one
//! does not yet, so it is a measurement that prints its counts, not a test
//! parked as failing.

mod common;

use std::time::Instant;

use mckibben::data::Trace;
use mckibben::eval::Evaluator;
use mckibben::eval::cpu::CpuEvaluator;
use mckibben::fit::cases::{Case, Judgement, SwitchAt, matrix, polished_truth};
use mckibben::fit::objective::{GENERATIONS, POPULATION, staged_plan};
use mckibben::fit::problem::FitProblem;
use mckibben::fit::run::run_fit;
use mckibben::fit::run::{FitRun, FitTarget};
use mckibben::fit::settings::FitSettings;
use mckibben::ident::fit::indistinguishable_up_to;
use mckibben::model::{Family, Flow, Loop, Switching, simulate};
use mckibben::optim::Algorithm;
use mckibben::optim::engine::StopRules;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// The default fit of `case` with `algo`, judged.
fn judged(case: &Case, algo: Algorithm) -> Judgement {
    let mut cpu = CpuEvaluator::new();
    let j = judged_at(case, algo, POPULATION, &mut cpu);
    eprintln!(
        "{:44} {algo}: validation RMSE ratio {:.4}{} -> {}",
        case.name(),
        j.ratio,
        j.polished_ratio
            .map_or(String::new(), |r| format!(" (the polished truth's {r:.4})")),
        if j.passes { "pass" } else { "FAIL" }
    );
    j
}

/// [`judged`] with population `n` on `evaluator`.
fn judged_at(case: &Case, algo: Algorithm, n: usize, evaluator: &mut dyn Evaluator) -> Judgement {
    let problem = case.problem();
    let plan = staged_plan(&problem, algo.staged_settings(n), n, GENERATIONS);
    let (_, out) = run_fit(&problem, plan, 1, StopRules::default(), evaluator).unwrap();
    case.judge(&out.params, evaluator).unwrap()
}

/// Of `count` cases of `family` with `algo`: how many are within 5 % of the
/// truth's validation RMSE, and how many pass either rule.
fn passes(family: Family, count: usize, algo: Algorithm) -> (usize, usize) {
    let judgements: Vec<Judgement> = matrix(family, count, 1000)
        .into_iter()
        .map(|spec| judged(&Case::generate(spec), algo))
        .collect();
    (
        judgements.iter().filter(|j| j.ratio <= 1.05).count(),
        judgements.iter().filter(|j| j.passes).count(),
    )
}

/// The first three classic cases of the matrix (a stair, a slow
/// multisine, a mixed input with a fast linear pole), every algorithm.
#[test]
fn classic_subset_reaches_the_noise_floor_with_every_algorithm() {
    for algo in Algorithm::ALL {
        assert_eq!(passes(Family::Classic, 3, algo).1, 3, "{algo}");
    }
}

/// The first three generalized cases, with the default algorithm.
#[test]
fn generalized_subset_reaches_the_noise_floor() {
    assert_eq!(passes(Family::Generalized, 3, Algorithm::De).1, 3);
}

#[test]
#[ignore = "full matrix: about a minute an algorithm on 2 cores; results in docs/RESULTS.md"]
fn classic_matrix_reaches_the_noise_floor_in_19_of_20() {
    for algo in Algorithm::ALL {
        let (within, passed) = passes(Family::Classic, 20, algo);
        eprintln!("classic {algo}: {within}/20 within 5 %, {passed}/20 pass");
        assert!(passed >= 19, "classic {algo}: {passed}/20");
    }
}

/// The generalized family's 20-case matrix, measured rather than passed:
/// it falls short of the 19-of-20 bar today (docs/RESULTS.md, "Generated
/// cases with a known truth", says which cases fail and why), so this
/// prints every case's judgement per algorithm and the counts, and asserts
/// only what holds whatever the count: every fit validates finite, and none
/// more than 1 % below the truth's own error. The truth's error is the
/// noise floor: the fit sees only the estimation half, so a ratio below it
/// would mean the case's truth or the validation is wrong.
#[test]
#[ignore = "measurement: about eight minutes an algorithm on 2 cores; prints the table of docs/RESULTS.md"]
fn generalized_matrix_is_measured_and_no_fit_beats_the_noise_floor() {
    let cases: Vec<Case> = matrix(Family::Generalized, 20, 1000)
        .into_iter()
        .map(Case::generate)
        .collect();
    for algo in Algorithm::ALL {
        let (mut within, mut passed) = (0, 0);
        for case in &cases {
            let j = judged(case, algo);
            assert!(
                j.ratio.is_finite() && j.ratio >= 0.99,
                "{} {algo}: validation RMSE ratio {} is not at or above the noise floor",
                case.name(),
                j.ratio
            );
            within += usize::from(j.ratio <= 1.05);
            passed += usize::from(j.passes);
        }
        eprintln!("generalized {algo}: {within}/20 within 5 %, {passed}/20 pass");
    }
}

/// The default fit of generalized `case` with `switching` ([`run_fit`]:
/// both starts of the default), judged: prints the fitted `x_s` against the
/// truth's and the estimation SSE.
fn judged_switching(case: &Case, switching: Switching, cpu: &mut CpuEvaluator) -> Judgement {
    let shape = (Loop::Bounded, switching);
    let problem = FitProblem::with_box(
        std::slice::from_ref(&case.trace),
        Family::Generalized,
        Flow::Joint,
        None,
        false,
        shape,
        &[],
    )
    .unwrap();
    let plan = staged_plan(
        &problem,
        Algorithm::De.staged_settings(POPULATION),
        POPULATION,
        GENERATIONS,
    );
    let start = Instant::now();
    let (_, out) = run_fit(&problem, plan, 1, StopRules::default(), cpu).unwrap();
    let j = case.judge(&out.params, cpu).unwrap();
    assert!(j.ratio.is_finite(), "{}: {switching:?}", case.name());
    let is = Family::Generalized.switch_index().unwrap();
    eprintln!(
        "{switching:?} {:44} x_s {:>9.4} (truth {:>9.4}) SSE {:>12.4}: ratio {:.4}{} -> {} ({:.1} s)",
        case.name(),
        out.params[is],
        case.truth[is],
        out.sse,
        j.ratio,
        j.polished_ratio
            .map_or(String::new(), |r| format!(" (the polished truth's {r:.4})")),
        if j.passes { "pass" } else { "FAIL" },
        start.elapsed().as_secs_f64()
    );
    j
}

/// A twin-like record of a generalized muscle whose loop switches at its
/// rest length, the sensor's zero (issue 44): a random stair of pressures
/// (levels in 0–0.4 MPa held 1–3 s) through a first-order valve lag of
/// 0.3 s, 4000 samples at 10 ms, as the rig twin's stair. The truth is the
/// generalized model `fit` finds on that stair (`data/stair_4.5kg.csv`,
/// rounded) with its loop switching at zero instead and its rest 10 mm
/// below zero (a loaded muscle: the output crosses zero at every low level,
/// in both halves), simulated in absolute units from zero; 0.05 mm of
/// noise. Returns the record and the truth in a fit's coordinates (its
/// estimation half's means).
fn stair_switching_at_zero(seed: u64) -> (Trace, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (len, dt) = (4000, 0.01);
    let lag = (-dt / 0.3f64).exp();
    let (mut p, mut level, mut held, mut valve) = (Vec::with_capacity(len), 0.0, 0, 0.0);
    while p.len() < len {
        if held == 0 {
            level = rng.random_range(0.0..0.4);
            held = rng.random_range(100..300);
        }
        valve = lag * valve + (1.0 - lag) * level;
        p.push(valve);
        held -= 1;
    }
    let (a, alpha, b, c) = (0.96, 0.9, 5.7, -0.4);
    let mut theta = vec![1.0, alpha, 0.21, 0.0, -0.06, -0.2, 0.0, 0.065];
    theta.extend([1.0, 0.0, a, b, c, 0.0]);
    let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
    let u: Vec<f32> = p.iter().map(|&v| v as f32).collect();
    let clean = simulate(Family::Generalized, &t, 0.0, &u, 0.0);
    assert!(clean.diverged_at.is_none());
    let l: Vec<f64> = clean
        .x
        .iter()
        .map(|&x| x as f64 + 0.05 * rng.sample::<f64, _>(StandardNormal))
        .collect();
    let trace = Trace::uniform(format!("stair switching at zero #{seed}"), dt, p, l);
    // In the estimation half's coordinates the intercept carries the means;
    // the switching level is absolute; the state starts at the noiseless
    // first sample.
    let problem = FitProblem::new(&trace, Family::Generalized, Flow::Joint, None, false).unwrap();
    let est = problem.estimation();
    let [_, _, ic] = Family::Generalized.linear_indices();
    theta[ic] = c + b * est.u_mean - (1.0 - a * alpha) * est.y_mean;
    theta[Family::Generalized.start_index()] = clean.x[0] as f64 - trace.output[0];
    (trace, theta)
}

/// Muscles that switch at their rest length, on six random stairs
/// (`stair_switching_at_zero`, records 44–49). The default `fit --model
/// generalized` searches the level and keeps the sensor's zero exactly on
/// every one (a level held at the estimation mean, every fit before `x_s`,
/// ends at four times the noise floor's estimation SSE); on five of six it
/// ends within the likelihood-ratio threshold of the truth polished on the
/// estimation half (or below it), and on four it validates within 5 % of
/// the truth's own error. Record 44 ends 0.07 % above the threshold and at
/// 1.07 times the truth's error, record 46 below its polished truth's SSE
/// and at 1.06: on such records the estimation half does not settle the
/// validation error that closely (docs/RESULTS.md, "Where the generalized
/// loop switches").
#[test]
fn muscles_switching_at_their_rest_length_keep_the_sensors_zero() {
    let what = FitTarget::chain(Family::Generalized, &[]);
    let is = Family::Generalized.switch_index().unwrap();
    let (mut settled, mut within) = (0, 0);
    for record in 44..50 {
        let (trace, truth) = stair_switching_at_zero(record);
        let problem =
            FitProblem::new(&trace, Family::Generalized, Flow::Joint, None, false).unwrap();
        let floor = problem.validate(&truth).rmse;
        assert!(floor < 0.06, "#{record}: the truth validates at {floor}");
        let (_, polished_sse) = polished_truth(&problem, &truth, &mut CpuEvaluator::new()).unwrap();
        let threshold = indistinguishable_up_to(polished_sse, problem.estimation().len() - 1);
        let mut fit = FitRun::new(
            std::slice::from_ref(&trace),
            &what,
            &FitSettings::staged(1),
            None,
            None,
            &|_| (),
        )
        .unwrap();
        let (out, _) = fit
            .run(&mut CpuEvaluator::new(), &mut [], None, None)
            .unwrap();
        let ratio = fit.problem.validate(&out.params).rmse / floor;
        eprintln!(
            "#{record}: validation RMSE ratio {ratio:.4}, estimation SSE {:.4} (polished truth {polished_sse:.4}), x_s {}",
            out.sse, out.params[is]
        );
        assert_eq!(out.params[is], 0.0, "#{record}: the sensor's zero kept");
        settled += usize::from(out.sse <= threshold);
        within += usize::from(ratio <= 1.05);
    }
    assert!(settled >= 5, "{settled} of 6 within the threshold");
    assert!(within >= 4, "{within} of 6 within 5 %");
}

/// Where the generalized model's sign terms switch, measured: the matrix
/// (half its truths switch at the estimation mean, half at the sensor's
/// zero) fitted by `fit`'s defaults with DE and `switching`. Prints every
/// judgement and the counts per kind of truth (docs/RESULTS.md, "Where the
/// generalized loop switches"); asserts only that every fit validates finite.
fn measure_switching(switching: Switching) {
    let cases: Vec<Case> = matrix(Family::Generalized, 20, 1000)
        .into_iter()
        .map(Case::generate)
        .collect();
    let mut cpu = CpuEvaluator::new();
    // (within 5 %, pass) per kind of truth: at the mean, at zero.
    let mut counts = [[0usize; 2]; 2];
    for case in &cases {
        let j = judged_switching(case, switching, &mut cpu);
        let kind = usize::from(case.spec.switch == SwitchAt::SensorZero);
        counts[kind][0] += usize::from(j.ratio <= 1.05);
        counts[kind][1] += usize::from(j.passes);
    }
    eprintln!(
        "generalized, --switch {switching:?}: truths at the mean {}/10 within 5 %, {}/10 pass; \
         at zero {}/10 within 5 %, {}/10 pass",
        counts[0][0], counts[0][1], counts[1][0], counts[1][1]
    );
}

#[test]
#[ignore = "measurement: about fifteen minutes on 2 cores; results in docs/RESULTS.md"]
fn generalized_switching_from_two_starts_is_measured() {
    measure_switching(Switching::Starts);
}

#[test]
#[ignore = "measurement: about ten minutes on 2 cores; results in docs/RESULTS.md"]
fn generalized_switching_searched_is_measured() {
    measure_switching(Switching::Search);
}

#[test]
#[ignore = "measurement: about ten minutes on 2 cores; results in docs/RESULTS.md"]
fn generalized_switching_at_the_mean_is_measured() {
    measure_switching(Switching::Mean);
}

#[test]
#[ignore = "measurement: about ten minutes on 2 cores; results in docs/RESULTS.md"]
fn generalized_switching_at_zero_is_measured() {
    measure_switching(Switching::Zero);
}

/// Issue 15, point 4: the default fit of the matrix's first classic case
/// (a stair) at N = 10² … 10⁶ (CPU; lavapipe to 10⁴, several times slower
/// there), fixed G. Prints the table of docs/RESULTS.md and checks that a
/// larger population never ends further from the truth than the one before
/// it, unless it is within the matrix's 5 % bar.
#[test]
#[ignore = "population sweep: about 20 minutes on 2 cores; results in docs/RESULTS.md"]
fn larger_populations_do_not_fit_worse() {
    let case = Case::generate(matrix(Family::Classic, 1, 1000)[0]);
    let mut lavapipe = common::require_lavapipe(Default::default());
    let mut cpu = CpuEvaluator::new();
    for (backend, top) in [("cpu", 1_000_000), ("lavapipe", 10_000)] {
        let mut previous = f64::INFINITY;
        for n in [100, 1_000, 10_000, 100_000, 1_000_000]
            .into_iter()
            .filter(|&n| n <= top)
        {
            let evaluator: &mut dyn Evaluator = match (backend, lavapipe.as_mut()) {
                ("cpu", _) => &mut cpu,
                (_, Some(gpu)) => gpu,
                _ => break,
            };
            let start = Instant::now();
            let r = judged_at(&case, Algorithm::De, n, evaluator).ratio;
            eprintln!(
                "{} {backend} N = {n}: validation RMSE ratio {r:.4} in {:.1} s",
                case.name(),
                start.elapsed().as_secs_f64()
            );
            assert!(
                r <= previous.max(1.05),
                "N = {n} fits worse: {r} > {previous}"
            );
            previous = r;
        }
    }
}
