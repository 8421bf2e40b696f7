//! One identification task on one recorded trace, as `fit` and `compare`
//! run it: the thesis' split (§4.3.1: estimate on the first half, validate
//! on the second), the ARX prior for the bounds, the search box of the
//! chosen flow, and the validation score of a fitted vector.

use crate::data::Trace;
use crate::eval::Problem;
use crate::fit::records::Records;
pub use crate::fit::records::Validation;
use crate::ident::{fit_percent, rmse};
use crate::model::bounds::Origin;
use crate::model::effects::{Augmented, Context, Effect, effect_box};
use crate::model::file::Chain;
use crate::model::presets::ThesisBounds;
use crate::model::{
    Experiment, Family, FittedModel, Flow, LinearPrior, Loop, Model, SearchSpace, Switching,
    UserBound, simulate,
};

/// How far beyond the estimation output's largest deviation a bounded model
/// may go on the whole record's input ([`Task::stress`]).
pub const STRESS_FACTOR: f64 = 10.0;

/// Everything a fit on one trace needs.
#[derive(Debug, Clone)]
pub struct Task {
    pub family: Family,
    pub flow: Flow,
    /// The trace, split and in its coordinates ([`Records::of`]).
    pub records: Records,
    pub space: SearchSpace,
    /// Which loop shapes the box admits (the joint flow's; the thesis' flow
    /// searches its own tables, of either sign).
    pub loop_shape: Loop,
    /// Where a generalized fit lets its sign terms switch (the joint
    /// flow's; the thesis' flow holds the level at the estimation mean).
    pub switching: Switching,
    pub input_name: String,
    pub output_name: String,
    /// Effect stages after the family (`fit --effects`), in chain order;
    /// their parameters follow the family's in every vector.
    pub effects: Vec<Effect>,
}

impl Task {
    /// Splits `trace`, identifies the ARX prior on the estimation half and
    /// builds the box: the joint flow's in the data's own scale, bounded
    /// loops ([`SearchSpace::scaled`]) and, for the generalized family, the
    /// default switching ([`Switching::Starts`]); the thesis' flow's from
    /// `hysteresis` (the hull of its tables when `None`) with the linear
    /// part fixed at ARX's. `n` is fixed at 1 unless `free_n`.
    pub fn new(
        trace: &Trace,
        family: Family,
        flow: Flow,
        hysteresis: Option<&ThesisBounds>,
        free_n: bool,
    ) -> anyhow::Result<Task> {
        let shape = (Loop::Bounded, Switching::Starts);
        Task::with_box(trace, family, flow, hysteresis, free_n, shape, &[])
    }

    /// As [`Task::new`], with the joint flow's loop class, switching and
    /// user bounds (`--loop`, `--switch`, `--bound`, `--fix`); the thesis'
    /// flow takes none of them.
    pub fn with_box(
        trace: &Trace,
        family: Family,
        flow: Flow,
        hysteresis: Option<&ThesisBounds>,
        free_n: bool,
        (loop_shape, switching): (Loop, Switching),
        bounds: &[UserBound],
    ) -> anyhow::Result<Task> {
        anyhow::ensure!(
            family != Family::Linear,
            "the linear model is fitted by least squares: use `mckibben identify`"
        );
        let records = Records::of(std::slice::from_ref(trace), None)?;
        let space = match flow {
            Flow::Thesis => {
                anyhow::ensure!(
                    bounds.is_empty(),
                    "the thesis' flow searches its own tables: --bound and --fix need the joint flow"
                );
                SearchSpace::around(family, hysteresis, records.prior, flow, free_n)
            }
            Flow::Joint => SearchSpace::scaled(
                family,
                records.prior,
                (loop_shape, switching),
                free_n,
                bounds,
            )
            .map_err(anyhow::Error::msg)?,
        };
        Ok(Task {
            family,
            flow,
            space,
            loop_shape,
            switching,
            records,
            input_name: trace.input_name.clone(),
            output_name: trace.output_name.clone(),
            effects: Vec::new(),
        })
    }

    /// The second start of [`Switching::Starts`]: the same task with the
    /// generalized switching level held at the sensor's zero instead of the
    /// estimation mean. `None` where a fit has one start: another family or
    /// switching, the thesis' flow, a level the user bounds or fixes, or an
    /// estimation mean of 0 (the two starts would be one).
    pub fn at_zero(&self) -> Option<Task> {
        let is = self.family.switch_index()?;
        let mean = self.estimation().y_mean;
        let held_at_mean = (self.space.lower[is], self.space.upper[is]) == (mean, mean)
            && self.space.origin[is] == [Origin::Class; 2];
        let two = self.flow == Flow::Joint
            && self.switching == Switching::Starts
            && held_at_mean
            && mean != 0.0;
        two.then(|| {
            let mut zero = self.clone();
            (zero.space.lower[is], zero.space.upper[is]) = (0.0, 0.0);
            zero
        })
    }

