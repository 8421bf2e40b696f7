//! The edge rule: a default fit that ends on a bound the data set (not the
//! bounded class's own edges, not a bound the user gave) was stopped by the
//! box, not by the data. The bound is widened and the fit refitted from its
//! best point, at most [`MAX_WIDENINGS`] times, and the result says so.

use serde::Serialize;

use super::objective::ModelObjective;
use super::problem::FitProblem;
use crate::eval::Evaluator;
use crate::model::bounds::Origin;
use crate::optim::engine::{Engine, Outcome, Plan, Space, StopReason, StopRules};

/// Refits after widening at most this many times.
pub const MAX_WIDENINGS: usize = 2;

/// One widening and the refit that followed it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Widening {
    /// The bounds widened, each as "NAME SIDE bound OLD -> NEW".
    pub bounds: Vec<String>,
    /// The estimation SSE before and after the refit (the refit is kept
    /// only when it is lower).
    pub sse_before: f64,
    pub sse_after: f64,
}

/// A bound still active at the end of a fit.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ActiveBound {
    /// The search coordinate's name.
    pub param: String,
    /// `"lower"` or `"upper"`.
    pub bound: &'static str,
    /// Where the bound comes from: `data` (a data-set bound, after the last
    /// widening), `class` (the bounded class's edge or the parameter's own
    /// range) or `user` (`--bound`, `--fix`).
    pub origin: Origin,
}

/// A generalized fit run from the default switching's two starts
/// ([`crate::model::Switching::Starts`]): the switching level held at the
/// estimation mean, and at the sensor's zero; the lower estimation SSE is
/// kept.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Switched {
    /// Estimation SSE with the level at the estimation mean.
    pub mean_sse: f64,
    /// Estimation SSE with the level at the sensor's zero.
    pub zero_sse: f64,
    /// `true` when the start at zero was kept.
    pub kept_zero: bool,
}

impl Switched {
    /// The two starts' outcomes compared: the one at zero is kept where it
    /// found a model at a lower estimation SSE.
    pub fn of(at_mean: &Outcome, at_zero: &Outcome) -> Switched {
        Switched {
            mean_sse: at_mean.sse,
            zero_sse: at_zero.sse,
            kept_zero: !at_zero.params.is_empty() && at_zero.sse < at_mean.sse,
        }
    }
}

/// Fits `problem` with `plan` on `evaluator`, with no observer, interrupt or
/// checkpoint (the studies of `compare` and the tests): from both starts of
/// the default switching where the problem has two ([`FitProblem::at_zero`]: the
/// lower estimation SSE kept), then the edge rule.
pub fn fit_problem(
    problem: &FitProblem,
    plan: Plan,
    seed: u64,
    stops: StopRules,
    evaluator: &mut dyn Evaluator,
) -> anyhow::Result<(Engine, Outcome)> {
    let run = |problem: &FitProblem,
               evaluator: &mut dyn Evaluator|
     -> anyhow::Result<(Engine, Outcome)> {
        let mut engine = Engine::new(
            plan.clone(),
            Space::from(&problem.space),
            seed,
            stops.clone(),
        )?;
        let mut objective = ModelObjective::for_problem(evaluator, problem);
        let outcome = engine.run(&mut objective, &mut [], None, None)?;
        Ok((engine, outcome))
    };
    let mut widened = problem.clone();
    let (mut engine, mut outcome) = run(problem, evaluator)?;
    if let Some(zero) = problem.at_zero() {
        let (e, o) = run(&zero, evaluator)?;
        let (evaluations, seconds) = (
            outcome.evaluations + o.evaluations,
            outcome.seconds + o.seconds,
        );
        if Switched::of(&outcome, &o).kept_zero {
            (engine, outcome, widened) = (e, o, zero);
        }
        (outcome.evaluations, outcome.seconds) = (evaluations, seconds);
    }
    let (outcome, _) = refit_off_edges(&mut widened, &engine, outcome, &stops, evaluator)?;
    Ok((engine, outcome))
}

/// Applies the edge rule to `outcome`, the result of the staged fit
/// `engine` ran on `problem`: widens the data-set bounds it ends on, refits
/// from its best point with the free-run and polish stages of the same plan
/// (a polish alone where the plan has no free run), and keeps the refit
/// when its estimation SSE is lower. `problem.space` is the widened box on
/// return. Does nothing for the thesis' flow, a plan that is a population
/// search alone (a study of the search, not a fit), or a fit that was
/// interrupted or found nothing.
pub fn refit_off_edges(
    problem: &mut FitProblem,
    engine: &Engine,
    mut outcome: Outcome,
    stops: &StopRules,
    evaluator: &mut dyn Evaluator,
) -> anyhow::Result<(Outcome, Vec<Widening>)> {
    let mut widenings = Vec::new();
    let refits = engine.plan.free_run.is_some() || engine.plan.polish.is_some();
    if problem.flow == crate::model::Flow::Thesis
        || !refits
        || outcome.params.is_empty()
        || outcome.stop == StopReason::Interrupted
    {
        return Ok((outcome, widenings));
    }
    for round in 0..MAX_WIDENINGS {
        let space = Space::from(&problem.space);
        let edges: Vec<(usize, &str)> = space
            .on_edge(&outcome.params)
            .into_iter()
            .filter(|&(i, side)| {
                problem.space.origin[i][usize::from(side == "upper")] == Origin::Data
            })
            .collect();
        if edges.is_empty() {
            break;
        }
        let bounds = problem.space.widen(&edges);
        let plan = Plan {
            global: None,
            free_run: engine.plan.free_run.clone(),
            polish: engine.plan.polish.clone(),
        };
        let seed = engine.seed.wrapping_add(1 + round as u64);
        let mut refit = Engine::new(plan, Space::from(&problem.space), seed, stops.clone())?
            .with_initial(&outcome.params);
        let mut objective = ModelObjective::for_problem(evaluator, problem);
        let next = refit.run(&mut objective, &mut [], None, None)?;
        let sse_before = outcome.sse;
        let sse_after = next.sse;
        outcome.evaluations += next.evaluations;
        outcome.generations += next.generations;
        outcome.seconds += next.seconds;
        outcome.stages.extend(next.stages.iter().cloned());
        if !next.params.is_empty() && next.sse < outcome.sse {
            outcome.params = next.params;
            outcome.sse = next.sse;
        }
        outcome.stop = next.stop;
        widenings.push(Widening {
            bounds,
            sse_before,
            sse_after,
        });
    }
    Ok((outcome, widenings))
}

