//! Every model with effect stages scores the same on every path: the CPU
//! batch path and (on lavapipe) the WGSL kernel give the bits of the
//! scalar augmented simulation, for every family × effect, several effects
//! in a chain, the free run and the multi-step-ahead prediction, scores and
//! residuals.
//!
//! The GPU half needs lavapipe: without it it fails when `CI=true` and
//! otherwise prints a loud SKIP message and returns
//! (`common::require_lavapipe`).

mod common;

use mckibben::eval::cpu::{CpuEvaluator, LANES};
use mckibben::eval::gpu::GpuOptions;
use mckibben::eval::workload::{mixed_population, search_space, stair_experiment};
use mckibben::eval::{Evaluator, Problem};
use mckibben::model::effects::{Context, Effect, EffectBox, ModelDescription, effect_box};
use mckibben::model::{Experiment, Family, Measure};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Two experiments (datasets) in the first one's coordinates.
fn experiments() -> Vec<Experiment> {
    let a = stair_experiment(900, 5);
    let mut b = stair_experiment(700, 6);
    b.u_mean = a.u_mean;
    b.y_mean = a.y_mean;
    vec![a, b]
}

/// A population of the augmented model: baselines drawn as the evaluator
/// tests draw them (finite and diverging candidates mixed), each effect's
/// parameters uniformly in its box, the first two rows' effects neutral (the
/// second's baseline is near the preset, so one candidate stays finite
/// however many effects the model has). A generalized baseline's switching
/// level is drawn across the output's span, and set at the datasets' output
/// mean (where the kernel forms the threshold 0) on every third row and at
/// the sensor's zero (below every sample) on every fifth.
fn population(model: &ModelDescription, ctx: &Context, count: usize, seed: u64) -> Vec<f64> {
    let exps = experiments();
    let space = search_space(model.family, &exps[0], false);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let base = mixed_population(&space, count, &mut rng);
    let d0 = model.family.dim();
    let mut rows = Vec::with_capacity(count * model.dim());
    for (i, b) in base.chunks_exact(d0).enumerate() {
        rows.extend_from_slice(b);
        if let Some(is) = model.family.switch_index() {
            let at = rows.len() - d0 + is;
            if i % 3 == 0 {
                rows[at] = ctx.y_mean;
            } else if i % 5 == 0 {
                rows[at] = 0.0;
            }
        }
        for &e in &model.effects {
            let EffectBox {
                neutral,
                lower: lo,
                upper: hi,
            } = effect_box(e, ctx, model.datasets);
            for j in 0..neutral.len() {
                rows.push(if i <= 1 {
                    neutral[j]
                } else {
                    rng.random_range(lo[j]..=hi[j])
                });
            }
        }
    }
    rows
}

/// The models checked: each effect alone on each family, on two datasets
/// and on one, and two chains. One dataset matters of its own: the
/// kernel's per-experiment constants are then arrays of one, which a
/// shader compiler may fold into literals and reassociate sums around
/// (it did, for the soft stop of a contracting muscle).
fn models() -> Vec<ModelDescription> {
    let mut all = Vec::new();
    for family in Family::ALL {
        for e in Effect::ALL {
            all.push(ModelDescription::new(family, vec![e], 2));
            all.push(ModelDescription::new(family, vec![e], 1));
        }
        all.push(ModelDescription::new(family, Effect::ALL.to_vec(), 2));
    }
    all.push(ModelDescription::new(
        Family::Classic,
        vec![Effect::Creep, Effect::Delay, Effect::Saturation],
        2,
    ));
    all
}

/// The two directions an input can drive the output: the stair muscle
/// extends (`drives_up`), the Cavatappi muscle contracts; the end stops
/// differ between them.
const DIRECTIONS: [bool; 2] = [true, false];

fn problem_of(
    model: &ModelDescription,
    measure: Measure,
    drives_up: bool,
) -> (Problem, Vec<Context>) {
    let mut exps = experiments();
    exps.truncate(model.datasets);
    let contexts: Vec<Context> = exps.iter().map(|e| Context::of(e, drives_up)).collect();
    let problem = Problem::new(model.family, exps)
        .with_measure(measure)
        .with_effects(model.effects.clone(), contexts.clone());
    (problem, contexts)
}

