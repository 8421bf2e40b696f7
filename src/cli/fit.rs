//! `mckibben fit`: identify a hysteresis model's parameters with one of the
//! thesis' optimizers (GA, MFA, PSO) or the differential-evolution baseline.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context;
use serde::Serialize;

use super::common::DataArgs;
use mckibben::data::{Trace, write_atomic};
use mckibben::eval::{self, Backend};
use mckibben::model::{Family, Flow, simulate};
use mckibben::optim::ga::{Crossover, Mutation};
use mckibben::optim::history::GenerationRecord;
use mckibben::optim::mfa::{Attractors, Distance, Lambda0Schedule, Scale};
use mckibben::optim::pso::PsoSettings;
use mckibben::optim::task::Task;
use mckibben::optim::{AlgoSettings, Algorithm, Observer, RunOutcome, RunSettings, Runner};
use mckibben::report::{Figure, Panel, Series};

/// Fit a Bouc-Wen hysteresis model (eq. 13 with the classic or generalized
/// state) to a recorded experiment. The first half of the data is used for
/// estimation, the second half for validation, as in the thesis (§4.3.1).
///
/// By default `a`, `b` and the intercept `c` are fitted together with the
/// hysteresis parameters (least squares on hysteretic data does not return
/// the hysteretic model's `a`, `b`, and removing means leaves an offset);
/// `--thesis-flow` fixes `a`, `b` at the ARX estimate with no intercept.
///
/// Default: differential evolution, N = 4000, G = 200 (8e5 evaluations, about
/// 2 s on two CPU cores for the shipped 4000-sample stair). Larger budgets
/// still lower the SSE a little there (docs/RESULTS.md); raise --pop and
/// --gens when time allows.
///
/// Writes to --out: model.json (read by `simulate`), result.json,
/// history.csv / history.json (best SSE, best parameters, mean and spread
/// of the population, diverged count per generation), and figures:
/// trends.svg (parameters over generations, the thesis' figs 9–24),
/// convergence.svg, loop.svg (displacement against pressure, fitted over
/// measured) and trace.svg. Ctrl-C stops after the current generation and
/// still writes the best so far.
///
/// Examples:
///   mckibben fit
///   mckibben fit run.csv --model generalized --algo pso --pop 10000 --gens 200
///   mckibben fit --algo ga --crossover weighted --thesis-flow --pop 30 --gens 30
///   mckibben fit --checkpoint fit.ckpt.json   # resumes if the file exists
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    #[command(flatten)]
    data: DataArgs,
    /// Hysteresis model: classic (A, α, β, γ) or generalized (A, α, β1..β6).
    #[arg(long, value_enum, default_value = "classic")]
    model: ModelArg,
    /// Optimizer: ga, mfa, pso (the thesis') or de (baseline).
    #[arg(long, value_enum, default_value = "de")]
    algo: Algorithm,
    /// Population size N (the thesis used 10–30).
    #[arg(long, default_value_t = DEFAULT_POP)]
    pop: usize,
    /// Generations G (the thesis used 30).
    #[arg(long, default_value_t = DEFAULT_GENS)]
    gens: usize,
    /// Seed of the run's random generator: same seed, same result.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Where populations are scored: auto (a hardware GPU if present, else
    /// the CPU), cpu, or gpu (any adapter, lavapipe included).
    #[arg(long, value_enum, default_value = "auto")]
    backend: Backend,
    /// GA crossover (§5.2.1.5).
    #[arg(long, value_enum, default_value = "proportional")]
    crossover: Crossover,
    /// The thesis' flow: a and b fixed at the ARX estimate, no intercept.
    #[arg(long)]
    thesis_flow: bool,
    /// Also fit the Bouc-Wen exponent n in [1, 3] (fixed at 1 in the thesis).
    #[arg(long)]
    free_n: bool,
    /// Stop once the estimation SSE is at or below this.
    #[arg(long, value_name = "SSE")]
    target_sse: Option<f64>,
    /// Stop after this many seconds (the result then depends on the machine).
    #[arg(long, value_name = "SECONDS")]
    time_budget: Option<f64>,
    /// Stop when the best SSE has not improved for this many generations.
    #[arg(long, value_name = "GENS")]
    stall: Option<usize>,
    /// GA: best individuals kept unchanged (0 in the thesis).
    #[arg(long, default_value_t = 0)]
    elitism: usize,
    /// GA: mutation probability P_mut (thesis 0.1).
    #[arg(long, default_value_t = 0.1)]
    p_mut: f64,
    /// GA: fixed ±m_m mutation (thesis), uniform in [−m_m, m_m], or
    /// non-uniform (Michalewicz: towards a bound, reach shrinking from the
    /// whole box to 0 over the generations; fits the generalized model with
    /// --elitism N/50 --p-mut 0.3, docs/RESULTS.md).
    #[arg(long, value_enum, default_value = "fixed")]
    mutation: Mutation,
    /// MFA: Λ0 schedule from a to b (appendix code) or to a − b (eq. 36).
    #[arg(long, value_enum, default_value = "code")]
    mfa_lambda0: Lambda0Schedule,
    /// MFA: attractiveness e^(−σr) (code) or e^(−σr²) (eq. 32).
    #[arg(long, value_enum, default_value = "linear")]
    mfa_distance: Distance,
    /// MFA: distances and walk in raw units (thesis) or box widths.
    #[arg(long, value_enum, default_value = "raw")]
    mfa_scale: Scale,
    /// MFA: move towards at most K brighter fireflies (all in the thesis;
    /// the all-pairs move costs O(N²·d) per generation).
    #[arg(long, value_name = "K")]
    mfa_attractors: Option<usize>,
    /// MFA: with --mfa-attractors, the K brightest instead of K at random.
    #[arg(long)]
    mfa_brightest: bool,
    /// MFA: start ρ0 of the random walk ρ(k) = ρ0·e^(−4.8k/G) (eq. 38:
    /// 0.1). 0.2 with --mfa-attractors 3 --mfa-brightest --mfa-distance
    /// squared --mfa-scale box fits the generalized model (docs/RESULTS.md).
    #[arg(long, default_value_t = 0.1, value_name = "RHO0")]
    mfa_rho0: f64,
    /// DE: share of the population x_pbest is drawn from (0.1; smaller is
    /// greedier, see docs/RESULTS.md).
    #[arg(long, default_value_t = 0.1)]
    de_p_best: f64,
    /// PSO: one random number for the social term (appendix code).
    #[arg(long)]
    pso_scalar_social: bool,
    /// Save the run state to FILE every 10 s and at the end; if FILE exists,
    /// resume from it to the identical result (N, G, seed and algorithm
    /// settings come from the checkpoint, stopping rules from this command).
    #[arg(long, value_name = "FILE")]
    checkpoint: Option<PathBuf>,
    /// Folder for the model, history and figures.
    #[arg(long, value_name = "DIR", default_value = "out/fit")]
    out: PathBuf,
    /// Print JSON on stdout instead of a report.
    #[arg(long)]
    json: bool,
}

