//! Wall time of the default `mckibben diagnose` on the shipped 4.5 kg stair:
//! the baseline fit, every round of candidate fits, the size intervals, the
//! explainable bound and the spectra, on the CPU backend, as the command
//! runs it without printing. Issue 17 asks for ≤ 30 s on two cores.
//! `cargo bench --bench diagnose_default`; figures in docs/PERFORMANCE.md.

use criterion::{Criterion, criterion_group, criterion_main};
use mckibben::data::csv::{ReadOptions, read_traces_with_notes};
use mckibben::diagnose::{Effect, Settings, diagnose};
use mckibben::model::Family;

fn default_diagnose(c: &mut Criterion) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/stair_4.5kg.csv");
    let (traces, _) =
        read_traces_with_notes(&path, &ReadOptions::default()).expect("the shipped stair");
    let mut group = c.benchmark_group("diagnose_default");
    // Criterion's fewest samples; one takes about 16 s here.
    group.sample_size(10);
    group.bench_function("classic stair_4.5kg", |b| {
        b.iter(|| {
            diagnose(
                &traces,
                Family::Classic,
                &Effect::by_default(),
                &Settings::default(),
            )
            .unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, default_diagnose);
criterion_main!(benches);
