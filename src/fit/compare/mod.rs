//! The optimizer comparison `mckibben compare` runs on one experiment: the
//! thesis' Table 21 redone, equal population budgets over many seeds, the
//! two flows, and the cross-load check of §4.10. Each part is a method of
//! [`Study`], so a caller runs the parts it wants and reports as it goes;
//! [`markdown`] writes the [`Report`] for people.

mod markdown;

use std::time::Instant;

use serde::Serialize;

use super::objective::{GENERATIONS, POPULATION, staged_plan};
use super::problem::FitProblem;
use super::run::run_fit;
use super::settings::thesis_model;
use crate::data::{Columns, Trace};
use crate::eval::Evaluator;
use crate::ident::fit_percent;
use crate::model::experiment::halves;
use crate::model::{Family, FittedBaseline, Flow};
use crate::optim::engine::{Plan, StopRules};
use crate::optim::{AlgoSettings, Algorithm};

pub use markdown::markdown;

/// The study's sizes, as `compare`'s flags set them (errors name the flags).
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// The thesis' population sizes of Table 21 (`--thesis-sizes`).
    pub thesis_sizes: Vec<usize>,
    /// Large population sizes added to Table 21; 0 is skipped (`--sizes`).
    pub sizes: Vec<usize>,
    /// Generations of Table 21 (`--gens`).
    pub gens: usize,
    /// Seeds of the equal-budget table, 0 to skip it (`--seeds`).
    pub seeds: u64,
    /// Population and generations of the equal-budget table
    /// (`--budget-pop`, `--budget-gens`).
    pub budget_pop: usize,
    pub budget_gens: usize,
    /// Largest N at which the MFA of Table 21 moves every firefly towards
    /// all brighter ones (`--mfa-all-pairs-max`).
    pub mfa_all_pairs_max: usize,
}

impl Settings {
    /// Refuses sizes some algorithm cannot search with: every algorithm runs
    /// at every size, so the largest minimum population rules.
    pub fn check(&self) -> anyhow::Result<()> {
        anyhow::ensure!(self.gens >= 1, "--gens must be at least 1");
        let (needy, min) = Algorithm::ALL
            .into_iter()
            .map(|a| (a, a.min_population()))
            .max_by_key(|&(_, m)| m)
            .expect("a registered algorithm");
        anyhow::ensure!(
            self.budget_pop >= min,
            "--budget-pop must be at least {min} ({needy} needs {min}; got {})",
            self.budget_pop
        );
        anyhow::ensure!(self.budget_gens >= 1, "--budget-gens must be at least 1");
        // The budget table's seeds are 1 to --seeds, each a seed of its own.
        anyhow::ensure!(
            self.seeds <= crate::optim::streams::MAX_SEED,
            "--seeds {}: at most {}, the largest seed",
            self.seeds,
            crate::optim::streams::MAX_SEED
        );
        if let Some(n) = self.table21_sizes().find(|&n| n < min) {
            anyhow::bail!(
                "--thesis-sizes and --sizes must be at least {min} ({needy} needs {min}), got {n}"
            );
        }
        Ok(())
    }

    /// The population sizes of Table 21, the thesis' first.
    fn table21_sizes(&self) -> impl Iterator<Item = usize> + '_ {
        self.thesis_sizes
            .iter()
            .chain(&self.sizes)
            .copied()
            .filter(|&n| n != 0)
    }
}

/// One fit: a row of Table 21, or one seed of an equal-budget variant.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub model: Family,
    pub algo: String,
    pub population: usize,
    pub generations: usize,
    pub evaluations: u64,
    pub seconds: f64,
    pub seconds_per_generation: f64,
    pub sse: Option<f64>,
    pub val_fit_percent: Option<f64>,
}

/// A variant of the equal-budget table over its seeds. A seed whose fit
/// diverged counts as the worst of each spread, so a method that diverges
/// often is not lifted by leaving its failures out.
#[derive(Debug, Clone, Serialize)]
pub struct Spread {
    pub model: Family,
    pub variant: String,
    pub seeds: u64,
    /// Seeds whose fit diverged (no finite SSE or validation fit).
    pub diverged: u64,
    /// Simulations per seed, the mean over the seeds (a staged fit's
    /// polish stops when it stops gaining, so the seeds differ).
    pub evaluations: u64,
    pub sse_median: Option<f64>,
    pub sse_min: Option<f64>,
    pub sse_max: Option<f64>,
    pub fit_median: Option<f64>,
    pub fit_min: Option<f64>,
    pub fit_max: Option<f64>,
}