/// Default population and generations of `fit` (and of the flow and
/// cross-load fits of `compare`).
pub const DEFAULT_POP: usize = 4000;
pub const DEFAULT_GENS: usize = 200;

/// The hysteretic families `fit` can fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ModelArg {
    Classic,
    Generalized,
}

impl From<ModelArg> for Family {
    fn from(m: ModelArg) -> Family {
        match m {
            ModelArg::Classic => Family::Classic,
            ModelArg::Generalized => Family::Generalized,
        }
    }
}

/// The `--json` output.
#[derive(Debug, Serialize)]
struct Output {
    model: Family,
    algo: Algorithm,
    params: serde_json::Map<String, serde_json::Value>,
    sse: Option<f64>,
    val_rmse: Option<f64>,
    val_fit_percent: Option<f64>,
    evaluations: u64,
    generations: usize,
    seconds: f64,
    backend: String,
    flow: Flow,
    seed: u64,
    population: usize,
    stop: mckibben::optim::StopReason,
    data: String,
    out: PathBuf,
}

/// The longest of the traces (several come from `--split-gaps`).
pub fn one_trace(mut traces: Vec<Trace>) -> anyhow::Result<Trace> {
    anyhow::ensure!(!traces.is_empty(), "the data file holds no samples");
    if traces.len() > 1 {
        eprintln!(
            "mckibben: note: {} pieces after splitting at gaps; fitting the longest",
            traces.len()
        );
    }
    traces.sort_by_key(|t| std::cmp::Reverse(t.len()));
    Ok(traces.swap_remove(0))
}

