//! Evaluator throughput (candidate-samples per second) for both backends and
//! both hysteretic models over populations 10³–10⁶, on a 1000-sample stair
//! experiment. `cargo bench --bench evaluator`; for single numbers with the
//! agreement check, use `mckibben bench`.
//!
//! The GPU group runs on whatever adapter exists (lavapipe included) and is
//! skipped with a message when there is none.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use mckibben::eval::cpu::CpuEvaluator;
use mckibben::eval::gpu::GpuEvaluator;
use mckibben::eval::workload::{mixed_population, search_space, stair_experiment};
use mckibben::eval::{Evaluator, Problem};
use mckibben::model::Family;
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
                b.iter(|| evaluator.evaluate(&problem, pop).expect("evaluate"))
            });
        }
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

criterion_group!(benches, cpu, gpu);
criterion_main!(benches);
