//! The run loop: ask, evaluate, tell, record; stopping, seeding, observers
//! and checkpoints.
//!
//! A [`Runner`] holds everything a run's future depends on — the optimizer's
//! state, the random generator's position, the history and the best so far —
//! and nothing else, so it serialises to a checkpoint from which a resumed run
//! continues to the bit-identical result.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::history::{GenerationRecord, History};
use super::{Algorithm, de::DeSettings, ga::GaSettings, mfa::MfaSettings, pso::PsoSettings};
use super::{AnyOptimizer, Bounds, Optimizer, de::De, ga::Ga, mfa::Mfa, pso::Pso};
use crate::data::write_atomic;
use crate::eval::{Evaluator, Problem};
use crate::model::SearchSpace;

/// When to stop and how to seed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSettings {
    /// Populations to evaluate (`G`); also the horizon of the MFA and PSO schedules.
    pub generations: usize,
    /// Individuals per generation (`N`).
    pub population: usize,
    pub seed: u64,
    /// Stop once the best SSE is at or below this.
    pub target_sse: Option<f64>,
    /// Stop after this many seconds of wall-clock time (makes the result
    /// depend on the machine; off by default).
    pub time_budget_s: Option<f64>,
    /// Stop when the best SSE has not improved by more than
    /// `stall_tolerance` (relative) for this many generations.
    pub stall_generations: Option<usize>,
    pub stall_tolerance: f64,
}

impl RunSettings {
    pub fn new(population: usize, generations: usize, seed: u64) -> RunSettings {
        RunSettings {
            generations,
            population,
            seed,
            target_sse: None,
            time_budget_s: None,
            stall_generations: None,
            stall_tolerance: 1e-9,
        }
    }
}

/// The algorithm settings of every optimizer, for building one by name.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct AlgoSettings {
    pub ga: GaSettings,
    pub mfa: MfaSettings,
    pub pso: PsoSettings,
    pub de: DeSettings,
}

impl AnyOptimizer {
    /// A fresh optimizer of `algo` over `bounds` for `settings`' N and G.
    pub fn new(algo: Algorithm, s: &AlgoSettings, bounds: Bounds, run: &RunSettings) -> Self {
        let (n, g) = (run.population, run.generations);
        match algo {
            Algorithm::Ga => AnyOptimizer::Ga(Ga::new(s.ga.clone(), bounds, n, g)),
            Algorithm::Mfa => AnyOptimizer::Mfa(Mfa::new(s.mfa.clone(), bounds, n, g)),
            Algorithm::Pso => AnyOptimizer::Pso(Pso::new(s.pso.clone(), bounds, n, g)),
            Algorithm::De => AnyOptimizer::De(De::new(s.de.clone(), bounds, n)),
        }
    }
}

/// Why a run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StopReason {
    Generations,
    TargetSse,
    TimeBudget,
    Stalled,
    /// The stop flag was raised (Ctrl-C).
    Interrupted,
}

/// Sees every generation as it completes (progress bars, logs).
pub trait Observer {
    fn generation(&mut self, record: &GenerationRecord, settings: &RunSettings);
}

/// A `ChaCha8Rng`'s position, as plain serialisable numbers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct RngState {
    seed: [u8; 32],
    stream: u64,
    /// The word position (`u128`, as a decimal string for JSON).
    word_pos: String,
}

impl RngState {
    fn of(rng: &ChaCha8Rng) -> RngState {
        RngState {
            seed: rng.get_seed(),
            stream: rng.get_stream(),
            word_pos: rng.get_word_pos().to_string(),
        }
    }

    fn restore(&self) -> anyhow::Result<ChaCha8Rng> {
        let mut rng = ChaCha8Rng::from_seed(self.seed);
        rng.set_stream(self.stream);
        rng.set_word_pos(self.word_pos.parse()?);
        Ok(rng)
    }
}

/// The best candidate of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunOutcome {
    /// Canonical parameter vector.
    pub params: Vec<f64>,
    /// Its SSE on the estimation problem (`+∞` if every candidate diverged).
    pub sse: f64,
    pub evaluations: u64,
    pub generations: usize,
    pub seconds: f64,
    pub stop: StopReason,
}

