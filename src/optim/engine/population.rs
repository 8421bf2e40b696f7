//! The engine's population stages: the global search, the free-run stage
//! and the refining rounds, every try's islands in lock-step, one
//! generation a step.

use std::ops::Range;

use super::{
    Chart, Engine, FreeRun, Members, Objective, Refine, Stage, StageEnd, Step, Ticket, keep_lowest,
    sanitized, timed,
};
use crate::search::{Coords, Measure, Params, Population, Rows};
use rayon::prelude::*;

use crate::optim::{AskTell, Streams};

/// Where one island's rows of a generation sit in the generation's buffers,
/// what they are scored under and the streams they are drawn from.
struct Span {
    try_index: usize,
    at: usize,
    count: usize,
    measure: Measure,
    streams: Streams,
}

/// Parts a generation goes in where the objective's calls pay a round trip
/// ([`Objective::round_trips`]): the host's asks and tells hide behind the
/// device's scoring but for one part's (a quarter), at the price of a
/// call a part and measure.
const OVERLAPPED_PARTS: usize = 4;

/// One call of a generation's scoring in flight: the islands it scores
/// (indices into the generation's spans, all of one measure), their rows
/// where they had to be gathered from the buffer, and the ticket.
struct Scoring {
    islands: Vec<usize>,
    measure: Measure,
    gathered: Option<Population<Params>>,
    ticket: Ticket,
}

/// The first row and the number of rows of consecutive spans.
fn rows_of(spans: &[Span]) -> (usize, usize) {
    let from = spans.first().map_or(0, |s| s.at);
    (from, spans.iter().map(|s| s.count).sum())
}

/// `spans` cut into at most `count` runs of whole islands, each holding
/// about an equal share of the rows, none empty.
fn parts_of(spans: &[Span], count: usize) -> Vec<Range<usize>> {
    let (_, total) = rows_of(spans);
    let mut parts = Vec::with_capacity(count);
    let (mut start, mut rows) = (0, 0);
    for (i, s) in spans.iter().enumerate() {
        rows += s.count;
        if rows * count >= total * (parts.len() + 1) || i + 1 == spans.len() {
            parts.push(start..i + 1);
            start = i + 1;
        }
    }
    parts
}

impl<C: Chart> Engine<C> {
    /// The streams of generation `generation` of `stage` in try `t` (0: the
    /// draws before the first population; `k`: the `k`-th population asked).
    fn streams(&self, t: usize, stage: Stage, generation: usize) -> Streams {
        Streams::new(self.tries[t].seed, stage, generation)
    }

    /// The generation of the streams of `step`'s `k`-th population: a
    /// refining round's count on from the rounds before it, so that no two
    /// rounds draw the same numbers. Each round draws from a slot of its
    /// own: the first [`Refine::DEFAULT_ROUNDS`] rounds, then the level
    /// rounds, then the rounds a larger cap adds, so that raising the cap
    /// moves no draw of the rounds a smaller one runs (a try that stops
    /// refining within the default's rounds ends bit for bit as with it).
    fn stream_generation(&self, step: Step, k: usize) -> usize {
        let Some(refine) = &self.plan.refine else {
            return k;
        };
        let first = Refine::DEFAULT_ROUNDS;
        let slot = match step {
            Step::Refine(r) if r < first => r,
            Step::Refine(r) => r + self.levels().len(),
            Step::Level(l) => first + l,
            _ => return k,
        };
        slot * (refine.generations + 1) + k
    }

