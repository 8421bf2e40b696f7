//! Reproducible evaluator workloads: a stair experiment when no data file is
//! given, and random populations drawn from the default search box. The
//! benchmark (`mckibben bench`, `benches/evaluator.rs`) and the evaluator
//! tests use them, so that what is timed is what is tested.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::data::Trace;
use crate::model::bounds::level_reach;
use crate::model::effects::{Context, EffectBox, ModelDescription, effect_box};
use crate::model::presets::{THESIS_A, THESIS_B, thesis_params};
use crate::model::{Experiment, Family, Flow, LinearPrior, SearchSpace, simulate};

/// Sample time of the synthetic stair: what is timed and tested depends on
/// its number of samples, not on their spacing.
pub const STAIR_DT: f64 = 0.1;

/// A stair experiment of `samples` samples: pressure steps (MPa) held for a
/// random 20–80 samples each, and the displacement (mm) the thesis' classic
/// model (Table 1 with eq. 12) produces from them, plus 0.05 mm of uniform
/// noise. Deviation coordinates over the whole trace. Deterministic in `seed`.
pub fn stair_experiment(samples: usize, seed: u64) -> Experiment {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut input = Vec::with_capacity(samples);
    while input.len() < samples {
        let level: f64 = rng.random_range(0.0..0.4);
        let hold: usize = rng.random_range(20..80);
        input.extend(std::iter::repeat_n(level, hold));
    }
    input.truncate(samples);
    let u_mean = input.iter().sum::<f64>() / samples.max(1) as f64;
    let u: Vec<f32> = input.iter().map(|&p| (p - u_mean) as f32).collect();
    let theta: Vec<f32> = thesis_params(Family::Classic)
        .iter()
        .map(|&v| v as f32)
        .collect();
    let sim = simulate(Family::Classic, &theta, 0.0, &u, 0.0);
    let output: Vec<f64> = sim
        .x
        .iter()
        .map(|&x| 30.0 + x as f64 + rng.random_range(-0.05..0.05))
        .collect();
    let trace = Trace::uniform(format!("stair(seed {seed})"), STAIR_DT, input, output);
    Experiment::with_means_of(&trace, 0..samples)
}

/// The default search box of `family` for `experiment` (thesis hull, `n = 1`
/// unless `free_n`, joint flow around the thesis' ARX estimate). Its `a` range
/// reaches past 1, so a uniform draw includes diverging candidates.
pub fn search_space(family: Family, experiment: &Experiment, free_n: bool) -> SearchSpace {
    let absolute =
        |v: &[f32], mean: f64| -> Vec<f64> { v.iter().map(|&x| x as f64 + mean).collect() };
    let input = absolute(&experiment.u, experiment.u_mean);
    let output = absolute(&experiment.y, experiment.y_mean);
    let prior = LinearPrior {
        a: THESIS_A,
        b: THESIS_B,
        max_abs_input: level_reach(&input),
        max_abs_output: level_reach(&output),
        output_range: crate::data::range(&output),
        est_output_min: output.iter().copied().fold(f64::INFINITY, f64::min),
        est_output_max: output.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        output_mean: experiment.y_mean,
    };
    SearchSpace::from_prior(family, None, prior, Flow::Joint, free_n)
}

/// `count` candidates: even rows uniform over `space` (for the generalized
/// model nearly all of them diverge), odd rows uniform within ±5 % of the box
/// width around the thesis' preset of the family (clamped to the box; nearly
/// all finite). A population an optimizer sees mid-run has both kinds.
pub fn mixed_population(space: &SearchSpace, count: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let center = thesis_params(space.family);
    let mut rows = Vec::with_capacity(count * space.dim());
    for i in 0..count {
        for (j, (&lo, &hi)) in space.lower.iter().zip(&space.upper).enumerate() {
            rows.push(if lo == hi {
                lo
            } else if i % 2 == 0 {
                rng.random_range(lo..hi)
            } else {
                let half = 0.05 * (hi - lo);
                (center[j] + rng.random_range(-half..half)).clamp(lo, hi)
            });
        }
    }
    rows
}

/// `count` candidates of `model` (a family with effect stages): the baseline
/// as [`mixed_population`] draws it from `space`, then each effect's
/// parameters from its box ([`effect_box`] with `ctx`, the first dataset's
/// context): uniform in the box on even rows, within ±5 % of the box width
/// around the effect's neutral value on odd rows (clamped to the box), so
/// that odd rows stay near the preset and nearly all finite.
pub fn augmented_population(
    model: &ModelDescription,
    space: &SearchSpace,
    ctx: &Context,
    count: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<f64> {
    assert_eq!(space.family, model.family, "search box of another family");
    let base = mixed_population(space, count, rng);
    let boxes: Vec<_> = model
        .effects
        .iter()
        .map(|&e| effect_box(e, ctx, model.datasets))
        .collect();
    let d0 = model.family.dim();
    let mut rows = Vec::with_capacity(count * model.dim());
    for (i, b) in base.chunks_exact(d0).enumerate() {
        rows.extend_from_slice(b);
        for EffectBox {
            neutral,
            lower: lo,
            upper: hi,
        } in &boxes
        {
            for j in 0..neutral.len() {
                let (lo, hi) = (lo[j], hi[j]);
                rows.push(if lo >= hi {
                    lo
                } else if i % 2 == 0 {
                    rng.random_range(lo..hi)
                } else {
                    let half = 0.05 * (hi - lo);
                    (neutral[j] + rng.random_range(-half..half)).clamp(lo, hi)
                });
            }
        }
    }
    rows
}
