//! The Bouc-Wen benchmark family: integration, identification on generated
//! data, the official files when present, and the shader's bit-exactness.
//! The last two need ../shared and lavapipe: they skip locally without them
//! and fail under `CI=true` (`common`).

mod common;

use mckibben::benchmark::boucwen::{self, Params, simulate_f64, sse_f32};
use mckibben::benchmark::evaluator::{CpuOscillator, GpuOscillator, OscillatorEvaluator};
use mckibben::benchmark::generator::{GeneratorSettings, generate};
use mckibben::benchmark::identify::{IdentifySettings, Training, identify, search_trace};
use mckibben::benchmark::{
    BenchmarkData, FS, PERIOD, Record, UPSAMPLE, default_data_dir, rmse, simulate_periodic,
    test_multisine_rmse, test_sinesweep_rmse,
};
use mckibben::eval::gpu::GpuOptions;
use mckibben::search::Rows;

fn small_settings() -> GeneratorSettings {
    GeneratorSettings {
        period: 1024,
        periods: 2,
        seed: 11,
        ..GeneratorSettings::default()
    }
}

#[test]
fn integration_converges_with_the_step() {
    // Halving the step changes the response far less than the benchmark's
    // error scale: Newmark is second order.
    let p = Params::benchmark();
    let n = 3000;
    let u = |fs: f64, k: usize| {
        let t = k as f64 / fs;
        40.0 * (2.0 * std::f64::consts::PI * 30.0 * t).sin()
            + 20.0 * (2.0 * std::f64::consts::PI * 110.0 * t).cos()
    };
    let coarse: Vec<f64> = (0..n).map(|k| u(15000.0, k)).collect();
    let fine: Vec<f64> = (0..2 * n).map(|k| u(30000.0, k)).collect();
    let yc = simulate_f64(&p, &coarse, 1.0 / 15000.0).unwrap();
    let yf = simulate_f64(&p, &fine, 1.0 / 30000.0).unwrap();
    let diff = (0..n)
        .map(|k| (yc[k] - yf[2 * k]).abs())
        .fold(0.0, f64::max);
    let amp = yc.iter().map(|v| v.abs()).fold(0.0, f64::max);
    assert!(amp > 1e-4, "the input moves the oscillator ({amp})");
    assert!(
        diff < 1e-3 * amp,
        "step halving changed y by {diff} of {amp}"
    );
}

#[test]
fn f32_twin_tracks_the_f64_reference() {
    let g = generate(&Params::benchmark(), &small_settings()).unwrap();
    let rec = &g.record;
    let p = Params::benchmark();
    let settings = IdentifySettings {
        search_samples: 1024,
        search_upsample: UPSAMPLE,
        ..IdentifySettings::default()
    };
    let trace = search_trace(rec, 1024, &settings);
    // Score the f32 twin against the f64 simulation's undecimated samples.
    let u15: Vec<f64> = trace.u.iter().map(|&v| v as f64).collect();
    let y15 = simulate_f64(&p, &u15, 1.0 / (FS * UPSAMPLE as f64)).unwrap();
    let y_ref: Vec<f32> = y15.iter().step_by(UPSAMPLE).map(|&v| v as f32).collect();
    let theta = p.to_vec().map(|v| v as f32);
    let sse = sse_f32(&theta, &trace.u, &y_ref, UPSAMPLE, trace.h) as f64;
    let rms = (sse / y_ref.len() as f64).sqrt();
    let amp = (y_ref.iter().map(|v| (*v as f64).powi(2)).sum::<f64>() / y_ref.len() as f64).sqrt();
    assert!(rms < 1e-4 * amp, "f32 twin off by {rms} m RMS on {amp} m");
    // A wrong stiffness must score much worse.
    let mut off = theta;
    off[2] *= 1.05;
    assert!(sse_f32(&off, &trace.u, &y_ref, UPSAMPLE, trace.h) as f64 > 100.0 * sse.max(1e-30));
}