impl Args {
    fn algo_settings(&self, family: Family) -> anyhow::Result<AlgoSettings> {
        anyhow::ensure!(
            (0.0..=1.0).contains(&self.p_mut),
            "--p-mut must be a probability in [0, 1] (got {})",
            self.p_mut
        );
        let mut s = AlgoSettings {
            pso: PsoSettings::thesis(family),
            ..AlgoSettings::default()
        };
        s.ga.crossover = self.crossover;
        s.ga.elitism = self.elitism;
        s.ga.p_mut = self.p_mut;
        s.ga.mutation = self.mutation;
        s.mfa.lambda0 = self.mfa_lambda0;
        s.mfa.distance = self.mfa_distance;
        s.mfa.scale = self.mfa_scale;
        s.mfa.max_attractors = self.mfa_attractors;
        anyhow::ensure!(
            self.mfa_rho0.is_finite() && self.mfa_rho0 >= 0.0,
            "--mfa-rho0 must be a finite step size ≥ 0 (got {})",
            self.mfa_rho0
        );
        s.mfa.rho0 = self.mfa_rho0;
        if self.mfa_brightest {
            s.mfa.attractors = Attractors::Brightest;
        }
        s.pso.scalar_social = self.pso_scalar_social;
        anyhow::ensure!(
            self.de_p_best > 0.0 && self.de_p_best <= 1.0,
            "--de-p-best must be in (0, 1] (got {})",
            self.de_p_best
        );
        s.de.p_best = self.de_p_best;
        Ok(s)
    }
}

/// A progress bar on stderr (hidden when stderr is not a terminal).
pub struct Progress(indicatif::ProgressBar);

impl Progress {
    pub fn new(total: usize, hidden: bool) -> Progress {
        let bar = if hidden {
            indicatif::ProgressBar::hidden()
        } else {
            indicatif::ProgressBar::new(total as u64)
        };
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} gen {pos}/{len} [{bar:30}] {msg} ({elapsed}, eta {eta})",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        Progress(bar)
    }

    pub fn finish(&self) {
        self.0.finish_and_clear();
    }
}

