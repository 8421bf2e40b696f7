//! The edge rule: a default fit that ends on or near a bound the data set
//! (not the bounded class's own edges, not a bound the user gave) was
//! stopped by the box, not by the data. The bound is widened and the fit
//! refitted from its best point, at most [`MAX_WIDENINGS`] times, and the
//! result says so. Every try of a fit is settled so, each in its own copy
//! of the box, before the lowest is kept ([`settle_tries`]): a try's end
//! then depends on nothing but its own seed, and a run of more tries never
//! ends higher than a run of fewer.

use serde::Serialize;

use super::chart::ModelChart;
use super::objective::ModelObjective;
use super::problem::FitProblem;
use crate::eval::Evaluator;
use crate::model::bounds::Origin;
use crate::optim::engine::{Engine, Outcome, Plan, StopReason, StopRules, TryEnd};
use crate::optim::streams::try_seed;
use crate::search::{Rows, Side};

/// Refits after widening at most this many times.
pub const MAX_WIDENINGS: usize = 2;

/// A fit that ends within this share of a data-set bound's box width of
/// it (on the scale of the smallest drawn values, for a coordinate that
/// spans decades: [`crate::optim::engine::space::Space::near_edge`]) counts as ended on it: a fit that
/// stops a hair inside a bound was stopped by it as surely (as a fit whose
/// truth lies beyond the bound can end just inside it).
pub const NEAR_EDGE: f64 = 0.01;

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
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ActiveBound {
    /// The search coordinate's name.
    pub param: String,
    pub bound: Side,
    /// Where the bound comes from: `data` (a data-set bound, after the last
    /// widening), `class` (the bounded class's edge or the parameter's own
    /// range) or `user` (`--bound`, `--fix`).
    pub origin: Origin,
    /// How far inside the bound the parameter ended, as a share of the
    /// box's width (0: on it).
    pub inside: f64,
}

/// Settles every try of `outcome`, what `engine` ran on `problem`, by the
/// edge rule ([`refit_off_edges`]), each in its own copy of the box, and
/// keeps the lowest (the first on a tie): on return `problem.space` is that
/// try's box, widened where its rule widened it, `outcome`'s parameters and
/// SSE are its, `outcome.tries` holds every try's end after its refits, and
/// the refits' work is counted in. Returns the kept try's widenings.
pub fn settle_tries(
    problem: &mut FitProblem,
    engine: &Engine<ModelChart>,
    mut outcome: Outcome,
    stops: &StopRules,
    evaluator: &mut dyn Evaluator,
) -> anyhow::Result<(Outcome, Vec<Widening>)> {
    let mut kept: Option<(usize, FitProblem, Vec<Widening>)> = None;
    let ends = std::mem::take(&mut outcome.tries);
    let mut settled: Vec<TryEnd> = Vec::with_capacity(ends.len());
    // The start's budget (`engine`'s: what the fit left it) covers its
    // refits too: each runs in what the run and the refits before it left.
    let budget = engine.stops.time_budget_s;
    for (t, end) in ends.into_iter().enumerate() {
        let mut own = problem.clone();
        let left = StopRules {
            time_budget_s: budget.map(|b| b - outcome.seconds),
            ..stops.clone()
        };
        let refit = refit_off_edges(
            &mut own,
            &engine.plan,
            try_seed(engine.seed, t),
            (end, outcome.stop),
            &left,
            evaluator,
        )?;
        outcome.evaluations += refit.evaluations;
        outcome.generations += refit.generations;
        outcome.seconds += refit.seconds;
        outcome.stages.extend(refit.stages);
        // The first reason a run or a refit ended early is the fit's: a
        // refit that completed in what was left does not undo a budget
        // that cut the run.
        if let Some(stop) = refit.stop {
            outcome.stop = outcome.stop.earliest(stop);
        }
        let lower = kept
            .as_ref()
            .is_none_or(|(k, _, _)| refit.end.sse < settled[*k].sse);
        if lower && !refit.end.params.is_empty() {
            kept = Some((t, own, refit.widenings));
        }
        settled.push(refit.end);
    }
    let mut widenings = Vec::new();
    if let Some((t, own, w)) = kept {
        *problem = own;
        outcome.params = settled[t].params.clone();
        outcome.sse = settled[t].sse;
        widenings = w;
    }
    outcome.tries = settled;
    Ok((outcome, widenings))
}

/// A try's end after the edge rule, and the work its refits took.
pub struct Refit {
    pub end: TryEnd,
    pub widenings: Vec<Widening>,
    pub evaluations: u64,
    pub generations: usize,
    pub seconds: f64,
    pub stages: Vec<crate::optim::engine::StageSummary>,
    /// Why the last refit stopped, where there was one.
    pub stop: Option<StopReason>,
}