#[test]
fn identifies_the_published_system_from_generated_data() {
    let truth = Params::benchmark();
    let g = generate(&truth, &small_settings()).unwrap();
    let noise = rmse(&g.record.y, &g.y_clean);
    assert!((noise - 8e-6).abs() < 1e-6, "noise RMS {noise}");
    let settings = IdentifySettings {
        search_samples: 512,
        population: 40,
        generations: 100,
        lm_iterations: 40,
        refine_samples: 0,
        ..IdentifySettings::default()
    };
    let id = identify(&g.record, 1024, &settings, &mut CpuOscillator::new()).unwrap();
    // 2.7 s of data with the benchmark's noise pin every parameter to a few
    // per cent (β·γ and β·δ: β, γ, δ separately are not identifiable).
    let p = id.params;
    let close = |got: f64, want: f64, tol: f64| (got - want).abs() <= tol * want.abs();
    assert!(close(p.m, truth.m, 0.01), "{p:?}");
    assert!(close(p.k + p.alpha, truth.k + truth.alpha, 0.01), "{p:?}");
    assert!(close(p.alpha, truth.alpha, 0.03), "{p:?}");
    assert!(close(p.beta_gamma, truth.beta_gamma, 0.03), "{p:?}");
    assert!(close(p.beta_delta, truth.beta_delta, 0.03), "{p:?}");
    assert!(close(p.c, truth.c, 0.05), "{p:?}");
    assert!(close(p.nu, truth.nu, 0.01), "{p:?}");
    // Fitted to the noise floor, and the model predicts a fresh multisine.
    assert!(
        id.train_rmse < 1.1 * noise,
        "train RMSE {} ({id:?})",
        id.train_rmse
    );
    let fresh = generate(
        &truth,
        &GeneratorSettings {
            seed: 99,
            noise_rms: 0.0,
            ..small_settings()
        },
    )
    .unwrap();
    let test = Record {
        u: fresh.record.u[1024..].to_vec(),
        y: fresh.y_clean[1024..].to_vec(),
    };
    let r = test_multisine_rmse(&id.params, &test).unwrap();
    eprintln!(
        "generated data: {p:?}, train RMSE {:e}, fresh multisine RMSE {r:e}",
        id.train_rmse
    );
    assert!(r < 1e-6, "fresh multisine RMSE {r}");
}

#[test]
fn pipeline_reproduces_the_official_test_data() {
    let Some(dir) = common::require_path(default_data_dir()) else {
        return;
    };
    let data = BenchmarkData::load(&dir).unwrap();
    let truth = Params::benchmark();
    // With the published parameters our upsampling, Newmark and decimation
    // reproduce the official noise-free multisine test output.
    let ms = test_multisine_rmse(&truth, &data.test_multisine).unwrap();
    assert!(ms < 1e-8, "multisine RMSE with the true system: {ms}");
    // And the training record down to its measurement noise (8e-3 mm).
    let y = simulate_periodic(&truth, &data.train.u[..PERIOD], 5).unwrap();
    let tr = rmse(&y, &data.train.y);
    assert!(
        tr > 6e-6 && tr < 9e-6,
        "training RMSE with the true system: {tr}"
    );
    let sw = test_sinesweep_rmse(&truth, &data.test_sinesweep).unwrap();
    assert!(sw < 5e-6, "sine sweep RMSE with the true system: {sw}");
    // The refinement's objective sees the same.
    let t = Training::new(&data.train, PERIOD);
    assert_eq!(t.simulate(&truth).unwrap().len(), data.train.y.len());
}

#[test]
fn shader_matches_the_cpu_twin_bit_for_bit_on_lavapipe() {
    // One workgroup per chunk: the 71 candidates take two chunks.
    let options = GpuOptions {
        max_groups_per_dim: Some(1),
        ..GpuOptions::default()
    };
    let Some(lavapipe) = common::require_lavapipe_adapter() else {
        return;
    };
    let mut gpu = GpuOscillator::with_adapter(lavapipe, options).unwrap();
    let g = generate(&Params::benchmark(), &small_settings()).unwrap();
    let settings = IdentifySettings {
        search_samples: 300,
        ..IdentifySettings::default()
    };
    let trace = search_trace(&g.record, 1024, &settings);
    // The truth, perturbations, and an unstable candidate (ν ≠ 1
    // is left out: WGSL's pow is not specified to the last bit).
    let truth = Params::benchmark().to_vec().map(|v| v as f32);
    let mut pop: Vec<f32> = Vec::new();
    for i in 0..70 {
        let mut th = truth;
        for (j, v) in th.iter_mut().enumerate().take(6) {
            *v *= 1.0 + 0.01 * (((i * 7 + j * 3) % 11) as f32 - 5.0);
        }
        pop.extend_from_slice(&th);
    }
    let mut wild = truth;
    wild[2] = -1.0e7; // negative stiffness: the response grows exponentially
    pop.extend_from_slice(&wild);
    let pop: Vec<f64> = pop.into_iter().map(f64::from).collect();
    let pop = Rows::new(&pop, boucwen::DIM);
    let a = CpuOscillator::new().evaluate(&trace, pop).unwrap();
    let b = gpu.evaluate(&trace, pop).unwrap();
    assert!(a[..70].iter().all(|v| v.is_finite()));
    assert_eq!(a[70], f32::INFINITY);
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        assert_eq!(x.to_bits(), y.to_bits(), "candidate {i}: cpu {x} gpu {y}");
    }
}
