//! How the diagnosis fits a model: the strategies (from scratch, through
//! the multi-step-ahead predictor, warm from the current model), the
//! polish, the size profile, and the statistics over seeds.
//!
//! Every search and every polish runs on the fitting engine
//! ([`crate::optim::engine`]) over one objective, the model description
//! scored in batches on the searches' evaluator; what is the diagnosis' own is
//! where each search starts and what it minimises.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Uniform};
use serde::Serialize;

use super::likelihood::indistinguishable_up_to;
use super::settings::{Interrupted, SEEDS_A_SALT, Settings};
use crate::fit::objective::ModelObjective;
use crate::fit::problem::FitProblem;
use crate::fit::searches::Searches;
use crate::model::{Family, Measure};
use crate::optim::AlgoSettings;
use crate::optim::de::DeSettings;
use crate::optim::engine::{Engine, Objective, Outcome, Plan, Polish, Space, StopRules};
use crate::search::{Params, Rows};

/// The fit's objective ([`ModelObjective::bounded_loops`]: the model
/// description scored in batches on the searches' evaluator, unbounded loops
/// and effects the diagnosis does not admit at `+∞`) under one `measure`,
/// whatever measure the engine asks for: each search of the diagnosis
/// minimises one measure, and the engine then keeps the best of it.
struct OneMeasure<'a> {
    objective: ModelObjective<'a>,
    measure: Measure,
}

impl Objective for OneMeasure<'_> {
    fn describe(&self) -> String {
        self.objective.describe()
    }

    fn costs(&mut self, rows: Rows<'_, Params>, _: Measure) -> anyhow::Result<Vec<f32>> {
        self.objective.costs(rows, self.measure)
    }

    fn residuals(
        &mut self,
        rows: Rows<'_, Params>,
        _: Measure,
    ) -> anyhow::Result<Vec<Option<Vec<f32>>>> {
        anyhow::ensure!(
            self.measure == Measure::FreeRun,
            "the diagnosis polishes on the free run only"
        );
        self.objective.residuals(rows, Measure::FreeRun)
    }
}

/// Runs `engine` on the problem's estimation part under `measure` alone
/// ([`OneMeasure`]), on the searches' evaluator; [`Interrupted`] once their
/// stop flag is raised (the engine stops after its current generation or
/// polish iteration).
fn run_engine(
    problem: &FitProblem,
    searches: &Searches,
    measure: Measure,
    engine: &mut Engine,
) -> anyhow::Result<Outcome> {
    let outcome = searches.run(|evaluator| {
        let mut objective = OneMeasure {
            objective: ModelObjective::for_problem(evaluator, problem),
            measure,
        };
        engine.run(
            &mut objective,
            &mut [],
            Some(searches.stop.as_atomic()),
            None,
        )
    })?;
    if searches.stop.raised() {
        return Err(Interrupted.into());
    }
    Ok(outcome)
}

/// The box of a search on `problem`: `lo..hi` (the problem's box, or a
/// part of it held), a coordinate with equal bounds held; the parameters
/// named as the model names them.
fn space_of(problem: &FitProblem, lo: &[f64], hi: &[f64]) -> Space {
    Space::new(lo.to_vec(), hi.to_vec(), problem.space.names())
}

/// Differential evolution on the engine over the box `lo..hi` from the
/// `initial` rows (canonical; the rest of the population drawn uniformly),
/// for `generations` generations after the initial population; returns
/// the best point seen and its cost.
fn evolve(
    (problem, searches): (&FitProblem, &Searches),
    measure: Measure,
    (lo, hi): (&[f64], &[f64]),
    initial: Rows<'_, Params>,
    (population, generations): (usize, usize),
    p_best: f64,
    rng: &mut ChaCha8Rng,
) -> anyhow::Result<(Vec<f64>, f64)> {
    let settings = AlgoSettings::De(DeSettings {
        p_best,
        ..DeSettings::default()
    });
    let plan = Plan::search(settings, population, generations + 1);
    let mut engine = Engine::new(
        plan,
        space_of(problem, lo, hi),
        rng.random(),
        StopRules::default(),
    )?
    .with_initial(initial);
    let outcome = run_engine(problem, searches, measure, &mut engine)?;
    if outcome.params.is_empty() {
        // Every candidate diverged: the start is as good as any.
        return Ok((initial.row(0).to_vec(), f64::INFINITY));
    }
    Ok((outcome.params, outcome.sse))
}

