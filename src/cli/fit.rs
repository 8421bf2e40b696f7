//! `mckibben fit`: identify a hysteresis model's parameters with the staged
//! fitting engine (a population search by GA, MFA, PSO or DE, a free-run
//! stage and a Levenberg–Marquardt polish), or with the thesis' flow.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context;
use serde::Serialize;

use super::common::{DataArgs, one_trace};
use mckibben::data::{Trace, write_atomic};
use mckibben::diagnose::chain::with_chain_start;
use mckibben::diagnose::{Settings as DiagnoseSettings, StopFlag, diagnose};
use mckibben::eval::{self, Backend};
use mckibben::fit::edge::{ActiveBound, Widening, active_bounds};
use mckibben::fit::objective::{GENERATIONS, POPULATION};
use mckibben::fit::records::Records;
use mckibben::fit::run::{
    Built, Fit, FitBox, FitSettings, Overrides, StartScores, Switched, model_file,
    yardstick_warnings,
};
use mckibben::fit::task::Task;
use mckibben::ident::{fit_percent, rmse};
use mckibben::model::bounds::Origin;
use mckibben::model::effects::Effect;
use mckibben::model::experiment::halves;
use mckibben::model::file::{Provenance, SearchBox};
use mckibben::model::{Family, Flow, Loop, ModelFile, Switching, UserBound};
use mckibben::optim::Algorithm;
use mckibben::optim::engine::{
    Engine, FreeRun, Observer, Outcome, StageSummary, StopReason, StopRules,
};
use mckibben::optim::ga::{Crossover, Mutation};
use mckibben::optim::history::GenerationRecord;
use mckibben::optim::mfa::{Distance, Lambda0Schedule, Scale};
use mckibben::report::fit_figures;
use mckibben::report::json::{Named, Versioned};