    /// The islands of try `t` for a population step: the global stage's
    /// start from the initial rows (the first try's first island) and
    /// [`super::Space::draw`]; each island of the free-run stage from the
    /// best members of the same island before, ranked on the free run; a
    /// refining round's one island from a cloud around the try's best
    /// ([`super::Space::cloud`]), or none where the try no longer refines.
    fn begin_try(&mut self, t: usize, step: Step) -> Vec<AskTell> {
        let bounds = self.space.bounds();
        let nf = bounds.dim();
        let islands = self.plan.islands();
        match step {
            Step::Global => {
                let g = self.plan.global.clone().expect("a global stage");
                let n = self.plan.try_size(t).global / islands;
                // Island i's rows are individuals i·n … of the try's stage.
                let streams = self.streams(t, Stage::Global, 0);
                (0..islands)
                    .map(|i| {
                        let rows = if i == 0 && t == 0 {
                            self.initial[..self.initial.len().min(n * nf)].to_vec()
                        } else {
                            Vec::new()
                        };
                        let mut rows = Population::new(rows, nf);
                        let given = rows.len();
                        let drawn = streams.from_row(i * n + given);
                        rows.extend(self.space.draw(n - given, &drawn).rows());
                        let free_run_island = g.ladder && i > 0 && i + 1 == islands;
                        let settings = if free_run_island {
                            FreeRun::ALGORITHM.default_settings()
                        } else {
                            g.settings.clone()
                        };
                        AskTell::new(&settings, bounds.clone(), n, g.generations, rows)
                    })
                    .collect()
            }
            Step::FreeRun => {
                let f = self.plan.free_run.clone().expect("a free-run stage");
                let n = self.plan.try_size(t).free_run / islands;
                (0..islands)
                    .map(|i| {
                        let start = match self.tries[t].carried.get(i) {
                            Some(m) => m.best(n, nf),
                            None if i == 0 && t == 0 => self.initial.clone(),
                            None => Vec::new(),
                        };
                        AskTell::new(
                            &FreeRun::ALGORITHM.default_settings(),
                            bounds.clone(),
                            n,
                            f.generations,
                            Population::new(start, nf),
                        )
                    })
                    .collect()
            }
            Step::Refine(_) => {
                let r = self.plan.refine.clone().expect("refining rounds");
                let Some(best) = self.tries[t]
                    .best
                    .clone()
                    .filter(|_| self.tries[t].refining)
                else {
                    return Vec::new();
                };
                self.tries[t].before_round = best.cost;
                let streams = self.streams(t, Stage::Refine, self.stream_generation(step, 0));
                let population = self.plan.try_size(t).refine;
                let cloud = self.space.cloud_rows(&best.params, population, &streams);
                vec![AskTell::new(
                    &FreeRun::ALGORITHM.default_settings(),
                    bounds,
                    population,
                    r.generations,
                    cloud,
                )]
            }
            Step::Level(k) => {
                let r = self.plan.refine.clone().expect("refining rounds");
                let Some(best) = self.tries[t].best.clone() else {
                    return Vec::new();
                };
                let (j, value, _) = self.levels()[k];
                let mut center = self.space.project_one(&best.params);
                if center[j] == value {
                    // Already there: nothing to hold it at.
                    return Vec::new();
                }
                self.tries[t].before_round = best.cost;
                center[j] = value;
                let streams = self.streams(t, Stage::Refine, self.stream_generation(step, 0));
                let center = self.space.embed(Rows::one(&center));
                let population = self.plan.try_size(t).refine;
                let mut cloud = self
                    .space
                    .cloud_rows(center.rows().row(0), population, &streams);
                for row in cloud.iter_mut() {
                    row[j] = value;
                }
                let mut held = bounds;
                (held.lower[j], held.upper[j]) = (value, value);
                vec![AskTell::new(
                    &FreeRun::ALGORITHM.default_settings(),
                    held,
                    population,
                    r.generations,
                    cloud,
                )]
            }
            Step::Polish | Step::RefinePolish(_) | Step::LevelPolish(_) => {
                unreachable!("not a population step")
            }
        }
    }

