//! The engine's polish: Levenberg–Marquardt from the best distinct members
//! of each try's population stages, every try's starts together.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use rayon::prelude::*;

use super::{
    Chart, Engine, Fork, Heard, Members, Objective, Scored, Space, Spent, Stage, StageEnd, Step,
    keep_lowest, plan, timed,
};
use crate::optim::Bounds;
use crate::optim::lm::{self, LmSettings};
use crate::search::{Measure, Rows};

/// Groups of polish starts a thread in one wave of groups run side by side
/// ([`Engine::polish`]): enough that the threads stay busy while the
/// groups' lengths differ, few enough that the history moves often.
const WAVE_GROUPS_PER_THREAD: usize = 4;

/// What a polish changes that an interrupted one puts back: each try's
/// best, the history's length and the evaluations counted.
struct PolishUndo {
    bests: Vec<Option<Scored>>,
    records: usize,
    evaluations: u64,
}

/// What a polish cut short leaves outside the state, which it puts back:
/// the best start it polished, its try's index beside it, and the
/// evaluations it recorded.
pub(super) struct CutPolish {
    pub(super) best: Option<(usize, Scored)>,
    pub(super) evaluations: u64,
}

/// What every group of a polish step's starts is polished with: the space
/// as the step found it (the groups' scores borrow the engine), its box,
/// the probe steps' floor, the settings, the horizons in turn, the
/// interrupt and the time budget's end.
struct PolishSetup<'a, C> {
    space: Space<C>,
    bounds: Bounds,
    floor: Vec<f64>,
    settings: LmSettings,
    measures: Vec<Measure>,
    interrupt: Option<&'a AtomicBool>,
    deadline: Option<Instant>,
}

impl<C> PolishSetup<'_, C> {
    /// Whether the interrupt has been raised or the time budget is spent.
    fn cut(&self) -> bool {
        self.interrupt.is_some_and(|f| f.load(Ordering::SeqCst))
            || self.deadline.is_some_and(|d| Instant::now() >= d)
    }
}

impl<C: Chart> Engine<C> {
    /// A polish step: Levenberg–Marquardt on the free-run residuals from
    /// each try's best distinct members (after the population stages, of
    /// all of them; after a refining round, of that round's; from the
    /// initial rows when there was none), each try's best result kept.
    ///
    /// Cut short by `interrupt` or the time budget, it leaves the state as
    /// it found it (a resumed fit redoes it whole, as an uninterrupted one
    /// did) and returns what it did ([`CutPolish`]). So it does too once a
    /// start reaches the target SSE, the best being that of the starts up
    /// to the first that reached it: the same on any number of threads,
    /// though a wave polishes more.
    pub(super) fn polish(
        &mut self,
        objective: &mut dyn Objective,
        step: Step,
        interrupt: Option<&AtomicBool>,
        heard: &mut Heard,
    ) -> anyhow::Result<Option<CutPolish>> {
        let p = self.plan.polish.clone().expect("a polish stage");
        self.rescore_pool(objective)?;
        let before = PolishUndo {
            bests: self.tries.iter().map(|t| t.best.clone()).collect(),
            records: self.history.records.len(),
            evaluations: self.evaluations,
        };
        self.start_stage();
        let after_round = matches!(step, Step::RefinePolish(_) | Step::LevelPolish(_));
        let setup = self.polish_setup(&p, after_round, interrupt);
        let starts = self.polish_starts(after_round, &setup.bounds);
        // Each polished start's score, its try's index beside it, in the
        // starts' order.
        let mut done: Vec<(usize, Scored)> = Vec::with_capacity(starts.len());
        // The starts through every horizon, in groups polished in
        // lock-step: each round, one call scores the points all unfinished
        // starts of the group need next (each start takes the very steps it
        // takes alone), and a start that is done drops out. On an objective
        // whose calls pay a round trip (a GPU) the group is every try's
        // every start; on the CPU four starts a thread, few enough that a
        // round's residuals stay in the caches, and the groups side by side
        // on forks of the objective, since one group's round is too little
        // work for the threads to share (docs/PERFORMANCE.md, "The polish
        // in lock-step").
        let together = if objective.round_trips() {
            starts.len().max(1)
        } else {
            4 * rayon::current_num_threads().max(1)
        };
        let groups: Vec<&[(usize, Vec<f64>)]> = starts.chunks(together).collect();
        // Side by side in waves, each recorded before the next begins, so
        // that the history and a progress bar move during a long polish.
        let per_wave = WAVE_GROUPS_PER_THREAD * rayon::current_num_threads().max(1);
        for wave in groups.chunks(per_wave) {
            if setup.cut() {
                break;
            }
            let forked = (wave.len() > 1)
                .then(|| objective.forks(wave.len()))
                .flatten()
                .map(|forks| polish_side_by_side(&setup, wave, forks))
                .transpose()?;
            match forked {
                // Cut short: nothing to record.
                Some(None) => break,
                Some(Some((polished, spent))) => {
                    self.spent(spent);
                    for (group, polished) in wave.iter().zip(polished) {
                        done.extend(self.record_group(objective, &setup, group, polished)?);
                    }
                }
                None => {
                    for group in wave {
                        if setup.cut() {
                            break;
                        }
                        done.extend(self.polish_group(objective, &setup, group)?);
                    }
                }
            }
            heard.tell(&self.history);
            if let Some(reached) = self.reaching_target(&done) {
                let cut = self.undo_polish(before);
                return Ok(Some(CutPolish {
                    best: Some(reached),
                    ..cut
                }));
            }
        }
        if setup.cut() {
            return Ok(Some(self.undo_polish(before)));
        }
        match step {
            Step::LevelPolish(k) => self.keep_level(k),
            Step::RefinePolish(_) => {
                self.scan_stepwise(objective)?;
                self.settle_round();
            }
            _ => self.scan_stepwise(objective)?,
        }
        self.end_step(Stage::Polish, StageEnd::Polished);
        Ok(None)
    }

