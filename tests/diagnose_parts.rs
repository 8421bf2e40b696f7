//! Numbers no choice saw: the diagnosis chooses on the selection part and
//! reads the test part once, and `fit` reads its estimation half alone. So
//! replacing the test part's outputs (the diagnosis) or the validation
//! half's (`fit`) by noise moves only the figures scored there.

mod common;

use std::ops::Range;

use mckibben::data::Trace;
use mckibben::data::csv::{Gaps, ReadOptions, read_traces};
use mckibben::diagnose::{Diagnosis, Settings, diagnose};
use mckibben::fit::run::{FitRun, FitTarget};
use mckibben::fit::settings::FitSettings;
use mckibben::model::Family;
use mckibben::model::experiment::halves;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// `trace` with the outputs on `ranges` replaced by their mean plus noise
/// three times their spread: wide of everything the record holds there.
fn scrambled(trace: &Trace, ranges: &[Range<usize>], seed: u64) -> Trace {
    let samples: Vec<f64> = ranges
        .iter()
        .flat_map(|r| trace.output[r.clone()].iter().copied())
        .collect();
    let mean = samples.iter().sum::<f64>() / samples.len() as f64;
    let spread =
        (samples.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / samples.len() as f64).sqrt();
    let noise = Normal::new(0.0, 3.0 * spread).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = trace.clone();
    for r in ranges {
        for v in &mut out.output[r.clone()] {
            *v = mean + noise.sample(&mut rng);
        }
    }
    out
}

/// The diagnosis' settings for these checks: the whole catalogue and every
/// stage, on smaller budgets (the invariance does not depend on them).
fn quick() -> Settings {
    Settings {
        generations: 60,
        baseline_generations: 150,
        baseline_seeds: 4,
        scratch_seeds: 1,
        ..Settings::default()
    }
}

/// Diagnoses `trace`, then the same with its test part's outputs
/// scrambled, and checks that only the figures on the test part moved.
fn test_part_is_read_only_for_test_figures(trace: &Trace) {
    let settings = quick();
    let effects = mckibben::diagnose::Effect::by_default();
    let d = diagnose(
        std::slice::from_ref(trace),
        Family::Classic,
        &effects,
        &settings,
    )
    .unwrap();
    let test = d.parts[0].test.clone();
    assert!(!test.is_empty());
    let other = scrambled(trace, &test, 7);
    let e = diagnose(
        std::slice::from_ref(&other),
        Family::Classic,
        &effects,
        &settings,
    )
    .unwrap();

    // Every choice and every parameter: bit for bit.
    assert_eq!(d.parts, e.parts);
    assert_eq!(d.selection, e.selection, "the selection moved");
    assert_eq!(d.named(), e.named());
    assert_eq!(d.final_model, e.final_model);
    assert_eq!(d.baseline_model, e.baseline_model);
    assert_eq!(d.size_intervals, e.size_intervals);
    assert_eq!(d.refits, e.refits);
    assert_eq!(d.explainable, e.explainable);
    assert_eq!(d.locate, e.locate);
    assert_eq!(d.spectrum, e.spectrum);
    assert_eq!(d.noise_floor_rmse.to_bits(), e.noise_floor_rmse.to_bits());
    // Every selection figure too; every test figure moved.
    assert_eq!(d.steps.len(), e.steps.len());
    for (a, b) in d.steps.iter().zip(&e.steps) {
        let selection = |s: &mckibben::diagnose::Step| {
            [s.selection_rmse, s.selection_fit_percent, s.gap_closed].map(f64::to_bits)
        };
        assert_eq!(selection(a), selection(b), "{:?}", a.effects);
        assert_ne!(a.test_rmse, b.test_rmse, "{:?}", a.effects);
        assert_ne!(a.test_fit_percent, b.test_fit_percent, "{:?}", a.effects);
    }
    checks_that_selection_scores_do_read_the_selection_part(&d, trace);
}

/// The same scramble on the selection part moves the selection figures:
/// the comparison above can fail.
fn checks_that_selection_scores_do_read_the_selection_part(d: &Diagnosis, trace: &Trace) {
    let selection = d.parts[0].selection.clone();
    let other = scrambled(trace, &selection, 7);
    let mut settings = quick();
    settings.max_effects = 0;
    let e = diagnose(
        std::slice::from_ref(&other),
        Family::Classic,
        &[],
        &settings,
    )
    .unwrap();
    assert_ne!(
        d.baseline().selection_rmse,
        e.baseline().selection_rmse,
        "scrambling the selection part left its figure alone"
    );
}

#[test]
fn the_shipped_stair_s_choices_never_read_its_test_part() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv");
    let trace = read_traces(path.as_ref(), &ReadOptions::default()).unwrap();
    test_part_is_read_only_for_test_figures(&trace[0]);
}

#[test]
fn the_cavatappi_300g_choices_never_read_its_test_part() {
    let Some(path) = common::require_external("cavatappi_muscle/sample1_300g.csv") else {
        return;
    };
    let read = ReadOptions {
        time: "t_s".into(),
        input: "pressure_psi".into(),
        output: "disp_mm".into(),
        gaps: Gaps::Resample(0.01),
        ..ReadOptions::default()
    };
    let trace = read_traces(&path, &read).unwrap();
    test_part_is_read_only_for_test_figures(&trace[0]);
}

/// `fit` (with and without effects) on `trace` and on the same record with
/// its validation half's outputs scrambled: the parameters must not move.
#[test]
fn fit_never_reads_its_validation_half() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv");
    let trace = read_traces(path.as_ref(), &ReadOptions::default())
        .unwrap()
        .remove(0);
    let second = halves(trace.len()).1;
    let other = scrambled(&trace, &[second], 11);
    let effects = mckibben::diagnose::Effect::by_default();
    let creep = effects
        .iter()
        .find(|e| e.name() == "creep")
        .copied()
        .unwrap();
    for chain in [vec![], vec![creep]] {
        let params = |t: &Trace| {
            let what = FitTarget::chain(Family::Classic, &chain);
            let settings = FitSettings {
                pop: 60,
                gens: 30,
                ..FitSettings::staged(1)
            };
            let t = std::slice::from_ref(t);
            let fit = FitRun::new(t, &what, &settings, None, None, &|_| ()).unwrap();
            let mut fit = mckibben::diagnose::chain::with_chain_start(
                fit,
                t,
                &settings,
                mckibben::eval::Backend::Cpu,
                Default::default(),
            )
            .unwrap();
            let mut cpu = mckibben::eval::cpu::CpuEvaluator::new();
            let (outcome, widened) = fit.run(&mut cpu, &mut [], None, None).unwrap();
            let validation = fit.problem.validate(&outcome.params);
            (outcome.params, widened, validation)
        };
        let (a, wa, va) = params(&trace);
        let (b, wb, vb) = params(&other);
        assert_eq!(a, b, "{chain:?}: the parameters moved");
        assert_eq!(wa, wb, "{chain:?}: the edge rule moved");
        // The validation figure does read the scrambled half.
        assert_ne!(va.rmse, vb.rmse, "{chain:?}");
    }
}