    /// Re-scores on the free run the islands in every try's pool (and in
    /// hand) that another measure ranked, in one call, so that whatever
    /// starts from them ranks them as the simulator does: on data the model
    /// cannot fit exactly, the prediction error's best can lie in another
    /// basin than the free run's (on the shipped stair the prediction ranks
    /// the linear model, A → 0, first and the free run a hysteretic one:
    /// docs/ARCHITECTURE.md, "Where the model cannot fit exactly, the free
    /// run judges every basin").
    pub(super) fn rescore_pool(&mut self, objective: &mut dyn Objective) -> anyhow::Result<()> {
        let stale: Vec<(usize, usize)> = self
            .tries
            .iter()
            .enumerate()
            .flat_map(|(t, tr)| {
                tr.pool
                    .iter()
                    .enumerate()
                    .filter(|(_, m)| m.measure != Measure::FreeRun)
                    .map(move |(i, _)| (t, i))
            })
            .collect();
        if !stale.is_empty() {
            let rows: Vec<f64> = stale
                .iter()
                .flat_map(|&(t, i)| self.tries[t].pool[i].rows.iter().copied())
                .collect();
            let nf = self.space.free_dim();
            let (canonical, costs) =
                self.score(objective, Rows::new(&rows, nf), Measure::FreeRun)?;
            let mut at = 0;
            for (t, i) in stale {
                let members = &mut self.tries[t].pool[i];
                let n = members.rows.len() / nf;
                let own = &costs[at..at + n];
                keep_lowest(&mut self.tries[t].best, canonical.rows().span(at, n), own);
                let members = &mut self.tries[t].pool[i];
                members.costs = own.to_vec();
                members.measure = Measure::FreeRun;
                at += n;
            }
        }
        // The islands just ended are the pool's first entries.
        for tr in &mut self.tries {
            let fresh = tr.carried.len().min(tr.pool.len());
            tr.carried = tr.pool[..fresh].to_vec();
        }
        Ok(())
    }

    /// One generation of a population step: every island of every try still
    /// in the stage asks (island `i`'s individuals numbered after those of
    /// the try's islands before it, so that each has its own stream), every
    /// row is embedded into one buffer of canonical rows, the rows that
    /// share a measure are scored in one call, and every island is told its
    /// own. Each try's first island's costs rank the try's stage best, and
    /// fill the record: the others may measure other horizons.
    ///
    /// Where the objective's calls pay a round trip (a device), the islands
    /// go in [`OVERLAPPED_PARTS`] parts: while the device scores one part,
    /// the host asks the next and tells the one before. An island's rows,
    /// costs and moves do not depend on which part it is in, so the bits
    /// are those of one part.
    pub(super) fn step_population(
        &mut self,
        objective: &mut dyn Objective,
        step: Step,
    ) -> anyhow::Result<()> {
        let stage = step.stage();
        // A step in progress has a try with islands: every try done ends it.
        if self.tries.iter().all(|t| t.optimizers.is_empty())
            && !self.begin_population_step(objective, step)?
        {
            return Ok(());
        }
        let d = self.space.dim();
        let spans = self.generation_spans(step, stage);
        let at = spans.last().map_or(0, |s| s.at + s.count);
        let free = self.space.free_dim();
        let mut rows = match self.asked.take() {
            Some(rows) if rows.dim() == free => rows,
            _ => Population::zeros(0, free),
        };
        // Every island writes all of its rows: no refill either.
        rows.resize(at);
        let mut canonical = self
            .canonical
            .take()
            .unwrap_or_else(|| Population::zeros(0, d));
        // The same size every generation after the first: no refill.
        canonical.resize(at);
        let mut costs = vec![0.0f32; at];
        let parts = parts_of(
            &spans,
            if objective.round_trips() {
                OVERLAPPED_PARTS
            } else {
                1
            },
        );
        let mut scoring: Option<(Range<usize>, Vec<Scoring>)> = None;
        for part in parts {
            let (from, count) = rows_of(&spans[part.clone()]);
            self.ask_islands(&spans, part.clone(), &mut rows)?;
            let asked = rows.rows().span(from, count);
            self.space.embed_at(asked, &mut canonical, from);
            let submitted = self.submit_part(objective, &spans, part.clone(), canonical.rows())?;
            if let Some((before, scorings)) = scoring.replace((part, submitted)) {
                self.collect_part(objective, &spans, scorings, canonical.rows(), &mut costs)?;
                self.tell_islands(&spans, before, &costs)?;
            }
        }
        if let Some((last, scorings)) = scoring {
            self.collect_part(objective, &spans, scorings, canonical.rows(), &mut costs)?;
            self.tell_islands(&spans, last, &costs)?;
        }
        let ranked = self.rank_generation(&spans, canonical.rows(), &costs);
        self.stage_steps += 1;
        let measure = self.island_measure(stage, 0);
        self.record(stage, measure, Some(&ranked));
        self.canonical = Some(canonical);
        self.asked = Some(rows);
        self.end_finished_tries(step, stage);
        Ok(())
    }