const MEASURES: [Measure; 2] = [Measure::FreeRun, Measure::Ahead { horizon: 13 }];

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn cpu_batches_give_the_scalar_simulations_bits() {
    let (mut seen_finite, mut seen_diverged) = (false, false);
    for model in models() {
        for (measure, up) in MEASURES
            .into_iter()
            .flat_map(|m| DIRECTIONS.map(|up| (m, up)))
        {
            let (problem, contexts) = problem_of(&model, measure, up);
            // Full batches and a short last one of each narrower width.
            let count = if up { 2 * LANES + 5 } else { LANES + 13 };
            let pop = population(&model, &contexts[0], count, 3);
            let scores = CpuEvaluator::new()
                .evaluate(&problem, problem.rows(&pop))
                .unwrap();
            let d = model.dim();
            for (e, exp) in problem.experiments.iter().enumerate() {
                let want: Vec<f32> = pop
                    .chunks_exact(d)
                    .map(|row| {
                        let t: Vec<f32> = row.iter().map(|&v| v as f32).collect();
                        model.measured_sse(&t, e, &contexts[e], exp, measure)
                    })
                    .collect();
                let what = format!(
                    "{} + {:?}, {measure}, drives up {up}, experiment {e}",
                    model.family, model.effects
                );
                assert_eq!(bits(&scores.per_experiment[e]), bits(&want), "{what}");
                assert!(want.iter().any(|v| v.is_finite()), "{what}: all diverged");
            }
            // The residuals (a polish's probes), a short last batch among
            // them: each row's every experiment in turn, or none where one
            // diverged.
            let residuals = CpuEvaluator::new()
                .residuals(&problem, problem.rows(&pop))
                .unwrap();
            assert_eq!(residuals.len(), pop.len() / d);
            for (i, (row, got)) in pop.chunks_exact(d).zip(&residuals).enumerate() {
                let t: Vec<f32> = row.iter().map(|&v| v as f32).collect();
                let want: Option<Vec<f32>> = problem
                    .experiments
                    .iter()
                    .enumerate()
                    .map(|(e, exp)| model.residuals(&t, e, &contexts[e], exp, measure))
                    .collect::<Option<Vec<Vec<f32>>>>()
                    .map(|r| r.concat());
                assert_eq!(
                    got.as_deref().map(bits),
                    want.as_deref().map(bits),
                    "{} + {:?}, {measure}, drives up {up}: residuals of row {i}",
                    model.family,
                    model.effects
                );
            }
            seen_finite |= residuals.iter().any(Option::is_some);
            seen_diverged |= residuals.iter().any(Option::is_none);
        }
    }
    assert!(seen_finite && seen_diverged, "rows of both kinds");
}

#[test]
fn gpu_kernels_give_the_cpu_bits() {
    let Some(mut gpu) = common::require_lavapipe(GpuOptions::default()) else {
        return;
    };
    let mut cpu = CpuEvaluator::new();
    for model in models() {
        for (measure, up) in MEASURES
            .into_iter()
            .flat_map(|m| DIRECTIONS.map(|up| (m, up)))
        {
            let (problem, contexts) = problem_of(&model, measure, up);
            let pop = population(&model, &contexts[0], 70, 4);
            let what = format!(
                "{} + {:?}, {measure}, drives up {up}",
                model.family, model.effects
            );
            let want = cpu.evaluate(&problem, problem.rows(&pop)).unwrap();
            let got = gpu.evaluate(&problem, problem.rows(&pop)).unwrap();
            for e in 0..problem.experiments.len() {
                assert_eq!(
                    bits(&got.per_experiment[e]),
                    bits(&want.per_experiment[e]),
                    "{what}, experiment {e}"
                );
            }
            let few = &pop[..5 * model.dim()];
            let want = cpu.residuals(&problem, problem.rows(few)).unwrap();
            let got = gpu.residuals(&problem, problem.rows(few)).unwrap();
            for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                assert_eq!(
                    g.as_deref().map(bits),
                    w.as_deref().map(bits),
                    "{what}: residuals of candidate {i}"
                );
            }
        }
    }
}
