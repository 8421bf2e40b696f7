//! Every shader the GPU host assembles is valid WGSL, checked on the CPU
//! with naga's WGSL front end and validator (what wgpu runs before it
//! hands a shader to the driver), so that a broken stage fails here on a
//! machine without a Vulkan adapter too. The sources are the host's own
//! (`eval::gpu::shader_source`, `benchmark::evaluator::source`): every
//! family alone, every family with each realisation of the catalogue alone
//! (on one dataset and on two: the load gains are per dataset), with the
//! whole catalogue, and with the chains the lavapipe tests run
//! (`tests/eval_effects.rs`, `tests/model_flow.rs`), each as the free run
//! and the prediction, sums and residuals, `n = 1` and a free exponent;
//! the benchmark oscillator's; and the calibration kernel's three variants.
//! That they give the CPU's bits is the lavapipe tests' to check.

use mckibben::benchmark::evaluator::{self as oscillator, OscillatorProblem};
use mckibben::eval::Problem;
use mckibben::eval::gpu::calibration::Variant;
use mckibben::eval::gpu::shader_source;
use mckibben::eval::workload::stair_experiment;
use mckibben::model::effects::{Context, Effect};
use mckibben::model::{Family, Measure};

/// `source` parsed and validated by naga with every check and no optional
/// capability (what any adapter accepts), with the compute entry point
/// `main` the host binds; the error, with the offending lines, names `what`.
fn validate(what: &str, source: &str) -> Result<(), String> {
    let module = naga::front::wgsl::parse_str(source)
        .map_err(|e| format!("{what}: {}", e.emit_to_string(source)))?;
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .map_err(|e| format!("{what}: {}", e.emit_to_string(source)))?;
    let main = module
        .entry_points
        .iter()
        .find(|ep| ep.name == "main")
        .ok_or_else(|| format!("{what}: no entry point `main`"))?;
    if main.stage != naga::ShaderStage::Compute {
        return Err(format!("{what}: `main` is not a compute entry point"));
    }
    Ok(())
}

/// The chains of effects on every family: none, each realisation alone,
/// the whole catalogue, and the chains the lavapipe tests score.
fn chains() -> Vec<Vec<Effect>> {
    let mut all = vec![Vec::new()];
    all.extend(Effect::ALL.map(|e| vec![e]));
    all.push(Effect::ALL.to_vec());
    all.push(vec![Effect::Creep, Effect::Delay, Effect::Saturation]);
    all.push(vec![Effect::Creep, Effect::Ringing]);
    all
}

/// The problem of `family` with `effects` on `datasets` experiments.
fn problem(family: Family, effects: &[Effect], datasets: usize, measure: Measure) -> Problem {
    let exps: Vec<_> = (0..datasets)
        .map(|d| stair_experiment(60, d as u64))
        .collect();
    let problem = Problem::new(family, exps.clone()).with_measure(measure);
    if effects.is_empty() {
        return problem;
    }
    let contexts = exps.iter().map(|e| Context::of(e, true)).collect();
    problem.with_effects(effects.to_vec(), contexts)
}

/// Every variant of every model the evaluator builds a pipeline for.
fn variants() -> Vec<(String, String)> {
    let mut out = Vec::new();
    for family in Family::ALL {
        for effects in chains() {
            for datasets in [1, 2] {
                for measure in [Measure::FreeRun, Measure::Ahead { horizon: 7 }] {
                    let p = problem(family, &effects, datasets, measure);
                    for (n_one, residuals) in [(true, false), (false, false), (true, true)] {
                        let what = format!(
                            "{family} + {effects:?} on {datasets} datasets, {measure}, \
                             n = 1 {n_one}, residuals {residuals}"
                        );
                        out.push((what, shader_source(&p, n_one, residuals)));
                    }
                }
            }
        }
    }
    out
}

#[test]
fn every_assembled_shader_is_valid_wgsl() {
    let variants = variants();
    // 3 families × 24 chains × 2 dataset counts × 2 measures × 3 switches.
    assert_eq!(variants.len(), 3 * (Effect::ALL.len() + 4) * 2 * 2 * 3);
    let failures: Vec<String> = variants
        .iter()
        .filter_map(|(what, source)| validate(what, source).err())
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} shaders are invalid; the first:\n{}",
        failures.len(),
        variants.len(),
        failures[0]
    );
}

#[test]
fn the_oscillator_shader_is_valid_wgsl() {
    let problem = OscillatorProblem {
        u: vec![0.0; 64],
        y: vec![0.0; 8],
        stride: 8,
        h: 1.0 / 750.0,
    };
    validate("the benchmark oscillator", &oscillator::source(&problem)).unwrap();
}

/// The check itself fails on a broken stage: one realisation's step with an
/// undefined name, and one with a type error (an `f32` added to a `u32`).
#[test]
fn the_calibration_shaders_are_valid_wgsl() {
    for variant in Variant::ALL {
        validate(&format!("calibration {variant:?}"), &variant.source()).unwrap();
    }
}

#[test]
fn a_broken_stage_is_caught() {
    let p = problem(Family::Classic, &[Effect::Creep], 1, Measure::FreeRun);
    let good = shader_source(&p, true, false);
    validate("the unbroken shader", &good).unwrap();
    let step = "return y + *s;";
    assert!(good.contains(step));
    for broken in ["return y + *s + creep_gain;", "return y + *s + at.k;"] {
        let err = validate("broken", &good.replacen(step, broken, 1)).unwrap_err();
        assert!(err.contains("creep_step") || err.contains(broken), "{err}");
    }
}
