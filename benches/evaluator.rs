//! Evaluator throughput (candidate-samples per second) for both backends and
//! both hysteretic models over populations 10³–10⁶, on a 1000-sample stair
//! experiment. `cargo bench --bench evaluator`; for single numbers with the
//! agreement check, use `mckibben bench`.
//!
//! The `effects` group scores the classic model with each effect of the
//! diagnosis' catalogue against the plain classic model on the CPU batch
//! path (`cargo bench --bench evaluator -- effects`).
//!
//! The GPU group runs on whatever adapter exists (lavapipe included) and is
//! skipped with a message when there is none.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use mckibben::eval::cpu::CpuEvaluator;
use mckibben::eval::gpu::GpuEvaluator;
use mckibben::eval::workload::{mixed_population, search_space, stair_experiment};
use mckibben::eval::{Evaluator, Problem};
use mckibben::model::Family;
use mckibben::model::effects::{Context, Effect, EffectBox, effect_box};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

const SAMPLES: usize = 1000;
const POPULATIONS: [usize; 4] = [1_000, 10_000, 100_000, 1_000_000];

fn throughput(c: &mut Criterion, name: &str, evaluator: &mut dyn Evaluator) {
    let exp = stair_experiment(SAMPLES, 1);
    let mut group = c.benchmark_group(name);
    group.sample_size(10);
    for family in [Family::Classic, Family::Generalized] {
        let space = search_space(family, &exp, false);
        let problem = Problem::new(family, vec![exp.clone()]);
        for n in POPULATIONS {
            let pop = mixed_population(&space, n, &mut ChaCha8Rng::seed_from_u64(1));
            group.throughput(Throughput::Elements((n * SAMPLES) as u64));
            group.bench_with_input(BenchmarkId::new(family.name(), n), &pop, |b, pop| {
                b.iter(|| {
                    evaluator
                        .evaluate(&problem, problem.rows(pop))
                        .expect("evaluate")
                })
            });
        }
    }
    group.finish();
}

/// Population of the effect group: the size the plain model's reference
/// throughput was measured at.
const EFFECT_POPULATION: usize = 131_072;

fn effects(c: &mut Criterion) {
    let exp = stair_experiment(SAMPLES, 1);
    let ctx = Context::of(&exp, true);
    let family = Family::Classic;
    let space = search_space(family, &exp, false);
    let base = mixed_population(&space, EFFECT_POPULATION, &mut ChaCha8Rng::seed_from_u64(1));
    let mut group = c.benchmark_group("effects");
    group.sample_size(10);
    group.throughput(Throughput::Elements((EFFECT_POPULATION * SAMPLES) as u64));
    let mut evaluator = CpuEvaluator::new();
    let plain = Problem::new(family, vec![exp.clone()]);
    group.bench_function("classic", |b| {
        b.iter(|| {
            evaluator
                .evaluate(&plain, plain.rows(&base))
                .expect("evaluate")
        })
    });
    for effect in Effect::ALL.into_iter().filter(|e| e.applicable(1)) {
        // Every candidate carries the effect halfway into its box.
        let EffectBox {
            neutral,
            lower: lo,
            upper: hi,
        } = effect_box(effect, &ctx, 1);
        let extra: Vec<f64> = (0..neutral.len())
            .map(|j| neutral[j] + 0.5 * (0.5 * (lo[j] + hi[j]) - neutral[j]))
            .collect();
        let pop: Vec<f64> = base
            .chunks_exact(family.dim())
            .flat_map(|row| row.iter().chain(&extra).copied())
            .collect();
        let problem = Problem::new(family, vec![exp.clone()]).with_effects(vec![effect], vec![ctx]);
        group.bench_function(format!("classic+{effect}"), |b| {
            b.iter(|| {
                evaluator
                    .evaluate(&problem, problem.rows(&pop))
                    .expect("evaluate")
            })
        });
    }
    group.finish();
}

fn cpu(c: &mut Criterion) {
    throughput(c, "cpu", &mut CpuEvaluator::new());
}

fn gpu(c: &mut Criterion) {
    match GpuEvaluator::open(Default::default()) {
        Ok(mut g) => {
            eprintln!("{}", g.describe());
            throughput(c, "gpu", &mut g);
        }
        Err(e) => eprintln!("SKIP gpu benchmarks: {e:#}"),
    }
}

criterion_group!(benches, cpu, effects, gpu);
criterion_main!(benches);