/// Fit a Bouc-Wen hysteresis model (eq. 13 with the classic or generalized
/// state) to a recorded experiment. The first half of the data is used for
/// estimation, the second half for validation, as in the thesis (§4.3.1).
///
/// The fit runs in three stages (docs/ARCHITECTURE.md, "fitting engine"):
///   1. global: a population search (--algo) on the h-step-ahead prediction
///      error, h about a third of the data's time constant, in 4 islands;
///   2. free run: differential evolution on the free-run error from the
///      global stage's best members (N/5 for G/4 generations);
///   3. polish: Levenberg–Marquardt on the free-run residuals from the best
///      16 distinct members (4 per island).
///
/// The free-run error of a slow hysteretic model is a needle that a
/// population search alone stalls beside; the prediction error is smooth
/// around it. Default N = 1000, G = 300, sized for the ≤ 2 s target on two
/// CPU cores with the shipped 4000-sample stair (timings:
/// docs/PERFORMANCE.md, "The default fit").
///
/// `a`, `b`, the intercept `c` and the start offset `x0` are fitted with the
/// hysteresis parameters. `--thesis-flow` redoes the thesis instead: `a`, `b`
/// fixed at the ARX estimate, no intercept, one population search on the
/// free run with the thesis' settings (chapter 5), as in its Table 21.
///
/// The search box is in the data's own scale, so any units work (MPa→mm,
/// psi→mm, kPa→m): the static gain within 5× of ARX's, the time constant
/// within 10×, loop shapes normalised by the output range, A held at 1
/// (the Bouc-Wen gauge: only A·a·(1 − α) is determined), and loops in the
/// bounded class (--loop free lifts it). A fit that ends on one of these
/// data-set bounds widens it and refits from its best point, at most twice,
/// and says so; --bound and --fix set any parameter's box yourself
/// (docs/ARCHITECTURE.md, "The search space").
///
/// The generalized model's sign terms in x switch where the output crosses
/// a level x_s (output units; before it was a parameter, always the
/// estimation half's mean). By default (--switch starts) the fit runs
/// twice, x_s held at that mean and at the sensor's zero (a muscle's rest
/// length), and keeps the lower estimation SSE: on generated truths of both
/// kinds this reaches as many as the better of the two would alone, and
/// more than either alone or a search of x_s over the output's span
/// (docs/RESULTS.md, "Where the generalized loop switches"). It doubles a
/// generalized fit's time. --switch search searches x_s; --fix x_s=0 holds
/// a sensor zero at rest.
///
/// Writes to --out: model.json (read by `simulate`), result.json,
/// history.csv / history.json (per generation and polish start: stage,
/// horizon, best SSE, best parameters, population mean and spread, diverged
/// count), and figures: trends.svg (parameters over generations, the
/// thesis' figs 9–24), convergence.svg, loop.svg (displacement against
/// pressure, fitted over measured) and trace.svg. Ctrl-C stops after the
/// current generation and still writes the best so far.
///
/// Examples:
///   mckibben fit
///   mckibben fit run.csv --model generalized --algo pso --pop 10000
///   mckibben fit --thesis-flow --algo ga --crossover weighted --pop 30 --gens 30
///   mckibben fit --checkpoint fit.ckpt.json   # resumes if the file exists
///   mckibben fit run.csv --bound gain=0.1:20 --fix alpha=0.5
///   mckibben fit run.csv --bound A=0.2:2 --loop free
///   mckibben fit run.csv --model generalized --fix x_s=0
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    #[command(flatten)]
    data: DataArgs,
    /// Hysteresis model: classic (A, α, β, γ) or generalized (A, α, β1..β6)
    /// (default: the --from model's, else classic).
    #[arg(long, value_enum)]
    model: Option<ModelArg>,
    /// Effects after the baseline, comma-separated, in chain order (e.g.
    /// `creep:two-pole,inertia:ringing`; `mckibben diagnose --help` lists
    /// the catalogue). Their parameters are fitted with the baseline's, each
    /// in its own box from the record, from two starts: the search from
    /// scratch, and the chain built one effect at a time as the diagnosis
    /// builds it; the lower estimation SSE is kept (the `built` line says
    /// which). `auto` runs the diagnosis' selection
    /// over the whole catalogue and returns its final model (as `mckibben
    /// diagnose`; minutes, not seconds). Default: the --from model's, else none.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "LIST",
        conflicts_with = "thesis_flow"
    )]
    effects: Option<Vec<EffectArg>>,
    /// Start from a model file (a warm start): its parameters are the first
    /// member of the first population, and its family, effects and --bound
    /// / --fix are taken unless given here. DATA is read as the model's
    /// data were (columns, time column, --resample) unless flags say
    /// otherwise, and must have the model's units and sample time. The fit
    /// runs in the model's coordinates (its means), so the start is the
    /// saved model itself; the box is the new record's, widened where the
    /// model lies outside it. The report shows the start as it was
    /// (`validation fit, from`) and warns when the refit validates clearly
    /// worse.
    #[arg(long, value_name = "MODEL.json", conflicts_with = "thesis_flow")]
    from: Option<PathBuf>,
    /// Update rule of the population search: ga, mfa, pso (the thesis') or
    /// de. It changes the time a fit takes, not where it ends.
    #[arg(long, value_enum, default_value = "de")]
    algo: Algorithm,
    /// Population size N of the global stage (the thesis used 10–30).
    #[arg(long, default_value_t = POPULATION)]
    pop: usize,
    /// Generations G of the global stage: populations evaluated, the
    /// initial one included (the thesis used 30).
    #[arg(long, default_value_t = GENERATIONS)]
    gens: usize,
    /// Seed of the run's random generator: same seed, same result on any
    /// backend and thread count.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Where populations are scored: auto (a hardware GPU if present, else
    /// the CPU), cpu, or gpu (any adapter, lavapipe included).
    #[arg(long, value_enum, default_value = "auto")]
    backend: Backend,
    /// The thesis' flow: a and b fixed at the ARX estimate, no intercept or
    /// start offset, one population search on the free run with the
    /// thesis' algorithm settings (the flags below still override them).
    #[arg(long)]
    thesis_flow: bool,
    /// Independent sub-populations of the staged fit's population stages.
    #[arg(long, value_name = "K", conflicts_with = "thesis_flow")]
    islands: Option<usize>,
    /// Prediction horizon of the global stage in samples (default: a third
    /// of the ARX time constant).
    #[arg(long, value_name = "SAMPLES", conflicts_with = "thesis_flow")]
    horizon: Option<usize>,
    /// Also fit the Bouc-Wen exponent n in [1, 3] (fixed at 1 in the thesis).
    #[arg(long)]
    free_n: bool,
    /// Loop shapes the fit may take: bounded (the class whose state stays
    /// bounded for every bounded input: classic β ≥ 0 and β + γ ≥ 0,
    /// generalized ψ ≥ 0 on every loading branch and no unloading branch
    /// steeper) or free (any signs, for hysteresis outside that class).
    #[arg(
        long = "loop",
        value_enum,
        default_value = "bounded",
        conflicts_with = "thesis_flow"
    )]
    loop_shape: Loop,
    /// Where the generalized model's sign terms in x switch (its level x_s,
    /// in the output's units): starts (two fits, x_s held at the estimation
    /// half's output mean and at the sensor's zero, the lower estimation SSE
    /// kept), search (x_s searched over the estimation output's span), mean
    /// or zero (held there). A --from warm start holds its model's x_s.
    #[arg(
        long = "switch",
        value_enum,
        default_value = "starts",
        conflicts_with = "thesis_flow"
    )]
    switching: Switching,
    /// Bound one parameter to [LO, HI] (repeatable): a canonical name (A,
    /// alpha, beta, gamma, beta1..beta6, n, x_s, a, b, c, x0) or a search
    /// coordinate's (gain, offset, x0_range, loading, beta_range, psi_pp, ...;
    /// result.json's search_box lists them). Bounding A frees the gauge;
    /// bounding b or c searches the linear part in b, c, x0 themselves; a
    /// loop-shape parameter, the loop shape in its own parameters.
    #[arg(long, value_name = "NAME=LO:HI", conflicts_with = "thesis_flow")]
    bound: Vec<UserBound>,
    /// Hold one parameter at VALUE (repeatable; names as --bound).
    #[arg(long, value_name = "NAME=VALUE", conflicts_with = "thesis_flow")]
    fix: Vec<UserBound>,
    /// Stop once the estimation SSE (free run) is at or below this.
    #[arg(long, value_name = "SSE")]
    target_sse: Option<f64>,
    /// Stop after this many seconds (the result then depends on the machine).
    #[arg(long, value_name = "SECONDS")]
    time_budget: Option<f64>,
    /// End a population stage when its best has not improved for this many
    /// generations.
    #[arg(long, value_name = "GENS")]
    stall: Option<usize>,
    /// GA crossover (§5.2.1.5; default proportional).
    #[arg(long, value_enum)]
    crossover: Option<Crossover>,
    /// GA: best individuals kept unchanged (thesis 0; staged fit N/10).
    #[arg(long)]
    elitism: Option<usize>,
    /// GA: mutation probability P_mut (thesis 0.1; staged fit 0.3).
    #[arg(long)]
    p_mut: Option<f64>,
    /// GA: fixed ±m_m mutation (thesis), uniform in [−m_m, m_m] (staged
    /// fit), or non-uniform (Michalewicz: towards a bound, reach shrinking
    /// over the generations).
    #[arg(long, value_enum)]
    mutation: Option<Mutation>,
    /// MFA: Λ0 schedule from a to b (appendix code) or to a − b (eq. 36).
    #[arg(long, value_enum)]
    mfa_lambda0: Option<Lambda0Schedule>,
    /// MFA: attractiveness e^(−σr) (thesis' code) or e^(−σr²) (eq. 32;
    /// staged fit).
    #[arg(long, value_enum)]
    mfa_distance: Option<Distance>,
    /// MFA: distances and walk in raw units (thesis) or box widths (staged fit).
    #[arg(long, value_enum)]
    mfa_scale: Option<Scale>,
    /// MFA: move towards at most K brighter fireflies (thesis: all of them,
    /// O(N²·d) a generation; staged fit: the 10 brightest). 0 means all.
    #[arg(long, value_name = "K")]
    mfa_attractors: Option<usize>,
    /// MFA: with --mfa-attractors, the K brightest instead of K at random.
    #[arg(long)]
    mfa_brightest: bool,
    /// MFA: start ρ0 of the random walk ρ(k) = ρ0·e^(−4.8k/G) (eq. 38: 0.1).
    #[arg(long, value_name = "RHO0")]
    mfa_rho0: Option<f64>,
    /// DE: share of the population x_pbest is drawn from (0.1; smaller is
    /// greedier).
    #[arg(long)]
    de_p_best: Option<f64>,
    /// PSO: one random number for the social term (appendix code).
    #[arg(long)]
    pso_scalar_social: bool,
    /// Save the run state to FILE every 10 s and at the end; if FILE exists,
    /// resume from it to the identical result (the plan, N, G, seed and
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