/// The bounds of `problem`'s box that the canonical `params` sit on, with why
/// each stays.
pub fn active_bounds(problem: &FitProblem, params: &[f64]) -> Vec<ActiveBound> {
    if params.is_empty() {
        return Vec::new();
    }
    let space = Space::from(&problem.space);
    space
        .on_edge(params)
        .into_iter()
        .map(|(i, bound)| ActiveBound {
            param: space.names[i].clone(),
            bound,
            origin: problem.space.origin[i][usize::from(bound == "upper")],
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::cpu::CpuEvaluator;
    use crate::fit::cases::{Case, CaseSpec, matrix};
    use crate::fit::objective::staged_plan;
    use crate::model::Family;
    use crate::model::Measure;
    use crate::optim::engine::Objective;
    use crate::optim::{Algorithm, engine::Space as EngineSpace};

    #[test]
    fn a_fit_stopped_by_a_data_bound_widens_it_and_refits() {
        let case = Case::generate(CaseSpec {
            samples: 2000,
            ..matrix(Family::Classic, 1, 7)[0]
        });
        let mut problem = case.problem();
        // A gain box whose top is half the truth's: the fit must end there.
        let truth = problem.space.from_native(&case.truth);
        let ib = Family::Classic.linear_indices()[1];
        problem.space.upper[ib] = 0.5 * truth[ib];
        problem.space.lower[ib] = 0.1 * truth[ib];
        let plan = staged_plan(&problem, Algorithm::De.staged_settings(60), 60, 20);
        let mut cpu = CpuEvaluator::new();
        let mut engine = Engine::new(
            plan,
            EngineSpace::from(&problem.space),
            1,
            StopRules::default(),
        )
        .unwrap();
        let outcome = engine
            .run(
                &mut ModelObjective::for_problem(&mut cpu, &problem),
                &mut [],
                None,
                None,
            )
            .unwrap();
        let stuck = active_bounds(&problem, &outcome.params);
        assert!(
            stuck
                .iter()
                .any(|b| b.param == "gain" && b.bound == "upper"),
            "{stuck:?}"
        );
        let before = outcome.sse;
        let (after, widenings) = refit_off_edges(
            &mut problem,
            &engine,
            outcome,
            &StopRules::default(),
            &mut cpu,
        )
        .unwrap();
        assert!(!widenings.is_empty());
        assert!(
            widenings[0].bounds[0].starts_with("gain upper bound"),
            "{widenings:?}"
        );
        assert!(
            problem.space.upper[ib] > truth[ib],
            "two widenings reach the truth's gain"
        );
        assert!(after.sse < before, "{} !< {before}", after.sse);
        let left = active_bounds(&problem, &after.params);
        assert!(left.iter().all(|b| b.param != "gain"), "{left:?}");

        // A user's bound is never widened.
        let mut user = case.problem();
        user.space.origin[ib] = [Origin::User; 2];
        user.space.upper[ib] = 0.5 * truth[ib];
        let (_, none) = refit_off_edges(
            &mut user,
            &engine,
            Outcome {
                params: problem.space.to_native(&{
                    let mut z = truth.clone();
                    z[ib] = 0.5 * truth[ib];
                    z
                }),
                ..after.clone()
            },
            &StopRules::default(),
            &mut cpu,
        )
        .unwrap();
        assert!(none.is_empty());
    }

    #[test]
    fn a_task_objective_rejects_unbounded_loops_on_the_free_run_only() {
        let spec = CaseSpec {
            samples: 2000,
            ..matrix(Family::Classic, 1, 5)[0]
        };
        let case = Case::generate(spec);
        let problem = case.problem();
        let mut unbounded = case.truth.clone();
        // β + γ < 0: the loop grows without bound.
        unbounded[3] = -unbounded[2] - 0.05;
        let rows: Vec<f64> = case.truth.iter().chain(&unbounded).copied().collect();
        let mut cpu = CpuEvaluator::new();
        let mut objective = ModelObjective::for_problem(&mut cpu, &problem);
        let free = objective.costs(&rows, Measure::FreeRun).unwrap();
        assert!(free[0].is_finite() && free[1] == f32::INFINITY, "{free:?}");
        let residuals = objective.residuals(&rows, Measure::FreeRun).unwrap();
        assert!(residuals[0].is_some() && residuals[1].is_none());
        let ahead = Measure::Ahead { horizon: 10 };
        let checked = objective.costs(&rows, ahead).unwrap();
        // The plain objective scores what it simulates; the check only
        // touches the free run.
        let mut cpu = CpuEvaluator::new();
        let mut plain = ModelObjective::new(&mut cpu, problem.est_problem());
        let bits = |c: Vec<f32>| c.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(plain.costs(&rows, ahead).unwrap()), bits(checked));
        assert_eq!(plain.costs(&rows, Measure::FreeRun).unwrap()[0], free[0]);
    }
}