/// Applies the edge rule to a try's `end` (`stop`: why its fit ended), a
/// fit of `plan` on `problem` seeded by `seed`: widens the data-set bounds
/// it ends on or near ([`NEAR_EDGE`]), refits from its best point with the
/// plan from a point on ([`Plan::from_point`]: the free-run stage, the
/// polish and the refining rounds; a polish alone where the plan has no
/// free run), and keeps the refit when its estimation SSE is lower.
/// `problem.space` is the widened box on return. Does nothing for the
/// thesis' flow, a plan that is a population search alone (a study of the
/// search, not a fit), or a fit that was interrupted or found nothing; a
/// round runs in what `stops`' budget and the rounds before it left, and
/// none where nothing is left.
pub fn refit_off_edges(
    problem: &mut FitProblem,
    plan: &Plan,
    seed: u64,
    (mut end, stop): (TryEnd, StopReason),
    stops: &StopRules,
    evaluator: &mut dyn Evaluator,
) -> anyhow::Result<Refit> {
    let mut refit = Refit {
        end: TryEnd {
            params: Vec::new(),
            sse: f64::INFINITY,
            cut_gain: None,
        },
        widenings: Vec::new(),
        evaluations: 0,
        generations: 0,
        seconds: 0.0,
        stages: Vec::new(),
        stop: None,
    };
    let refits = plan.free_run.is_some() || plan.polish.is_some();
    if problem.flow == crate::model::Flow::Thesis
        || !refits
        || end.params.is_empty()
        || stop == StopReason::Interrupted
    {
        refit.end = end;
        return Ok(refit);
    }
    for round in 0..MAX_WIDENINGS {
        let space = problem.engine_space();
        let edges: Vec<(usize, Side)> = space
            .near_edge(&end.params, NEAR_EDGE)
            .into_iter()
            .filter(|&(i, side)| problem.space.origin[i][side.index()] == Origin::Data)
            .collect();
        if edges.is_empty() {
            break;
        }
        // Each round runs in what the budget and the rounds before it left;
        // with nothing left the try ends where it is, and the budget says
        // why it was not refitted.
        let left = stops.time_budget_s.map(|b| b - refit.seconds);
        if left.is_some_and(|t| t <= 0.0) {
            refit.stop = Some(StopReason::TimeBudget);
            break;
        }
        let bounds = problem.space.widen(&edges);
        let seed = seed.wrapping_add(1 + round as u64);
        let mut engine = Engine::new(
            plan.from_point(),
            problem.engine_space(),
            seed,
            StopRules {
                time_budget_s: left,
                ..stops.clone()
            },
        )?
        .with_initial(Rows::one(&end.params));
        let mut objective = ModelObjective::for_problem(evaluator, problem);
        let next = engine.run(&mut objective, &mut [], None, None)?;
        let sse_before = end.sse;
        refit.evaluations += next.evaluations;
        refit.generations += next.generations;
        refit.seconds += next.seconds;
        refit.stages.extend(next.stages.iter().cloned());
        // A round cut short says so, whatever the round after it does.
        refit.stop = Some(
            refit
                .stop
                .unwrap_or(StopReason::Completed)
                .earliest(next.stop),
        );
        if !next.params.is_empty() && next.sse < end.sse {
            // A refit that stopped refining in time does not undo a cut
            // in the fit it started from: more rounds there would have
            // handed it another point.
            end = TryEnd {
                params: next.params,
                sse: next.sse,
                cut_gain: next.tries.first().and_then(|t| t.cut_gain).or(end.cut_gain),
            };
        }
        refit.widenings.push(Widening {
            bounds,
            sse_before,
            sse_after: next.sse,
        });
        if matches!(next.stop, StopReason::Interrupted | StopReason::TimeBudget) {
            break;
        }
    }
    refit.end = end;
    Ok(refit)
}