/// The staged fit in one flow.
#[derive(Debug, Clone, Serialize)]
pub struct FlowRow {
    pub model: Family,
    pub flow: Flow,
    pub sse: Option<f64>,
    pub val_fit_percent: Option<f64>,
    pub val_rmse: Option<f64>,
}

/// A model fitted on one experiment, scored on another (or its own).
#[derive(Debug, Clone, Serialize)]
pub struct CrossRow {
    pub model: Family,
    pub fitted_on: String,
    pub scored_on: String,
    pub fit_percent: Option<f64>,
}

/// The whole study (`compare.json`).
#[derive(Debug, Serialize)]
pub struct Report {
    pub data: String,
    /// The record's input and output columns and their units: what the
    /// SSEs (output unit squared) and RMSEs are in.
    pub columns: Columns,
    pub backend: String,
    pub table21: Vec<Row>,
    pub budget: Vec<Spread>,
    pub flows: Vec<FlowRow>,
    pub cross_load: Vec<CrossRow>,
}

/// What the flows part hands on to the cross-load check.
pub struct Flows {
    pub rows: Vec<FlowRow>,
    /// The joint flow's models, one per family of the study.
    pub joint: Vec<FittedBaseline>,
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// The model families every part compares.
const MODELS: [Family; 2] = [Family::Classic, Family::Generalized];

/// A row of the equal-budget table: one search on the free run with these
/// settings, as the thesis does, or the staged fit with this algorithm.
enum Variant {
    Thesis(AlgoSettings),
    Staged(Algorithm),
}

/// Fits on one evaluator.
struct Fitter<'a> {
    evaluator: &'a mut dyn Evaluator,
}

impl Fitter<'_> {
    /// One fit of `problem` with `plan`, seeded by `seed`.
    fn run(
        &mut self,
        problem: &FitProblem,
        plan: Plan,
        algo: &str,
        seed: u64,
    ) -> anyhow::Result<(Row, Vec<f64>)> {
        let population = plan.global.as_ref().map_or(0, |g| g.population);
        let t = Instant::now();
        let (_, out) = run_fit(problem, plan, seed, StopRules::default(), self.evaluator)?;
        let seconds = t.elapsed().as_secs_f64();
        let val = problem.validate(&out.params);
        Ok((
            Row {
                model: problem.model.family,
                algo: algo.into(),
                population,
                generations: out.generations,
                evaluations: out.evaluations,
                seconds,
                seconds_per_generation: seconds / out.generations.max(1) as f64,
                sse: finite(out.sse),
                val_fit_percent: finite(val.fit_percent),
            },
            out.params,
        ))
    }

    /// The thesis' flow: one search with `settings` on the free run.
    fn thesis(
        &mut self,
        problem: &FitProblem,
        settings: &AlgoSettings,
        n: usize,
        g: usize,
        seed: u64,
    ) -> anyhow::Result<(Row, Vec<f64>)> {
        let plan = Plan::thesis(settings.clone(), n, g);
        self.run(problem, plan, settings.algorithm().name(), seed)
    }

    /// The staged fit of `mckibben fit` with `algo`.
    fn staged(
        &mut self,
        problem: &FitProblem,
        algo: Algorithm,
        n: usize,
        g: usize,
        seed: u64,
    ) -> anyhow::Result<(Row, Vec<f64>)> {
        let plan = staged_plan(problem, algo.staged_settings(n), n, g);
        self.run(problem, plan, algo.name(), seed)
    }
}

/// The median, least and largest of `v`, where a diverged run is an
/// infinity on its worse side (`+∞` for an SSE, `−∞` for a fit %): it
/// takes its place in the order, and a statistic that lands on it is
/// `None`, diverged.
fn median_min_max(mut v: Vec<f64>) -> (Option<f64>, Option<f64>, Option<f64>) {
    if v.is_empty() {
        return (None, None, None);
    }
    v.sort_by(f64::total_cmp);
    let m = v.len();
    let median = if m % 2 == 1 {
        v[m / 2]
    } else {
        0.5 * (v[m / 2 - 1] + v[m / 2])
    };
    (finite(median), finite(v[0]), finite(v[m - 1]))
}

/// The study on one experiment.
pub struct Study<'a> {
    settings: &'a Settings,
    trace: &'a Trace,
    /// The joint flow's problem of each of [`MODELS`].
    problems: Vec<FitProblem>,
    fitter: Fitter<'a>,
}

