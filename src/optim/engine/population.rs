//! The engine's population stages: the global search and the free-run
//! stage, island by island, one generation a step.

use super::{Engine, FreeRun, Members, Objective, Stage, StageEnd, keep_lowest};
use crate::model::Measure;
use crate::optim::{AskTell, Streams};

impl Engine {
    /// The streams of generation `generation` of `stage` (0: the draws
    /// before the first population; `k`: the `k`-th population asked).
    fn streams(&self, stage: Stage, generation: usize) -> Streams {
        Streams::new(self.seed, stage, generation)
    }

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
        self.start_stage();
        let islands = self.plan.islands();
        match stage {
            Stage::Global => {
                let g = self.plan.global.clone().expect("a global stage");
                let n = g.population / islands;
                // Island i's rows are individuals i·n … of the stage.
                let streams = self.streams(stage, 0);
                Ok((0..islands)
                    .map(|i| {
                        let mut rows = if i == 0 {
                            self.initial[..self.initial.len().min(n * nf)].to_vec()
                        } else {
                            Vec::new()
                        };
                        let given = rows.len() / nf;
                        let drawn = streams.from_row(i * n + given);
                        rows.extend(self.space.draw(n - given, &drawn));
                        let free_run_island = g.ladder && i > 0 && i + 1 == islands;
                        let settings = if free_run_island {
                            FreeRun::ALGORITHM.default_settings()
                        } else {
                            g.settings.clone()
                        };
                        AskTell::new(&settings, bounds.clone(), n, g.generations, rows)
                    })
                    .collect())
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
                            start,
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

    /// One generation of a population stage: every island asks (island
    /// `i`'s individuals numbered after those of the islands before it, so
    /// that each has its own stream), every island's rows are embedded into
    /// one buffer of canonical rows, scored (in one batch when every island
    /// has the same measure) and every island is told its own. The first
    /// island's costs rank the stage's best and fill the record: the others
    /// may measure other horizons.
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
        let one_batch = measures.iter().all(|&m| m == measure);
        let streams = self.streams(stage, self.stage_steps + 1);
        let (d, nf) = (self.space.dim(), self.space.free().len().max(1));
        // Each island's rows go straight from the optimizer into its part of
        // the canonical buffer; `spans[i]` is island i's first row and count.
        let mut canonical = std::mem::take(&mut self.canonical);
        let mut spans = Vec::with_capacity(self.optimizers.len());
        let mut at = 0;
        for opt in &mut self.optimizers {
            let rows = opt.ask(&streams.from_row(at))?;
            let n = rows.len() / nf;
            // The same size every generation after the first: no refill.
            if canonical.len() < (at + n) * d {
                canonical.resize((at + n) * d, 0.0);
            }
            self.space
                .embed_into(rows, &mut canonical[at * d..(at + n) * d]);
            spans.push((at, n));
            at += n;
        }
        canonical.truncate(at * d);
        let costs: Vec<Vec<f32>> = if one_batch {
            vec![self.score_canonical(objective, &canonical, measure)?]
        } else {
            spans
                .iter()
                .zip(&measures)
                .map(|(&(at, n), &m)| {
                    self.score_canonical(objective, &canonical[at * d..(at + n) * d], m)
                })
                .collect::<anyhow::Result<_>>()?
        };
        // Island i's costs: its part of the one batch, or its own batch.
        let island_costs = |i: usize| -> &[f32] {
            if one_batch {
                let (at, n) = spans[i];
                &costs[0][at..at + n]
            } else {
                &costs[i]
            }
        };
        for (i, opt) in self.optimizers.iter_mut().enumerate() {
            opt.tell(island_costs(i))?;
        }
        for (i, &(at, n)) in spans.iter().enumerate() {
            if measures[i] == Measure::FreeRun {
                keep_lowest(
                    &mut self.best,
                    &canonical[at * d..(at + n) * d],
                    island_costs(i),
                    d,
                );
            }
        }
        // The stage's best and the record: every island when they share a
        // measure, else the first.
        let (ranked_rows, ranked_costs) = if one_batch {
            (&canonical[..], &costs[0][..])
        } else {
            let (at, n) = spans[0];
            (&canonical[at * d..(at + n) * d], &costs[0][..])
        };
        keep_lowest(&mut self.stage_best, ranked_rows, ranked_costs, d);
        self.stage_steps += 1;
        self.record(stage, measure, Some(ranked_costs));
        self.canonical = canonical;
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