    /// What every group of the polish's starts is polished with, built once
    /// a step from the plan's polish `p`: whether the step follows a
    /// refining round decides the horizons.
    fn polish_setup<'a>(
        &self,
        p: &plan::Polish,
        after_round: bool,
        interrupt: Option<&'a AtomicBool>,
    ) -> PolishSetup<'a, C> {
        let space = self.space.clone();
        let bounds = space.bounds();
        let nf = bounds.dim();
        let floor: Vec<f64> = (0..nf).map(|j| p.step_floor * bounds.width(j)).collect();
        let free = space.free();
        let settings = LmSettings {
            max_iterations: p.iterations,
            rel_step: p.rel_step,
            tolerance: p.tolerance,
            central: p.central,
            held: free
                .iter()
                .map(|&i| space.stepwise.iter().any(|s| s.index == i))
                .collect(),
        };
        // The horizons a start is polished through: from the global stage's
        // up by factors of four, then the free run; after a refining round,
        // which starts in the free run's own basin, the free run alone.
        let mut measures = Vec::new();
        if let (true, false, Some(Measure::Ahead { horizon })) = (
            p.continuation,
            after_round,
            self.plan.global.as_ref().map(|g| g.measure),
        ) {
            let mut h = horizon.max(1);
            while h < p.longest {
                measures.push(Measure::Ahead { horizon: h });
                h *= 4;
            }
        }
        measures.push(Measure::FreeRun);
        let deadline = self.stops.time_budget_s.map(|budget| {
            Instant::now() + Duration::from_secs_f64((budget - self.elapsed()).clamp(0.0, 1e9))
        });
        PolishSetup {
            space,
            bounds,
            floor,
            settings,
            measures,
            interrupt,
            deadline,
        }
    }

    /// Each try's starts for the polish, the try's index beside each: after
    /// a refining round, from the members of the round of each try that
    /// took part in it; else from the try's whole pool.
    fn polish_starts(&self, after_round: bool, bounds: &Bounds) -> Vec<(usize, Vec<f64>)> {
        let nf = bounds.dim();
        let mut starts: Vec<(usize, Vec<f64>)> = Vec::new();
        for t in 0..self.tries.len() {
            let wanted = match (&self.plan.refine, after_round) {
                (Some(r), true) => r.starts,
                _ => self.plan.try_size(t).polish,
            };
            let tr = &self.tries[t];
            let pool: &[Members] = if after_round {
                // Only a try that took part in the round polishes its members.
                if !tr.before_round.is_finite() {
                    continue;
                }
                &tr.carried
            } else {
                &tr.pool
            };
            let initial: &[f64] = if t == 0 { &self.initial } else { &[] };
            for x in distinct_starts(pool, initial, nf, wanted, &|j| bounds.width(j)) {
                starts.push((t, x));
            }
        }
        starts
    }

    /// Polishes one group of starts in lock-step through every horizon,
    /// then scores and records the results, so that each try keeps its
    /// best.
    fn polish_group(
        &mut self,
        objective: &mut dyn Objective,
        setup: &PolishSetup<C>,
        group: &[(usize, Vec<f64>)],
    ) -> anyhow::Result<Vec<(usize, Scored)>> {
        let polished = polish_through(objective, setup, group)?;
        self.spent(polished.spent);
        self.record_group(objective, setup, group, polished)
    }

    /// Counts a group's polish evaluations, then scores and records its
    /// results ([`Engine::record_polished`]).
    fn record_group(
        &mut self,
        objective: &mut dyn Objective,
        setup: &PolishSetup<C>,
        group: &[(usize, Vec<f64>)],
        polished: GroupPolish,
    ) -> anyhow::Result<Vec<(usize, Scored)>> {
        let before_group = self.evaluations;
        self.evaluations += polished.evaluations;
        let GroupPolish { xs, points, .. } = polished;
        self.record_polished(objective, setup, group, &xs, points, before_group)
    }

    /// Scores a group's polished starts as every other candidate, so that
    /// they compare in the same arithmetic, and keeps each try's best; one
    /// record a start, in order, each counting the evaluations up to its
    /// own last score, as if the starts had been polished one after
    /// another. Returns the starts' scores, in order, each try's index
    /// beside it.
    fn record_polished(
        &mut self,
        objective: &mut dyn Objective,
        setup: &PolishSetup<C>,
        group: &[(usize, Vec<f64>)],
        xs: &[Vec<f64>],
        points: Vec<usize>,
        before_group: u64,
    ) -> anyhow::Result<Vec<(usize, Scored)>> {
        let polished = xs.concat();
        let polished = setup
            .space
            .embed(Rows::new(&polished, setup.space.free_dim()));
        let rows = self.space.project(polished.rows());
        let (canonical, costs) = self.score(objective, rows.rows(), Measure::FreeRun)?;
        let total = self.evaluations;
        let mut counted = before_group;
        for (((row, cost), points), &(t, _)) in canonical
            .rows()
            .iter()
            .zip(costs.chunks(1))
            .zip(points)
            .zip(group)
        {
            let tr = &mut self.tries[t];
            keep_lowest(&mut tr.stage_best, Rows::one(row), cost);
            keep_lowest(&mut tr.best, Rows::one(row), cost);
            self.stage_steps += 1;
            counted += points as u64 + 1;
            self.evaluations = counted;
            self.record(Stage::Polish, Measure::FreeRun, None);
        }
        debug_assert_eq!(counted, total);
        self.evaluations = total;
        Ok(canonical
            .rows()
            .iter()
            .zip(&costs)
            .zip(group)
            .map(|((row, &cost), &(t, _))| {
                let scored = Scored {
                    params: row.to_vec(),
                    cost: cost as f64,
                };
                (t, scored)
            })
            .collect())
    }

    /// Once one of the polished starts `done` (in the starts' order) reached
    /// the target SSE: the best of those up to the first that did (the
    /// first of equals).
    fn reaching_target(&self, done: &[(usize, Scored)]) -> Option<(usize, Scored)> {
        let target = self.stops.target_sse?;
        let first = done.iter().position(|(_, s)| s.cost <= target)?;
        done[..=first]
            .iter()
            .min_by(|a, b| a.1.cost.total_cmp(&b.1.cost))
            .cloned()
    }

    /// Puts back what an interrupted polish changed, so that a resumed fit
    /// redoes it whole, and returns what it did: its best so far.
    fn undo_polish(&mut self, before: PolishUndo) -> CutPolish {
        let best = self
            .tries
            .iter_mut()
            .enumerate()
            .filter_map(|(t, tr)| Some((t, tr.stage_best.take()?)))
            .min_by(|a, b| a.1.cost.total_cmp(&b.1.cost));
        for (t, b) in self.tries.iter_mut().zip(before.bests) {
            t.best = b;
        }
        self.history.records.truncate(before.records);
        let evaluations = self.evaluations - before.evaluations;
        self.evaluations = before.evaluations;
        CutPolish { best, evaluations }
    }

    /// After level round `k`: a try whose round, with the level held at
    /// that preferred value, ended within the value's tolerance of the
    /// try's best keeps it (the estimation data cannot tell the two apart,
    /// and the preferred value is the one to keep among alikes).
    fn keep_level(&mut self, k: usize) {
        let (_, _, tolerance) = self.levels()[k];
        for tr in &mut self.tries {
            let took_part = tr.before_round.is_finite();
            tr.before_round = f64::INFINITY;
            let (Some(held), Some(best)) = (&tr.stage_best, &tr.best) else {
                continue;
            };
            if took_part && held.cost <= best.cost * (1.0 + tolerance) {
                tr.best = Some(held.clone());
            }
        }
    }

    /// Moves each try's best along each free [`super::Stepwise`] coordinate
    /// to the lowest of a grid of its levels, every try's grid in one call:
    /// [`SCAN_LEVELS`] levels over [`SCAN_WINDOW`] of the box's width either
    /// side of the best, then as many between the grid's neighbours of the
    /// lowest, so that the level is placed to a fraction of a sample's
    /// spacing; the preferred values in the window are scored too and kept
    /// where they score as low as the lowest. The other coordinates stay:
    /// the refining round that follows moves them with the level.
    fn scan_stepwise(&mut self, objective: &mut dyn Objective) -> anyhow::Result<()> {
        let free = self.space.free();
        let scanned: Vec<(usize, Vec<f64>, f64)> = self
            .space
            .stepwise
            .iter()
            .filter_map(|s| {
                let j = free.iter().position(|&i| i == s.index)?;
                Some((j, s.preferred.clone(), s.tolerance))
            })
            .collect();
        for (j, preferred, tolerance) in scanned {
            let (lo, hi) = (self.space.lower[free[j]], self.space.upper[free[j]]);
            let window = SCAN_WINDOW * (hi - lo);
            // Coarse, then fine around the coarse grid's lowest.
            for pass in 0..2 {
                let bests: Vec<Option<Vec<f64>>> = self
                    .tries
                    .iter()
                    .map(|t| t.best.as_ref().map(|b| self.space.project_one(&b.params)))
                    .collect();
                let step = if pass == 0 {
                    window
                } else {
                    2.0 * window / SCAN_LEVELS as f64
                };
                let levels: Vec<Vec<f64>> = bests
                    .iter()
                    .map(|b| match b {
                        Some(row) => {
                            let at = row[j];
                            let mut v: Vec<f64> = (0..=SCAN_LEVELS)
                                .map(|k| at - step + 2.0 * step * k as f64 / SCAN_LEVELS as f64)
                                .map(|v| v.clamp(lo, hi))
                                .collect();
                            v.extend(
                                preferred
                                    .iter()
                                    .filter(|p| (at - step..=at + step).contains(*p))
                                    .filter(|p| (lo..=hi).contains(*p)),
                            );
                            v
                        }
                        None => Vec::new(),
                    })
                    .collect();
                let rows: Vec<f64> = bests
                    .iter()
                    .zip(&levels)
                    .flat_map(|(b, ls)| {
                        ls.iter().flat_map(move |&l| {
                            let mut row = b.clone().expect("levels only for a best");
                            row[j] = l;
                            row
                        })
                    })
                    .collect();
                if rows.is_empty() {
                    break;
                }
                let rows = Rows::new(&rows, self.space.free_dim());
                let (canonical, costs) = self.score(objective, rows, Measure::FreeRun)?;
                let mut at = 0;
                for (t, ls) in levels.iter().enumerate() {
                    let own = &costs[at..at + ls.len()];
                    let Some(mut k) = crate::optim::argmin(own) else {
                        at += ls.len();
                        continue;
                    };
                    // A preferred value that scores alike: within the
                    // tolerance of the lowest and of the try's best.
                    let tr = &mut self.tries[t];
                    let current = tr.best.as_ref().map_or(f64::INFINITY, |b| b.cost);
                    let alike = (own[k] as f64).min(current) * (1.0 + tolerance);
                    let at_preferred = (0..ls.len())
                        .filter(|&i| preferred.contains(&ls[i]) && own[i] as f64 <= alike)
                        .min_by(|&a, &b| own[a].total_cmp(&own[b]));
                    if let Some(p) = at_preferred {
                        k = p;
                    }
                    let cost = own[k] as f64;
                    let already = tr
                        .best
                        .as_ref()
                        .is_some_and(|b| self.space.project_one(&b.params)[j] == ls[k]);
                    if !already && (cost < current || at_preferred.is_some()) {
                        let i = at + k;
                        tr.best = Some(Scored {
                            params: canonical.rows().row(i).to_vec(),
                            cost,
                        });
                    }
                    at += ls.len();
                }
            }
        }
        Ok(())
    }
}

