//! The default staged fit reaches the noise floor on generated cases with a
//! known truth (issue 15, point 3): the validation RMSE within 5 % of the
//! truth's own, whatever the algorithm of the global stage.
//!
//! The cases come from `optim::cases` (truths across the thesis' boxes, slow
//! poles, negative γ, stair / multisine / mixed inputs, 0.02–0.1 mm noise).
//! A cheap subset runs in CI; the full 20-case matrix per family is ignored
//! for its time (`cargo test --release --test optim_convergence --
//! --ignored --nocapture`), and its results are in docs/RESULTS.md. The
//! classic matrix meets the bar; the generalized one does not yet, so it is
//! a measurement that prints its table, not a test parked as failing.

mod common;

use std::time::Instant;

use mckibben::eval::Evaluator;
use mckibben::eval::cpu::CpuEvaluator;
use mckibben::model::Family;
use mckibben::optim::Algorithm;
use mckibben::optim::cases::{Case, matrix};
use mckibben::optim::engine::StopRules;
use mckibben::optim::engine::model::{GENERATIONS, POPULATION, fit_task, staged_plan};

/// The fit's validation RMSE over the truth's, with the default plan.
fn ratio(case: &Case, algo: Algorithm) -> f64 {
    let r = ratio_at(case, algo, POPULATION, &mut CpuEvaluator::new());
    eprintln!("{:36} {algo}: validation RMSE ratio {r:.4}", case.name());
    r
}

/// [`ratio`] with population `n` on `evaluator`.
fn ratio_at(case: &Case, algo: Algorithm, n: usize, evaluator: &mut dyn Evaluator) -> f64 {
    let task = case.task();
    let plan = staged_plan(&task, algo.staged_settings(n), n, GENERATIONS);
    let (_, out) = fit_task(&task, plan, 1, StopRules::default(), evaluator).unwrap();
    task.validate(&out.params).rmse / case.truth_validation.rmse
}

/// Cases within 5 % of the truth, out of `count`, for `algo`.
fn passes(family: Family, count: usize, algo: Algorithm) -> usize {
    matrix(family, count, 1000)
        .into_iter()
        .map(Case::generate)
        .filter(|c| ratio(c, algo) <= 1.05)
        .count()
}

/// The first three classic cases of the matrix (a stair, a slow multisine,
/// a mixed input), every algorithm.
#[test]
fn classic_subset_reaches_the_noise_floor_with_every_algorithm() {
    for algo in Algorithm::ALL {
        assert_eq!(passes(Family::Classic, 3, algo), 3, "{algo}");
    }
}

#[test]
#[ignore = "full matrix: about 40 seconds an algorithm on 2 cores; results in docs/RESULTS.md"]
fn classic_matrix_reaches_the_noise_floor_in_19_of_20() {
    for algo in Algorithm::ALL {
        let n = passes(Family::Classic, 20, algo);
        eprintln!("classic {algo}: {n}/20");
        assert!(n >= 19, "classic {algo}: {n}/20");
    }
}

/// The generalized family's 20-case matrix, measured rather than passed:
/// it falls short of the 19-of-20 bar today (docs/RESULTS.md, "Where it
/// stands", says which cases fail and why), so this prints the table —
/// every case's validation RMSE over the truth's, per algorithm, `*` past
/// the 5 % bar, and the count within it — and asserts only what holds
/// whatever the count: every fit validates finite, and none more than 1 %
/// below the truth's own error. The truth's error is the noise floor: the
/// fit sees only the estimation half, so it cannot follow the validation
/// half's noise, and a ratio below the floor would mean the case's truth or
/// the validation is wrong.
#[test]
#[ignore = "measurement: about 75 seconds an algorithm on 2 cores; prints the table of docs/RESULTS.md"]
fn generalized_matrix_is_measured_and_no_fit_beats_the_noise_floor() {
    let cases: Vec<Case> = matrix(Family::Generalized, 20, 1000)
        .into_iter()
        .map(Case::generate)
        .collect();
    let mut table = format!("{:36}", "generalized case");
    for algo in Algorithm::ALL {
        table.push_str(&format!(" {:>8}", algo.to_string()));
    }
    let mut within = [0usize; Algorithm::ALL.len()];
    for case in &cases {
        table.push_str(&format!("\n{:36}", case.name()));
        for (a, algo) in Algorithm::ALL.into_iter().enumerate() {
            let r = ratio(case, algo);
            assert!(
                r.is_finite() && r >= 0.99,
                "{} {algo}: validation RMSE ratio {r} is not at or above the noise floor",
                case.name()
            );
            within[a] += usize::from(r <= 1.05);
            let mark = if r <= 1.05 { ' ' } else { '*' };
            table.push_str(&format!(" {r:>7.4}{mark}"));
        }
    }
    table.push_str(&format!("\n{:36}", "within 5 % of the truth"));
    for n in within {
        table.push_str(&format!(" {:>8}", format!("{n}/{}", cases.len())));
    }
    eprintln!("{table}");
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
            let r = ratio_at(&case, Algorithm::De, n, evaluator);
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