    /// Every island of every try still in the stage, in the order of the
    /// generation's spans.
    fn active_islands(&mut self) -> Vec<&mut AskTell> {
        self.tries
            .iter_mut()
            .filter(|t| !t.done)
            .flat_map(|t| t.optimizers.iter_mut())
            .collect()
    }

    /// Starts a population step: rescores the pool where the stage starts
    /// from it, and gives every try its islands. Returns whether any try has
    /// something to search; where none has, the step ends here, since a
    /// round that no try refines has no generations.
    fn begin_population_step(
        &mut self,
        objective: &mut dyn Objective,
        step: Step,
    ) -> anyhow::Result<bool> {
        let stage = step.stage();
        self.start_stage();
        if stage != Stage::Global {
            self.rescore_pool(objective)?;
        }
        for t in 0..self.tries.len() {
            let islands = self.begin_try(t, step);
            let tr = &mut self.tries[t];
            tr.done = islands.is_empty();
            tr.optimizers = islands;
        }
        if self.tries.iter().all(|t| t.done) {
            self.end_step(stage, StageEnd::Generations);
            return Ok(false);
        }
        Ok(true)
    }

    /// Where each island of every try still in the stage puts its rows in
    /// the generation's buffer, what it is scored under and the streams it
    /// draws from: a try's islands number their individuals on from each
    /// other, so that no two draw the same numbers.
    fn generation_spans(&self, step: Step, stage: Stage) -> Vec<Span> {
        let mut spans: Vec<Span> = Vec::new();
        let mut at = 0;
        for t in 0..self.tries.len() {
            if self.tries[t].done {
                continue;
            }
            let generation = self.stream_generation(step, self.tries[t].steps + 1);
            let streams = self.streams(t, stage, generation);
            let mut within = 0;
            for (i, opt) in self.tries[t].optimizers.iter().enumerate() {
                let count = opt.population();
                spans.push(Span {
                    try_index: t,
                    at,
                    count,
                    measure: self.island_measure(stage, i),
                    streams: streams.from_row(within),
                });
                within += count;
                at += count;
            }
        }
        spans
    }

    /// The islands of `part` (indices into `spans`, the generation's) ask
    /// at once, each into its own rows of the generation's buffer: with many
    /// tries, islands are small, and a generation's update is many small
    /// jobs rather than one large one.
    fn ask_islands(
        &mut self,
        spans: &[Span],
        part: Range<usize>,
        rows: &mut Population<Coords>,
    ) -> anyhow::Result<()> {
        let nf = rows.dim();
        let (from, count) = rows_of(&spans[part.clone()]);
        let mut free: &mut [f64] = rows.span_mut(from, count);
        let mut parts: Vec<&mut [f64]> = Vec::with_capacity(part.len());
        for s in &spans[part.clone()] {
            let (own, rest) = free.split_at_mut(s.count * nf);
            parts.push(own);
            free = rest;
        }
        let islands: Vec<&mut AskTell> = self.active_islands().drain(part.clone()).collect();
        islands
            .into_par_iter()
            .zip(parts)
            .zip(&spans[part])
            .try_for_each(|((opt, own), s)| {
                own.copy_from_slice(opt.ask(&s.streams)?.as_flat());
                Ok::<_, crate::optim::PhaseError>(())
            })?;
        Ok(())
    }

    /// The islands of `part` are told their costs at once.
    fn tell_islands(
        &mut self,
        spans: &[Span],
        part: Range<usize>,
        costs: &[f32],
    ) -> anyhow::Result<()> {
        let islands: Vec<&mut AskTell> = self.active_islands().drain(part.clone()).collect();
        islands
            .into_par_iter()
            .zip(&spans[part])
            .try_for_each(|(opt, s)| opt.tell(&costs[s.at..s.at + s.count]))?;
        Ok(())
    }