/// One fitted model: its parameters, its estimation SSE (what the fit
/// minimised) and its RMSE on the selection part (what the diagnosis
/// chooses by).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScoredFit {
    pub params: Vec<f64>,
    pub est_sse: f64,
    pub sel_rmse: f64,
}

/// The fits of one model over several seeds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SeededFit {
    /// The seed with the lowest estimation SSE (among those finite on the
    /// selection part).
    pub best: ScoredFit,
    /// Selection RMSE of every seed.
    pub seed_sel_rmse: Vec<f64>,
    /// Their spread, `1.4826·MAD` (a robust standard deviation), over the
    /// seeds the estimation data cannot tell from the best: those within the
    /// likelihood-ratio test's 95 % threshold of its SSE.
    pub spread: f64,
    /// The lowest and highest selection RMSE among those same seeds.
    pub indistinguishable: RmseSpan,
}

/// The lowest and the highest of a set of selection RMSEs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RmseSpan {
    pub lowest: f64,
    pub highest: f64,
}

impl RmseSpan {
    /// The span of `rmse`; non-finite values count as +∞, and so does an
    /// empty set (nothing was reached).
    pub fn of(rmse: &[f64]) -> RmseSpan {
        let nan_as_inf = rmse
            .iter()
            .map(|&r| if r.is_nan() { f64::INFINITY } else { r });
        match nan_as_inf.clone().reduce(f64::min) {
            Some(lowest) => RmseSpan {
                lowest,
                highest: nan_as_inf.fold(lowest, f64::max),
            },
            None => RmseSpan {
                lowest: f64::INFINITY,
                highest: f64::INFINITY,
            },
        }
    }
}

/// Where a fit starts.
#[derive(Debug, Clone, Copy)]
pub enum Start<'a> {
    /// From scratch over the whole box (the baseline).
    Scratch,
    /// From scratch in two stages: half the generations on the
    /// `horizon`-step-ahead prediction error ([`FitProblem::est_sse_ahead`]), the
    /// other half on the free run, started around the first stage's best.
    /// The free-run cost of a slow, hysteretic model is a needle along the
    /// pole and the static gain that differential evolution rarely finds
    /// from scratch; the prediction error's is not (docs/ARCHITECTURE.md,
    /// "Decisions of the fitting engine").
    Ahead { horizon: usize },
    /// From a known model: `params` is the current model with the new
    /// effect's parameters (from `new_from` on) at their neutral values; the
    /// refit of the current model itself has `new_from == params.len()`.
    Warm { params: &'a [f64], new_from: usize },
}

