//! The engine's tries and the steps of its plan: each try's state (its
//! seed, islands, pool and best), the order the plan's steps run in, and
//! the best over every try.

use serde::{Deserialize, Serialize};

use super::{Chart, Engine, Stage, StageEnd};
use crate::optim::best_indices;
use crate::optim::{AskTell, argmin};
use crate::search::{Measure, Params, Rows};

/// The members of one island and their costs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct Members {
    pub(super) rows: Vec<f64>,
    #[serde(with = "crate::optim::inf_serde")]
    pub(super) costs: Vec<f32>,
    /// What the costs measure.
    pub(super) measure: Measure,
}

impl Members {
    /// Row indices, best first (ties by index).
    pub(super) fn order(&self) -> Vec<usize> {
        best_indices(&self.costs, self.costs.len())
    }

    /// The `count` best rows, best first (a partial selection).
    pub(super) fn best(&self, count: usize, nf: usize) -> Vec<f64> {
        best_indices(&self.costs, count)
            .iter()
            .flat_map(|&i| self.rows[i * nf..(i + 1) * nf].iter().copied())
            .collect()
    }
}

/// A candidate and its cost.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct Scored {
    /// Canonical parameters.
    pub(super) params: Vec<f64>,
    pub(super) cost: f64,
}

/// Replaces `slot` by the lowest finite of `costs` (rows of `d` canonical
/// parameters) when it is lower than the slot's.
pub(super) fn keep_lowest(slot: &mut Option<Scored>, canonical: Rows<'_, Params>, costs: &[f32]) {
    if let Some(i) = argmin(costs)
        && slot.as_ref().is_none_or(|b| (costs[i] as f64) < b.cost)
    {
        *slot = Some(Scored {
            params: canonical.row(i).to_vec(),
            cost: costs[i] as f64,
        });
    }
}

/// One step of a plan, in the order the engine runs them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Step {
    Global,
    FreeRun,
    Polish,
    /// Refining round `r` (from 0): the population around each try's best.
    Refine(usize),
    /// The polish after refining round `r`.
    RefinePolish(usize),
    /// A refining round with a [`Stepwise`] coordinate held at preferred
    /// value `k` ([`Engine::levels`]), after the refining rounds.
    Level(usize),
    /// The polish after level round `k`, which keeps its model where it
    /// scores alike with the try's best.
    LevelPolish(usize),
}

impl Step {
    pub(super) fn stage(self) -> Stage {
        match self {
            Step::Global => Stage::Global,
            Step::FreeRun => Stage::FreeRun,
            Step::Polish | Step::RefinePolish(_) | Step::LevelPolish(_) => Stage::Polish,
            Step::Refine(_) | Step::Level(_) => Stage::Refine,
        }
    }
}

/// One try's state: its seed, the islands of the population stage in
/// progress, what its stages handed on, and its best.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct Try {
    pub(super) seed: u64,
    /// The islands of the population stage in progress (empty between
    /// stages, and for a try that sits the stage out).
    pub(super) optimizers: Vec<AskTell>,
    /// Generations of the current stage so far.
    pub(super) steps: usize,
    /// Whether it has ended the current population stage (its generations
    /// run, or stalled): it waits for the other tries.
    pub(super) done: bool,
    /// Its stage's best cost after each of its generations (the stall rule).
    #[serde(with = "crate::optim::inf_serde::f64s")]
    pub(super) stage_bests: Vec<f64>,
    pub(super) stage_best: Option<Scored>,
    /// The members each island of its last population stage ended with
    /// (free coordinates) and their costs under its measure.
    pub(super) carried: Vec<Members>,
    /// The islands of its population stages so far, the latest stage's
    /// first: the polish's pool of starts.
    pub(super) pool: Vec<Members>,
    /// Its lowest free-run SSE seen.
    pub(super) best: Option<Scored>,
    /// Its best before the refining round in progress: the round's gain is
    /// measured against it.
    #[serde(with = "crate::optim::inf_serde::one_f64")]
    pub(super) before_round: f64,
    /// Whether it still refines: false once a round gained too little.
    pub(super) refining: bool,
    /// The share of its SSE its last refining round took off.
    #[serde(default)]
    pub(super) round_gain: Option<f64>,
}

