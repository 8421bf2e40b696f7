//! Gain tuning on batched closed-loop episodes: the cost of a gain vector is
//! the mean steady-state RMS tracking error over every (frequency, load)
//! episode on the rig twin, the thesis' own suggestion for future work
//! (§7: "use it to identify the best gains for a PID controller").

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::closed_loop::{Episode, run_episode};
use super::limits::ValveLimits;
use super::pi::{Pi, PiGains};
use crate::twin::{Rig, TwinConfig};

/// The episodes a gain vector is scored on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TuningEpisodes {
    pub freqs_rad_s: Vec<f64>,
    pub loads_kg: Vec<f64>,
    /// Settling before the sine (s).
    pub warmup_s: f64,
    /// Sine length (s).
    pub duration_s: f64,
    /// Scoring starts this long into the sine (s).
    pub steady_from_s: f64,
    /// Sensor-noise seed of the twin.
    pub seed: u64,
}

impl Default for TuningEpisodes {
    /// All three frequencies and both loads of §6.2, shortened episodes (5 s
    /// settling, 12 s of sine scored from 6 s) to keep a tuning run to
    /// seconds per generation.
    fn default() -> Self {
        TuningEpisodes {
            freqs_rad_s: vec![1.0, 2.0, 3.0],
            loads_kg: vec![4.5, 7.0],
            warmup_s: 5.0,
            duration_s: 12.0,
            steady_from_s: 6.0,
            seed: 1,
        }
    }
}

/// Cost of a diverged or constraint-breaking episode: worse than any loop
/// that follows at all, finite so that rankings stay informative.
pub const FAILED_COST: f64 = 1.0e3;

/// Mean steady-state RMS error (mm) of the PID `gains` over `episodes`.
pub fn pi_cost(gains: PiGains, episodes: &TuningEpisodes, config: &TwinConfig) -> f64 {
    let mut total = 0.0;
    let mut count = 0usize;
    for &load in &episodes.loads_kg {
        for &w in &episodes.freqs_rad_s {
            let ep = Episode::short(
                w,
                episodes.warmup_s,
                episodes.duration_s,
                episodes.steady_from_s,
            );
            let mut rig = Rig::new(config, load, episodes.seed);
            let mut pi = Pi::new(gains, ValveLimits::default(), rig.dt(), "pi");
            let m = run_episode(&mut rig, &mut pi, &ep).metrics;
            let cost = if m.diverged || m.constraint_violations > 0 || !m.rms_error_mm.is_finite() {
                FAILED_COST
            } else {
                m.rms_error_mm
            };
            total += cost;
            count += 1;
        }
    }
    total / count.max(1) as f64
}

/// Costs of a population of gain rows `[kp, ki, kd]` (row-major), in
/// parallel; each row's cost is independent of the thread count.
pub fn pi_costs(population: &[f64], episodes: &TuningEpisodes, config: &TwinConfig) -> Vec<f64> {
    population
        .par_chunks(3)
        .map(|g| {
            pi_cost(
                PiGains {
                    kp: g[0],
                    ki: g[1],
                    kd: g[2],
                },
                episodes,
                config,
            )
        })
        .collect()
}

/// A tuning run's outcome.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tuned {
    pub gains: PiGains,
    /// Mean RMS error (mm) of the tuned gains on the tuning episodes.
    pub cost: f64,
    /// Mean RMS error (mm) of the thesis' gains on the same episodes.
    pub baseline_cost: f64,
    /// Gain vectors scored.
    pub evaluations: usize,
    pub seconds: f64,
}

/// Tunes the PID gains (TEMPORARY until the optimizers land).
pub fn tune_pi(
    algo: &str,
    _pop: usize,
    _gens: usize,
    _seed: u64,
    _episodes: &TuningEpisodes,
    _config: &TwinConfig,
) -> anyhow::Result<Tuned> {
    anyhow::bail!("--algo {algo}: the optimizers are not merged yet; pass --tuned-gains")
}
