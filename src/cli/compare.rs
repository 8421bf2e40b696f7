//! `mckibben compare`: the thesis' Table 21 redone, what large populations
//! buy, the thesis' methods against the baseline at equal budgets over many
//! seeds, the two flows, and the cross-load check of §4.10.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use serde::Serialize;

use super::common::{ColumnArgs, DataArgs, one_trace};
use mckibben::data::{Trace, write_atomic};
use mckibben::eval::{self, Backend, Evaluator};
use mckibben::ident::fit_percent;
use mckibben::model::{Family, Flow};
use mckibben::optim::engine::model::{GENERATIONS, POPULATION, fit_task, staged_plan};
use mckibben::optim::engine::{Plan, StopRules};
use mckibben::optim::mfa::ALL_PAIRS_MAX as MFA_ALL_PAIRS_MAX;
use mckibben::optim::mfa::Attractors;
use mckibben::optim::task::Task;
use mckibben::optim::{AlgoSettings, Algorithm};

/// Compare the optimizers on one experiment (the shipped 4.5 kg stair by
/// default), as Markdown tables (and JSON with --json):
///
/// 1. the thesis' Table 21: every algorithm × both models × N = 10, 20, 30
///    at G = 30, with total and per-generation time, final SSE and
///    validation fit %; then the same at N = 1e3, 1e4, 1e5 (--sizes);
/// 2. equal population budgets over --seeds seeds (median, min, max): the
///    thesis-faithful GA, MFA, PSO, the documented fixes of GA and MFA, and
///    differential evolution, each one search on the free run as the thesis
///    does; then the staged fit of `mckibben fit` with each update rule;
/// 3. the joint flow (a, b, c, x0 fitted; staged fit) against the thesis'
///    flow (a, b at the ARX estimate, no intercept; same staged fit);
/// 4. the cross-load check (§4.10): fitted on this data with the default
///    staged fit, scored on --cross (default: data/stair_7kg.csv beside the
///    default data), and back.
///
/// The MFA's all-pairs move costs O(N²·d) per generation; above
/// --mfa-all-pairs-max fireflies it moves towards the 10 brightest only
/// (marked `mfa*`).
///
/// Example: mckibben compare --sizes 1000,10000 --seeds 10
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    #[command(flatten)]
    data: DataArgs,
    /// The thesis' population sizes (Table 21).
    #[arg(long, value_delimiter = ',', default_value = "10,20,30")]
    thesis_sizes: Vec<usize>,
    /// Large population sizes to add to Table 21 (`--sizes 0`: none).
    #[arg(long, value_delimiter = ',', default_value = "1000,10000,100000")]
    sizes: Vec<usize>,
    /// Generations for Table 21 (the thesis used 30).
    #[arg(long, default_value_t = 30)]
    gens: usize,
    /// Seeds for the equal-budget table (0: skip it).
    #[arg(long, default_value_t = 10)]
    seeds: u64,
    /// Population and generations of the equal-budget table.
    #[arg(long, default_value_t = 500)]
    budget_pop: usize,
    #[arg(long, default_value_t = 100)]
    budget_gens: usize,
    /// Largest N at which the MFA moves every firefly towards all brighter ones.
    #[arg(long, default_value_t = MFA_ALL_PAIRS_MAX)]
    mfa_all_pairs_max: usize,
    /// Second experiment for the cross-load check.
    #[arg(long, value_name = "FILE")]
    cross: Option<PathBuf>,
    /// Where populations are scored (see `fit --help`).
    #[arg(long, value_enum, default_value = "auto")]
    backend: Backend,
    /// Folder for compare.md and compare.json.
    #[arg(long, value_name = "DIR", default_value = "out/compare")]
    out: PathBuf,
    /// Print JSON on stdout instead of Markdown.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Clone, Serialize)]