/// Fits `model` on the estimation part with seed `seed`.
///
/// The search is differential evolution on the fitting engine (the update
/// rule `mckibben fit --algo de` uses). From scratch with the narrow
/// `p_best = 0.02`, greedier than DE's default, so that more seeds leave the
/// linear model's plateau (docs/lab/diagnosis.md, "How the diagnosis was
/// built, and what it measured"); one member is the ARX model, so the fit
/// starts no worse than least squares.
///
/// Warm-started in two stages. First the new effect's parameters alone, the
/// rest held at the start (a search in one or two dimensions that rarely
/// misses); then everything together from there, with `p_best = 0.2` so the
/// population does not collapse onto the start: the baseline had compensated
/// for the missing effect and must move back. The start is a member
/// throughout, so a fit never ends worse than it started.
pub fn fit_candidate(
    problem: &FitProblem,
    searches: &Searches,
    start: Start<'_>,
    seed: u64,
    population: usize,
    generations: usize,
) -> anyhow::Result<ScoredFit> {
    let (neutral, lo, hi) = (
        problem.centre(),
        problem.space.lower.clone(),
        problem.space.upper.clone(),
    );
    let d = lo.len();
    let np = population.max(6);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (initial, p_best, generations) = match start {
        Start::Scratch => (
            scratch_rows(problem, (&neutral, &lo, &hi), np, &mut rng),
            0.02,
            generations,
        ),
        Start::Ahead { horizon } => {
            let rows = scratch_rows(problem, (&neutral, &lo, &hi), np, &mut rng);
            let first = generations / 2;
            let (best, _) = evolve(
                (problem, searches),
                Measure::Ahead { horizon },
                (&lo, &hi),
                Rows::new(&rows, d),
                (np, first),
                0.02,
                &mut rng,
            )?;
            let rows = warm_population(&best, &best, d, (&lo, &hi), np, &mut rng);
            (rows, 0.2, generations - first)
        }
        Start::Warm {
            params: s,
            new_from,
        } => {
            let staged = if new_from < d {
                let k = d - new_from;
                let np1 = (10 * k).max(12);
                // The current model's parameters held where they are.
                let (mut held_lo, mut held_hi) = (lo.clone(), hi.clone());
                held_lo[..new_from].copy_from_slice(&s[..new_from]);
                held_hi[..new_from].copy_from_slice(&s[..new_from]);
                let mut first = s.to_vec();
                // A mode starts where the residual's spectrum peaks.
                first.extend(super::hints::mode_hints(problem, s, new_from, (&lo, &hi)));
                let (best, _) = evolve(
                    (problem, searches),
                    Measure::FreeRun,
                    (&held_lo, &held_hi),
                    Rows::new(&first, d),
                    (np1, 60),
                    0.2,
                    &mut rng,
                )?;
                best
            } else {
                s.to_vec()
            };
            let rows = warm_population(s, &staged, new_from, (&lo, &hi), np, &mut rng);
            (rows, 0.2, generations)
        }
    };
    let (best, _) = evolve(
        (problem, searches),
        Measure::FreeRun,
        (&lo, &hi),
        Rows::new(&initial, d),
        (np, generations),
        p_best,
        &mut rng,
    )?;
    // In `f64`, as the polish compares.
    let est_sse = problem.est_sse(&best);
    let (best, est_sse) = polish(problem, searches, best, est_sse, (&lo, &hi))?;
    Ok(ScoredFit {
        sel_rmse: problem.selection_rmse(&best),
        est_sse,
        params: best,
    })
}

/// Levenberg–Marquardt from the search's best on the free-run residuals;
/// the polished point is kept only if its estimation SSE is lower. The
/// free-run cost of a slow, hysteretic model is a narrow curved valley
/// along its pole and static gain (docs/ARCHITECTURE.md, "Decisions of the
/// fitting engine"), along which differential evolution creeps while
/// Gauss–Newton steps follow it.
///
/// The engine's polish from `best` alone: one start, because every seed of
/// the diagnosis is polished already and their spread is what the
/// acceptance rule measures; no continuation through the prediction
/// horizons, because the diagnosis' fits end on the free run. Forward
/// differences in the `f32` simulation: steps of 1e-4 of the coordinate's
/// size (taken as at least 1 % of its box width, so that a coordinate near
/// zero is still probed) stay well above its rounding, at half the
/// simulations of the fit's central differences ([`Polish::default`]):
/// central ones move the diagnosis' fits no more than a change of seed
/// does (docs/lab/diagnosis.md, "One polish, one prior"). A coordinate
/// with equal bounds is held.
pub(super) fn polish(
    problem: &FitProblem,
    searches: &Searches,
    best: Vec<f64>,
    est_sse: f64,
    (lo, hi): (&[f64], &[f64]),
) -> anyhow::Result<(Vec<f64>, f64)> {
    let plan = Plan::polish(Polish {
        starts: 1,
        iterations: 30,
        rel_step: 1e-4,
        step_floor: 1e-2,
        tolerance: 1e-9,
        central: false,
        continuation: false,
        longest: usize::MAX,
    });
    // The polish draws nothing: the seed is never used.
    let mut engine = Engine::new(plan, space_of(problem, lo, hi), 0, StopRules::default())?
        .with_initial(Rows::one(&best));
    let outcome = run_engine(problem, searches, Measure::FreeRun, &mut engine)?;
    // No params: the start and every step diverged. The polished point is
    // scored in `f64`, as the start was.
    if outcome.params.is_empty() {
        return Ok((best, est_sse));
    }
    let sse = problem.est_sse(&outcome.params);
    Ok(if sse < est_sse {
        (outcome.params, sse)
    } else {
        (best, est_sse)
    })
}