/// A run in progress (serialisable: a checkpoint is this value as JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Runner {
    pub settings: RunSettings,
    pub space: SearchSpace,
    optimizer: AnyOptimizer,
    rng: RngState,
    pub history: History,
    best_params: Vec<f64>,
    best_sse: Option<f64>,
    evaluations: u64,
    /// Seconds spent before the last resume.
    seconds_before: f64,
    #[serde(skip)]
    started: Option<Instant>,
}

impl Runner {
    /// A new run of `algo` over the free coordinates of `space`.
    pub fn new(
        algo: Algorithm,
        algo_settings: &AlgoSettings,
        space: SearchSpace,
        settings: RunSettings,
    ) -> anyhow::Result<Runner> {
        let bounds = Bounds::of(&space);
        anyhow::ensure!(
            bounds.dim() > 0,
            "the search space has no free parameter (every lower bound equals its upper bound)"
        );
        let min_pop = if algo == Algorithm::De { 4 } else { 2 };
        anyhow::ensure!(
            settings.population >= min_pop,
            "{algo} needs a population of at least {min_pop} (got {})",
            settings.population
        );
        anyhow::ensure!(settings.generations >= 1, "need at least one generation");
        let optimizer = AnyOptimizer::new(algo, algo_settings, bounds, &settings);
        let rng = ChaCha8Rng::seed_from_u64(settings.seed);
        Ok(Runner {
            history: History::new(space.family),
            rng: RngState::of(&rng),
            settings,
            space,
            optimizer,
            best_params: Vec::new(),
            best_sse: None,
            evaluations: 0,
            seconds_before: 0.0,
            started: None,
        })
    }

    pub fn algorithm(&self) -> Algorithm {
        self.optimizer.algorithm()
    }

    pub fn generation(&self) -> usize {
        self.history.records.len()
    }

    /// Best so far: canonical parameters and SSE.
    pub fn best(&self) -> Option<(&[f64], f64)> {
        self.best_sse.map(|s| (self.best_params.as_slice(), s))
    }

    fn elapsed(&self) -> f64 {
        self.seconds_before + self.started.map_or(0.0, |t| t.elapsed().as_secs_f64())
    }

    /// Places free-coordinate rows into canonical rows.
    fn embed(&self, rows: &[f64]) -> Vec<f64> {
        let free = self.space.free();
        let d = self.space.dim();
        let nf = free.len();
        let mut out = Vec::with_capacity(rows.len() / nf * d);
        for row in rows.chunks_exact(nf) {
            let start = out.len();
            out.extend_from_slice(&self.space.lower);
            for (k, &i) in free.iter().enumerate() {
                out[start + i] = row[k];
            }
        }
        out
    }

    /// One generation: ask, evaluate, tell, record.
    pub fn step(
        &mut self,
        problem: &Problem,
        evaluator: &mut dyn Evaluator,
    ) -> anyhow::Result<&GenerationRecord> {
        anyhow::ensure!(
            problem.family == self.space.family,
            "the problem is a {} model but the run searches {}",
            problem.family,
            self.space.family
        );
        self.started.get_or_insert_with(Instant::now);
        let mut rng = self.rng.restore()?;
        let rows = self.optimizer.ask(&mut rng);
        self.rng = RngState::of(&rng);
        let canonical = self.embed(&rows);
        let scores = evaluator.evaluate(problem, &canonical)?;
        let n = canonical.len() / self.space.dim();
        anyhow::ensure!(
            scores.total.len() == n,
            "evaluator returned {} scores for {n} candidates",
            scores.total.len()
        );
        let costs: Vec<f32> = scores
            .total
            .iter()
            .map(|&c| if c.is_nan() { f32::INFINITY } else { c })
            .collect();
        self.optimizer.tell(&costs);
        self.evaluations += n as u64;
        let d = self.space.dim();
        if let Some(i) = super::argmin(&costs) {
            if self.best_sse.is_none_or(|b| (costs[i] as f64) < b) {
                self.best_sse = Some(costs[i] as f64);
                self.best_params = canonical[i * d..(i + 1) * d].to_vec();
            }
        }
        let (gbest, mean, std, diverged) = GenerationRecord::stats(&costs);
        let record = GenerationRecord {
            generation: self.history.records.len() + 1,
            evaluations: self.evaluations,
            seconds: self.elapsed(),
            best_sse: self.best_sse,
            generation_best_sse: gbest,
            mean_sse: mean,
            std_sse: std,
            diverged,
            best_params: self.best_params.clone(),
        };
        self.history.records.push(record);
        Ok(self.history.records.last().expect("just pushed"))
    }

