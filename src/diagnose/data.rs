//! The data of a diagnosis: its records (split as `fit` splits them, the
//! second half of each then cut into selection and test blocks,
//! [`Parts`]), the costs and scores of a model on them, and the box its
//! parameters are searched in.

use std::ops::Range;
use std::sync::{Arc, Mutex};

use nalgebra::DVector;

use super::effects::{Augmented, Context, effect_box};
use super::settings::StopFlag;
use crate::data::Trace;
use crate::eval::cpu::CpuEvaluator;
use crate::eval::{Evaluator, Problem};
use crate::fit::records::{Records, Validation};
use crate::model::experiment::Parts;
use crate::model::{Experiment, Family, Flow, Measure, Model, SearchSpace};

/// The data of a diagnosis: its records ([`Records::of`]: every dataset in
/// the coordinates of the first one's estimation half, the estimation
/// halves, where validation starts, the prior and the effects' constants),
/// each record's three parts, the evaluator its searches score populations
/// on, and their stop flag.
///
/// The parts keep the diagnosis honest: the fits read the estimation half,
/// every choice (which effect, which realisation, which seed, when to stop,
/// the noise floor and the explainable bound it compares with) reads the
/// selection part, and the test part is read once, by [`Data::test`], after
/// the model is final. Its figures are the ones no choice saw.
#[derive(Debug, Clone)]
pub struct Data {
    /// The traces, split as `fit` splits them.
    pub records: Records,
    /// Each record's estimation, selection and test samples.
    pub parts: Vec<Parts>,
    scorer: Scorer,
    /// Stops every search on these data ([`Data::stopped_by`]).
    pub(super) stop: StopFlag,
}

/// The evaluator a diagnosis scores populations on, shared by the clones of
/// its data: one that forks ([`Evaluator::fork`]: the CPU path), of which
/// every search takes a fork, so searches run side by side; or a device
/// behind the same lock, on which searches take turns.
#[derive(Clone)]
struct Scorer(Arc<Mutex<Box<dyn Evaluator + Send>>>);

impl Scorer {
    fn of(evaluator: Box<dyn Evaluator + Send>) -> Scorer {
        Scorer(Arc::new(Mutex::new(evaluator)))
    }
}

impl std::fmt::Debug for Scorer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0.lock() {
            Ok(e) => f.write_str(&e.describe()),
            Err(_) => f.write_str("(evaluator poisoned)"),
        }
    }
}

impl Data {
    /// Splits every trace in halves as `fit` does ([`Records::of`], which
    /// also checks that the data can be fitted at all), the second halves
    /// in `blocks` blocks ([`Parts::of`]), or in as many as each record's
    /// input asks for ([`Parts::chosen`]) when `None`.
    pub fn new(traces: &[Trace], blocks: Option<usize>) -> anyhow::Result<Data> {
        Data::in_coordinates(traces, None, blocks)
    }

    /// As [`Data::new`], in `model`'s coordinates when one is given
    /// (`diagnose --from`, as `fit --from`: [`Records::of`]).
    pub fn in_coordinates(
        traces: &[Trace],
        model: Option<&Model>,
        blocks: Option<usize>,
    ) -> anyhow::Result<Data> {
        let records = Records::of(traces, model)?;
        let settle = Data::settle_of(&records);
        let parts = traces
            .iter()
            .map(|t| match blocks {
                Some(b) => Parts::of(t.len(), b, settle),
                None => Parts::chosen(&t.input, settle),
            })
            .collect();
        Ok(Data {
            records,
            parts,
            scorer: Scorer::of(Box::new(CpuEvaluator::new())),
            stop: StopFlag::default(),
        })
    }

    /// The settling gap between blocks: three time constants of the ARX
    /// pole (95 % settled), at least one sample.
    fn settle_of(records: &Records) -> usize {
        let shortest = records.whole.iter().map(|w| w.len()).min().unwrap_or(0);
        super::settle_samples(records.prior.a, shortest)
    }

    /// An error naming the record and the length it needs when a record is
    /// too short for useful selection and test blocks: the diagnosis then
    /// refuses to run rather than choose and report on the same samples.
    pub fn check_parts(&self) -> anyhow::Result<()> {
        let settle = Data::settle_of(&self.records);
        for (w, p) in self.records.whole.iter().zip(&self.parts) {
            let blocks = p.selection.len() + p.test.len();
            if let Some(e) = Parts::too_short(w.len(), blocks, settle) {
                anyhow::bail!("{}: {e}", w.name);
            }
        }
        Ok(())
    }

    /// The same data scored on `evaluator` (the CPU batch path by default).
    pub fn scored_on(mut self, evaluator: Box<dyn Evaluator + Send>) -> Data {
        self.scorer = Scorer::of(evaluator);
        self
    }

    /// The same data, every search on them stopped once `stop` is raised.
    pub fn stopped_by(mut self, stop: StopFlag) -> Data {
        self.stop = stop;
        self
    }

