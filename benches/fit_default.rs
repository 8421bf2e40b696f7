//! Wall time of the default `mckibben fit` on the shipped 4.5 kg stair: the
//! whole staged fit (global stage, free-run stage, polish) on the CPU
//! backend, as the command runs it without its file output.
//! `cargo bench --bench fit_default`; figures in docs/PERFORMANCE.md.

use criterion::{Criterion, criterion_group, criterion_main};
use mckibben::data::csv::{ReadOptions, read_traces_with_notes};
use mckibben::eval::cpu::CpuEvaluator;
use mckibben::fit::objective::{GENERATIONS, POPULATION, staged_plan};
use mckibben::fit::problem::FitProblem;
use mckibben::fit::run::run_fit;
use mckibben::model::{Family, Flow};
use mckibben::optim::Algorithm;
use mckibben::optim::engine::StopRules;

fn default_fit(c: &mut Criterion) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/stair_4.5kg.csv");
    let (traces, _) =
        read_traces_with_notes(&path, &ReadOptions::default()).expect("the shipped stair");
    let problem = FitProblem::new(&traces[0], Family::Classic, Flow::Joint, None, false).unwrap();
    let mut group = c.benchmark_group("fit_default");
    group.sample_size(10);
    group.bench_function("classic de stair_4.5kg", |b| {
        b.iter(|| {
            let plan = staged_plan(
                &problem,
                Algorithm::De.staged_settings(POPULATION),
                POPULATION,
                GENERATIONS,
            );
            run_fit(
                &problem,
                plan,
                1,
                StopRules::default(),
                &mut CpuEvaluator::new(),
            )
            .unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, default_fit);
criterion_main!(benches);