    /// Holds the generalized switching level at `x_s` where the default
    /// switching holds it ([`Switching::Starts`]; not a level the user
    /// bounds or fixes): a warm start keeps its model's own level.
    pub fn hold_switch_at(&mut self, x_s: f64) {
        let Some(is) = self.family.switch_index() else {
            return;
        };
        if self.switching == Switching::Starts && self.space.origin[is] == [Origin::Class; 2] {
            (self.space.lower[is], self.space.upper[is]) = (x_s, x_s);
        }
    }

    /// The same task in `model`'s coordinates ([`Records::of`]): a warm
    /// start then starts at the saved model itself.
    pub fn in_coordinates_of(mut self, trace: &Trace, model: &Model) -> anyhow::Result<Task> {
        self.records = Records::of(std::slice::from_ref(trace), Some(model))?;
        Ok(self)
    }

    /// The same task with `effects` after the family: their parameters
    /// join the box in their own units (each effect's box from the record,
    /// [`effect_box`]); `bounds` may name them (`creep.kappa=0:1`).
    pub fn with_effects(
        mut self,
        effects: &[Effect],
        bounds: &[UserBound],
    ) -> anyhow::Result<Task> {
        anyhow::ensure!(
            effects.is_empty() || self.flow == Flow::Joint,
            "the thesis' flow fits the thesis' models: --effects needs the joint flow"
        );
        for (k, e) in effects.iter().enumerate() {
            anyhow::ensure!(
                !effects[..k].contains(e),
                "--effects names `{e}` twice: each effect enters a chain once"
            );
            anyhow::ensure!(
                e.applicable(1),
                "--effects: `{e}` needs several datasets (one per load); `fit` fits one record"
            );
        }
        self.effects = effects.to_vec();
        let augmented = self.augmented();
        let names = augmented.param_names();
        let d = self.family.dim();
        let (mut lower, mut upper) = (Vec::new(), Vec::new());
        for &e in effects {
            let (_, lo, hi) = effect_box(e, self.context(), 1);
            lower.extend(lo);
            upper.extend(hi);
        }
        self.space = self
            .space
            .with_extra(names[d..].to_vec(), lower, upper, bounds)
            .map_err(anyhow::Error::msg)?;
        Ok(self)
    }

    /// The estimation half.
    pub fn estimation(&self) -> &Experiment {
        &self.records.est[0]
    }

    /// The ARX prior the box is built on.
    pub fn prior(&self) -> LinearPrior {
        self.records.prior
    }

    /// The effects' constants: the estimation half's, in its coordinates
    /// (as the diagnosis takes them).
    pub fn context(&self) -> &Context {
        &self.records.ctx[0]
    }

    /// The model description: the family and its effects.
    pub fn augmented(&self) -> Augmented {
        Augmented::new(self.family, self.effects.clone(), 1)
    }

    /// The start of every effect in the chain at its neutral value (the
    /// baseline's output, bit for bit), after the baseline's `params`.
    pub fn neutral_effects(&self, params: &[f64]) -> Vec<f64> {
        let mut theta = params[..self.family.dim()].to_vec();
        for &e in &self.effects {
            theta.extend(effect_box(e, self.context(), 1).0);
        }
        theta
    }

    /// The problem of `experiment` with the task's effects.
    fn problem_of(&self, experiment: Experiment) -> Problem {
        let problem = Problem::new(self.family, vec![experiment]);
        if self.effects.is_empty() {
            problem
        } else {
            problem.with_effects(self.effects.clone(), vec![*self.context()])
        }
    }

    /// The estimation problem the optimizer scores.
    pub fn problem(&self) -> Problem {
        self.problem_of(self.estimation().clone())
    }

    /// The check that a candidate stays bounded on every input of the
    /// trace: the whole record's input (estimation and validation halves)
    /// with the measured output replaced by its first sample and zeros, so
    /// that a candidate's free-run "SSE" on it is the energy of its own
    /// output, and the largest energy a bounded model may have.
    ///
    /// Why: a model fitted to one half can be unstable on the other. An
    /// estimation optimum with β + γ < 0 lets `w` grow without bound once
    /// the input leaves the estimation half's range, and the fit then writes
    /// a model that diverges on its own validation half (as it did on the
    /// Cavatappi muscle: docs/lab/results.md, "Real data: the Cavatappi
    /// muscle"). The check uses the validation half's input, never its
    /// output; the bound is ten times the estimation output's largest
    /// deviation, on every sample.
    pub fn stress(&self) -> (Problem, f64) {
        let mut whole = self.records.whole[0].clone();
        let start = whole.y.first().copied().unwrap_or(0.0);
        whole.y = vec![0.0; whole.u.len()];
        if let Some(first) = whole.y.first_mut() {
            *first = start;
        }
        let largest = self
            .estimation()
            .y
            .iter()
            .fold(0.0f64, |m, &v| m.max((v as f64).abs()));
        let bound = whole.u.len() as f64 * (STRESS_FACTOR * largest).powi(2);
        (self.problem_of(whole), bound)
    }