/// One entry of `--effects`: an effect of the catalogue, or `auto`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum EffectArg {
    Auto,
    Effect(Effect),
}

impl std::str::FromStr for EffectArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "auto" => Ok(EffectArg::Auto),
            _ => s.parse().map(EffectArg::Effect),
        }
    }
}

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
    /// The effects after the baseline, in chain order.
    effects: Vec<String>,
    algo: Algorithm,
    /// Fitted parameters by name, in the family's canonical order.
    params: Named,
    /// Estimation SSE of the free run.
    sse: Option<f64>,
    val_rmse: Option<f64>,
    val_fit_percent: Option<f64>,
    /// The first-order ARX model's validation fit on the same halves
    /// (`Records::linear_yardstick`): what the fit should beat.
    linear_val_fit_percent: Option<f64>,
    /// With `--from`: the start model as it was, on this record's halves
    /// (`null` without `--from`, or where it diverges).
    start_sse: Option<f64>,
    start_val_fit_percent: Option<f64>,
    /// With effects from scratch: the search from scratch against the
    /// chain built one effect at a time, and which was kept (`null`
    /// otherwise).
    built: Option<Built>,
    /// A generalized fit from the default switching's two starts: each
    /// start's estimation SSE and which was kept (`null` otherwise).
    switching: Option<Switched>,
    evaluations: u64,
    generations: usize,
    seconds: f64,
    backend: String,
    flow: Flow,
    seed: u64,
    population: usize,
    stop: StopReason,
    stages: Vec<StageSummary>,
    /// Search coordinates that ended on a bound of the box, with where
    /// each bound comes from (after the edge rule's widenings).
    on_edge: Vec<ActiveBound>,
    /// The edge rule's widenings and refits, in order.
    widened: Vec<Widening>,
    /// The search box's coordinates (`names`) and bounds, after widening.
    search_box: SearchBox,
    data: String,
    out: PathBuf,
}