    /// The estimation part under `measure` as the evaluator's problem: the
    /// model description (family and effect stages) and every dataset.
    pub fn est_problem(&self, model: &Augmented, measure: Measure) -> Problem {
        Problem::new(model.family, self.records.est.clone())
            .with_measure(measure)
            .with_effects(model.effects.clone(), self.records.ctx.clone())
    }

    /// Runs `job` on the evaluator: a fork of it where it forks (searches
    /// run side by side), else the evaluator itself in turn.
    pub(super) fn with_evaluator<T>(
        &self,
        job: impl FnOnce(&mut dyn Evaluator) -> anyhow::Result<T>,
    ) -> anyhow::Result<T> {
        let mut evaluator = self
            .scorer
            .0
            .lock()
            .map_err(|_| anyhow::anyhow!("the evaluator failed in an earlier call"))?;
        match evaluator.fork() {
            Some(mut fork) => {
                drop(evaluator);
                job(fork.as_mut())
            }
            None => job(evaluator.as_mut()),
        }
    }

    /// Whether the diagnosis fits `theta` at all: only models whose loop is
    /// bounded ([`Family::loop_bounded`]), every other costs `+∞` under
    /// every measure. Why: a model fitted to one half with an unbounded loop
    /// (`β + γ < 0`) lets `w` run away once the input leaves the estimation
    /// half's range, and then diverges on its own validation half, leaving
    /// no gap to diagnose (as every seed did on the Cavatappi 500 g file:
    /// docs/lab/diagnosis.md, "Real data: the Cavatappi muscle"). `fit` applies
    /// the same rule (`optim::engine::ModelObjective::for_task`).
    ///
    /// And every effect must be admitted ([`Augmented::effects_admit`]: a
    /// ringing must ring).
    pub fn admits(model: &Augmented, theta: &[f64]) -> bool {
        model.family.loop_bounded(theta) && model.effects_admit(theta)
    }

    pub fn datasets(&self) -> usize {
        self.records.whole.len()
    }

    /// Estimation residuals over all datasets (the first sample of each is
    /// the start, not a residual).
    pub fn est_samples(&self) -> usize {
        self.records
            .est
            .iter()
            .map(|e| e.len().saturating_sub(1))
            .sum()
    }

    /// Selection samples over all datasets.
    pub fn selection_samples(&self) -> usize {
        self.parts.iter().map(Parts::selection_len).sum()
    }

    /// Each dataset's selection blocks.
    pub fn selection_ranges(&self) -> Vec<Vec<Range<usize>>> {
        self.parts.iter().map(|p| p.selection.clone()).collect()
    }

    /// Each dataset's test blocks.
    pub fn test_ranges(&self) -> Vec<Vec<Range<usize>>> {
        self.parts.iter().map(|p| p.test.clone()).collect()
    }

    /// Estimation SSE of `theta` (summed over datasets, `+∞` if any diverged).
    pub fn est_sse(&self, model: &Augmented, theta: &[f64]) -> f64 {
        self.est_sum(model, theta, |t, i, c, e| model.sse(t, i, c, e))
    }

    /// Estimation SSE of the `horizon`-step-ahead prediction (see
    /// [`Augmented::sse_ahead`]).
    pub fn est_sse_ahead(&self, model: &Augmented, theta: &[f64], horizon: usize) -> f64 {
        self.est_sum(model, theta, |t, i, c, e| {
            model.sse_ahead(t, i, c, e, horizon)
        })
    }

    /// `cost(θ, dataset, context, estimation part)` summed over the datasets
    /// (`+∞` for a model the diagnosis does not admit).
    fn est_sum(
        &self,
        model: &Augmented,
        theta: &[f64],
        cost: impl Fn(&[f32], usize, &Context, &Experiment) -> f32,
    ) -> f64 {
        if !Data::admits(model, theta) {
            return f64::INFINITY;
        }
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        self.records
            .est
            .iter()
            .zip(&self.records.ctx)
            .enumerate()
            .map(|(i, (e, c))| cost(&t, i, c, e) as f64)
            .sum()
    }

    /// Free-run residuals `ŷ − y` of the estimation part, every dataset from
    /// its second sample on; `None` if the simulation diverged or the model
    /// is not admitted ([`Data::admits`]).
    pub fn est_residuals(&self, model: &Augmented, theta: &[f64]) -> Option<DVector<f64>> {
        if !Data::admits(model, theta) {
            return None;
        }
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        let mut r = Vec::with_capacity(self.records.est.iter().map(|e| e.len()).sum());
        for (i, (e, c)) in self.records.est.iter().zip(&self.records.ctx).enumerate() {
            let p = model.simulate(&t, i, c, e);
            r.extend(p.iter().zip(&e.y).skip(1).map(|(&a, &b)| (a - b) as f64));
        }
        r.iter()
            .all(|v| v.is_finite())
            .then(|| DVector::from_vec(r))
    }

