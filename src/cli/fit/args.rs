//! `mckibben fit`'s flags: what each asks for, and the fit settings they
//! make.

use std::path::PathBuf;

use super::super::common::{ModelArg, MultiDataArgs, population};
use mckibben::eval::Backend;
use mckibben::fit::objective::{GENERATIONS, POPULATION};
use mckibben::fit::problem::Overshoot;
use mckibben::fit::request::FitRequest;
use mckibben::fit::settings::{FitSettings, Overrides};
use mckibben::model::effects::Effect;
use mckibben::model::{Family, Loop, Switching, UserBound};
use mckibben::names::UnknownName;
use mckibben::optim::Algorithm;
use mckibben::optim::engine::StopRules;
use mckibben::optim::ga::{Crossover, Mutation};
use mckibben::optim::mfa::{Distance, Lambda0Schedule, Scale};

/// Fit a Bouc-Wen hysteresis model (eq. 13 with the classic or generalized
/// state) to a recorded experiment. The first half of the data is used for
/// estimation, the second half for validation, as in the thesis (§4.3.1).
///
/// Several files (experiments on one muscle: a stair and a sine, say) fit
/// one model to all of them, as MATLAB's `merge` of experiments: each file
/// split in halves, the estimation halves' errors summed, and the
/// validation halves scored pooled and each on its own. They must share
/// columns and sample time. A file `--split-gaps` cuts gives its longest
/// piece.
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
/// a level x_s (output units). By default (--switch search) the fit
/// searches x_s over the estimation output's span as a level: the error
/// changes only where the level passes a sample, so the polish holds it
/// and a scan of levels moves it, and where the estimation half cannot
/// tell the best level from the sensor's zero (a muscle's rest length) or
/// the estimation mean, the fit keeps that one. --fix x_s=0 holds a
/// sensor zero at rest; --switch starts runs two fits, x_s held at the
/// mean and at zero (docs/RESULTS.md, "Where the generalized loop
/// switches").
///
/// --pop buys independent tries: a population of 2000 or more runs tries
/// of 1000 and of 100 (each its own global search, free-run stage, polish
/// and, for the generalized model, refining rounds), scored together, and
/// keeps the lowest estimation SSE: two of 1000, then ten of 100 and one
/// of 1000 in turn (--pop 10000: 6 of 1000 and 40 of 100), since on some
/// records only a small population stops before its loop saturates. The
/// same seed runs the same tries, so of two populations from 2000 on the
/// larger never ends higher (below 2000 a population is one try, which may
/// end anywhere).
/// The report says how many tries ended within the likelihood-ratio
/// threshold of the best: few of many means the basin was found by luck,
/// and more tries may find a better one.
///
/// Writes to --out: model.json (read by `simulate`), result.json,
/// history.csv / history.json (per generation and polish start: stage,
/// horizon, best SSE, best parameters, population mean and spread, diverged
/// count), and figures: trends.svg (parameters over generations, the
/// thesis' figs 9–24), convergence.svg, loop.svg (displacement against
/// pressure, fitted over measured) and trace.svg. Ctrl-C stops after the
/// current generation, still writes the best so far and exits with status
/// 130, as an interrupted program does, so that a script stops too.
///
/// Examples:
///   mckibben fit
///   mckibben fit run.csv --model generalized --algo pso --pop 10000
///   mckibben fit data/stair_4.5kg.csv data/sine_2rads_4.5kg.csv
///   mckibben fit --thesis-flow --algo ga --crossover weighted --pop 30 --gens 30
///   mckibben fit --checkpoint fit.ckpt.json   # resumes if the file exists
///   mckibben fit run.csv --bound gain=0.1:20 --fix alpha=0.5
///   mckibben fit run.csv --bound A=0.2:2 --loop free
///   mckibben fit run.csv --model generalized --fix x_s=0
///   mckibben fit next.csv --carry out/diagnose/model.json
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    #[command(flatten)]
    pub(super) data: MultiDataArgs,
    /// Hysteresis model: classic (A, α, β, γ) or generalized (A, α, β1..β6)
    /// (default: the --from model's, which it must be, else classic).
    #[arg(long, value_enum, ignore_case = true)]
    pub(super) model: Option<ModelArg>,
    /// Effects after the baseline, comma-separated, in chain order (e.g.
    /// `creep:two-pole,inertia:ringing`; `mckibben diagnose --help` lists
    /// the catalogue). Their parameters are fitted with the baseline's, each
    /// in its own box from the record, from two starts: the search from
    /// scratch, and the chain built one effect at a time as the diagnosis
    /// builds it; the lower estimation SSE is kept (the `built` line says
    /// which). `auto` runs the diagnosis' selection
    /// over the whole catalogue and returns its final model (as `mckibben
    /// diagnose`; minutes, not seconds), its searches set by --seed and
    /// --backend alone (the search flags are refused beside it); its
    /// validation half holds the selection part that chose the effects,
    /// so the report adds the test part's fit, which no choice read, and
    /// warns of what weakens the diagnosis' verdict.
    /// Default:
    /// the --from model's, else none.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "LIST",
        conflicts_with = "thesis_flow"
    )]
    pub(super) effects: Option<Vec<EffectArg>>,
    /// Start from a model file (a warm start): its parameters are the first
    /// member of the first population, its family is kept (another --model
    /// is an error; an ARX model from `identify` cannot start a fit), and
    /// its effects and --bound / --fix are taken unless given here. DATA is read as the model's
    /// data were (columns, time column, --resample) unless flags say
    /// otherwise, and must have the model's units and sample time. The fit
    /// runs in the model's coordinates (its means), so the start is the
    /// saved model itself; the box is the new record's, widened where the
    /// model lies outside it. The report shows the start as it was
    /// (`validation fit, from`) and warns when the refit validates clearly
    /// worse.
    #[arg(long, value_name = "MODEL.json", conflicts_with = "thesis_flow")]
    pub(super) from: Option<PathBuf>,
    /// Carry a model's chain to this record, as `diagnose --transfer`
    /// does: the model's family and effects fitted here from scratch, with
    /// the effects' dynamics (poles, delays, how fast a ratchet's steps or
    /// a cyclic softening's growth fall) held at the model's values, and the baseline and
    /// the effects' sizes (gains, levels, starts) fitted on this record's
    /// first half. For the next record of the same muscle: its first half
    /// pins a gain far better than the pole of a state slower than the
    /// record. DATA is read as the model's data were and must have its units
    /// and sample time (the held poles are per sample). The model written
    /// keeps them held (its `user_bounds`), so a later --from refit does too.
    #[arg(
        long,
        value_name = "MODEL.json",
        conflicts_with_all = ["thesis_flow", "from", "effects", "model"]
    )]
    pub(super) carry: Option<PathBuf>,
    /// Update rule of the population search: ga, mfa, pso (the thesis') or
    /// de. On the shipped stair it changes the time a fit takes, not where
    /// it ends; on a record with several basins it can change both
    /// (docs/RESULTS.md): tries (--pop 2000) show it and keep the best.
    #[arg(long, value_enum, ignore_case = true, default_value = "de")]
    pub(super) algo: Algorithm,
    /// Population size N of the global stage (the thesis used 10–30); from
    /// 2000 on, independent tries of 1000 and 100, scored together (what a
    /// whole try does not fill is left, with a note: 3500 runs 3000).
    #[arg(long, default_value_t = POPULATION, value_parser = population)]
    pub(super) pop: usize,
    /// Generations G of the global stage: populations evaluated, the
    /// initial one included (the thesis used 30).
    #[arg(long, default_value_t = GENERATIONS, value_parser = crate::cli::common::generations)]
    pub(super) gens: usize,
    /// Seed of the run's random generator: same seed, same result on any
    /// backend and thread count.
    #[arg(long, default_value_t = 1, value_parser = crate::cli::common::seed)]
    pub(super) seed: u64,
    /// Where populations are scored: auto (a hardware GPU if present, else
    /// the CPU), cpu, or gpu (any adapter, lavapipe included).
    #[arg(long, value_enum, ignore_case = true, default_value = "auto")]
    pub(super) backend: Backend,
    /// The thesis' flow: a and b fixed at the ARX estimate, no intercept or
    /// start offset, one population search on the free run with the
    /// thesis' algorithm settings (the flags below still override them), in
    /// the thesis' box, whose loop shapes are per mm of stroke: an output
    /// column whose name states another length unit (`x_m`, `x [cm]`) gets
    /// them converted; one that states none is taken in mm.
    #[arg(long)]
    pub(super) thesis_flow: bool,
    /// Independent sub-populations of the staged fit's population stages.
    #[arg(long, value_name = "K", conflicts_with = "thesis_flow")]
    pub(super) islands: Option<usize>,
    /// Prediction horizon of the global stage in samples (default: a third
    /// of the ARX time constant).
    #[arg(long, value_name = "SAMPLES", conflicts_with = "thesis_flow")]
    pub(super) horizon: Option<usize>,
    /// Most refining rounds of a generalized fit (default 4, at most 100). After the
    /// polish, rounds of differential evolution around each try's best
    /// step over the ledges the switching level makes; they go on while a
    /// round lowers the SSE by a thousandth. When the last allowed round
    /// still did, the fit says so: more rounds go on from there, at about
    /// a tenth of the default fit's time each. They lower the estimation
    /// SSE; check the validation fit, which on a record that barely
    /// settles the model can fall as well as rise.
    #[arg(long, value_name = "ROUNDS", conflicts_with = "thesis_flow")]
    pub(super) refine_rounds: Option<usize>,
    /// Also fit the Bouc-Wen exponent n in [1, 3] (fixed at 1 in the thesis).
    #[arg(long)]
    pub(super) free_n: bool,
    /// Loop shapes the fit may take: bounded (the class whose state stays
    /// bounded for every bounded input: classic β ≥ 0 and β + γ ≥ 0,
    /// generalized ψ ≥ 0 on every loading branch and no unloading branch
    /// steeper) or free (any signs, for hysteresis outside that class).
    #[arg(
        long = "loop",
        value_enum,
        ignore_case = true,
        default_value = "bounded",
        conflicts_with = "thesis_flow"
    )]
    pub(super) loop_shape: Loop,
    /// Where the generalized model's sign terms in x switch (its level x_s,
    /// in the output's units): search (x_s searched over the estimation
    /// output's span, the sensor's zero or the estimation mean kept where
    /// the estimation half cannot tell it from the best level), starts (two
    /// fits, x_s held at the estimation mean and at the sensor's zero, the
    /// lower estimation SSE kept), mean or zero (held there). A --from warm
    /// start holds its model's x_s unless another value is given here.
    /// [default: search]
    #[arg(
        long = "switch",
        value_enum,
        ignore_case = true,
        conflicts_with = "thesis_flow"
    )]
    pub(super) switching: Option<Switching>,
    /// Whether the fit admits a loop whose discrete update overshoots on
    /// the steps its estimation records take (the report's `stable steps`):
    /// allow, or refuse (every candidate's loop must settle on all but the
    /// fastest 1 % of the estimation halves' output steps a sample). An
    /// overshooting loop is the update's, not the continuous model's, and a
    /// record that turns back and forth at such steps pumps it: where a
    /// classic fit warns that its run steps past its stable step and
    /// validates poorly, or a larger --pop validates worse, refit with
    /// refuse (on real records it kept larger populations from hurting;
    /// docs/RESULTS.md). Allowed by default: on other records, and for the
    /// generalized family, the loops that overshoot fitted better. Not
    /// checked with --effects, whose loop steps on the baseline's own
    /// output. [default: allow]
    #[arg(long, value_enum, ignore_case = true, conflicts_with = "thesis_flow")]
    pub(super) overshoot: Option<Overshoot>,
    /// Bound one parameter to [LO, HI] (repeatable): a canonical name (A,
    /// alpha, beta, gamma, beta1..beta6, n, x_s, a, b, c, x0) or a search
    /// coordinate's (gain, offset, x0_range, loading, beta_range, psi_pp, ...;
    /// result.json's search_box lists them), or an effect's as EFFECT.PARAM
    /// (creep.rho, inertia:ringing.a1: the names `fit --json`'s params
    /// prints, with --effects or --carry). Bounding A frees the gauge;
    /// bounding b or c searches the linear part in b, c, x0 themselves; a
    /// loop-shape parameter, the loop shape in its own parameters. NAME=VALUE
    /// holds it at VALUE, as --fix does; a name may be given once.
    #[arg(long, value_name = "NAME=LO:HI", conflicts_with = "thesis_flow")]
    pub(super) bound: Vec<UserBound>,
    /// Hold one parameter at VALUE (repeatable; names as --bound).
    #[arg(long, value_name = "NAME=VALUE", conflicts_with = "thesis_flow")]
    pub(super) fix: Vec<UserBound>,
    /// Stop once the estimation SSE (free run) is at or below this.
    #[arg(long, value_name = "SSE")]
    pub(super) target_sse: Option<f64>,
    /// Stop after this many seconds of the fit (the result then depends on
    /// the machine). The budget is the whole fit's: the --effects chain's
    /// build and every start (a start with no time left is not run), and
    /// a fit resumed from --checkpoint counts the seconds it ran before.
    #[arg(long, value_name = "SECONDS")]
    pub(super) time_budget: Option<f64>,
    /// End a population stage when its best has not improved for this many
    /// generations (at least 1).
    #[arg(long, value_name = "GENS", value_parser = crate::cli::common::stall)]
    pub(super) stall: Option<usize>,
    /// GA crossover (§5.2.1.5; default proportional).
    #[arg(long, value_enum, ignore_case = true)]
    pub(super) crossover: Option<Crossover>,
    /// GA: best individuals kept unchanged (thesis 0; staged fit N/10).
    #[arg(long)]
    pub(super) elitism: Option<usize>,
    /// GA: mutation probability P_mut (thesis 0.1; staged fit 0.3).
    #[arg(long)]
    pub(super) p_mut: Option<f64>,
    /// GA: fixed ±m_m mutation (thesis), uniform in [−m_m, m_m] (staged
    /// fit), or non-uniform (Michalewicz: towards a bound, reach shrinking
    /// over the generations).
    #[arg(long, value_enum, ignore_case = true)]
    pub(super) mutation: Option<Mutation>,
    /// MFA: Λ0 schedule from a to b (appendix code) or to a − b (eq. 36).
    #[arg(long, value_enum, ignore_case = true)]
    mfa_lambda0: Option<Lambda0Schedule>,
    /// MFA: attractiveness e^(−σr) (thesis' code) or e^(−σr²) (eq. 32;
    /// staged fit).
    #[arg(long, value_enum, ignore_case = true)]
    pub(super) mfa_distance: Option<Distance>,
    /// MFA: distances and walk in raw units (thesis) or box widths (staged fit).
    #[arg(long, value_enum, ignore_case = true)]
    pub(super) mfa_scale: Option<Scale>,
    /// MFA: move towards at most K brighter fireflies (thesis: all of them,
    /// O(N²·d) a generation; staged fit: the 10 brightest). 0 means all.
    #[arg(long, value_name = "K")]
    pub(super) mfa_attractors: Option<usize>,
    /// MFA: with --mfa-attractors, the K brightest instead of K at random.
    #[arg(long)]
    pub(super) mfa_brightest: bool,
    /// MFA: start ρ0 of the random walk ρ(k) = ρ0·e^(−4.8k/G) (eq. 38: 0.1).
    #[arg(long, value_name = "RHO0")]
    mfa_rho0: Option<f64>,
    /// DE: share of the population x_pbest is drawn from (0.1; smaller is
    /// greedier).
    #[arg(long)]
    pub(super) de_p_best: Option<f64>,
    /// PSO: one random number for the social term (appendix code).
    #[arg(long)]
    pub(super) pso_scalar_social: bool,
    /// Save the run state to FILE every 10 s and at the end; if FILE exists,
    /// resume from it to the identical result (the plan, N, G, seed and
    /// settings come from the checkpoint, stopping rules from this command).
    /// A checkpoint made on other data (file, columns, resampling) is
    /// refused.
    #[arg(long, value_parser = crate::cli::common::output_path, value_name = "FILE")]
    pub(super) checkpoint: Option<PathBuf>,
    /// Folder for the model, history and figures.
    #[arg(long, value_parser = crate::cli::common::output_path, value_name = "DIR", default_value = "out/fit")]
    pub(super) out: PathBuf,
    /// Print JSON on stdout instead of a report.
    #[arg(long)]
    pub(super) json: bool,
}

