//! The default staged fit reaches the noise floor on generated cases with a
//! known truth: the validation RMSE within 5 % of the truth's own, whatever
//! the algorithm of the global stage; or, where the data cannot reach the
//! truth (its own polished optimum validates worse than that), an
//! estimation SSE within the likelihood-ratio threshold of that optimum's
//! ([`Case::judge`]).
//!
//! The cases come from `optim::cases`: truths of the bounded class drawn on
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

use mckibben::eval::Evaluator;
use mckibben::eval::cpu::CpuEvaluator;
use mckibben::model::Family;
use mckibben::optim::Algorithm;
use mckibben::optim::cases::{Case, Judgement, matrix};
use mckibben::optim::edge::fit_task;
use mckibben::optim::engine::StopRules;
use mckibben::optim::engine::model::{GENERATIONS, POPULATION, staged_plan};

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
    let task = case.task();
    let plan = staged_plan(&task, algo.staged_settings(n), n, GENERATIONS);
    let (_, out) = fit_task(&task, plan, 1, StopRules::default(), evaluator).unwrap();
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
#[ignore = "measurement: about five minutes an algorithm on 2 cores; prints the table of docs/RESULTS.md"]
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