    /// The prediction horizon of [`Start::Ahead`](super::fitting::Start::Ahead):
    /// the fit's global stage's ([`crate::fit::objective::horizon`]),
    /// from the ARX pole and the shortest estimation part (shorter and
    /// longer horizons measured on the self-test: docs/lab/diagnosis.md,
    /// the budget's "in the first round" item).
    pub fn horizon(&self) -> usize {
        let shortest = self.records.est.iter().map(|e| e.len()).min().unwrap_or(8);
        crate::fit::objective::horizon(self.records.prior.a, shortest)
    }

    /// Predicted output (deviation coordinates) over each whole dataset: the
    /// free run from the first sample, so the validation part starts from a
    /// warmed-up state rather than `w = 0`.
    pub fn predict(&self, model: &Augmented, theta: &[f64]) -> Vec<Vec<f32>> {
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        self.records
            .whole
            .iter()
            .zip(&self.records.ctx)
            .enumerate()
            .map(|(i, (e, c))| model.simulate(&t, i, c, e))
            .collect()
    }

    /// Residuals `y − ŷ` of the free run on each selection block, with the
    /// dataset each belongs to and its range.
    pub fn selection_residuals(
        &self,
        model: &Augmented,
        theta: &[f64],
    ) -> Vec<(usize, Range<usize>, Vec<f64>)> {
        let runs = self.predict(model, theta);
        let mut blocks = Vec::new();
        for (i, (p, w)) in runs.iter().zip(&self.records.whole).enumerate() {
            for r in &self.parts[i].selection {
                let res = r.clone().map(|k| w.y[k] as f64 - p[k] as f64).collect();
                blocks.push((i, r.clone(), res));
            }
        }
        blocks
    }

    /// Scores on the selection part, every dataset pooled (infinite RMSE
    /// where the simulation diverged): what every choice reads.
    pub fn selection(&self, model: &Augmented, theta: &[f64]) -> Validation {
        self.records
            .score_on(model, theta, &self.selection_ranges())
    }

    /// [`Data::selection`]'s RMSE.
    pub fn selection_rmse(&self, model: &Augmented, theta: &[f64]) -> f64 {
        self.selection(model, theta).rmse
    }

    /// Scores on the test part, every dataset pooled: read once the model
    /// is final, and by nothing that chooses.
    pub fn test(&self, model: &Augmented, theta: &[f64]) -> Validation {
        self.records.score_on(model, theta, &self.test_ranges())
    }

    /// The SSE of the free run on each selection block of every dataset, in
    /// order (`+∞` where it diverged): whether a gain holds across the part,
    /// not only pooled.
    pub fn block_sse(&self, model: &Augmented, theta: &[f64]) -> Vec<f64> {
        self.selection_residuals(model, theta)
            .iter()
            .map(|(_, _, r)| {
                let sse: f64 = r.iter().map(|v| v * v).sum();
                if sse.is_finite() { sse } else { f64::INFINITY }
            })
            .collect()
    }

    /// The search box of `model`: the default joint-flow box of the baseline
    /// (thesis hull, `a`, `b`, `c` around the ARX estimate) plus each
    /// effect's box.
    pub fn space(&self, model: &Augmented) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let mut base =
            SearchSpace::around(model.family, None, self.records.prior, Flow::Joint, false);
        // Least squares on hysteretic data underestimates the input gain: the
        // hysteretic model's `b` relates to the ARX static gain
        // `G = b_ARX/(1 − a_ARX)` through `1 − a·α`, not `1 − a`. Widen the
        // box to reach `G` itself.
        let ib = model.family.linear_indices()[1];
        let g = self.records.prior.b / (1.0 - self.records.prior.a).abs().max(1e-3);
        if g.abs() > base.upper[ib].abs().max(base.lower[ib].abs()) {
            if g > 0.0 {
                base.upper[ib] = g;
            } else {
                base.lower[ib] = g;
            }
        }
        // The classic loop stays bounded for every input only when β ≥ 0 (and
        // β + γ > 0, else w grows without bound and the fit diverges anyway):
        // with β < 0 the loading branch settles at A/(β+γ), above the level
        // A/(γ−β) past which the unloading branch drives w away. A baseline
        // fitted there follows the data but turns wild under any change of
        // input or parameters, so it is no base to attribute effects to.
        if model.family == Family::Classic {
            base.lower[2] = base.lower[2].max(0.0);
        }
        let mid: Vec<f64> = base
            .lower
            .iter()
            .zip(&base.upper)
            .map(|(l, u)| 0.5 * (l + u))
            .collect();
        let (mut neutral, mut lo, mut hi) = (mid, base.lower, base.upper);
        for &e in &model.effects {
            let (n, l, h) = effect_box(e, &self.records.ctx[0], self.datasets());
            neutral.extend(n);
            lo.extend(l);
            hi.extend(h);
        }
        (neutral, lo, hi)
    }
}