impl<'a> Study<'a> {
    /// The study of `trace` with `settings` (checked by [`Settings::check`]),
    /// fitting on `evaluator`.
    pub fn new(
        trace: &'a Trace,
        settings: &'a Settings,
        evaluator: &'a mut dyn Evaluator,
    ) -> anyhow::Result<Study<'a>> {
        let problems = MODELS
            .iter()
            .map(|&f| FitProblem::new(trace, f, Flow::Joint, None, false))
            .collect::<anyhow::Result<_>>()?;
        Ok(Study {
            settings,
            trace,
            problems,
            fitter: Fitter { evaluator },
        })
    }

    /// The thesis' Table 21: every algorithm with its thesis settings ×
    /// both models × every size, G = `gens`, seed 1. Above
    /// `mfa_all_pairs_max` fireflies the MFA moves towards the brightest
    /// only (marked `mfa*`).
    pub fn table21(&mut self, progress: &dyn Fn(String)) -> anyhow::Result<Vec<Row>> {
        let settings = self.settings;
        let mut rows = Vec::new();
        for n in settings.table21_sizes() {
            for problem in &self.problems {
                for algo in Algorithm::ALL {
                    let mut s = algo.thesis_settings(thesis_model(problem.model.family));
                    let mut capped = false;
                    if let AlgoSettings::Mfa(m) = &mut s
                        && n > settings.mfa_all_pairs_max
                    {
                        m.towards_brightest();
                        capped = true;
                    }
                    progress(format!("table 21: {} {algo} N = {n}", problem.model.family));
                    let (mut row, _) = self.fitter.thesis(problem, &s, n, settings.gens, 1)?;
                    if capped {
                        row.algo = "mfa*".into();
                    }
                    rows.push(row);
                }
            }
        }
        Ok(rows)
    }

    /// Equal population budgets (`budget_pop` × `budget_gens`) over seeds
    /// 1..=`seeds`: the thesis-faithful GA, MFA and PSO, the documented fixes
    /// of GA and MFA and DE, each one search on the free run as the thesis
    /// does; then the staged fit with each update rule. None with 0 seeds.
    pub fn budget(&mut self, progress: &dyn Fn(String)) -> anyhow::Result<Vec<Spread>> {
        let settings = self.settings;
        let (n, g, seeds) = (settings.budget_pop, settings.budget_gens, settings.seeds);
        let mut out = Vec::new();
        if seeds == 0 {
            return Ok(out);
        }
        for problem in &self.problems {
            let thesis = |algo: Algorithm| {
                Variant::Thesis(algo.thesis_settings(thesis_model(problem.model.family)))
            };
            // The documented fixes (docs/RESULTS.md) are the staged fit's
            // settings: GA with 10 % elitism, uniform mutation, P_mut 0.3;
            // MFA towards the 10 brightest, r², box units.
            let fixed = |algo: Algorithm| Variant::Thesis(algo.staged_settings(n));
            let mut variants = vec![
                (
                    "ga (thesis, proportional)".to_string(),
                    thesis(Algorithm::Ga),
                ),
                ("ga (fixed)".into(), fixed(Algorithm::Ga)),
                ("mfa (thesis)".into(), thesis(Algorithm::Mfa)),
                ("mfa (fixed)".into(), fixed(Algorithm::Mfa)),
                ("pso (thesis)".into(), thesis(Algorithm::Pso)),
                ("de (baseline)".into(), thesis(Algorithm::De)),
            ];
            variants.extend(
                Algorithm::ALL.map(|algo| (format!("staged fit, {algo}"), Variant::Staged(algo))),
            );
            for (name, variant) in variants {
                progress(format!(
                    "budget: {} {name}, {seeds} seeds",
                    problem.model.family
                ));
                let mut sse = Vec::new();
                let mut fit = Vec::new();
                let (mut evaluations, mut diverged) = (0, 0);
                for seed in 1..=seeds {
                    let (row, _) = match &variant {
                        Variant::Thesis(s) => self.fitter.thesis(problem, s, n, g, seed)?,
                        Variant::Staged(algo) => self.fitter.staged(problem, *algo, n, g, seed)?,
                    };
                    sse.push(row.sse.unwrap_or(f64::INFINITY));
                    fit.push(row.val_fit_percent.unwrap_or(f64::NEG_INFINITY));
                    diverged += u64::from(row.sse.is_none() || row.val_fit_percent.is_none());
                    evaluations += row.evaluations;
                }
                let (sse_median, sse_min, sse_max) = median_min_max(sse);
                let (fit_median, fit_min, fit_max) = median_min_max(fit);
                out.push(Spread {
                    model: problem.model.family,
                    variant: name,
                    seeds,
                    diverged,
                    evaluations: (evaluations as f64 / seeds.max(1) as f64).round() as u64,
                    sse_median,
                    sse_min,
                    sse_max,
                    fit_median,
                    fit_min,
                    fit_max,
                });
            }
        }
        Ok(out)
    }

    /// The joint flow (a, b, c, x0 fitted) against the thesis' flow (a, b at
    /// the ARX estimate, no intercept), both with the default staged fit
    /// (DE, N = [`POPULATION`], G = [`GENERATIONS`], seed 1).
    pub fn flows(&mut self, progress: &dyn Fn(String)) -> anyhow::Result<Flows> {
        let (n, g) = (POPULATION, GENERATIONS);
        let mut rows = Vec::new();
        let mut joint = Vec::new();
        for problem in &self.problems {
            for flow in [Flow::Joint, Flow::Thesis] {
                let t = FitProblem::new(self.trace, problem.model.family, flow, None, false)?;
                progress(format!("flows: {} {flow:?}", problem.model.family));
                let (row, params) = self.fitter.staged(&t, Algorithm::De, n, g, 1)?;
                let val = t.validate(&params);
                rows.push(FlowRow {
                    model: t.model.family,
                    flow,
                    sse: row.sse,
                    val_fit_percent: row.val_fit_percent,
                    val_rmse: finite(val.rmse),
                });
                if flow == Flow::Joint {
                    joint.push(t.fitted_model(&params).base);
                }
            }
        }
        Ok(Flows { rows, joint })
    }

    /// The cross-load check (§4.10): the joint flow's models of [`flows`]
    /// scored on `other`, the models fitted on `other` (default staged
    /// fit) scored here, and each on its own data; fit % of the free run
    /// from the record's first sample, on its second half.
    ///
    /// [`flows`]: Study::flows
    pub fn cross_load(
        &mut self,
        other: &Trace,
        flows: &Flows,
        progress: &dyn Fn(String),
    ) -> anyhow::Result<Vec<CrossRow>> {
        let (n, g) = (POPULATION, GENERATIONS);
        // On the second half, as a fit validates: the record a model was
        // fitted on is scored where its fit did not look.
        let score = |m: &FittedBaseline, on: &Trace| {
            let from = halves(on.len()).1.start;
            finite(fit_percent(
                &on.output[from..],
                &m.simulate_trace(on)[from..],
            ))
        };
        let problems: Vec<FitProblem> = MODELS
            .iter()
            .map(|&f| FitProblem::new(other, f, Flow::Joint, None, false))
            .collect::<anyhow::Result<_>>()?;
        let mut out = Vec::new();
        for (problem, here) in problems.iter().zip(&flows.joint) {
            let family = problem.model.family;
            progress(format!("cross-load: {family}"));
            let (_, params) = self.fitter.staged(problem, Algorithm::De, n, g, 1)?;
            let back = problem.fitted_model(&params).base;
            for (model, from, on) in [
                (here, self.trace, other),
                (&back, other, self.trace),
                (here, self.trace, self.trace),
                (&back, other, other),
            ] {
                out.push(CrossRow {
                    model: family,
                    fitted_on: from.source.clone(),
                    scored_on: on.source.clone(),
                    fit_percent: score(model, on),
                });
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optim::mfa;

    /// A diverged seed is the worst of its spread: it moves the median
    /// (2.5 of the four that ran would have read better than the 3 of all
    /// five), and the worst is `None`, diverged.
    #[test]
    fn spreads_count_diverged_runs_as_the_worst() {
        let inf = f64::INFINITY;
        assert_eq!(
            median_min_max(vec![3.0, inf, 1.0, 2.0, 10.0]),
            (Some(3.0), Some(1.0), None)
        );
        assert_eq!(
            median_min_max(vec![90.0, -inf, 80.0, -inf, -inf]),
            (None, None, Some(90.0))
        );
        assert_eq!(median_min_max(vec![inf]), (None, None, None));
    }

    #[test]
    fn sizes_below_an_algorithms_minimum_name_the_flag() {
        let settings = Settings {
            thesis_sizes: vec![10],
            sizes: vec![0, 2],
            gens: 1,
            seeds: 0,
            budget_pop: 10,
            budget_gens: 1,
            mfa_all_pairs_max: mfa::ALL_PAIRS_MAX,
        };
        let e = settings.check().unwrap_err().to_string();
        assert!(e.starts_with("--thesis-sizes and --sizes"), "{e}");
        assert_eq!(settings.table21_sizes().collect::<Vec<_>>(), [10, 2]);
    }
}