/// Levels a scan of a [`super::Stepwise`] coordinate scores per pass.
const SCAN_LEVELS: usize = 128;

/// Half the width of a scan's first grid, as a share of the coordinate's box.
const SCAN_WINDOW: f64 = 0.05;

/// Up to `wanted` starts for the polish from `pool`, best first, each
/// distinct from those before it; `initial`'s rows when the pool is empty.
///
/// The islands' best on the free run first (the free-run stage's, then the
/// global stage's members re-scored), then their second best, and so on:
/// each island's basin gets a start before any gets two. The global stage's
/// members matter when the model cannot fit the data exactly: there the
/// free-run stage can drift from a good basin into a degenerate one
/// (towards the linear model, A → 0, on the shipped stair:
/// docs/ARCHITECTURE.md, "Decisions of the fitting engine"), which
/// continuation from the global stage's members avoids.
///
/// A start is new when its parameters differ from every start's by more
/// than [`plan::DISTINCT`] of a coordinate's box `width` and its free-run
/// SSE does too: members that differ only in parameters the output does
/// not feel (a coordinate multiplied by another that is zero) are one model.
fn distinct_starts(
    pool: &[Members],
    initial: &[f64],
    nf: usize,
    wanted: usize,
    width: &dyn Fn(usize) -> f64,
) -> Vec<Vec<f64>> {
    let ranked: Vec<(&[f64], f32)> = if pool.is_empty() {
        initial
            .chunks_exact(nf)
            .map(|row| (row, f32::INFINITY))
            .collect()
    } else {
        let orders: Vec<Vec<usize>> = pool.iter().map(Members::order).collect();
        let deepest = orders.iter().map(Vec::len).max().unwrap_or(0);
        (0..deepest)
            .flat_map(|r| {
                pool.iter().zip(&orders).filter_map(move |(m, o)| {
                    o.get(r)
                        .map(|&i| (&m.rows[i * nf..(i + 1) * nf], m.costs[i]))
                })
            })
            .collect()
    };
    let mut starts: Vec<(Vec<f64>, f32)> = Vec::new();
    for (row, cost) in ranked {
        if starts.len() == wanted {
            break;
        }
        let distinct = starts.iter().all(|(s, c)| {
            // Two infinite costs are not the same model.
            let same_cost = (cost - c).abs() <= plan::DISTINCT as f32 * c.abs();
            (0..nf).any(|j| (s[j] - row[j]).abs() > plan::DISTINCT * width(j)) && !same_cost
        });
        if distinct {
            starts.push((row.to_vec(), cost));
        }
    }
    starts.into_iter().map(|(x, _)| x).collect()
}