    /// Whether the run should stop now, and why.
    pub fn should_stop(&self, interrupt: Option<&AtomicBool>) -> Option<StopReason> {
        let s = &self.settings;
        if interrupt.is_some_and(|f| f.load(Ordering::SeqCst)) {
            return Some(StopReason::Interrupted);
        }
        if self.generation() >= s.generations {
            return Some(StopReason::Generations);
        }
        if let (Some(t), Some(b)) = (s.target_sse, self.best_sse)
            && b <= t
        {
            return Some(StopReason::TargetSse);
        }
        if s.time_budget_s.is_some_and(|t| self.elapsed() >= t) {
            return Some(StopReason::TimeBudget);
        }
        if let Some(w) = s.stall_generations {
            let r = &self.history.records;
            if r.len() > w {
                let then = r[r.len() - 1 - w].best_sse.unwrap_or(f64::INFINITY);
                let now = r[r.len() - 1].best_sse.unwrap_or(f64::INFINITY);
                if then.is_finite() && now >= then * (1.0 - s.stall_tolerance) {
                    return Some(StopReason::Stalled);
                }
            }
        }
        None
    }

    /// Runs until a stop condition holds. `interrupt` (Ctrl-C) stops cleanly
    /// after the current generation; `checkpoint` is rewritten every
    /// `checkpoint_every_s` seconds and when the run stops.
    pub fn run(
        &mut self,
        problem: &Problem,
        evaluator: &mut dyn Evaluator,
        observers: &mut [&mut dyn Observer],
        interrupt: Option<&AtomicBool>,
        checkpoint: Option<&Path>,
    ) -> anyhow::Result<RunOutcome> {
        let checkpoint_every_s = 10.0;
        let mut last_save = Instant::now();
        let stop = loop {
            if let Some(reason) = self.should_stop(interrupt) {
                break reason;
            }
            self.step(problem, evaluator)?;
            let record = self.history.records.last().expect("stepped");
            for o in observers.iter_mut() {
                o.generation(record, &self.settings);
            }
            if let Some(path) = checkpoint
                && last_save.elapsed().as_secs_f64() >= checkpoint_every_s
            {
                self.save(path)?;
                last_save = Instant::now();
            }
        };
        if let Some(path) = checkpoint {
            self.save(path)?;
        }
        Ok(RunOutcome {
            params: self.best_params.clone(),
            sse: self.best_sse.unwrap_or(f64::INFINITY),
            evaluations: self.evaluations,
            generations: self.generation(),
            seconds: self.elapsed(),
            stop,
        })
    }

    /// Writes the checkpoint (JSON) atomically.
    pub fn save(&mut self, path: &Path) -> anyhow::Result<()> {
        self.seconds_before = self.elapsed();
        self.started = Some(Instant::now());
        let json = serde_json::to_vec(self)?;
        write_atomic(path, &json)
            .map_err(|e| anyhow::anyhow!("cannot write checkpoint {}: {e}", path.display()))
    }

    /// Reads a checkpoint written by [`Runner::save`].
    pub fn load(path: &Path) -> anyhow::Result<Runner> {
        let bytes = std::fs::read(path)
            .map_err(|e| anyhow::anyhow!("cannot read checkpoint {}: {e}", path.display()))?;
        serde_json::from_slice(&bytes).map_err(|e| {
            anyhow::anyhow!(
                "{} is not a mckibben checkpoint (or a damaged one): {e}",
                path.display()
            )
        })
    }
}