/// The bounds of `problem`'s box that the canonical `params` end on or near
/// ([`NEAR_EDGE`]), with why each stays and how far inside it they are.
pub fn active_bounds(problem: &FitProblem, params: &[f64]) -> Vec<ActiveBound> {
    if params.is_empty() {
        return Vec::new();
    }
    let space = problem.engine_space();
    let z = problem.space.from_native(params);
    space
        .near_edge(params, NEAR_EDGE)
        .into_iter()
        .map(|(i, bound)| {
            let b = match bound {
                Side::Lower => space.lower[i],
                Side::Upper => space.upper[i],
            };
            ActiveBound {
                param: space.names[i].clone(),
                bound,
                origin: problem.space.origin[i][bound.index()],
                inside: (z[i] - b).abs() / (space.upper[i] - space.lower[i]),
            }
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
    use crate::optim::Algorithm;
    use crate::optim::engine::Objective;

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
        let mut engine =
            Engine::new(plan, problem.engine_space(), 1, StopRules::default()).unwrap();
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
                .any(|b| b.param == "gain" && b.bound == Side::Upper),
            "{stuck:?}"
        );
        let before = outcome.sse;
        let end = |o: &Outcome| TryEnd {
            params: o.params.clone(),
            sse: o.sse,
            cut_gain: None,
        };
        let stop = StopReason::Completed;
        let after = refit_off_edges(
            &mut problem,
            &engine.plan,
            1,
            (end(&outcome), stop),
            &StopRules::default(),
            &mut cpu,
        )
        .unwrap();
        let widenings = &after.widenings;
        assert!(!widenings.is_empty());
        assert!(
            widenings[0].bounds[0].starts_with("gain upper bound"),
            "{widenings:?}"
        );
        assert!(
            problem.space.upper[ib] > truth[ib],
            "two widenings reach the truth's gain"
        );
        assert!(after.end.sse < before, "{} !< {before}", after.end.sse);
        let left = active_bounds(&problem, &after.end.params);
        assert!(left.iter().all(|b| b.param != "gain"), "{left:?}");

        // A fit that stops a hair inside the bound is widened as well.
        let mut near = case.problem();
        near.space.upper[ib] = 0.5 * truth[ib];
        near.space.lower[ib] = 0.1 * truth[ib];
        let width = near.space.upper[ib] - near.space.lower[ib];
        let mut z = near.space.from_native(&outcome.params);
        z[ib] = near.space.upper[ib] - 3e-4 * width;
        let inside = TryEnd {
            params: near.space.to_native(&z),
            sse: near.est_sse(&near.space.to_native(&z)),
            // As if refining had been cut short on the way here.
            cut_gain: Some(0.01),
        };
        let bound = active_bounds(&near, &inside.params);
        let gain = bound
            .iter()
            .find(|b| b.param == "gain")
            .expect("near the gain's bound");
        assert!((gain.inside - 3e-4).abs() < 1e-9, "{gain:?}");
        let refit = refit_off_edges(
            &mut near,
            &engine.plan,
            1,
            (inside, stop),
            &StopRules::default(),
            &mut cpu,
        )
        .unwrap();
        assert!(
            refit.widenings[0].bounds[0].starts_with("gain upper bound"),
            "{:?}",
            refit.widenings
        );
        // The refit, kept, ran no refining rounds of its own to cut: the
        // cut on the way to its start still stands.
        assert!(refit.end.sse < refit.widenings[0].sse_before);
        assert_eq!(refit.end.cut_gain, Some(0.01));

        // A user's bound is never widened.
        let mut user = case.problem();
        user.space.origin[ib] = [Origin::User; 2];
        user.space.upper[ib] = 0.5 * truth[ib];
        let mut z = truth.clone();
        z[ib] = 0.5 * truth[ib];
        let on_user = TryEnd {
            params: problem.space.to_native(&z),
            sse: after.end.sse,
            cut_gain: None,
        };
        let none = refit_off_edges(
            &mut user,
            &engine.plan,
            1,
            (on_user, stop),
            &StopRules::default(),
            &mut cpu,
        )
        .unwrap();
        assert!(none.widenings.is_empty());
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
        let rows = Rows::new(&rows, unbounded.len());
        let mut cpu = CpuEvaluator::new();
        let mut objective = ModelObjective::for_problem(&mut cpu, &problem);
        let free = objective.costs(rows, Measure::FreeRun).unwrap();
        assert!(free[0].is_finite() && free[1] == f32::INFINITY, "{free:?}");
        let residuals = objective.residuals(rows, Measure::FreeRun).unwrap();
        assert!(residuals[0].is_some() && residuals[1].is_none());
        let ahead = Measure::Ahead { horizon: 10 };
        let checked = objective.costs(rows, ahead).unwrap();
        // The plain objective scores what it simulates; the check only
        // touches the free run.
        let mut cpu = CpuEvaluator::new();
        let mut plain = ModelObjective::new(&mut cpu, problem.est_problem());
        let bits = |c: Vec<f32>| c.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(plain.costs(rows, ahead).unwrap()), bits(checked));
        assert_eq!(plain.costs(rows, Measure::FreeRun).unwrap()[0], free[0]);
    }
}