/// One entry of `--effects`: an effect of the catalogue, or `auto`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum EffectArg {
    Auto,
    Effect(Effect),
}

impl std::str::FromStr for EffectArg {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "auto" => Ok(EffectArg::Auto),
            _ => s.parse().map(EffectArg::Effect),
        }
    }
}

impl Args {
    /// The flags `--effects auto` would not read, given: the diagnosis'
    /// selection runs its own searches from the seed alone.
    pub(super) fn unread_by_auto(&self) -> Vec<&'static str> {
        let given = [
            ("--from", self.from.is_some()),
            ("--carry", self.carry.is_some()),
            ("--bound", !self.bound.is_empty()),
            ("--fix", !self.fix.is_empty()),
            ("--algo", self.algo != Algorithm::De),
            ("--pop", self.pop != POPULATION),
            ("--gens", self.gens != GENERATIONS),
            ("--thesis-flow", self.thesis_flow),
            ("--islands", self.islands.is_some()),
            ("--horizon", self.horizon.is_some()),
            ("--refine-rounds", self.refine_rounds.is_some()),
            ("--free-n", self.free_n),
            ("--loop", self.loop_shape != Loop::Bounded),
            ("--switch", self.switching.is_some()),
            ("--overshoot", self.overshoot.is_some()),
            ("--target-sse", self.target_sse.is_some()),
            ("--time-budget", self.time_budget.is_some()),
            ("--stall", self.stall.is_some()),
            ("--crossover", self.crossover.is_some()),
            ("--elitism", self.elitism.is_some()),
            ("--p-mut", self.p_mut.is_some()),
            ("--mutation", self.mutation.is_some()),
            ("--mfa-distance", self.mfa_distance.is_some()),
            ("--mfa-scale", self.mfa_scale.is_some()),
            ("--mfa-attractors", self.mfa_attractors.is_some()),
            ("--mfa-brightest", self.mfa_brightest),
            ("--mfa-lambda0", self.mfa_lambda0.is_some()),
            ("--mfa-rho0", self.mfa_rho0.is_some()),
            ("--de-p-best", self.de_p_best.is_some()),
            ("--pso-scalar-social", self.pso_scalar_social),
            ("--checkpoint", self.checkpoint.is_some()),
        ];
        given
            .iter()
            .filter(|(_, g)| *g)
            .map(|(flag, _)| *flag)
            .collect()
    }
    /// The fit the flags ask for.
    pub(super) fn settings(&self) -> FitSettings {
        FitSettings {
            algo: self.algo,
            pop: self.pop,
            gens: self.gens,
            seed: self.seed,
            thesis_flow: self.thesis_flow,
            islands: self.islands,
            horizon: self.horizon,
            refine_rounds: self.refine_rounds,
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

    /// The fit the flags ask for, before `--from` fills in the rest
    /// (`--effects auto` is the diagnosis' and is not one).
    pub(super) fn request(&self) -> anyhow::Result<FitRequest> {
        for f in &self.fix {
            anyhow::ensure!(
                f.lower == f.upper,
                "--fix {}: expected NAME=VALUE (use --bound for a range)",
                f.name
            );
        }
        anyhow::ensure!(
            !(self.free_n && self.fix.iter().any(|f| f.name == "n")),
            "--free-n fits the exponent n and --fix n holds it: give one of them"
        );
        // One box a parameter: two flags on one name would leave the user
        // guessing which one held.
        let given: Vec<&str> = self
            .bound
            .iter()
            .chain(&self.fix)
            .map(|b| b.name.as_str())
            .collect();
        for (i, name) in given.iter().enumerate() {
            anyhow::ensure!(
                !given[..i].contains(name),
                "`{name}` is given twice in --bound and --fix: give each parameter one box"
            );
        }
        let effects = self
            .effects
            .as_ref()
            .map(|list| {
                list.iter()
                    .map(|e| match e {
                        EffectArg::Effect(e) => Ok(*e),
                        EffectArg::Auto => Err(anyhow::anyhow!(
                            "--effects: `auto` stands alone (the diagnosis chooses every effect)"
                        )),
                    })
                    .collect::<anyhow::Result<Vec<Effect>>>()
            })
            .transpose()?;
        Ok(FitRequest {
            family: self.model.map(Family::from),
            effects,
            free_n: self.free_n,
            loop_shape: self.loop_shape,
            switching: self.switching,
            overshoot: self.overshoot,
            bounds: self.bound.iter().chain(&self.fix).cloned().collect(),
            carry: self.carry.is_some(),
        })
    }
}