/// Where a group's starts ended after every horizon of its polish, the
/// points each had scored, and what the polish cost.
struct GroupPolish {
    xs: Vec<Vec<f64>>,
    points: Vec<usize>,
    evaluations: u64,
    spent: Spent,
}

/// A group's polish in lock-step through every horizon of `setup`: each
/// round, one call of `objective` scores the points all its unfinished
/// starts need next (each start takes the very steps it takes alone), and
/// a start that is done drops out.
fn polish_through<C: Chart>(
    objective: &mut dyn Objective,
    setup: &PolishSetup<C>,
    group: &[(usize, Vec<f64>)],
) -> anyhow::Result<GroupPolish> {
    let mut polished = GroupPolish {
        xs: group.iter().map(|(_, x)| x.clone()).collect(),
        points: vec![0; group.len()],
        evaluations: 0,
        spent: Spent {
            kernel: Some(0.0),
            ..Spent::default()
        },
    };
    for &measure in &setup.measures {
        if setup.cut() {
            break;
        }
        polish_on(objective, setup, measure, &mut polished)?;
    }
    Ok(polished)
}

/// One horizon of a group's polish: Levenberg–Marquardt under `measure`
/// from where its starts stand, which move to where they end.
fn polish_on<C: Chart>(
    objective: &mut dyn Objective,
    setup: &PolishSetup<C>,
    measure: Measure,
    polished: &mut GroupPolish,
) -> anyhow::Result<()> {
    let mut evaluations = 0u64;
    let spent = &mut polished.spent;
    let mut residuals = |points: &[Vec<f64>]| {
        evaluations += points.len() as u64;
        let points = points.concat();
        let canonical = setup
            .space
            .embed(Rows::new(&points, setup.space.free_dim()));
        let (r, s) = timed(objective, |o| o.residuals(canonical.rows(), measure));
        spent.seconds += s.seconds;
        spent.kernel = spent.kernel.zip(s.kernel).map(|(a, b)| a + b);
        r
    };
    let runs = lm::levenberg_marquardt_lockstep(
        &mut residuals,
        &polished.xs,
        (&setup.bounds.lower, &setup.bounds.upper),
        &setup.floor,
        &setup.settings,
        setup.interrupt,
    );
    polished.evaluations += evaluations;
    for ((x, count), run) in polished.xs.iter_mut().zip(&mut polished.points).zip(runs?) {
        *count += run.points;
        // A start whose simulation or a probe's diverges keeps its place:
        // the search's value is still a candidate.
        if let Ok(out) = run.outcome {
            *x = out.x;
        }
    }
    Ok(())
}

