//! Gain tuning on batched closed-loop episodes: the cost of a gain vector is
//! the mean steady-state RMS tracking error over every (frequency, load)
//! episode on the rig twin, the thesis' own suggestion for future work
//! (§7: "use it to identify the best gains for a PID controller").

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::closed_loop::{Episode, run_episode};
use super::interrupt::go_on;
use super::limits::ValveLimits;
use super::pi::{Pi, PiGains};
use super::sweep::Kind;
use crate::model::Measure;
use crate::names::UnknownName;
use crate::optim::engine::{Engine, Objective, Plan, Space, StopRules};
use crate::optim::stop::StopFlag;
use crate::optim::{Algorithm, Bounds};
use crate::search::{Params, Rows};
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
            // Gains that leave the muscle slack (a large --effect ringing)
            // run outside the twin's physics: no cost to trust.
            let failed = m.diverged
                || m.constraint_violations > 0
                || !m.rms_error_mm.is_finite()
                || rig.slack_from().is_some();
            let cost = if failed { FAILED_COST } else { m.rms_error_mm };
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
    /// Best cost after each generation (as the engine ranks it, in `f32`).
    pub best_per_generation: Vec<f64>,
}

/// The box the gains are searched in: `Kp ∈ [0, 10]` V/mm, `Ki ∈ [0, 500]`
/// V/(mm·s), `Kd ∈ [0, 0.1]` V·s/mm: wide enough to hold the optimum with
/// room on every side, since larger gains track worse again (the slew limit
/// and the sensor noise) and a narrower box stops the search at its edges
/// (measured on the twin: docs/CONTROL.md, "The controllers", `pi-tuned`).
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

/// The closed-loop cost of gain vectors, as the fitting engine sees it.
struct GainObjective<'a> {
    episodes: &'a TuningEpisodes,
    config: &'a TwinConfig,
}

impl Objective for GainObjective<'_> {
    fn describe(&self) -> String {
        "closed-loop episodes on the rig twin".into()
    }

    /// One measure only: the mean RMS error of [`pi_costs`].
    fn costs(&mut self, rows: Rows<'_, Params>, _: Measure) -> anyhow::Result<Vec<f32>> {
        Ok(pi_costs(rows.as_flat(), self.episodes, self.config)
            .into_iter()
            .map(|c| c as f32)
            .collect())
    }
}

/// Tunes the PID gains on the fitting engine: a population search with
/// `algo`'s default settings (the global stage alone: the cost is no sum of
/// squares to polish), every generation scored on all `episodes` in
/// parallel. Deterministic for a seed.
pub fn tune_pi(
    algo: &str,
    pop: usize,
    gens: usize,
    seed: u64,
    episodes: &TuningEpisodes,
    config: &TwinConfig,
    stop: &StopFlag,
) -> anyhow::Result<Tuned> {
    let algorithm: Algorithm = algo
        .parse()
        .map_err(|e: UnknownName| anyhow::anyhow!("--algo: {e}"))?;
    let min = algorithm.min_population();
    anyhow::ensure!(
        pop >= min,
        "tuning needs --pop ≥ {min} for --algo {algorithm} (got {pop})"
    );
    anyhow::ensure!(gens >= 1, "tuning needs --gens ≥ 1");
    let start = std::time::Instant::now();
    let bounds = gain_bounds();
    let space = Space::new(bounds.lower, bounds.upper, bounds.names);
    let plan = Plan::search(algorithm.default_settings(), pop, gens);
    let mut engine = Engine::new(plan, space, seed, StopRules::default())?;
    let mut objective = GainObjective { episodes, config };
    let outcome = engine.run(&mut objective, &mut [], Some(stop.as_atomic()), None)?;
    // Gains from a tuning cut short are not the tuning's: nothing to run.
    go_on(stop)?;
    anyhow::ensure!(
        !outcome.params.is_empty(),
        "tuning scored no candidate with a finite cost"
    );
    let gains = PiGains {
        kp: outcome.params[0],
        ki: outcome.params[1],
        kd: outcome.params[2],
    };
    Ok(Tuned {
        gains,
        // In f64, as the episodes compute it (the engine ranks in f32).
        cost: pi_cost(gains, episodes, config),
        baseline_cost: pi_cost(PiGains::default(), episodes, config),
        evaluations: outcome.evaluations as usize,
        seconds: start.elapsed().as_secs_f64(),
        best_per_generation: engine
            .history
            .records
            .iter()
            .map(|r| r.best_sse.unwrap_or(f64::INFINITY))
            .collect(),
    })
}

/// The gains pi-tuned and ff-pid ran with, tuned or given: `mckibben
/// control`'s `tuned` in its JSON.
#[derive(Debug, Serialize)]
pub struct TunedGains {
    pub gains: PiGains,
    /// Whether `--tuned-gains` gave them (then no tuning ran).
    pub given: bool,
    /// The tuning run; null when the gains were given.
    pub tuning: Option<Tuned>,
    /// Gains that ended on an edge of the tuning box.
    pub on_edges: Vec<String>,
}

/// How `mckibben control` tunes the PID when no gains are given: its
/// `--algo`, `--pop`, `--gens` and `--seed`.
#[derive(Debug, Clone, PartialEq)]
pub struct TuningRun {
    pub algo: String,
    pub pop: usize,
    pub gens: usize,
    pub seed: u64,
}

/// The PID gains for `kinds`: none when no kind needs them, `given` when
/// there are some, else tuned by `run` on the default episodes (minutes),
/// which `progress` hears of before and after.
pub fn gains_for(
    kinds: &[Kind],
    given: Option<PiGains>,
    run: &TuningRun,
    config: &TwinConfig,
    stop: &StopFlag,
    progress: &dyn Fn(String),
) -> anyhow::Result<Option<TunedGains>> {
    if !kinds.iter().any(|k| k.needs_gains()) {
        return Ok(None);
    }
    if let Some(gains) = given {
        return Ok(Some(TunedGains {
            gains,
            given: true,
            tuning: None,
            on_edges: Vec::new(),
        }));
    }
    let episodes = TuningEpisodes::default();
    progress(format!(
        "tuning the PID: {} × {} gain vectors ({}), each on {} episodes ...",
        run.pop,
        run.gens,
        run.algo,
        episodes.freqs_rad_s.len() * episodes.loads_kg.len()
    ));
    let t = tune_pi(
        &run.algo, run.pop, run.gens, run.seed, &episodes, config, stop,
    )?;
    let edges = gains_on_edges(&t.gains);
    progress(format!(
        "tuned PID ({:.0} s): kp {:.5} ki {:.5} kd {:.5}, mean RMS {:.3} mm (thesis gains {:.3} mm); on the box's edges: {}",
        t.seconds,
        t.gains.kp,
        t.gains.ki,
        t.gains.kd,
        t.cost,
        t.baseline_cost,
        if edges.is_empty() {
            "none".to_string()
        } else {
            edges.join(", ")
        }
    ));
    Ok(Some(TunedGains {
        gains: t.gains,
        given: false,
        tuning: Some(t),
        on_edges: edges,
    }))
}