/// Nodes of the size profile on each side of neutral: the box's edge times
/// `2^-k`, `k < PROFILE_NODES`.
const PROFILE_NODES: i32 = 6;

/// The profile of a candidate's new effect along its size: from the best fit,
/// the effect's primary parameter (index `at`) is stepped away from neutral
/// toward each edge of its box over a geometric ladder ([`PROFILE_NODES`]
/// nodes a side, so that small sizes are probed as finely as large ones),
/// the rest polished at each node from the node before; the best node is
/// then polished with everything free, and kept if it beats the fit on the
/// estimation part. Why: when the current model has absorbed part of an
/// effect, the fits warm-started from it find the effect small, and the
/// model with the effect at its true size lies along a valley in which the
/// rest of the model must move back with it (docs/lab/diagnosis.md, "How
/// the diagnosis was built, and what it measured").
pub(super) fn profile(
    problem: &FitProblem,
    searches: &Searches,
    fit: ScoredFit,
    at: usize,
) -> anyhow::Result<ScoredFit> {
    let (lo, hi) = (&problem.space.lower, &problem.space.upper);
    let centre = problem.centre()[at].clamp(lo[at], hi[at]);
    let (mut best, mut best_sse) = (fit.params.clone(), fit.est_sse);
    for edge in [lo[at], hi[at]] {
        if edge == centre {
            continue;
        }
        let mut start = fit.params.clone();
        for k in (0..PROFILE_NODES).rev() {
            let v = centre + (edge - centre) * 0.5f64.powi(k);
            let (node, node_sse) = polish_held(problem, searches, &start, (at, v), (lo, hi))?;
            if node_sse < best_sse {
                (best, best_sse) = (node.clone(), node_sse);
            }
            start = node;
        }
    }
    if best_sse >= fit.est_sse {
        return Ok(fit);
    }
    let (params, est_sse) = polish(problem, searches, best, best_sse, (lo, hi))?;
    let sel_rmse = problem.selection_rmse(&params);
    Ok(if sel_rmse.is_finite() {
        ScoredFit {
            params,
            est_sse,
            sel_rmse,
        }
    } else {
        fit
    })
}

/// [`polish`] from `start` with coordinate `at` held at `v`: one point of
/// the profile along that coordinate.
pub(super) fn polish_held(
    problem: &FitProblem,
    searches: &Searches,
    start: &[f64],
    (at, v): (usize, f64),
    (lo, hi): (&[f64], &[f64]),
) -> anyhow::Result<(Vec<f64>, f64)> {
    let (mut l, mut h) = (lo.to_vec(), hi.to_vec());
    (l[at], h[at]) = (v, v);
    let mut p = start.to_vec();
    p[at] = v;
    let sse = problem.est_sse(&p);
    polish(problem, searches, p, sse, (&l, &h))
}