    /// The free-run SSE of `params` on the estimation half, the cost a fit
    /// minimises (`+∞` where the run diverges).
    pub fn est_sse(&self, params: &[f64]) -> f64 {
        let theta: Vec<f32> = params.iter().map(|&v| v as f32).collect();
        let sse = self
            .augmented()
            .sse(&theta, 0, self.context(), self.estimation()) as f64;
        if sse.is_finite() { sse } else { f64::INFINITY }
    }

    /// Validation scores on the record's second half
    /// ([`Records::validate`]).
    pub fn validate(&self, params: &[f64]) -> Validation {
        self.records.validate(&self.augmented(), params)
    }

    /// The first-order ARX model's validation scores on the same halves
    /// ([`Records::linear_yardstick`]).
    pub fn linear_yardstick(&self) -> Option<Validation> {
        self.records.linear_yardstick(0)
    }

    /// The fitted model in the estimation half's coordinates.
    pub fn model(&self, params: &[f64]) -> Model {
        let d = self.family.dim();
        let base = FittedModel {
            family: self.family,
            params: params[..d].to_vec(),
            input_mean: self.estimation().u_mean,
            output_mean: self.estimation().y_mean,
            dt: self.estimation().dt,
            input_name: self.input_name.clone(),
            output_name: self.output_name.clone(),
        };
        let chain = (!self.effects.is_empty()).then(|| Chain {
            effects: self.effects.clone(),
            params: params[d..].to_vec(),
            context: *self.context(),
            datasets: 1,
        });
        Model { base, chain }
    }
}

/// RMSE and fit % of a free run of `params` on `experiment` (deviation
/// coordinates; differences are in output units): the thesis' models
/// scored on a whole trace, as `compare` scores them. A diverged run scores
/// infinite RMSE and −∞ fit.
pub fn score(family: Family, params: &[f64], experiment: &Experiment) -> Validation {
    let diverged = Validation {
        rmse: f64::INFINITY,
        fit_percent: f64::NEG_INFINITY,
    };
    if params.is_empty() || experiment.is_empty() {
        return diverged;
    }
    let theta: Vec<f32> = params.iter().map(|&v| v as f32).collect();
    let sim = simulate(
        family,
        &theta,
        experiment.y_mean as f32,
        &experiment.u,
        experiment.y[0],
    );
    if sim.diverged_at.is_some() {
        return diverged;
    }
    let y: Vec<f64> = experiment.y.iter().map(|&v| v as f64).collect();
    let x: Vec<f64> = sim.x.iter().map(|&v| v as f64).collect();
    Validation {
        rmse: rmse(&y, &x),
        fit_percent: fit_percent(&y, &x),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::synthetic::Synthetic;

    #[test]
    fn the_truth_validates_near_the_noise() {
        let s = Synthetic::new(Family::Classic, 600, 0.05, 1);
        let task = Task::new(&s.trace, Family::Classic, Flow::Joint, None, false).unwrap();
        // The box holds the truth's twin in its gauge A = 1.
        let twin = crate::model::coords::gauge_fixed(Family::Classic, &s.truth);
        assert!(task.space.contains(&twin), "{twin:?}");
        assert!(!task.space.contains(&s.truth), "A is held at 1");
        let v = task.validate(&s.truth);
        assert!(v.rmse < 0.2 && v.fit_percent > 95.0, "{v:?}");
        let thesis = Task::new(&s.trace, Family::Classic, Flow::Thesis, None, false).unwrap();
        assert_eq!(thesis.space.free(), vec![0, 1, 2, 3]);
        assert!(Task::new(&s.trace, Family::Linear, Flow::Joint, None, false).is_err());
    }

    #[test]
    fn in_a_models_coordinates_its_parameters_are_that_model_on_another_record() {
        for family in [Family::Classic, Family::Generalized] {
            let s = Synthetic::new(family, 600, 0.05, 3);
            let fitted_on = Task::new(&s.trace, family, Flow::Joint, None, false).unwrap();
            let model = fitted_on.model(&s.truth);
            // Another record of the same muscle: its means are not the model's.
            let t = &s.trace;
            let later = Trace::uniform(
                "later",
                t.dt(),
                t.input[150..].to_vec(),
                t.output[150..].to_vec(),
            );
            let task = Task::new(&later, family, Flow::Joint, None, false).unwrap();
            assert!((task.estimation().y_mean - model.base.output_mean).abs() > 0.1);
            let saved = model.simulate_trace(&later);
            let val_start = task.records.val_start[0];
            let expected = fit_percent(&later.output[val_start..], &saved[val_start..]);
            let here = task
                .clone()
                .in_coordinates_of(&later, &model)
                .unwrap()
                .validate(&s.truth);
            assert!(
                (here.fit_percent - expected).abs() < 1e-6,
                "{family}: {} against the model's own {expected}",
                here.fit_percent
            );
            // In the record's own coordinates the same numbers are another model.
            let moved = task.validate(&s.truth).fit_percent;
            assert!((moved - expected).abs() > 1e-3, "{family}: {moved}");
        }
    }
}