impl Observer for Progress {
    fn generation(&mut self, r: &GenerationRecord, _: &RunSettings) {
        self.0.set_position(r.generation as u64);
        let best = r.best_sse.map_or("-".into(), |b| format!("{b:.4e}"));
        self.0
            .set_message(format!("best SSE {best}, {} diverged", r.diverged));
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let family: Family = args.model.into();
    let trace = one_trace(args.data.load()?)?;
    let flow = if args.thesis_flow {
        Flow::Thesis
    } else {
        Flow::Joint
    };
    let task = Task::new(&trace, family, flow, None, args.free_n)?;
    let mut runner = match &args.checkpoint {
        Some(path) if path.exists() => {
            let mut r = Runner::load(path)?;
            // Stopping rules come from this command line; N, G, the seed and
            // the algorithm settings from the checkpoint.
            r.settings.target_sse = args.target_sse;
            r.settings.time_budget_s = args.time_budget;
            r.settings.stall_generations = args.stall;
            anyhow::ensure!(
                r.space.family == family,
                "checkpoint {} is a {} fit, not {family}: pass --model {}",
                path.display(),
                r.space.family,
                r.space.family
            );
            eprintln!(
                "mckibben: note: resuming {} at generation {} of {} from {} (its N, G, seed and settings win)",
                r.algorithm(),
                r.generation(),
                r.settings.generations,
                path.display()
            );
            r
        }
        _ => {
            let mut settings = RunSettings::new(args.pop, args.gens, args.seed);
            settings.target_sse = args.target_sse;
            settings.time_budget_s = args.time_budget;
            settings.stall_generations = args.stall;
            Runner::new(
                args.algo,
                &args.algo_settings(family)?,
                task.space.clone(),
                settings,
            )?
        }
    };
    if runner.algorithm() == Algorithm::Mfa
        && runner.settings.population > 2000
        && args.mfa_attractors.is_none()
        && !args.json
    {
        eprintln!(
            "mckibben: note: the MFA's all-pairs move is O(N²·d): N = {} takes seconds per \
             generation; --mfa-attractors 10 --mfa-brightest makes it O(N·10·d)",
            runner.settings.population
        );
    }
    let mut evaluator = eval::open(args.backend)?;
    let backend = evaluator.describe();
    let interrupt = Arc::new(AtomicBool::new(false));
    {
        let flag = interrupt.clone();
        // A second handler cannot be installed in one process; a failure
        // only means Ctrl-C kills instead of stopping cleanly.
        let _ = ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst));
    }
    if !args.json {
        eprintln!(
            "fitting {family} with {} (N = {}, G = {}, seed {}) on {} [{}]",
            runner.algorithm(),
            runner.settings.population,
            runner.settings.generations,
            runner.settings.seed,
            trace.source,
            backend
        );
    }
    let mut progress = Progress::new(runner.settings.generations, args.json);
    let problem = task.problem();
    let outcome = runner.run(
        &problem,
        evaluator.as_mut(),
        &mut [&mut progress],
        Some(&interrupt),
        args.checkpoint.as_deref(),
    )?;
    progress.finish();
    let output = write_results(&args.out, &task, &runner, &outcome, &trace, &backend)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&output)?);
    } else {
        print_report(&output, &task);
    }
    Ok(())
}

fn write_results(
    out: &Path,
    task: &Task,
    runner: &Runner,
    outcome: &RunOutcome,
    trace: &Trace,
    backend: &str,
) -> anyhow::Result<Output> {
    std::fs::create_dir_all(out)
        .with_context(|| format!("cannot create --out {}", out.display()))?;
    let found = !outcome.params.is_empty();
    let val = found.then(|| task.validate(&outcome.params));
    let params: serde_json::Map<String, serde_json::Value> = task
        .family
        .params()
        .iter()
        .zip(&outcome.params)
        .map(|(p, &v)| (p.name.to_string(), serde_json::json!(v)))
        .collect();
    let finite = |v: f64| v.is_finite().then_some(v);
    let output = Output {
        model: task.family,
        algo: runner.algorithm(),
        params,
        sse: finite(outcome.sse),
        val_rmse: val.and_then(|v| finite(v.rmse)),
        val_fit_percent: val.and_then(|v| finite(v.fit_percent)),
        evaluations: outcome.evaluations,
        generations: outcome.generations,
        seconds: outcome.seconds,
        backend: backend.to_string(),
        flow: task.flow,
        seed: runner.settings.seed,
        population: runner.settings.population,
        stop: outcome.stop,
        data: trace.source.clone(),
        out: out.to_path_buf(),
    };
    let write = |name: &str, bytes: &[u8]| {
        let path = out.join(name);
        write_atomic(&path, bytes).with_context(|| format!("cannot write {}", path.display()))
    };
    write(
        "result.json",
        serde_json::to_string_pretty(&output)?.as_bytes(),
    )?;
    runner.history.save(out)?;
    let title = format!("{} {} fit", runner.algorithm(), task.family);
    runner
        .history
        .trends_figure(&format!("{title}: best parameters"), &runner.space.free())
        .save(&out.join("trends.svg"))?;
    runner
        .history
        .convergence_figure(&format!("{title}: convergence"))
        .save(&out.join("convergence.svg"))?;
    if found {
        let model = task.model(&outcome.params);
        write(
            "model.json",
            serde_json::to_string_pretty(&model)?.as_bytes(),
        )?;
        let (loop_fig, trace_fig) = fit_figures(task, &outcome.params, trace, &title);
        loop_fig.save(&out.join("loop.svg"))?;
        trace_fig.save(&out.join("trace.svg"))?;
    }
    Ok(output)
}