impl Try {
    pub(super) fn new(seed: u64) -> Try {
        Try {
            seed,
            optimizers: Vec::new(),
            steps: 0,
            done: false,
            stage_bests: Vec::new(),
            stage_best: None,
            carried: Vec::new(),
            pool: Vec::new(),
            best: None,
            before_round: f64::INFINITY,
            refining: true,
            round_gain: None,
        }
    }
}

impl<C: Chart> Engine<C> {
    /// The plan's steps in order: the global stage, the free-run stage, the
    /// polish, then each refining round and its polish.
    pub(super) fn steps(&self) -> Vec<Step> {
        let mut v = Vec::new();
        if self.plan.global.is_some() {
            v.push(Step::Global);
        }
        if self.plan.free_run.is_some() {
            v.push(Step::FreeRun);
        }
        if self.plan.polish.is_some() {
            v.push(Step::Polish);
        }
        for r in 0..self.plan.refine.as_ref().map_or(0, |r| r.rounds) {
            v.push(Step::Refine(r));
            if self.plan.polish.is_some() {
                v.push(Step::RefinePolish(r));
            }
        }
        if self.plan.refine.is_some() && self.plan.polish.is_some() {
            for k in 0..self.levels().len() {
                v.push(Step::Level(k));
                v.push(Step::LevelPolish(k));
            }
        }
        v
    }

    /// The preferred values of the free [`Stepwise`] coordinates inside the
    /// box, each as its coordinate's index among the free ones, the value
    /// and the coordinate's tolerance: what the level rounds hold.
    pub(super) fn levels(&self) -> Vec<(usize, f64, f64)> {
        let free = self.space.free();
        self.space
            .stepwise
            .iter()
            .filter_map(|s| Some((free.iter().position(|&i| i == s.index)?, s)))
            .flat_map(|(j, s)| {
                let (lo, hi) = (self.space.lower[free[j]], self.space.upper[free[j]]);
                s.preferred
                    .iter()
                    .filter(move |v| (lo..=hi).contains(*v))
                    .map(move |&v| (j, v, s.tolerance))
            })
            .collect()
    }

    /// Generations of all population steps, every refining and level round
    /// run: a progress bar's length.
    pub fn planned_generations(&self) -> usize {
        let rounds = self
            .steps()
            .iter()
            .filter(|s| matches!(s, Step::Level(_)))
            .count();
        self.plan.generations() + rounds * self.plan.refine.as_ref().map_or(0, |r| r.generations)
    }

    /// The stages of the plan, in order (a refining round and its polish
    /// each time the plan refines).
    pub fn stages(&self) -> Vec<Stage> {
        self.steps().into_iter().map(Step::stage).collect()
    }

    /// The step in progress, `None` once every step ran.
    pub(super) fn step(&self) -> Option<Step> {
        self.steps().get(self.cursor).copied()
    }

    /// The stage in progress, `None` once every stage ran.
    pub fn stage(&self) -> Option<Stage> {
        self.step().map(Step::stage)
    }

    /// The lowest of the tries' bests (the first try's on a tie).
    pub(super) fn overall_best(&self) -> Option<&Scored> {
        self.tries.iter().filter_map(|t| t.best.as_ref()).fold(
            None,
            |b: Option<&Scored>, s| match b {
                Some(b) if b.cost <= s.cost => Some(b),
                _ => Some(s),
            },
        )
    }

    /// Ends the current step: its summary, and on to the next (past the
    /// refining rounds that no try still refines in).
    pub(super) fn end_step(&mut self, stage: Stage, ended: StageEnd) {
        let summary = self.summary(stage, ended);
        self.summaries.push(summary);
        self.cursor += 1;
        let steps = self.steps();
        let refining = self.tries.iter().any(|t| t.refining && t.best.is_some());
        while let Some(Step::Refine(_) | Step::RefinePolish(_)) = steps.get(self.cursor)
            && !refining
        {
            self.cursor += 1;
        }
    }
}