struct Row {
    model: Family,
    algo: String,
    population: usize,
    generations: usize,
    evaluations: u64,
    seconds: f64,
    seconds_per_generation: f64,
    sse: Option<f64>,
    val_fit_percent: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
struct Spread {
    model: Family,
    variant: String,
    seeds: u64,
    evaluations: u64,
    sse_median: Option<f64>,
    sse_min: Option<f64>,
    sse_max: Option<f64>,
    fit_median: Option<f64>,
    fit_min: Option<f64>,
    fit_max: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
struct FlowRow {
    model: Family,
    flow: Flow,
    sse: Option<f64>,
    val_fit_percent: Option<f64>,
    val_rmse: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
struct CrossRow {
    model: Family,
    fitted_on: String,
    scored_on: String,
    fit_percent: Option<f64>,
}

#[derive(Debug, Serialize)]
struct Report {
    data: String,
    backend: String,
    table21: Vec<Row>,
    budget: Vec<Spread>,
    flows: Vec<FlowRow>,
    cross_load: Vec<CrossRow>,
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// A row of the equal-budget table: one search on the free run with these
/// settings, as the thesis does, or the staged fit with this algorithm.
enum Variant {
    Thesis(AlgoSettings),
    Staged(Algorithm),
}

struct Fitter<'a> {
    evaluator: &'a mut dyn Evaluator,
}

impl Fitter<'_> {
    /// One fit of `task` with `plan`, seeded by `seed`.
    fn run(
        &mut self,
        task: &Task,
        plan: Plan,
        algo: &str,
        seed: u64,
    ) -> anyhow::Result<(Row, Vec<f64>)> {
        let population = plan.global.as_ref().map_or(0, |g| g.population);
        let t = Instant::now();
        let (_, out) = fit_task(task, plan, seed, StopRules::default(), self.evaluator)?;
        let seconds = t.elapsed().as_secs_f64();
        let val = task.validate(&out.params);
        Ok((
            Row {
                model: task.family,
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
        task: &Task,
        settings: &AlgoSettings,
        n: usize,
        g: usize,
        seed: u64,
    ) -> anyhow::Result<(Row, Vec<f64>)> {
        self.run(
            task,
            Plan::thesis(settings.clone(), n, g),
            settings.algorithm().name(),
            seed,
        )
    }

    /// The staged fit of `mckibben fit` with `algo`.
    fn staged(
        &mut self,
        task: &Task,
        algo: Algorithm,
        n: usize,
        g: usize,
        seed: u64,
    ) -> anyhow::Result<(Row, Vec<f64>)> {
        let plan = staged_plan(task, algo.staged_settings(n), n, g);
        self.run(task, plan, algo.name(), seed)
    }
}

fn median_min_max(mut v: Vec<f64>) -> (Option<f64>, Option<f64>, Option<f64>) {
    v.retain(|x| x.is_finite());
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
    (Some(median), Some(v[0]), Some(v[m - 1]))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.gens >= 1, "--gens must be at least 1");
    // Every algorithm runs at every size: the largest minimum rules.
    let (needy, min) = Algorithm::ALL
        .into_iter()
        .map(|a| (a, a.min_population()))
        .max_by_key(|&(_, m)| m)
        .expect("a registered algorithm");
    anyhow::ensure!(
        args.budget_pop >= min,
        "--budget-pop must be at least {min} ({needy} needs {min}; got {})",
        args.budget_pop
    );
    anyhow::ensure!(args.budget_gens >= 1, "--budget-gens must be at least 1");
    let sizes: Vec<usize> = args
        .thesis_sizes
        .iter()
        .chain(&args.sizes)
        .copied()
        .filter(|&n| n != 0)
        .collect();
    if let Some(&n) = sizes.iter().find(|&&n| n < min) {
        anyhow::bail!(
            "--thesis-sizes and --sizes must be at least {min} ({needy} needs {min}), got {n}"
        );
    }
    let trace = one_trace(args.data.load()?)?;
    let mut evaluator = eval::open(args.backend)?;
    let backend = evaluator.describe();
    eprintln!("comparing on {} [{backend}]", trace.source);
    let mut fitter = Fitter {
        evaluator: evaluator.as_mut(),
    };
    let models = [Family::Classic, Family::Generalized];
    let tasks: Vec<Task> = models
        .iter()
        .map(|&f| Task::new(&trace, f, Flow::Joint, None, false))
        .collect::<anyhow::Result<_>>()?;

    let mut table21 = Vec::new();
    for &n in &sizes {
        for task in &tasks {
            for algo in Algorithm::ALL {
                let mut s = algo.thesis_settings(task.family);
                let mut capped = false;
                if let AlgoSettings::Mfa(mfa) = &mut s
                    && n > args.mfa_all_pairs_max
                {
                    mfa.max_attractors = Some(10);
                    mfa.attractors = Attractors::Brightest;
                    capped = true;
                }
                eprintln!("table 21: {} {algo} N = {n}", task.family);
                let (mut row, _) = fitter.thesis(task, &s, n, args.gens, 1)?;
                if capped {
                    row.algo = "mfa*".into();
                }
                table21.push(row);
            }
        }
    }

    let mut budget = Vec::new();
    if args.seeds > 0 {
        let (n, g) = (args.budget_pop, args.budget_gens);
        for task in &tasks {
            let thesis = |algo: Algorithm| Variant::Thesis(algo.thesis_settings(task.family));
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
                eprintln!("budget: {} {name}, {} seeds", task.family, args.seeds);
                let mut sse = Vec::new();
                let mut fit = Vec::new();
                let mut evaluations = 0;
                for seed in 1..=args.seeds {
                    let (row, _) = match &variant {
                        Variant::Thesis(s) => fitter.thesis(task, s, n, g, seed)?,
                        Variant::Staged(algo) => fitter.staged(task, *algo, n, g, seed)?,
                    };
                    sse.push(row.sse.unwrap_or(f64::INFINITY));
                    fit.push(row.val_fit_percent.unwrap_or(f64::NEG_INFINITY));
                    evaluations = row.evaluations;
                }
                let (sse_median, sse_min, sse_max) = median_min_max(sse);
                let (fit_median, fit_min, fit_max) = median_min_max(fit);
                budget.push(Spread {
                    model: task.family,
                    variant: name,
                    seeds: args.seeds,
                    evaluations,
                    sse_median,
                    sse_min,
                    sse_max,
                    fit_median,
                    fit_min,
                    fit_max,
                });
            }
        }
    }

    // The flows and the cross-load check use the default fit.
    let (n, g) = (POPULATION, GENERATIONS);
    let mut flows = Vec::new();
    let mut fitted = Vec::new();
    for task in &tasks {
        for flow in [Flow::Joint, Flow::Thesis] {
            let t = Task::new(&trace, task.family, flow, None, false)?;
            eprintln!("flows: {} {flow:?}", task.family);
            let (row, params) = fitter.staged(&t, Algorithm::De, n, g, 1)?;
            let val = t.validate(&params);
            flows.push(FlowRow {
                model: t.family,
                flow,
                sse: row.sse,
                val_fit_percent: row.val_fit_percent,
                val_rmse: finite(val.rmse),
            });
            if flow == Flow::Joint {
                fitted.push(t.model(&params));
            }
        }
    }

    let mut cross_load = Vec::new();
    if let Some(other) = cross_trace(&args)? {
        let other_tasks: Vec<Task> = models
            .iter()
            .map(|&f| Task::new(&other, f, Flow::Joint, None, false))
            .collect::<anyhow::Result<_>>()?;
        for (k, task) in other_tasks.iter().enumerate() {
            eprintln!("cross-load: {}", task.family);
            let (_, params) = fitter.staged(task, Algorithm::De, n, g, 1)?;
            let back = task.model(&params);
            let score = |m: &mckibben::model::FittedModel, on: &Trace| {
                finite(fit_percent(&on.output, &m.simulate_trace(on)))
            };
            for (model, from, on) in [
                (&fitted[k], &trace, &other),
                (&back, &other, &trace),
                (&fitted[k], &trace, &trace),
                (&back, &other, &other),
            ] {
                cross_load.push(CrossRow {
                    model: task.family,
                    fitted_on: from.source.clone(),
                    scored_on: on.source.clone(),
                    fit_percent: score(model, on),
                });
            }
        }
    }

    let report = Report {
        data: trace.source.clone(),
        backend,
        table21,
        budget,
        flows,
        cross_load,
    };
    let md = markdown(&report, &args);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create --out {}", args.out.display()))?;
    let json = serde_json::to_string_pretty(&report)?;
    write_atomic(&args.out.join("compare.json"), json.as_bytes())
        .with_context(|| format!("cannot write into {}", args.out.display()))?;
    write_atomic(&args.out.join("compare.md"), md.as_bytes())
        .with_context(|| format!("cannot write into {}", args.out.display()))?;
    if args.json {
        println!("{json}");
    } else {
        print!("{md}");
    }
    Ok(())
}

/// The second experiment: --cross, or the 7 kg stair beside the default data.
fn cross_trace(args: &Args) -> anyhow::Result<Option<Trace>> {
    let path = match (&args.cross, &args.data.data) {
        (Some(p), _) => p.clone(),
        (None, None) => {
            let default = super::common::default_data()?;
            let sibling = default.with_file_name("stair_7kg.csv");
            if !sibling.is_file() {
                eprintln!(
                    "mckibben: note: no {} for the cross-load check",
                    sibling.display()
                );
                return Ok(None);
            }
            sibling
        }
        (None, Some(_)) => return Ok(None),
    };
    let cols: &ColumnArgs = &args.data.columns;
    let other = DataArgs {
        data: Some(path),
        columns: cols.clone(),
    };
    Ok(Some(one_trace(other.load()?)?))
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("diverged".into(), |v| format!("{v:.digits$}"))
}

fn markdown(r: &Report, args: &Args) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Optimizer comparison on {} [{}]\n", r.data, r.backend);
    if !r.table21.is_empty() {
        let _ = writeln!(
            s,
            "## Table 21 redone (G = {}, seed 1, thesis settings; `mfa*`: 10 brightest attractors above N = {})\n",
            args.gens, args.mfa_all_pairs_max
        );
        let _ = writeln!(
            s,
            "| N | algorithm | model | total (s) | per generation (s) | SSE (estimation) | validation fit % |\n|---:|---|---|---:|---:|---:|---:|"
        );
        for row in &r.table21 {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.3} | {:.4} | {} | {} |",
                row.population,
                row.algo,
                row.model,
                row.seconds,
                row.seconds_per_generation,
                opt(row.sse, 3),
                opt(row.val_fit_percent, 2)
            );
        }
    }
    if !r.budget.is_empty() {
        let _ = writeln!(
            s,
            "\n## Equal population budgets (N = {}, G = {}), seeds 1..={}: median [min, max]\n\nThe staged fits add a free-run stage (N/5 for G/4) and a polish to the same global stage.\n",
            args.budget_pop, args.budget_gens, args.seeds
        );
        let _ = writeln!(
            s,
            "| model | variant | evaluations | SSE | validation fit % |\n|---|---|---:|---|---|"
        );
        for b in &r.budget {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} [{}, {}] | {} [{}, {}] |",
                b.model,
                b.variant,
                b.evaluations,
                opt(b.sse_median, 3),
                opt(b.sse_min, 3),
                opt(b.sse_max, 3),
                opt(b.fit_median, 2),
                opt(b.fit_min, 2),
                opt(b.fit_max, 2)
            );
        }
    }
    let _ = writeln!(
        s,
        "\n## Flows (staged fit, DE, N = {POPULATION}, G = {GENERATIONS}, seed 1)\n\n| model | flow | SSE | validation fit % | validation RMSE |\n|---|---|---:|---:|---:|"
    );
    for f in &r.flows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} |",
            f.model,
            match f.flow {
                Flow::Joint => "joint (a, b, c, x0 fitted)",
                Flow::Thesis => "thesis (a, b = ARX, c = 0)",
            },
            opt(f.sse, 3),
            opt(f.val_fit_percent, 2),
            opt(f.val_rmse, 4)
        );
    }
    if !r.cross_load.is_empty() {
        let _ = writeln!(
            s,
            "\n## Cross-load check (§4.10; staged fit, DE, joint flow; fit % over the whole trace)\n\n| model | fitted on | scored on | fit % |\n|---|---|---|---:|"
        );
        for c in &r.cross_load {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} |",
                c.model,
                c.fitted_on,
                c.scored_on,
                opt(c.fit_percent, 2)
            );
        }
    }
    s
}
