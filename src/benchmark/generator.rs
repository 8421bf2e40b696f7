//! Benchmark-like training data from the published system, so that the
//! identification can be tested without the external files.
//!
//! It follows the PDF's `BoucWen_ExampleIntegration.m` (§4): a random-phase
//! multisine designed directly at the 15 kHz integration rate, with every
//! line of the 5–150 Hz band excited at unit amplitude, scaled to 50 N RMS and
//! repeated; one extra period is integrated so that the decimation filter's
//! edge falls outside, and removed afterwards; the input is kept at every
//! 20th integration sample. Measurement noise: Gaussian, band-limited to
//! 0–375 Hz — at 750 Hz that is the whole band, i.e. white — with 8e-3 mm RMS
//! (PDF §4).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Uniform};

use super::boucwen::{Params, simulate_f64};
use super::{FS, Record, UPSAMPLE, resample};

/// Settings of the generated record. Defaults: the benchmark's (PDF §4–5).
#[derive(Debug, Clone, PartialEq)]
pub struct GeneratorSettings {
    /// Samples per period at 750 Hz (PDF: 8192).
    pub period: usize,
    /// Periods kept (PDF: 5).
    pub periods: usize,
    /// Excited band (Hz; PDF: 5–150).
    pub f_min: f64,
    pub f_max: f64,
    /// Input RMS (N; PDF: 50).
    pub rms: f64,
    /// Output noise RMS (m; PDF: 8e-3 mm).
    pub noise_rms: f64,
    /// Seed of the phases and the noise.
    pub seed: u64,
}

impl Default for GeneratorSettings {
    fn default() -> Self {
        GeneratorSettings {
            period: super::PERIOD,
            periods: 5,
            f_min: 5.0,
            f_max: 150.0,
            rms: 50.0,
            noise_rms: 8.0e-6,
            seed: 1,
        }
    }
}

/// A generated record and its noise-free output.
#[derive(Debug, Clone)]
pub struct Generated {
    /// Input and noisy output at 750 Hz.
    pub record: Record,
    /// The output before noise.
    pub y_clean: Vec<f64>,
}

/// One period of the multisine at the integration rate (`period · 20`
/// samples), as the PDF's example designs it.
pub fn multisine_15k(s: &GeneratorSettings, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let nint = s.period * UPSAMPLE;
    let fres = FS * UPSAMPLE as f64 / nint as f64;
    let first = ((s.f_min / fres).floor() as usize).max(1);
    let last = (s.f_max / fres).ceil() as usize;
    let phase = Uniform::new(0.0, 2.0 * std::f64::consts::PI).expect("valid range");
    let lines: Vec<(usize, f64)> = (first..=last).map(|k| (k, phase.sample(rng))).collect();
    let mut u: Vec<f64> = (0..nint)
        .map(|n| {
            lines
                .iter()
                .map(|&(k, ph)| {
                    // (k·n mod Nint) keeps the angle exact for long periods.
                    let idx = (k * n) % nint;
                    (2.0 * std::f64::consts::PI * idx as f64 / nint as f64 + ph).cos()
                })
                .sum::<f64>()
        })
        .collect();
    let mean = u.iter().sum::<f64>() / nint as f64;
    let std = (u.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (nint as f64 - 1.0)).sqrt();
    u.iter_mut().for_each(|v| *v *= s.rms / std);
    u
}

/// Generates a training record from the system `p` (e.g.
/// [`Params::benchmark`]). `None` if the system diverges on this input.
pub fn generate(p: &Params, s: &GeneratorSettings) -> Option<Generated> {
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
    let one = multisine_15k(s, &mut rng);
    let u15: Vec<f64> = (0..s.periods + 1)
        .flat_map(|_| one.iter().copied())
        .collect();
    let y15 = simulate_f64(p, &u15, 1.0 / (FS * UPSAMPLE as f64))?;
    let keep = s.periods * s.period;
    let mut y_clean = resample::decimate(&y15);
    y_clean.truncate(keep);
    let u: Vec<f64> = u15.iter().step_by(UPSAMPLE).take(keep).copied().collect();
    let noise = Normal::new(0.0, s.noise_rms).expect("finite noise level");
    let y = y_clean.iter().map(|v| v + noise.sample(&mut rng)).collect();
    Some(Generated {
        record: Record { u, y },
        y_clean,
    })
}