impl Args {
    /// The fit the flags ask for.
    fn settings(&self) -> FitSettings {
        FitSettings {
            algo: self.algo,
            pop: self.pop,
            gens: self.gens,
            seed: self.seed,
            thesis_flow: self.thesis_flow,
            islands: self.islands,
            horizon: self.horizon,
            overrides: Overrides {
                crossover: self.crossover,
                elitism: self.elitism,
                p_mut: self.p_mut,
                mutation: self.mutation,
                mfa_lambda0: self.mfa_lambda0,
                mfa_distance: self.mfa_distance,
                mfa_scale: self.mfa_scale,
                mfa_attractors: self.mfa_attractors,
                mfa_brightest: self.mfa_brightest,
                mfa_rho0: self.mfa_rho0,
                de_p_best: self.de_p_best,
                pso_scalar_social: self.pso_scalar_social,
            },
            stops: StopRules {
                target_sse: self.target_sse,
                time_budget_s: self.time_budget,
                stall_generations: self.stall,
                stall_tolerance: 0.0,
            },
        }
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
    fn record(&mut self, r: &GenerationRecord, _: usize) {
        self.0.set_position(r.generation as u64);
        let best = r.stage_best.map_or("-".into(), |b| format!("{b:.4e}"));
        let measure = match r.measure {
            mckibben::model::Measure::FreeRun => "free run".to_string(),
            mckibben::model::Measure::Ahead { horizon } => format!("{horizon}-step"),
        };
        self.0.set_message(format!(
            "{} ({measure}) best {best}, {} diverged",
            r.stage.name(),
            r.diverged
        ));
    }
}

pub fn run(mut args: Args) -> anyhow::Result<()> {
    let start = match &args.from {
        Some(path) => Some(ModelFile::load(path).map_err(|e| anyhow::anyhow!("--from: {e:#}"))?),
        None => None,
    };
    if let Some(file) = &start {
        args.data.columns = args.data.columns.or_as_read_for(file);
    }
    let start_model = start.as_ref().map(|f| f.model()).transpose()?;
    let family: Family = match (args.model, &start_model) {
        (Some(m), _) => m.into(),
        (None, Some(m)) => m.base.family,
        (None, None) => Family::Classic,
    };
    let given: Option<Vec<Effect>> = match args.effects.as_deref() {
        None => None,
        Some([EffectArg::Auto]) => {
            anyhow::ensure!(
                start_model.is_none() && args.bound.is_empty() && args.fix.is_empty(),
                "--effects auto runs the diagnosis' own selection: not with --from, --bound or --fix"
            );
            let trace = one_trace(args.data.load()?)?;
            return run_auto(&args, family, &trace);
        }
        Some(list) => Some(
            list.iter()
                .map(|e| match e {
                    EffectArg::Effect(e) => Ok(*e),
                    EffectArg::Auto => Err(anyhow::anyhow!(
                        "--effects: `auto` stands alone (the diagnosis chooses every effect)"
                    )),
                })
                .collect::<anyhow::Result<_>>()?,
        ),
    };
    let effects: Vec<Effect> = match (given, &start_model) {
        (Some(e), _) => e,
        (None, Some(m)) => m.effects().to_vec(),
        (None, None) => Vec::new(),
    };
    let trace = one_trace(args.data.load()?)?;
    for f in &args.fix {
        anyhow::ensure!(
            f.lower == f.upper,
            "--fix {}: expected NAME=VALUE (use --bound for a range)",
            f.name
        );
    }
    let saved_bounds: Vec<UserBound> = match &start {
        Some(f) => f
            .user_bounds
            .iter()
            .map(|b| b.parse().map_err(anyhow::Error::msg))
            .collect::<anyhow::Result<_>>()
            .context("--from: its user_bounds")?,
        None => Vec::new(),
    };
    let what = FitBox {
        family,
        effects: effects.clone(),
        free_n: args.free_n,
        loop_shape: args.loop_shape,
        switching: args.switching,
        // The file's bounds first, so that the flags given here win.
        bounds: saved_bounds
            .iter()
            .chain(&args.bound)
            .chain(&args.fix)
            .cloned()
            .collect(),
    };
    let note = |s: String| {
        if !args.json {
            eprintln!("mckibben: note: {s}");
        }
    };
    let fit = Fit::new(
        &trace,
        &what,
        &args.settings(),
        start_model.as_ref(),
        args.checkpoint.as_deref(),
        &note,
    )?;
    let mut evaluator = eval::open(args.backend)?;
    let backend = evaluator.describe();
    let interrupt = Arc::new(AtomicBool::new(false));
    let chain_stop = StopFlag::default();
    {
        let (flag, chain) = (interrupt.clone(), chain_stop.clone());
        // A second handler cannot be installed in one process; a failure
        // only means Ctrl-C kills instead of stopping cleanly.
        let _ = ctrlc::set_handler(move || {
            flag.store(true, Ordering::SeqCst);
            chain.raise();
        });
    }
    if !effects.is_empty() && start_model.is_none() && !args.json {
        eprintln!(
            "building the chain one effect at a time, as the diagnosis does: the fit's second start"
        );
    }
    let mut fit = with_chain_start(fit, &trace, &args.settings(), args.backend, chain_stop)?;
    let engine = &fit.engine;
    if !args.json {
        // A warm start has no global stage: its first is the free run's.
        let (algo, population, generations) = match (&engine.plan.global, &engine.plan.free_run) {
            (Some(g), _) => (g.algorithm(), g.population, g.generations),
            (None, Some(f)) => (FreeRun::ALGORITHM, f.population, f.generations),
            (None, None) => (FreeRun::ALGORITHM, 0, 0),
        };
        let stages: Vec<&str> = engine.stages().iter().map(|s| s.name()).collect();
        let model = effects
            .iter()
            .fold(family.to_string(), |m, e| format!("{m} + {e}"));
        let from = match &args.from {
            Some(p) => format!(", warm start from {}", p.display()),
            None => String::new(),
        };
        eprintln!(
            "fitting {model} with {algo} (N = {population}, G = {generations}, seed {}; stages {}{from}) on {} [{}]",
            engine.seed,
            stages.join(" → "),
            trace.source,
            backend
        );
    }
    let mut progress = Progress::new(engine.plan.generations(), args.json);
    let (outcome, widened) = fit.run(
        evaluator.as_mut(),
        &mut [&mut progress],
        Some(&interrupt),
        args.checkpoint.as_deref(),
    )?;
    progress.finish();
    let (task, engine) = (&fit.task, &fit.engine);
    let start = fit.start_scores();
    let provenance = args.data.provenance(Some(engine.seed))?;
    let output = write_results(
        &args.out,
        Written {
            task,
            engine,
            outcome: &outcome,
            widened: &widened,
            start,
            built: fit.built,
            switched: fit.switched,
            trace: &trace,
            backend: &backend,
            bounds: &what.bounds,
            provenance,
        },
    )?;
    if args.json {
        println!("{}", Versioned::new(&output).to_string_pretty()?);
    } else {
        print_report(&output, task);
        if let Some(fit) = output.val_fit_percent {
            let linear = output.linear_val_fit_percent;
            for w in yardstick_warnings(outcome.sse, fit, linear, start) {
                eprintln!("mckibben: warning: {w}");
            }
        }
    }
    if outcome.params.is_empty() && outcome.evaluations == 0 {
        eprintln!(
            "mckibben: note: stopped ({:?}) before any candidate was scored; no model was written",
            outcome.stop
        );
    } else {
        anyhow::ensure!(
            !outcome.params.is_empty(),
            "every candidate diverged: no model was written (the history is in {}); \
             check the data's units and columns",
            args.out.display()
        );
    }
    Ok(())
}

/// `--effects auto`: the diagnosis' forward selection over the whole
/// catalogue on `trace` (its settings, with this command's seed and
/// backend); writes and reports its final model as a fit's.
fn run_auto(args: &Args, family: Family, trace: &Trace) -> anyhow::Result<()> {
    let settings = DiagnoseSettings {
        seed: args.seed,
        backend: args.backend,
        ..DiagnoseSettings::default()
    };
    if !args.json {
        eprintln!(
            "fitting {family} with the effects the diagnosis selects from its catalogue \
             (seed {}) on {}",
            args.seed, trace.source
        );
    }
    let started = std::time::Instant::now();
    let d = diagnose(
        std::slice::from_ref(trace),
        family,
        &Effect::by_default(),
        &settings,
    )?;
    let model = d.final_model.clone();
    let run = model.simulate_absolute(&trace.input, trace.output[0]);
    let from = halves(trace.len()).1.start;
    let (y, yhat) = (&trace.output[from..], &run.output[from..]);
    let finite = |v: f64| v.is_finite().then_some(v);
    let output = Output {
        model: family,
        effects: model
            .effects()
            .iter()
            .map(|e| e.name().to_string())
            .collect(),
        algo: Algorithm::De,
        params: model.named_params().into_iter().collect(),
        sse: finite(d.selection.final_fit.est_sse),
        val_rmse: finite(rmse(y, yhat)),
        val_fit_percent: finite(fit_percent(y, yhat)),
        linear_val_fit_percent: Records::of(std::slice::from_ref(trace), None)?
            .linear_yardstick(0)
            .and_then(|v| finite(v.fit_percent)),
        start_sse: None,
        start_val_fit_percent: None,
        built: None,
        switching: None,
        evaluations: 0,
        generations: 0,
        seconds: started.elapsed().as_secs_f64(),
        backend: format!("{:?} (the diagnosis' searches)", args.backend).to_lowercase(),
        flow: Flow::Joint,
        seed: args.seed,
        population: settings.population,
        stop: StopReason::Completed,
        stages: Vec::new(),
        on_edge: Vec::new(),
        widened: Vec::new(),
        search_box: SearchBox {
            names: Vec::new(),
            lower: Vec::new(),
            upper: Vec::new(),
            origin: Vec::new(),
        },
        data: trace.source.clone(),
        out: args.out.clone(),
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create --out {}", args.out.display()))?;
    ModelFile::new(&model, None, args.data.provenance(Some(args.seed))?)
        .save(&args.out.join("model.json"))?;
    let result = args.out.join("result.json");
    write_atomic(
        &result,
        Versioned::new(&output).to_string_pretty()?.as_bytes(),
    )
    .with_context(|| format!("cannot write {}", result.display()))?;
    let title = format!("diagnosed {family} fit");
    let (loop_fig, trace_fig) = fit_figures(&model, trace, &title);
    loop_fig.save(&args.out.join("loop.svg"))?;
    trace_fig.save(&args.out.join("trace.svg"))?;
    if args.json {
        println!("{}", Versioned::new(&output).to_string_pretty()?);
        return Ok(());
    }
    println!(
        "{family} fit of {} with the diagnosis' effects: {}",
        trace.source,
        if output.effects.is_empty() {
            "none".to_string()
        } else {
            output.effects.join(", ")
        }
    );
    for (name, value) in &output.params.0 {
        println!("  {name:<7} {value:>14.6}");
    }
    let show = |v: Option<f64>| v.map_or("diverged".to_string(), |v| format!("{v:.4}"));
    println!("  SSE (estimation)     {}", show(output.sse));
    println!(
        "  validation fit       {} %   (RMSE {})",
        show(output.val_fit_percent),
        show(output.val_rmse)
    );
    println!(
        "  {:.2} s; `mckibben diagnose` gives the selection's report; wrote model.json, \
         result.json and figures to {}",
        output.seconds,
        args.out.display()
    );
    Ok(())
}

/// What a finished fit writes.
struct Written<'a> {
    task: &'a Task,
    engine: &'a Engine,
    outcome: &'a Outcome,
    widened: &'a [Widening],
    /// With `--from`: the start model's own scores ([`Fit::start_scores`]).
    start: Option<StartScores>,
    /// Which of the two starts of a fit with effects was kept ([`Fit::run`]).
    built: Option<Built>,
    /// Which of the two switching starts was kept ([`Fit::run`]).
    switched: Option<Switched>,
    trace: &'a Trace,
    backend: &'a str,
    /// The --bound and --fix in force (the file's and the flags').
    bounds: &'a [UserBound],
    provenance: Provenance,
}

fn write_results(out: &Path, w: Written) -> anyhow::Result<Output> {
    let Written {
        task,
        engine,
        outcome,
        widened,
        start,
        built,
        switched,
        trace,
        backend,
        bounds,
        provenance,
    } = w;
    std::fs::create_dir_all(out)
        .with_context(|| format!("cannot create --out {}", out.display()))?;
    let found = !outcome.params.is_empty();
    let val = found.then(|| task.validate(&outcome.params));
    let params = Named::zip(&task.augmented().param_names(), &outcome.params);
    let on_edge = active_bounds(task, &outcome.params);
    let finite = |v: f64| v.is_finite().then_some(v);
    let global = engine.plan.global.as_ref();
    let output = Output {
        model: task.family,
        effects: task.effects.iter().map(|e| e.name().to_string()).collect(),
        algo: global.map_or(Algorithm::De, |g| g.algorithm()),
        params,
        sse: finite(outcome.sse),
        val_rmse: val.and_then(|v| finite(v.rmse)),
        val_fit_percent: val.and_then(|v| finite(v.fit_percent)),
        linear_val_fit_percent: task.linear_yardstick().and_then(|v| finite(v.fit_percent)),
        start_sse: start.and_then(|s| finite(s.est_sse)),
        start_val_fit_percent: start.and_then(|s| finite(s.validation.fit_percent)),
        built,
        switching: switched,
        evaluations: outcome.evaluations,
        generations: outcome.generations,
        seconds: outcome.seconds,
        backend: backend.to_string(),
        flow: task.flow,
        seed: engine.seed,
        population: global.map_or(
            engine.plan.free_run.as_ref().map_or(0, |f| f.population),
            |g| g.population,
        ),
        stop: outcome.stop,
        stages: outcome.stages.clone(),
        on_edge,
        widened: widened.to_vec(),
        search_box: SearchBox::of(&task.space),
        data: trace.source.clone(),
        out: out.to_path_buf(),
    };
    let write = |name: &str, bytes: &[u8]| {
        let path = out.join(name);
        write_atomic(&path, bytes).with_context(|| format!("cannot write {}", path.display()))
    };
    write(
        "result.json",
        Versioned::new(&output).to_string_pretty()?.as_bytes(),
    )?;
    engine.history.save(out)?;
    let title = format!("{} {} fit", output.algo, task.family);
    engine
        .history
        .trends_figure(&format!("{title}: best parameters"), &engine.space.free())
        .save(&out.join("trends.svg"))?;
    engine
        .history
        .convergence_figure(&format!("{title}: convergence"))
        .save(&out.join("convergence.svg"))?;
    if found {
        model_file(task, &outcome.params, bounds, provenance).save(&out.join("model.json"))?;
        let model = task.model(&outcome.params);
        let (loop_fig, trace_fig) = fit_figures(&model, trace, &title);
        loop_fig.save(&out.join("loop.svg"))?;
        trace_fig.save(&out.join("trace.svg"))?;
    }
    Ok(output)
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
    if !o.effects.is_empty() {
        println!("  effects: {}", o.effects.join(", "));
    }
    let free = task.space.free();
    for (i, name) in task.augmented().param_names().iter().enumerate() {
        if let Some(v) = o.params.get(name) {
            let fixed = if free.contains(&i) { "" } else { "  (fixed)" };
            println!("  {name:<7} {v:>14.6}{fixed}");
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
        "  validation fit, ARX  {} %   (the first-order linear model on the same halves)",
        show(o.linear_val_fit_percent)
    );
    if o.start_sse.is_some() || o.start_val_fit_percent.is_some() {
        println!(
            "  validation fit, from  {} %   (the --from model as it was, on the same halves; SSE {})",
            show(o.start_val_fit_percent),
            show(o.start_sse)
        );
    }
    if let Some(s) = o.switching {
        println!(
            "  switching: x_s at the estimation mean ended at SSE {:.4}, at the sensor's zero at \
             {:.4}: kept the {}",
            s.mean_sse,
            s.zero_sse,
            if s.kept_zero { "zero" } else { "mean" }
        );
    }
    if let Some(b) = o.built {
        println!(
            "  built: the search from scratch ended at SSE {:.4}, the chain built one effect at a \
             time at {:.4}: kept the {}",
            b.scratch_sse,
            b.chain_sse,
            if b.kept_chain {
                "chain"
            } else {
                "search from scratch"
            }
        );
    }
    for s in &o.stages {
        println!(
            "  stage {:<9} {:>4} steps, {:>9} evaluations, {:>7.2} s, best {:.4e} ({}), ended: {:?}",
            s.stage.name(),
            s.steps,
            s.evaluations,
            s.seconds,
            s.best_cost,
            s.measure,
            s.ended
        );
    }
    println!(
        "  {} evaluations in {} generations, {:.2} s, stopped: {:?}",
        o.evaluations, o.generations, o.seconds, o.stop
    );
    for w in &o.widened {
        eprintln!(
            "mckibben: note: the fit ended on a bound the data set; widened {} and refitted from \
             its best point: estimation SSE {:.6e} -> {:.6e}",
            w.bounds.join(", "),
            w.sse_before,
            w.sse_after
        );
    }
    for e in &o.on_edge {
        let why = match e.origin {
            Origin::Data => {
                "a bound the data set, still active after the widenings: the box \
                             stopped it, not the data; widen it with --bound"
            }
            Origin::User => "your --bound or --fix",
            Origin::Class if e.param.contains('.') => {
                "the edge of the effect's range: where it is neutral, or as far as \
                 the record lets it go"
            }
            Origin::Class => {
                "the edge of its range or of the bounded class (--loop free lifts \
                              the class)"
            }
        };
        let level = if e.origin == Origin::Data {
            "warning"
        } else {
            "note"
        };
        eprintln!(
            "mckibben: {level}: {} ended on the {} bound of its search box ({why})",
            e.param, e.bound
        );
    }
    if o.sse.is_some() {
        println!(
            "  wrote model.json, result.json, history.csv/json and figures to {}",
            o.out.display()
        );
    }
}
