//! The optimizer's own work in one generation, without the evaluator: each
//! algorithm's ask and tell (its staged settings) on an island of 25 000
//! rows, a quarter of `fit --pop 100000`, in the seven free coordinates of
//! the classic fit of the shipped stair; and the mapping of 10⁵ such rows to
//! canonical parameters (`Space::embed_into`). The costs told are a fixed
//! pseudo-random draw, so every generation does the same work. And a
//! polish step's algebra after its probes: the Jacobian of 2000 residuals
//! in those seven coordinates, its normal equations, and for comparison
//! the same equations by nalgebra's explicit product.
//! `cargo bench --bench optimizer_step`; figures in docs/PERFORMANCE.md.

use criterion::{Criterion, criterion_group, criterion_main};
use mckibben::data::csv::{ReadOptions, read_traces_with_notes};
use mckibben::fit::chart::ModelChart;
use mckibben::fit::problem::FitProblem;
use mckibben::model::{Family, Flow};
use mckibben::optim::engine::Space;
use mckibben::optim::normal::Jacobian;
use mckibben::optim::stage::Stage;
use mckibben::optim::{Algorithm, AskTell, Streams};
use mckibben::search::Population;
use nalgebra::{DMatrix, DVector};

/// Rows of one island of `fit --pop 100000` (four islands).
const ISLAND: usize = 25_000;

fn stair_space() -> Space<ModelChart> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/stair_4.5kg.csv");
    let (traces, _) =
        read_traces_with_notes(&path, &ReadOptions::default()).expect("the shipped stair");
    let problem = FitProblem::new(&traces[0], Family::Classic, Flow::Joint, None, false).unwrap();
    Space::from(&problem.space)
}

/// Costs for `n` rows: a fixed scramble of 1..n, so the ranking is dense.
fn costs(n: usize) -> Vec<f32> {
    (0..n).map(|i| ((i * 7919) % n) as f32 + 1.0).collect()
}

fn generation(c: &mut Criterion) {
    let space = stair_space();
    let bounds = space.bounds();
    let told = costs(ISLAND);
    let mut group = c.benchmark_group("optimizer_step");
    group.sample_size(20);
    for algo in Algorithm::ALL {
        // A search that has asked and been told once; every iteration then
        // makes a move and is told its costs, in its steady state (its
        // buffers already made).
        let rows = space.draw(ISLAND, &Streams::new(1, Stage::Global, 0));
        let mut search = AskTell::new(
            &algo.staged_settings(4 * ISLAND),
            bounds.clone(),
            ISLAND,
            300,
            rows,
        );
        search.ask(&Streams::new(1, Stage::Global, 1)).unwrap();
        search.tell(&told).unwrap();
        let mut generation = 2;
        group.bench_function(format!("{algo} ask+tell, 25000 rows"), |b| {
            b.iter(|| {
                search
                    .ask(&Streams::new(1, Stage::Global, generation))
                    .unwrap();
                search.tell(&told).unwrap();
                generation += 1;
            })
        });
    }
    let rows = space.draw(4 * ISLAND, &Streams::new(1, Stage::Global, 0));
    let mut canonical = Population::zeros(4 * ISLAND, space.dim());
    group.bench_function("Space::embed_into, 100000 rows", |b| {
        b.iter(|| space.embed_into(rows.rows(), &mut canonical))
    });
    group.finish();
}

/// Residuals a polish step's Jacobian has: the shipped stair's estimation
/// half.
const SAMPLES: usize = 2000;

/// A polish step once its probes are scored: the Jacobian's columns from
/// the probes' residuals and the start's, then `JᵀJ` and `Jᵀr`.
fn polish_step(c: &mut Criterion) {
    let d = stair_space().bounds().dim();
    let wave = |j: usize| -> Vec<f64> {
        (0..SAMPLES)
            .map(|k| ((k * (j + 3)) as f64 * 0.01).sin())
            .collect()
    };
    let r = wave(0);
    let probes: Vec<Vec<f64>> = (1..=d).map(wave).collect();
    let step = 1e-6;
    let mut group = c.benchmark_group("polish_step");
    group.sample_size(50);
    let mut jac = Jacobian::zeros(SAMPLES, d);
    group.bench_function(
        format!("Jacobian and normal equations, {SAMPLES} x {d}"),
        |b| {
            b.iter(|| {
                for (j, p) in probes.iter().enumerate() {
                    jac.set_column(j, p.iter().zip(&r).map(|(p, r)| (p - r) / step));
                }
                jac.normal_equations(&r)
            })
        },
    );
    let r_vec = DVector::from_column_slice(&r);
    group.bench_function(
        format!("the same by nalgebra's explicit product, {SAMPLES} x {d}"),
        |b| {
            b.iter(|| {
                let mut explicit = DMatrix::<f64>::zeros(SAMPLES, d);
                for (j, p) in probes.iter().enumerate() {
                    let p = DVector::from_column_slice(p);
                    explicit.set_column(j, &((p - &r_vec) / step));
                }
                (
                    explicit.transpose() * &explicit,
                    explicit.transpose() * &r_vec,
                )
            })
        },
    );
    group.finish();
}

criterion_group!(benches, generation, polish_step);
criterion_main!(benches);
