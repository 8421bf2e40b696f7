//! The batched CPU evaluator against the reference `model::sse`, bit for bit.

use mckibben::eval::cpu::{CpuEvaluator, LANES};
use mckibben::eval::workload::{mixed_population, search_space, stair_experiment};
use mckibben::eval::{Evaluator, Problem, to_f32};
use mckibben::model::{Family, sse};
use mckibben::search::Rows;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// Reference scores, one candidate at a time.
fn reference(problem: &Problem, population: &[f64]) -> Vec<Vec<f32>> {
    let d = problem.family.dim();
    let rows = to_f32(population);
    problem
        .experiments
        .iter()
        .map(|e| {
            rows.chunks_exact(d)
                .map(|t| sse(problem.family, t, e.y_mean as f32, &e.u, &e.y))
                .collect()
        })
        .collect()
}

fn assert_bit_identical(got: &[f32], want: &[f32], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: count");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert_eq!(
            g.to_bits(),
            w.to_bits(),
            "{what}: candidate {i}: {g} vs {w}"
        );
    }
}

#[test]
fn batched_cpu_is_bit_identical_to_reference_sse() {
    let exp = stair_experiment(1500, 7);
    for family in Family::ALL {
        for free_n in [false, true] {
            if free_n && family == Family::Linear {
                continue;
            }
            let space = search_space(family, &exp, free_n);
            let mut rng = ChaCha8Rng::seed_from_u64(11);
            // 5 full batches and a short one.
            let pop = mixed_population(&space, 5 * LANES + 7, &mut rng);
            let problem = Problem::new(family, vec![exp.clone()]);
            let scores = CpuEvaluator::new()
                .evaluate(&problem, problem.rows(&pop))
                .unwrap();
            let want = reference(&problem, &pop);
            let what = format!("{family} free_n={free_n}");
            assert_bit_identical(&scores.per_experiment[0], &want[0], &what);
            assert_bit_identical(&scores.total, &want[0], &what);
            let diverged = want[0].iter().filter(|v| v.is_infinite()).count();
            let finite = want[0].len() - diverged;
            assert!(
                diverged > 0 && finite > 0,
                "{what}: the draw must mix finite ({finite}) and diverged ({diverged}) candidates"
            );
        }
    }
}

#[test]
fn several_experiments_score_separately_and_sum() {
    let (e1, e2) = (stair_experiment(700, 1), stair_experiment(400, 2));
    let space = search_space(Family::Generalized, &e1, false);
    let pop = mixed_population(&space, 40, &mut ChaCha8Rng::seed_from_u64(3));
    let both = Problem::new(Family::Generalized, vec![e1.clone(), e2.clone()]);
    let scores = CpuEvaluator::new()
        .evaluate(&both, both.rows(&pop))
        .unwrap();
    let want = reference(&both, &pop);
    assert_bit_identical(&scores.per_experiment[0], &want[0], "first");
    assert_bit_identical(&scores.per_experiment[1], &want[1], "second");
    for (i, total) in scores.total.iter().enumerate() {
        assert_eq!(total.to_bits(), (want[0][i] + want[1][i]).to_bits());
    }
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let exp = stair_experiment(600, 5);
    let space = search_space(Family::Classic, &exp, false);
    let pop = mixed_population(&space, 300, &mut ChaCha8Rng::seed_from_u64(9));
    let problem = Problem::new(Family::Classic, vec![exp]);
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            CpuEvaluator::new()
                .evaluate(&problem, problem.rows(&pop))
                .unwrap()
        })
    };
    assert_eq!(run(1), run(3));
}

#[test]
fn short_traces_and_bad_lengths() {
    let exp = stair_experiment(1, 5);
    let problem = Problem::new(Family::Classic, vec![exp]);
    let d = Family::Classic.dim();
    let pop = vec![0.5; d * 3];
    let scores = CpuEvaluator::new()
        .evaluate(&problem, problem.rows(&pop))
        .unwrap();
    assert_eq!(scores.total, vec![0.0; 3]);
    // Rows of another model's length are refused, not read across.
    let err = CpuEvaluator::new()
        .evaluate(&problem, Rows::new(&pop[..3 * (d - 1)], d - 1))
        .unwrap_err();
    assert!(
        err.to_string().contains(&format!("has {d} parameters")),
        "{err}"
    );
}