/// The initial population of a from-scratch fit: one member at the ARX
/// model (loop closed: `α` at its top, `β = γ = 0`), the rest uniform over
/// the box, except that every other member draws the loop-shape parameters
/// (β, γ or β1…β6) log-uniformly in magnitude over four decades: fits of the
/// muscle often need them near zero, a sliver of the box that a uniform draw
/// and DE's differences of uniform draws rarely visit; more seeds then leave
/// the linear model's plateau (A = 0) (docs/lab/diagnosis.md, "How the
/// diagnosis was built, and what it measured").
fn scratch_rows(
    problem: &FitProblem,
    (neutral, lo, hi): (&[f64], &[f64], &[f64]),
    np: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<f64> {
    let d = lo.len();
    let family = problem.model.family;
    let mut v = neutral.to_vec();
    if family != Family::Linear {
        v[1] = hi[1];
        v[2] = 0.0f64.clamp(lo[2], hi[2]);
        v[3] = 0.0f64.clamp(lo[3], hi[3]);
    }
    let [ia, ib, ic] = family.linear_indices();
    v[ia] = problem.records.prior.a.clamp(lo[ia], hi[ia]);
    v[ib] = problem.records.prior.b.clamp(lo[ib], hi[ib]);
    v[ic] = 0.0f64.clamp(lo[ic], hi[ic]);
    let mut rows = v;
    let shape = 2..family.exponent_index().unwrap_or(2);
    for i in 1..np {
        for j in 0..d {
            let uniform = Uniform::new_inclusive(lo[j], hi[j]).map_or(lo[j], |u| u.sample(rng));
            let v = if i % 2 == 1 && shape.contains(&j) {
                let decades = Uniform::new(-4.0, 0.0).map_or(0.0, |u| u.sample(rng));
                let sign = if lo[j] < 0.0 && rng.random::<bool>() {
                    -1.0
                } else {
                    1.0
                };
                (sign * 10f64.powf(decades) * hi[j].abs().max(lo[j].abs())).clamp(lo[j], hi[j])
            } else {
                uniform
            };
            rows.push(v);
        }
    }
    rows
}

/// The initial population of a warm-started fit: the start, the staged
/// model, then members around the staged model: the parameters before
/// `new_from` close (half) or farther (half), the rest near the staged value
/// (half) or anywhere in the box.
fn warm_population(
    start: &[f64],
    staged: &[f64],
    new_from: usize,
    (lo, hi): (&[f64], &[f64]),
    np: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<f64> {
    let d = lo.len();
    (0..np)
        .flat_map(|i| {
            (0..d)
                .map(|j| {
                    let near_staged = |sd: f64, rng: &mut ChaCha8Rng| {
                        let v = staged[j]
                            + Normal::new(0.0, sd * (hi[j] - lo[j])).map_or(0.0, |n| n.sample(rng));
                        v.clamp(lo[j], hi[j])
                    };
                    match i {
                        0 => start[j],
                        1 => staged[j],
                        _ if j < new_from => near_staged(if i % 2 == 0 { 0.1 } else { 0.02 }, rng),
                        _ if i % 2 == 0 => near_staged(0.05, rng),
                        _ => Uniform::new_inclusive(lo[j], hi[j]).map_or(lo[j], |u| u.sample(rng)),
                    }
                })
                .collect::<Vec<f64>>()
        })
        .collect()
}

/// Fits `model` with `settings.seeds` seeds (from scratch: `baseline_seeds`
/// of the baseline budget); `start` as in [`fit_candidate`].
pub fn fit_seeds(
    problem: &FitProblem,
    searches: &Searches,
    start: Start<'_>,
    settings: &Settings,
    salt: u64,
) -> anyhow::Result<SeededFit> {
    Ok(summarize(
        seed_fits(problem, searches, start, settings, salt)?,
        problem.est_samples(),
    ))
}

/// [`fit_seeds`] with the fits from scratch `scratch` ([`scratch_fits`])
/// among the seeds: the first round's fits. A from-scratch baseline fitted
/// to data with an unmodelled effect ends where it compensates the effect
/// best, often far from where the model with the effect fits (as on the
/// self-test's `asymmetry (large)` case: docs/lab/diagnosis.md, "How the
/// diagnosis was built, and what it measured"), and a warm start cannot
/// walk back; a search from scratch can.
pub(super) fn fit_seeds_with(
    problem: &FitProblem,
    searches: &Searches,
    start: Start<'_>,
    settings: &Settings,
    salt: u64,
    scratch: &[ScoredFit],
) -> anyhow::Result<SeededFit> {
    let mut fits = seed_fits(problem, searches, start, settings, salt)?;
    fits.extend_from_slice(scratch);
    Ok(summarize(fits, problem.est_samples()))
}

/// The fits of [`fit_seeds`], one per seed.
fn seed_fits(
    problem: &FitProblem,
    searches: &Searches,
    start: Start<'_>,
    settings: &Settings,
    salt: u64,
) -> anyhow::Result<Vec<ScoredFit>> {
    let (seeds, pop, gens) = match start {
        Start::Scratch | Start::Ahead { .. } => (
            settings.baseline_seeds,
            settings.baseline_population,
            settings.baseline_generations,
        ),
        Start::Warm { .. } => (settings.seeds, settings.population, settings.generations),
    };
    (0..seeds.max(1) as u64)
        .map(|i| {
            fit_candidate(
                problem,
                searches,
                start,
                settings.seed_of(salt, i),
                pop,
                gens,
            )
        })
        .collect()
}

/// `current` (with parameters `params`) plus `effect`, fitted warm from
/// `params` with the new effect at its neutral values ([`Start::Warm`],
/// [`fit_seeds_with`], the fits from scratch `scratch` among the seeds), the
/// best seed then profiled along the effect's size ([`profile`]): how the
/// selection tries a candidate, and how a given chain is built
/// (`diagnose::chain`).
pub(super) fn fit_with_effect(
    current: &FitProblem,
    searches: &Searches,
    params: &[f64],
    effect: super::Effect,
    settings: &Settings,
    salt: u64,
    scratch: &[ScoredFit],
) -> anyhow::Result<(FitProblem, SeededFit)> {
    let candidate = current.with_model(&current.model.with(effect));
    let mut start = params.to_vec();
    start.extend_from_slice(&candidate.centre()[params.len()..]);
    let warm = Start::Warm {
        params: &start,
        new_from: params.len(),
    };
    let mut fit = fit_seeds_with(&candidate, searches, warm, settings, salt, scratch)?;
    fit.best = profile(
        &candidate,
        searches,
        fit.best,
        params.len() + effect.primary(),
    )?;
    Ok((candidate, fit))
}

/// `settings.scratch_seeds` fits of `model` from scratch through the
/// multi-step-ahead predictor ([`Start::Ahead`]) with the baseline's
/// population and generations. They do not depend on the current model, so
/// a round that is judged again after a rebase reuses them.
pub(super) fn scratch_fits(
    problem: &FitProblem,
    searches: &Searches,
    settings: &Settings,
    salt: u64,
) -> anyhow::Result<Vec<ScoredFit>> {
    let ahead = Start::Ahead {
        horizon: problem.horizon(),
    };
    (0..settings.scratch_seeds as u64)
        .map(|i| {
            let seed = settings.seed_of(salt, SEEDS_A_SALT as u64 + i);
            fit_candidate(
                problem,
                searches,
                ahead,
                seed,
                settings.baseline_population,
                settings.baseline_generations,
            )
        })
        .collect()
}

/// The best fit of several seeds and their spread; `samples` estimation
/// residuals.
fn summarize(fits: Vec<ScoredFit>, samples: usize) -> SeededFit {
    let seed_sel_rmse: Vec<f64> = fits.iter().map(|f| f.sel_rmse).collect();
    // The spread among the seeds that reached the best estimation fit: how
    // much the selection RMSE moves between fits the estimation data cannot tell
    // apart, those within the likelihood-ratio test's 95 % threshold of the
    // best, `χ²₁(0.95)·σ̂²` with `σ̂² = SSE/N` (the threshold of the profile
    // intervals, `interval`). A seed stuck in a worse basin is a failed fit,
    // not a competing answer, and does not widen it.
    let best_sse = fits.iter().map(|f| f.est_sse).fold(f64::INFINITY, f64::min);
    let threshold = indistinguishable_up_to(best_sse, samples);
    let converged: Vec<f64> = fits
        .iter()
        .filter(|f| f.est_sse <= threshold)
        .map(|f| f.sel_rmse)
        .collect();
    let spread = std_dev(&converged);
    let indistinguishable = RmseSpan::of(&converged);
    // The seed with the lowest estimation SSE among those that stay finite on
    // the selection part: a fit that diverges there is not a model (the
    // selection part is used for nothing else in this choice).
    let any_finite = fits.iter().any(|f| f.sel_rmse.is_finite());
    let best = fits
        .into_iter()
        .filter(|f| f.sel_rmse.is_finite() || !any_finite)
        .min_by(|a, b| a.est_sse.total_cmp(&b.est_sse))
        .expect("at least one seed");
    SeededFit {
        best,
        seed_sel_rmse,
        spread,
        indistinguishable,
    }
}

/// The seed-to-seed spread: a robust standard deviation, `1.4826·MAD` of the
/// seeds' selection RMSEs (non-finite ones count as +∞). A seed stuck in a
/// poor basin is a failed fit, not spread, and the median ignores it while
/// seeds that agree give a small spread.
fn std_dev(v: &[f64]) -> f64 {
    if v.len() < 2 {
        return 0.0;
    }
    let median = |x: &mut Vec<f64>| {
        x.sort_by(f64::total_cmp);
        let m = x.len() / 2;
        if x.len().is_multiple_of(2) {
            0.5 * (x[m - 1] + x[m])
        } else {
            x[m]
        }
    };
    let mut w: Vec<f64> = v
        .iter()
        .map(|&x| if x.is_nan() { f64::INFINITY } else { x })
        .collect();
    let med = median(&mut w);
    let mut dev: Vec<f64> = w.iter().map(|x| (x - med).abs()).collect();
    let mad = median(&mut dev);
    if mad.is_finite() {
        1.4826 * mad
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Trace;
    use crate::model::presets::thesis_params;
    use crate::model::simulate;

    #[test]
    fn the_spread_counts_the_seeds_the_estimation_data_cannot_tell_apart() {
        let fit = |est_sse: f64, sel_rmse: f64| ScoredFit {
            params: vec![0.0],
            est_sse,
            sel_rmse,
        };
        // 1000 residuals: the window is 3.841·100/1000 = 0.38 above the best.
        let fits = vec![fit(100.0, 1.0), fit(100.3, 1.2), fit(100.9, 5.0)];
        let s = summarize(fits, 1000);
        assert_eq!(s.best.est_sse, 100.0);
        // 1.4826·MAD of 1.0 and 1.2; the third seed (0.9 % worse, which a
        // fixed 1 % window would count) is a different fit, not spread.
        assert!((s.spread - 1.4826 * 0.1).abs() < 1e-12, "{}", s.spread);
        assert_eq!(s.seed_sel_rmse, vec![1.0, 1.2, 5.0]);
        // Rule 1's second form reads the same seeds' lowest and highest.
        let span = RmseSpan {
            lowest: 1.0,
            highest: 1.2,
        };
        assert_eq!(s.indistinguishable, span);
    }

    #[test]
    fn a_span_of_nothing_or_of_a_diverged_fit_reaches_nothing() {
        // An empty span's highest is +∞: it beats no current model.
        let none = RmseSpan::of(&[]);
        assert_eq!((none.lowest, none.highest), (f64::INFINITY, f64::INFINITY));
        let diverged = RmseSpan::of(&[0.5, f64::NAN]);
        assert_eq!((diverged.lowest, diverged.highest), (0.5, f64::INFINITY));
    }

    /// A stair of pressures through a valve (pole 0.6) and the thesis'
    /// classic model's response (Table 1), plus 0.1 mm of seeded noise.
    fn stair_data() -> FitProblem {
        let levels = [0.05, 0.2, 0.35, 0.5, 0.3, 0.1, 0.25, 0.45, 0.15];
        let mut p = vec![levels[0]; 1080];
        for k in 1..p.len() {
            p[k] = 0.6 * p[k - 1] + 0.4 * levels[(k / 60) % levels.len()];
        }
        let theta: Vec<f32> = thesis_params(Family::Classic)
            .iter()
            .map(|&v| v as f32)
            .collect();
        let u: Vec<f32> = p.iter().map(|&v| v as f32).collect();
        let x = simulate(Family::Classic, &theta, 0.0, &u, 0.0).x;
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let noise = Normal::new(0.0, 0.1).unwrap();
        let y = x
            .iter()
            .map(|&v| v as f64 + noise.sample(&mut rng))
            .collect();
        FitProblem::diagnosis(
            &[Trace::uniform("stair", 0.1, p, y)],
            Family::Classic,
            None,
            crate::diagnose::Settings::default().blocks,
        )
        .unwrap()
    }

    #[test]
    fn only_bounded_loops_are_admitted_under_every_measure() {
        let data = stair_data();
        let bounded = thesis_params(Family::Classic);
        // β + γ < 0 with A > 0: w grows without bound.
        let mut unbounded = bounded.clone();
        unbounded[3] = -2.0 * unbounded[2];
        let rows: Vec<f64> = bounded.iter().chain(&unbounded).copied().collect();
        let rows = Rows::new(&rows, bounded.len());
        let mut cpu = crate::eval::cpu::CpuEvaluator::new();
        for measure in [Measure::FreeRun, Measure::Ahead { horizon: 5 }] {
            let costs = ModelObjective::for_problem(&mut cpu, &data)
                .costs(rows, measure)
                .unwrap();
            assert!(costs[0].is_finite(), "{measure:?}: {costs:?}");
            assert_eq!(costs[1], f32::INFINITY, "{measure:?}");
            // The batch scores what the diagnosis' own sums score.
            let own = match measure {
                Measure::Ahead { horizon } => data.est_sse_ahead(&bounded, horizon),
                Measure::FreeRun => data.est_sse(&bounded),
            };
            assert_eq!(costs[0], own as f32, "{measure:?}");
        }
        assert!(data.est_sse(&bounded).is_finite());
        assert_eq!(data.est_sse(&unbounded), f64::INFINITY);
        assert_eq!(data.est_sse_ahead(&unbounded, 5), f64::INFINITY);
        assert!(data.est_residuals(&unbounded).is_none());
        let batch = ModelObjective::for_problem(&mut cpu, &data)
            .residuals(rows, Measure::FreeRun)
            .unwrap();
        assert!(batch[0].is_some() && batch[1].is_none());
    }

    #[test]
    fn the_polish_walks_back_along_the_slow_poles_valley() {
        let data = stair_data();
        let (lo, hi) = (data.space.lower.clone(), data.space.upper.clone());
        let clamp = |p: Vec<f64>| -> Vec<f64> {
            p.iter()
                .zip(lo.iter().zip(&hi))
                .map(|(v, (l, h))| v.clamp(*l, *h))
                .collect()
        };
        // The least-squares fit nearest the generating model is the reference
        // (the data's own coordinates shift the intercept).
        let start = clamp(thesis_params(Family::Classic));
        let start_sse = data.est_sse(&start);
        let (reference, reference_sse) =
            polish(&data, &Searches::cpu(), start, start_sse, (&lo, &hi)).unwrap();
        assert!(reference_sse < start_sse);
        // One percent off in α, a needle's width across the valley.
        let mut off = reference.clone();
        off[1] *= 0.99;
        let off_sse = data.est_sse(&off);
        assert!(
            off_sse > 10.0 * reference_sse,
            "{off_sse} vs {reference_sse}"
        );
        let (back, back_sse) = polish(&data, &Searches::cpu(), off, off_sse, (&lo, &hi)).unwrap();
        assert!(
            back_sse < 1.01 * reference_sse,
            "{back_sse} vs {reference_sse}"
        );
        assert!(
            (back[1] - reference[1]).abs() < 1e-3 * reference[1],
            "α {} vs {}",
            back[1],
            reference[1]
        );
    }

    #[test]
    fn the_polish_never_leaves_a_fit_worse_than_the_search_did() {
        let data = stair_data();
        let (neutral, lo, hi) = (
            data.centre(),
            data.space.lower.clone(),
            data.space.upper.clone(),
        );
        let sse = data.est_sse(&neutral);
        let (p, polished) =
            polish(&data, &Searches::cpu(), neutral.clone(), sse, (&lo, &hi)).unwrap();
        assert!(polished <= sse);
        assert_eq!(polished, data.est_sse(&p));
        assert!(
            p.iter()
                .zip(lo.iter().zip(&hi))
                .all(|(v, (l, h))| l <= v && v <= h)
        );
    }
}