    /// Hands the canonical rows of `part`'s islands to the objective, one
    /// call per measure over every island of the part that measures it, so
    /// that the objective sees as few and as large batches as the measures
    /// allow; nothing waits for the costs.
    fn submit_part(
        &mut self,
        objective: &mut dyn Objective,
        spans: &[Span],
        part: Range<usize>,
        canonical: Rows<'_, Params>,
    ) -> anyhow::Result<Vec<Scoring>> {
        let mut measures: Vec<Measure> = Vec::new();
        for s in &spans[part.clone()] {
            if !measures.contains(&s.measure) {
                measures.push(s.measure);
            }
        }
        let mut scorings = Vec::with_capacity(measures.len());
        for measure in measures {
            let islands: Vec<usize> = part
                .clone()
                .filter(|&i| spans[i].measure == measure)
                .collect();
            let gathered = (islands.len() < part.len()).then(|| {
                let mut rows = Population::zeros(0, canonical.dim());
                for &i in &islands {
                    rows.extend(canonical.span(spans[i].at, spans[i].count));
                }
                rows
            });
            let rows = match &gathered {
                Some(rows) => rows.rows(),
                None => {
                    let (from, count) = rows_of(&spans[part.clone()]);
                    canonical.span(from, count)
                }
            };
            let (ticket, spent) = timed(objective, |o| o.submit(rows, measure));
            self.spent(spent);
            scorings.push(Scoring {
                islands,
                measure,
                gathered,
                ticket: ticket?,
            });
        }
        Ok(scorings)
    }

    /// Waits for a part's calls ([`Engine::submit_part`]) and writes their
    /// costs, NaN and −∞ made +∞, into the generation's `costs`, counting
    /// the evaluations and the evaluator's seconds.
    fn collect_part(
        &mut self,
        objective: &mut dyn Objective,
        spans: &[Span],
        scorings: Vec<Scoring>,
        canonical: Rows<'_, Params>,
        costs: &mut [f32],
    ) -> anyhow::Result<()> {
        for scoring in scorings {
            let own: Vec<&Span> = scoring.islands.iter().map(|&i| &spans[i]).collect();
            let n: usize = own.iter().map(|s| s.count).sum();
            let rows = match &scoring.gathered {
                Some(rows) => rows.rows(),
                None => canonical.span(own[0].at, n),
            };
            let (scored, spent) = timed(objective, |o| {
                o.collect(scoring.ticket, rows, scoring.measure)
            });
            self.spent(spent);
            let scored = sanitized(scored?, n, &*objective)?;
            self.evaluations += n as u64;
            let mut from = 0;
            for s in own {
                costs[s.at..s.at + s.count].copy_from_slice(&scored[from..from + s.count]);
                from += s.count;
            }
        }
        Ok(())
    }

    /// Ranks a scored generation: the free run's costs update each try's
    /// best, and each try's stage best takes every island when they share a
    /// measure, else the first, since other measures' costs do not compare.
    /// Returns the costs that ranked, for the generation's record.
    fn rank_generation(
        &mut self,
        spans: &[Span],
        canonical: Rows<'_, Params>,
        costs: &[f32],
    ) -> Vec<f32> {
        let mut ranked: Vec<f32> = Vec::new();
        for s in spans.iter().filter(|s| s.measure == Measure::FreeRun) {
            let own = &costs[s.at..s.at + s.count];
            let tr = &mut self.tries[s.try_index];
            keep_lowest(&mut tr.best, canonical.span(s.at, s.count), own);
        }
        for t in 0..self.tries.len() {
            let own: Vec<&Span> = spans.iter().filter(|s| s.try_index == t).collect();
            let Some(first) = own.first() else {
                continue;
            };
            let one_measure = own.iter().all(|s| s.measure == first.measure);
            let rank: Vec<&&Span> = if one_measure {
                own.iter().collect()
            } else {
                own.iter().take(1).collect()
            };
            for s in rank {
                let span_costs = &costs[s.at..s.at + s.count];
                keep_lowest(
                    &mut self.tries[t].stage_best,
                    canonical.span(s.at, s.count),
                    span_costs,
                );
                ranked.extend_from_slice(span_costs);
            }
            let tr = &mut self.tries[t];
            tr.steps += 1;
            let best = tr.stage_best.as_ref().map_or(f64::INFINITY, |b| b.cost);
            tr.stage_bests.push(best);
        }
        ranked
    }

