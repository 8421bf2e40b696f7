//! Gain tuning on batched closed-loop episodes: the cost of a gain vector is
//! the mean steady-state RMS tracking error over every (frequency, load)
//! episode on the rig twin, the thesis' own suggestion for future work
//! (§7: "use it to identify the best gains for a PID controller").

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::closed_loop::{Episode, run_episode};
use super::limits::ValveLimits;
use super::pi::{Pi, PiGains};
use crate::optim::{AlgoSettings, Algorithm, AnyOptimizer, Bounds, Optimizer};
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
    /// Best cost after each generation.
    pub best_per_generation: Vec<f64>,
}

/// The box the gains are searched in: `Kp ∈ [0, 10]` V/mm, `Ki ∈ [0, 500]`
/// V/(mm·s), `Kd ∈ [0, 0.1]` V·s/mm. The first box (`[0, 1] × [0, 20] ×
/// [0, 0.02]`) stopped DE and PSO at its edges `Kp = 1`, `Ki = 20`; on the
/// twin, 3 rad/s tracking gets worse again past about `Kp = 3`, `Ki = 80`
/// (the slew limit and the sensor noise), so this box holds the optimum
/// inside it with room on every side.
pub fn gain_bounds() -> Bounds {
    Bounds {
        lower: vec![0.0, 0.0, 0.0],
        upper: vec![10.0, 500.0, 0.1],
        names: vec!["kp".into(), "ki".into(), "kd".into()],
    }
}

/// The names of the gains within 1 % of the box's width of an edge: a gain
/// there was stopped by the box, not by the loop.
pub fn gains_on_edges(gains: &PiGains) -> Vec<String> {
    let b = gain_bounds();
    [gains.kp, gains.ki, gains.kd]
        .iter()
        .enumerate()
        .filter(|&(i, &g)| {
            let margin = 0.01 * (b.upper[i] - b.lower[i]);
            g - b.lower[i] < margin || b.upper[i] - g < margin
        })
        .map(|(i, _)| b.names[i].clone())
        .collect()
}

/// Tunes the PID gains with one of the project's optimizers (ask/tell):
/// every generation's population is scored on all `episodes` in parallel,
/// the best gains ever seen are returned. Deterministic for a seed.
pub fn tune_pi(
    algo: &str,
    pop: usize,
    gens: usize,
    seed: u64,
    episodes: &TuningEpisodes,
    config: &TwinConfig,
) -> anyhow::Result<Tuned> {
    use rand::SeedableRng;
    let algorithm: Algorithm = algo
        .parse()
        .map_err(|e: String| anyhow::anyhow!("--algo: {e}"))?;
    anyhow::ensure!(
        pop >= 4 && gens >= 1,
        "tuning needs --pop ≥ 4 and --gens ≥ 1"
    );
    let start = std::time::Instant::now();
    let mut opt = AnyOptimizer::new(
        algorithm,
        &AlgoSettings::default(),
        gain_bounds(),
        pop,
        gens,
    );
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut best: Option<(Vec<f64>, f64)> = None;
    let mut evaluations = 0;
    let mut history = Vec::with_capacity(gens);
    for _ in 0..gens {
        let population = opt.ask(&mut rng);
        let costs = pi_costs(&population, episodes, config);
        evaluations += costs.len();
        for (row, &c) in population.chunks(3).zip(&costs) {
            if best.as_ref().is_none_or(|(_, b)| c < *b) {
                best = Some((row.to_vec(), c));
            }
        }
        history.push(best.as_ref().map_or(f64::INFINITY, |b| b.1));
        let costs32: Vec<f32> = costs.iter().map(|&c| c as f32).collect();
        opt.tell(&costs32);
    }
    let (g, cost) = best.ok_or_else(|| anyhow::anyhow!("tuning scored no candidate"))?;
    Ok(Tuned {
        gains: PiGains {
            kp: g[0],
            ki: g[1],
            kd: g[2],
        },
        cost,
        baseline_cost: pi_cost(PiGains::default(), episodes, config),
        evaluations,
        seconds: start.elapsed().as_secs_f64(),
        best_per_generation: history,
    })
}