/// The hysteresis loop (displacement against pressure, figs 12, 14, 16,
/// 20, 21, 23) and the time trace, fitted over measured, on the whole trace
/// in absolute units (free run from the first sample).
pub fn fit_figures(task: &Task, params: &[f64], trace: &Trace, title: &str) -> (Figure, Figure) {
    let model = task.model(params);
    let theta: Vec<f32> = params.iter().map(|&v| v as f32).collect();
    let u: Vec<f32> = trace
        .input
        .iter()
        .map(|&p| (p - model.input_mean) as f32)
        .collect();
    let x0 = (trace.output[0] - model.output_mean) as f32;
    let sim = simulate(task.family, &theta, &u, x0);
    let fitted: Vec<f64> = sim
        .x
        .iter()
        .map(|&x| x as f64 + model.output_mean)
        .collect();
    let (xin, xout) = (
        format!("{} (input)", trace.input_name),
        format!("{} (output)", trace.output_name),
    );
    let loop_fig = Figure::new(format!("{title}: hysteresis loop")).with(
        Panel::new("output against input", xin.clone(), xout.clone())
            .with(Series::points(
                "measured",
                trace.input.clone(),
                trace.output.clone(),
            ))
            .with(Series::line("fitted", trace.input.clone(), fitted.clone())),
    );
    let half = trace.t.get(trace.len() / 2).copied().unwrap_or(0.0);
    let trace_fig = Figure::new(format!(
        "{title}: free run (estimation before t = {half:.1} s, validation after)"
    ))
    .with(
        Panel::new("output", "t (s)", xout)
            .with(Series::line(
                "measured",
                trace.t.clone(),
                trace.output.clone(),
            ))
            .with(Series::line("fitted", trace.t.clone(), fitted)),
    )
    .with(Panel::new("input", "t (s)", xin).with(Series::line(
        "input",
        trace.t.clone(),
        trace.input.clone(),
    )));
    (loop_fig, trace_fig)
}

fn print_report(o: &Output, task: &Task) {
    println!(
        "{} {} fit of {} ({} flow), N = {}, seed {}",
        o.algo,
        o.model,
        o.data,
        match o.flow {
            Flow::Joint => "joint",
            Flow::Thesis => "thesis",
        },
        o.population,
        o.seed
    );
    let free = task.space.free();
    for (i, p) in task.family.params().iter().enumerate() {
        if let Some(v) = o.params.get(p.name).and_then(|v| v.as_f64()) {
            let fixed = if free.contains(&i) { "" } else { "  (fixed)" };
            println!("  {:<7} {v:>14.6}{fixed}", p.name);
        }
    }
    let show = |v: Option<f64>| v.map_or("diverged".to_string(), |v| format!("{v:.4}"));
    println!("  SSE (estimation)     {}", show(o.sse));
    println!(
        "  validation fit       {} %   (RMSE {})",
        show(o.val_fit_percent),
        show(o.val_rmse)
    );
    println!(
        "  {} evaluations in {} generations, {:.2} s, stopped: {:?}",
        o.evaluations, o.generations, o.seconds, o.stop
    );
    println!(
        "  wrote model.json, result.json, history.csv/json and figures to {}",
        o.out.display()
    );
}