    /// Ends the stage of every try that has run its generations or stalled,
    /// and the step once no try is left in it, as stalled where any try
    /// stopped early, so that the summary tells a stall from a full run.
    fn end_finished_tries(&mut self, step: Step, stage: Stage) {
        let length = match step {
            Step::Global => self.plan.global.as_ref().map_or(0, |g| g.generations),
            Step::Refine(_) | Step::Level(_) => {
                self.plan.refine.as_ref().map_or(0, |r| r.generations)
            }
            _ => self.plan.free_run.as_ref().map_or(0, |f| f.generations),
        };
        let mut stalled_any = false;
        for t in 0..self.tries.len() {
            if self.tries[t].done {
                continue;
            }
            let stalled = self.stalled(t);
            if self.tries[t].steps >= length || stalled {
                stalled_any |= stalled && self.tries[t].steps < length;
                self.end_try_stage(t, stage);
            }
        }
        if self.tries.iter().all(|t| t.done) {
            if matches!(step, Step::Refine(_)) && self.plan.polish.is_none() {
                self.settle_round();
            }
            let ended = if stalled_any || self.stage_steps < length {
                StageEnd::Stalled
            } else {
                StageEnd::Generations
            };
            self.end_step(stage, ended);
        }
    }

    /// Try `t` has ended `stage`: its islands' members go to its pool.
    fn end_try_stage(&mut self, t: usize, stage: Stage) {
        let measures: Vec<Measure> = (0..self.tries[t].optimizers.len())
            .map(|i| self.island_measure(stage, i))
            .collect();
        let tr = &mut self.tries[t];
        tr.done = true;
        tr.carried = std::mem::take(&mut tr.optimizers)
            .iter()
            .zip(measures)
            .map(|(o, measure)| {
                let (rows, costs) = o.members();
                Members {
                    rows: rows.into_flat(),
                    costs,
                    measure,
                }
            })
            .collect();
        tr.pool.splice(0..0, tr.carried.iter().cloned());
    }

    /// Ends a refining round for every try in it: a try whose round lowered
    /// its SSE by less than the plan's share stops refining.
    pub(super) fn settle_round(&mut self) {
        let gain = self.plan.refine.as_ref().map_or(0.0, |r| r.gain);
        for tr in &mut self.tries {
            if !tr.refining || !tr.before_round.is_finite() {
                continue;
            }
            let now = tr.best.as_ref().map_or(f64::INFINITY, |b| b.cost);
            // A gain of NaN (no finite best) is no gain either.
            let gained = tr.before_round - now > gain * tr.before_round;
            tr.refining &= gained;
            tr.round_gain = Some((tr.before_round - now) / tr.before_round);
            tr.before_round = f64::INFINITY;
        }
    }

    /// Whether try `t`'s stage best has not improved by more than the stall
    /// tolerance over the last `stall_generations` of its generations.
    fn stalled(&self, t: usize) -> bool {
        let Some(w) = self.stops.stall_generations else {
            return false;
        };
        let bests = &self.tries[t].stage_bests;
        if bests.len() <= w {
            return false;
        }
        let (now, then) = (bests[bests.len() - 1], bests[bests.len() - 1 - w]);
        then.is_finite() && now >= then * (1.0 - self.stops.stall_tolerance)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spans(counts: &[usize]) -> Vec<Span> {
        let mut at = 0;
        counts
            .iter()
            .map(|&count| {
                let s = Span {
                    try_index: 0,
                    at,
                    count,
                    measure: Measure::FreeRun,
                    streams: Streams::new(1, Stage::Global, 1),
                };
                at += count;
                s
            })
            .collect()
    }

    #[test]
    fn parts_hold_whole_islands_and_about_equal_rows() {
        assert_eq!(parts_of(&spans(&[10; 8]), 4), vec![0..2, 2..4, 4..6, 6..8]);
        assert_eq!(parts_of(&spans(&[10; 8]), 1), vec![0..8]);
        // Fewer islands than parts: one island a part.
        assert_eq!(parts_of(&spans(&[10, 10]), 4), vec![0..1, 1..2]);
        // A large island is a part of its own; none is empty.
        assert_eq!(
            parts_of(&spans(&[70, 10, 10, 10]), 4),
            vec![0..1, 1..2, 2..3, 3..4]
        );
        assert_eq!(parts_of(&spans(&[10, 10, 10, 70]), 4), vec![0..3, 3..4]);
    }
}
