//! The engine's population stages: the global search and the free-run
//! stage, island by island, one generation a step.

use super::{Engine, FreeRun, Members, Objective, RngState, Stage, StageEnd, keep_lowest};
use crate::model::Measure;
use crate::optim::AskTell;

impl Engine {
    /// The islands of a population stage: the global stage's start from
    /// the initial rows (the first island) and [`super::Space::draw`]; each island
    /// of the free-run stage from the best members of the same island
    /// before, ranked on the free run.
    pub(super) fn begin(
        &mut self,
        objective: &mut dyn Objective,
        stage: Stage,
    ) -> anyhow::Result<Vec<AskTell>> {
        let bounds = self.space.bounds();
        let nf = bounds.dim();
        self.stage_steps = 0;
        self.stage_best = None;
        self.stage_start_evaluations = self.evaluations;
        self.stage_start_seconds = self.elapsed();
        let islands = self.plan.islands();
        match stage {
            Stage::Global => {
                let g = self.plan.global.clone().expect("a global stage");
                let n = g.population / islands;
                let mut rng = self.rng.restore()?;
                let optimizers = (0..islands)
                    .map(|i| {
                        let mut rows = if i == 0 {
                            self.initial[..self.initial.len().min(n * nf)].to_vec()
                        } else {
                            Vec::new()
                        };
                        rows.extend(self.space.draw(n - rows.len() / nf, &mut rng));
                        let free_run_island = g.ladder && i > 0 && i + 1 == islands;
                        let settings = if free_run_island {
                            FreeRun::ALGORITHM.default_settings()
                        } else {
                            g.settings.clone()
                        };
                        AskTell::new(&settings, bounds.clone(), n, g.generations, &rows)
                    })
                    .collect();
                self.rng = RngState::of(&rng);
                Ok(optimizers)
            }
            _ => {
                let f = self.plan.free_run.clone().expect("a free-run stage");
                let n = f.population / islands;
                self.rescore_pool(objective)?;
                Ok((0..islands)
                    .map(|i| {
                        let start = match self.carried.get(i) {
                            Some(m) => m.best(n, nf),
                            None if i == 0 => self.initial.clone(),
                            None => Vec::new(),
                        };
                        AskTell::new(
                            &FreeRun::ALGORITHM.default_settings(),
                            bounds.clone(),
                            n,
                            f.generations,
                            &start,
                        )
                    })
                    .collect())
            }
        }
    }

    /// Re-scores on the free run the islands in the pool (and in hand) that
    /// another measure ranked, so that whatever starts from them ranks them
    /// as the simulator does: on data the model cannot fit exactly, the
    /// prediction error's best can lie in another basin than the free run's
    /// (on the shipped stair the prediction ranks the linear model, A → 0,
    /// first and the free run a hysteretic one: docs/ARCHITECTURE.md, "Where
    /// the model cannot fit exactly, the free run judges every basin").
    pub(super) fn rescore_pool(&mut self, objective: &mut dyn Objective) -> anyhow::Result<()> {
        for i in 0..self.pool.len() {
            if self.pool[i].measure == Measure::FreeRun {
                continue;
            }
            let rows = std::mem::take(&mut self.pool[i].rows);
            let (canonical, costs) = self.score(objective, &rows, Measure::FreeRun)?;
            self.offer_best(&canonical, &costs);
            self.pool[i] = Members {
                rows,
                costs,
                measure: Measure::FreeRun,
            };
        }
        // The islands just ended are the pool's first entries.
        let fresh = self.carried.len().min(self.pool.len());
        self.carried = self.pool[..fresh].to_vec();
        Ok(())
    }

    /// One generation of a population stage: every island asks, the rows
    /// are scored (in one batch when every island has the same measure),
    /// every island is told its own. The first island's costs rank the
    /// stage's best and fill the record: the others may measure other horizons.
    pub(super) fn step_population(
        &mut self,
        objective: &mut dyn Objective,
        stage: Stage,
    ) -> anyhow::Result<()> {
        if self.optimizers.is_empty() {
            self.optimizers = self.begin(objective, stage)?;
        }
        let measures: Vec<Measure> = (0..self.optimizers.len())
            .map(|i| self.island_measure(stage, i))
            .collect();
        let measure = measures[0];
        let mut rng = self.rng.restore()?;
        let asked: Vec<Vec<f64>> = self
            .optimizers
            .iter_mut()
            .map(|o| o.ask(&mut rng))
            .collect::<Result<_, _>>()?;
        self.rng = RngState::of(&rng);
        let scored: Vec<(Vec<f64>, Vec<f32>)> = if measures.iter().all(|&m| m == measure) {
            let (canonical, costs) = self.score(objective, &asked.concat(), measure)?;
            let d = self.space.dim();
            let nf = self.space.free().len();
            let mut at = 0;
            asked
                .iter()
                .map(|rows| {
                    let n = rows.len() / nf;
                    let part = (
                        canonical[at * d..(at + n) * d].to_vec(),
                        costs[at..at + n].to_vec(),
                    );
                    at += n;
                    part
                })
                .collect()
        } else {
            asked
                .iter()
                .zip(&measures)
                .map(|(rows, &m)| self.score(objective, rows, m))
                .collect::<anyhow::Result<_>>()?
        };
        for (opt, (_, costs)) in self.optimizers.iter_mut().zip(&scored) {
            opt.tell(costs)?;
        }
        for ((canonical, costs), &m) in scored.iter().zip(&measures) {
            if m == Measure::FreeRun {
                self.offer_best(canonical, costs);
            }
        }
        let d = self.space.dim();
        let (canonical, costs) = if measures.iter().all(|&m| m == measure) {
            (
                scored.iter().flat_map(|s| s.0.clone()).collect::<Vec<_>>(),
                scored.iter().flat_map(|s| s.1.clone()).collect::<Vec<_>>(),
            )
        } else {
            scored[0].clone()
        };
        keep_lowest(&mut self.stage_best, &canonical, &costs, d);
        self.stage_steps += 1;
        self.record(stage, measure, Some(&costs));
        let length = match stage {
            Stage::Global => self.plan.global.as_ref().map_or(0, |g| g.generations),
            _ => self.plan.free_run.as_ref().map_or(0, |f| f.generations),
        };
        if self.stage_steps >= length {
            self.end_stage(stage, StageEnd::Generations);
        } else if self.stalled(stage) {
            self.end_stage(stage, StageEnd::Stalled);
        }
        Ok(())
    }

    /// Whether the current stage's best has not improved by more than the
    /// stall tolerance over the last `stall_generations` generations.
    pub(super) fn stalled(&self, stage: Stage) -> bool {
        let Some(w) = self.stops.stall_generations else {
            return false;
        };
        let bests: Vec<f64> = self
            .history
            .records
            .iter()
            .rev()
            .take_while(|r| r.stage == stage)
            .map(|r| r.stage_best.unwrap_or(f64::INFINITY))
            .collect();
        if bests.len() <= w {
            return false;
        }
        let (now, then) = (bests[0], bests[w]);
        then.is_finite() && now >= then * (1.0 - self.stops.stall_tolerance)
    }
}