/// Every group's polish ([`polish_through`]) on its own fork of the
/// objective, the groups side by side, in the groups' order; `None` when
/// cut short. Each start takes the very steps it takes in any group, so
/// the fit is the same bits as with the groups one after another. The
/// evaluator's seconds of this phase are its wall time times the share of
/// the groups' own time they spent in evaluator calls.
fn polish_side_by_side<C: Chart>(
    setup: &PolishSetup<C>,
    groups: &[&[(usize, Vec<f64>)]],
    forks: Vec<Box<dyn Fork + '_>>,
) -> anyhow::Result<Option<(Vec<GroupPolish>, Spent)>> {
    let started = Instant::now();
    let polished: Vec<anyhow::Result<(GroupPolish, f64)>> = groups
        .par_iter()
        .zip(forks)
        .map(|(group, mut fork)| {
            let began = Instant::now();
            let mut out = None;
            fork.run(&mut |forked| {
                out = Some(polish_through(forked, setup, group)?);
                Ok(())
            })?;
            let polished = out.context("a fork of the objective did not run its work")?;
            Ok((polished, began.elapsed().as_secs_f64()))
        })
        .collect();
    let wall = started.elapsed().as_secs_f64();
    let polished = polished.into_iter().collect::<anyhow::Result<Vec<_>>>()?;
    if setup.cut() {
        return Ok(None);
    }
    let busy: f64 = polished.iter().map(|(_, b)| b).sum();
    let inside: f64 = polished.iter().map(|(p, _)| p.spent.seconds).sum();
    let spent = Spent {
        seconds: if busy > 0.0 {
            wall * inside / busy
        } else {
            0.0
        },
        kernel: None,
    };
    Ok(Some((
        polished.into_iter().map(|(p, _)| p).collect(),
        spent,
    )))
}
