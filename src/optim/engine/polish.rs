//! The engine's last stage: Levenberg–Marquardt from the best distinct
//! members of the population stages.

use std::sync::atomic::{AtomicBool, Ordering};

use super::{Engine, Members, Objective, Scored, Stage, StageEnd, keep_lowest, plan, timed};
use crate::model::Measure;
use crate::optim::lm::{self, LmSettings};

impl Engine {
    /// The polish: Levenberg–Marquardt on the free-run residuals from the
    /// best distinct members of the population stages (or from the initial
    /// rows when there was none), the best result kept.
    ///
    /// Cut short by `interrupt`, it leaves the state as it found it (a
    /// resumed fit redoes it whole, as an uninterrupted one did) and returns
    /// the best it polished so far.
    pub(super) fn polish(
        &mut self,
        objective: &mut dyn Objective,
        interrupt: Option<&AtomicBool>,
    ) -> anyhow::Result<Option<Scored>> {
        let p = self.plan.polish.clone().expect("a polish stage");
        self.rescore_pool(objective)?;
        let before = (
            self.best.clone(),
            self.history.records.len(),
            self.evaluations,
        );
        self.start_stage();
        let space = self.space.clone();
        let bounds = space.bounds();
        let nf = bounds.dim();
        // The islands' best on the free run first (the free-run stage's,
        // then the global stage's members re-scored), then their second
        // best, and so on: each island's basin gets a start before any gets
        // two. The global stage's members matter when the model cannot fit
        // the data exactly: there the free-run stage can drift from a good
        // basin into a degenerate one (towards the linear model, A → 0, on
        // the shipped stair: docs/ARCHITECTURE.md, "Decisions of the fitting
        // engine"), which continuation from the global stage's members
        // avoids.
        let ranked: Vec<(&[f64], f32)> = if self.pool.is_empty() {
            self.initial
                .chunks_exact(nf)
                .map(|row| (row, f32::INFINITY))
                .collect()
        } else {
            let orders: Vec<Vec<usize>> = self.pool.iter().map(Members::order).collect();
            let deepest = orders.iter().map(Vec::len).max().unwrap_or(0);
            (0..deepest)
                .flat_map(|r| {
                    self.pool.iter().zip(&orders).filter_map(move |(m, o)| {
                        o.get(r)
                            .map(|&i| (&m.rows[i * nf..(i + 1) * nf], m.costs[i]))
                    })
                })
                .collect()
        };
        // A start is new when its parameters differ from every start's and
        // its free-run SSE does too: members that differ only in parameters
        // the output does not feel (β and γ when A = 0) are one model.
        let mut starts: Vec<(Vec<f64>, f32)> = Vec::new();
        for (row, cost) in ranked {
            if starts.len() == p.starts {
                break;
            }
            let distinct = starts.iter().all(|(s, c)| {
                // Two infinite costs are not the same model.
                let same_cost = (cost - c).abs() <= plan::DISTINCT as f32 * c.abs();
                (0..nf).any(|j| (s[j] - row[j]).abs() > plan::DISTINCT * bounds.width(j))
                    && !same_cost
            });
            if distinct {
                starts.push((row.to_vec(), cost));
            }
        }
        let floor: Vec<f64> = (0..nf).map(|j| p.step_floor * bounds.width(j)).collect();
        let settings = LmSettings {
            max_iterations: p.iterations,
            rel_step: p.rel_step,
            tolerance: p.tolerance,
            central: p.central,
        };
        let cut = || interrupt.is_some_and(|f| f.load(Ordering::SeqCst));
        // The horizons a start is polished through: from the global stage's
        // up by factors of four, then the free run.
        let mut measures = Vec::new();
        if let (true, Some(Measure::Ahead { horizon })) =
            (p.continuation, self.plan.global.as_ref().map(|g| g.measure))
        {
            let mut h = horizon.max(1);
            while h < p.longest {
                measures.push(Measure::Ahead { horizon: h });
                h *= 4;
            }
        }
        measures.push(Measure::FreeRun);
        // The starts through every horizon, in groups polished in
        // lock-step: each round, one call scores the points all unfinished
        // starts of the group need next (each start takes the very steps it
        // takes alone), and a start that is done drops out. On an objective
        // whose calls pay a round trip (a GPU) the group is every start; on
        // the CPU one start, since there a call costs only its rows and a
        // round of every start's residuals outgrows the caches: measured
        // slower (docs/PERFORMANCE.md, "The polish in lock-step").
        let starts: Vec<Vec<f64>> = starts.into_iter().map(|(x, _)| x).collect();
        let together = if objective.round_trips() {
            starts.len().max(1)
        } else {
            1
        };
        for group in starts.chunks(together) {
            if cut() {
                break;
            }
            let before_group = self.evaluations;
            let mut xs = group.to_vec();
            // The points each start had scored: its record counts them.
            let mut points = vec![0usize; xs.len()];
            for &measure in &measures {
                if cut() {
                    break;
                }
                let (mut evaluations, mut seconds) = (0u64, 0.0);
                let mut residuals = |points: &[Vec<f64>]| {
                    evaluations += points.len() as u64;
                    let canonical = space.embed(&points.concat());
                    let (r, s) = timed(objective, |o| o.residuals(&canonical, measure));
                    seconds += s;
                    r
                };
                let polished = lm::levenberg_marquardt_lockstep(
                    &mut residuals,
                    &xs,
                    (&bounds.lower, &bounds.upper),
                    &floor,
                    &settings,
                    interrupt,
                );
                self.evaluations += evaluations;
                self.evaluator_seconds += seconds;
                for ((x, count), run) in xs.iter_mut().zip(&mut points).zip(polished?) {
                    *count += run.points;
                    // A start whose simulation or a probe's diverges keeps
                    // its place: the search's value is still a candidate.
                    if let Ok(out) = run.outcome {
                        *x = out.x;
                    }
                }
            }
            // Scored as every other candidate, so that they compare in the
            // same arithmetic; one record a start, in order, each counting
            // the evaluations up to its own last score, as if the starts
            // had been polished one after another.
            let rows = self.space.project(&space.embed(&xs.concat()));
            let (canonical, costs) = self.score(objective, &rows, Measure::FreeRun)?;
            let (d, total) = (self.space.dim(), self.evaluations);
            let mut counted = before_group;
            for ((row, cost), points) in canonical.chunks_exact(d).zip(costs.chunks(1)).zip(points)
            {
                keep_lowest(&mut self.stage_best, row, cost, d);
                self.offer_best(row, cost);
                self.stage_steps += 1;
                counted += points as u64 + 1;
                self.evaluations = counted;
                self.record(Stage::Polish, Measure::FreeRun, None);
            }
            debug_assert_eq!(counted, total);
            self.evaluations = total;
        }
        if cut() {
            let partial = self.stage_best.take();
            (self.best, _, self.evaluations) = before.clone();
            self.history.records.truncate(before.1);
            return Ok(partial);
        }
        self.end_stage(Stage::Polish, StageEnd::Polished);
        Ok(None)
    }
}
