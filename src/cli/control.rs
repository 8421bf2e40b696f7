//! `mckibben control`: closed-loop sine tracking (chapter 6) on the rig twin
//! in process, or on a rig behind the line protocol. This file parses and
//! checks the flags and prints; the work is `control::{sweep, tuning, table,
//! figures}`'s and `rig::control_runs`'.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use super::common::{check_creatable, check_folder, given_once, population};
use mckibben::control::closed_loop::Episode;
use mckibben::control::figures;
use mckibben::control::reference::Waveform;
use mckibben::control::sweep::{
    self, DesignColumns, DesignRequest, Ingredients, Kind, ROBUST_LOAD_SCALE, Shape,
};
use mckibben::control::table::{self, DesignJson, JsonOutput, RunSettings};
use mckibben::control::tuning::{self, TuningRun};
use mckibben::control::{MpcSettings, PiGains, ValveLimits};
use mckibben::data::signals::nyquist_rad_s;
use mckibben::data::{same_step, tidy_step};
use mckibben::report::json::Versioned;
use mckibben::rig::Limits;
use mckibben::rig::control_runs::{self, PlantSpec, RigRunSettings};
use mckibben::twin::{MAX_LOAD_KG, Rig, TwinConfig};

/// The load (kg) the model is identified at on the twin unless
/// `--design-load` says otherwise: the thesis' lighter one.
const DESIGN_LOAD_KG: f64 = 4.5;
/// The gain tuning's optimizer, population and generations unless told.
const TUNING_ALGO: &str = "de";
const TUNING_POP: usize = 24;
const TUNING_GENS: usize = 30;
/// The longest MPC horizon `--horizon` takes (samples).
const MAX_HORIZON: usize = 500;

/// Track the sine reference of appendix A.1.2, r(t) = 30 + 10·sin(ω t) mm, by
/// closing the loop on the input valve voltage (0–10 V, slew 0.25 V per
/// sample; the output valve at 10 − u), and report the steady-state RMS and
/// maximum tracking error (the last 10 s of a 20 s sine after 10 s settling
/// at 30 mm), the valve effort and each controller step's time.
///
/// Controllers: `pi` — the thesis' gains (Table 22); `pi-tuned` — PID gains
/// tuned by an optimizer on every frequency and load; `ff-pid` — the tuned
/// PID plus the inverse of the identified model as feedforward; `mpc` — a QP
/// MPC whose model (valve map, eq. 13 with its Bouc-Wen loop) is identified
/// from an open-loop record, never read from the twin.
///
/// The plant is the in-process twin unless `--plant` names a rig speaking the
/// line protocol (docs/RIG_PROTOCOL.md): `cmd:COMMAND` runs COMMAND and talks
/// to its stdin/stdout, `udp:HOST:PORT` sends datagrams. Each sample has a
/// deadline; a missing measurement holds the last command; a malformed or
/// stale line ends the run with an error and the valve closed. A measurement
/// outside the rig's ranges, or a displacement jump faster than
/// --max-speed, is implausible: held like a missing one and never shown to
/// the controller; --max-implausible in a row end the run, valve closed,
/// and so does Ctrl-C.
///
/// Examples:
///   mckibben control --controller pi,mpc --freq 3 --load 4.5,7 --plot figs/
///   mckibben control --controller pi,pi-tuned,ff-pid,mpc --tuned-gains 2.2164,65.528,0.0219 --robustness --json
///   mckibben control --controller mpc --freq 3 --plant "cmd:mckibben twin serve --load 4.5" --log logs/
///   mckibben control --controller pi --plant udp:192.168.1.20:9000 --deadline 20 --design-data rig_multisine.csv
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// Controllers (comma-separated): pi, pi-tuned, ff-pid, mpc. Without
    /// `--tuned-gains`, `pi-tuned` and `ff-pid` tune first (minutes on 2 cores).
    #[arg(
        long,
        value_enum,
        ignore_case = true,
        value_delimiter = ',',
        default_value = "pi,mpc"
    )]
    controller: Vec<KindArg>,
    /// Reference frequencies ω (rad/s), comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "1,2,3",
        allow_negative_numbers = true
    )]
    freq: Vec<f64>,
    /// Loads (kg) of the in-process twin, comma-separated (ignored with --plant).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "4.5,7",
        allow_negative_numbers = true
    )]
    load: Vec<f64>,
    /// Load (kg) at which the model is identified on the twin.
    #[arg(long, default_value_t = DESIGN_LOAD_KG, allow_negative_numbers = true)]
    design_load: f64,
    /// Identify the model from this open-loop record (CSV with t, valve_in,
    /// pressure, displacement, or the names --design-columns gives; e.g. a
    /// multisine recorded on the rig) instead of the twin's design
    /// multisine. Its second half validates the model.
    #[arg(long, value_name = "FILE.csv")]
    design_data: Option<PathBuf>,
    /// The --design-data file's column names, in this order: its time, the
    /// input valve's voltage (V), the pressure and the displacement. A time
    /// whose name states ms, us or min (`t_ms`) is converted to seconds, a
    /// pressure or displacement whose name states its unit (`p_kPa`,
    /// `x_m`) to MPa or mm; one that states none is read so.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "TIME,VALVE,PRESSURE,DISPLACEMENT",
        requires = "design_data"
    )]
    design_columns: Option<Vec<String>>,
    /// Replace the identified displacement model by this one (a model file
    /// written by `fit --out`, `diagnose --out` or `identify --out`: the
    /// classic or linear family, with the effects the controllers can use).
    #[arg(long, value_name = "MODEL.json")]
    from: Option<PathBuf>,
    /// Also run the model-based controllers with the model's hysteresis
    /// scaled by these factors (e.g. 0.8,1.2).
    #[arg(long, value_delimiter = ',')]
    hysteresis_scale: Vec<f64>,
    /// Add the robustness table: for ff-pid and mpc at each --freq, the
    /// hysteresis ×0.8 and ×1.2 and the load 30 % below and above the design
    /// load, each against the nominal run.
    #[arg(long)]
    robustness: bool,
    /// PID gains `kp,ki,kd` (V/mm, V/(mm·s), V·s/mm) for pi-tuned and ff-pid.
    #[arg(long, value_delimiter = ',', value_name = "KP,KI,KD")]
    tuned_gains: Option<Vec<f64>>,
    /// Optimizer of the gain tuning: ga, mfa, pso or de.
    #[arg(long, default_value = TUNING_ALGO)]
    algo: String,
    /// Population of the gain tuning.
    #[arg(long, default_value_t = TUNING_POP, value_parser = population)]
    pop: usize,
    /// Generations of the gain tuning.
    #[arg(long, default_value_t = TUNING_GENS, value_parser = crate::cli::common::generations)]
    gens: usize,
    /// MPC horizon (samples), 2 to 500. Its QP is dense: its time a step
    /// grows about as the horizon's cube (200 samples took up to 0.13 s a
    /// step on a 2-core VM, past the 10 ms sample time; the command warns
    /// of late steps).
    #[arg(long, default_value_t = MpcSettings::default().horizon)]
    horizon: usize,
    /// MPC weight on valve moves (per V²) against tracking error (per mm²).
    #[arg(long, default_value_t = MpcSettings::default().r_move)]
    r_move: f64,
    /// The reference: `sine` (the thesis', 30 + 10·sin(ω t) mm) or `steps`
    /// (20 and 40 mm in turn, each held π/ω s: a square wave of the same
    /// period, after whose steps the hanging load rings).
    #[arg(long, value_enum, ignore_case = true, default_value = "sine")]
    reference: ReferenceArg,
    /// Scale one of the twin's non-ideal effects, as `mckibben twin
    /// --effect` (e.g. creep=1, ringing=1; repeatable): the in-process
    /// plant, the design record and the loop check all run with it.
    #[arg(long = "effect", value_name = "NAME=VALUE")]
    effects: Vec<String>,
    /// Seconds of regulation at 30 mm before the sine.
    #[arg(long, default_value_t = Shape::thesis().warmup_s)]
    warmup: f64,
    /// Seconds of sine.
    #[arg(long, default_value_t = Shape::thesis().duration_s)]
    duration: f64,
    /// Scoring starts this many seconds into the sine.
    #[arg(long, default_value_t = Shape::thesis().steady_from_s)]
    steady_from: f64,
    /// Seed of the twin's sensor noise (design record: this seed; its
    /// validation record: seed + 1) and of the tuning.
    #[arg(long, default_value_t = 1, value_parser = crate::cli::common::seed)]
    seed: u64,
    /// The plant: `twin` (in process), `cmd:COMMAND` or `udp:HOST:PORT`.
    #[arg(long, default_value = "twin", value_name = "SPEC")]
    plant: String,
    /// Deadline of each sample on an external plant (ms): a measurement is
    /// due this long after the one before it [default: 1.5 samples of the
    /// rig's sample time, i.e. one sample plus jitter; 15 ms at 10 ms].
    #[arg(long, value_name = "MS")]
    deadline: Option<f64>,
    /// Missing measurements in a row after which the run on a rig stops
    /// (valve closed) [default: 10].
    #[arg(long, value_name = "COUNT")]
    max_missing: Option<usize>,
    /// Pressures (MPa, gauge) the rig's sensor can read; a measurement
    /// outside is implausible [default: the ranges the rig announces in
    /// READY, else the twin's, -0.04,0.44].
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "MIN,MAX",
        allow_hyphen_values = true
    )]
    pressure_range: Option<Vec<f64>>,
    /// Displacements (mm, contraction positive) the rig's sensor can read
    /// [default: as --pressure-range; the twin's -10.5,55.5].
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "MIN,MAX",
        allow_hyphen_values = true
    )]
    displacement_range: Option<Vec<f64>>,
    /// Fastest the rig's displacement can change (mm/s); a larger jump
    /// since the last plausible sample is implausible [default: 500; the
    /// twin's load moves at most about 105 mm/s].
    #[arg(long, value_name = "MM_S")]
    max_speed: Option<f64>,
    /// Implausible measurements in a row after which the run on a rig stops
    /// (valve closed) [default: 3].
    #[arg(long, value_name = "COUNT")]
    max_implausible: Option<usize>,
    /// Write each external run's log into this folder as it goes.
    #[arg(long, value_parser = crate::cli::common::output_path, value_name = "DIR")]
    log: Option<PathBuf>,
    /// Write SVG figures (tracking, valve command, error per run; the
    /// model's loop and prediction error) into this folder.
    #[arg(long, value_parser = crate::cli::common::output_path, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Write one CSV per run, its columns in this order: t (s), pressure
    /// (MPa), displacement (mm), valve_in (V), reference (mm).
    #[arg(long, value_parser = crate::cli::common::output_path, value_name = "DIR")]
    csv: Option<PathBuf>,
    /// Print JSON (design, tuning, runs, robustness) instead of tables.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum KindArg {
    Pi,
    PiTuned,
    FfPid,
    Mpc,
}

impl From<KindArg> for Kind {
    fn from(k: KindArg) -> Kind {
        match k {
            KindArg::Pi => Kind::Pi,
            KindArg::PiTuned => Kind::PiTuned,
            KindArg::FfPid => Kind::FfPid,
            KindArg::Mpc => Kind::Mpc,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum ReferenceArg {
    Sine,
    Steps,
}

/// What the twin's settings decide before any run on it: every load the
/// runs hang on it and the episode's samples at its sample time.
fn check_on_twin(args: &Args, config: &TwinConfig, kinds: &[Kind]) -> anyhow::Result<()> {
    // Every load the runs hang on the twin: the tracking runs', the
    // design runs' (× ROBUST_LOAD_SCALE for the robustness table) and
    // the PI tuning's episodes'. The effects can make a load the
    // range checks above let through too heavy (a softer rubber).
    let mut hung: Vec<(&str, f64)> = args.load.iter().map(|&m| ("--load", m)).collect();
    hung.push(("--design-load", args.design_load));
    if args.robustness {
        hung.push(("--design-load", args.design_load * ROBUST_LOAD_SCALE));
    }
    if kinds.contains(&Kind::PiTuned) {
        let tuning = tuning::TuningEpisodes::default().loads_kg;
        hung.extend(tuning.into_iter().map(|m| ("the PI tuning's load", m)));
    }
    // An effect can make a load the rig cannot carry (the creep softens
    // the rubber) or take the rig outside its physics (a friction a
    // million times the twin's): the error names the effects beside the
    // load, as much their doing as the load's.
    let effects = match args.effects.as_slice() {
        [] => String::new(),
        given => format!(" with --effect {}", given.join(" --effect ")),
    };
    for (what, load) in hung {
        Rig::check_holds(config, load, args.seed)
            .map_err(|e| anyhow::anyhow!("{what}{effects}: {e}"))?;
    }
    // A rig's sample time is checked once its handshake gives it.
    Episode::short(1.0, args.warmup, args.duration, args.steady_from)
        .check(config.sample_time_s)
        .map_err(|e| anyhow::anyhow!("--warmup, --duration, --steady-from: {e}"))?;
    Ok(())
}

/// `--design-columns`' four names (the defaults without it), or why not.
fn design_columns(names: Option<&[String]>) -> anyhow::Result<DesignColumns> {
    let Some(names) = names else {
        return Ok(DesignColumns::default());
    };
    let [time, valve, pressure, displacement] = names else {
        anyhow::bail!(
            "--design-columns: {} name{} given; it takes four, in this order: \
             TIME,VALVE,PRESSURE,DISPLACEMENT (e.g. t,valve_in,pressure,displacement)",
            names.len(),
            if names.len() == 1 { "" } else { "s" }
        );
    };
    let named: Vec<&str> = names.iter().map(|n| n.trim()).collect();
    anyhow::ensure!(
        named.iter().all(|n| !n.is_empty()),
        "--design-columns: an empty name in \"{}\"; give four column names",
        names.join(",")
    );
    given_once(
        "--design-columns",
        &named,
        "a column is one signal: time, valve, pressure and displacement are four",
    )?;
    Ok(DesignColumns {
        time: time.trim().into(),
        valve: valve.trim().into(),
        pressure: pressure.trim().into(),
        displacement: displacement.trim().into(),
    })
}

fn check_args(args: &Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        !args.freq.is_empty() && !args.load.is_empty(),
        "--freq and --load need values"
    );
    let twice = "each run would be made, and reported, twice";
    let controllers: Vec<&str> = args
        .controller
        .iter()
        .map(|&k| Kind::from(k).label())
        .collect();
    given_once("--controller", &controllers, twice)?;
    given_once("--freq", &args.freq, twice)?;
    given_once("--load", &args.load, twice)?;
    given_once("--hysteresis-scale", &args.hysteresis_scale, twice)?;
    design_columns(args.design_columns.as_deref())?;
    for &w in &args.freq {
        anyhow::ensure!(
            w > 0.0 && w.is_finite(),
            "--freq: {w} is not a positive frequency (rad/s)"
        );
    }
    // The twin carries at most MAX_LOAD_KG; the robustness table runs it
    // at the design load × 1.3 too. Checked here, before any run.
    let heaviest = |flag: &str, m: f64, scale: f64| {
        anyhow::ensure!(
            m > 0.0 && m.is_finite(),
            "{flag}: {m} is not a positive mass (kg)"
        );
        anyhow::ensure!(
            m * scale <= MAX_LOAD_KG,
            "{flag} {m}: the twin carries at most {MAX_LOAD_KG} kg{}",
            if scale > 1.0 {
                format!(
                    ", and --robustness runs it at {scale} × the design load (so at most {:.2} kg)",
                    MAX_LOAD_KG / scale
                )
            } else {
                String::new()
            }
        );
        Ok(())
    };
    for &m in &args.load {
        heaviest("--load", m, 1.0)?;
    }
    let perturbed = if args.robustness {
        ROBUST_LOAD_SCALE
    } else {
        1.0
    };
    heaviest("--design-load", args.design_load, perturbed)?;
    for &s in &args.hysteresis_scale {
        anyhow::ensure!(
            s > 0.0 && s.is_finite(),
            "--hysteresis-scale: {s} must be positive"
        );
        // The nominal run is made anyway: a 1 would make it, and report
        // it, twice under one label.
        anyhow::ensure!(
            s != 1.0,
            "--hysteresis-scale: 1 is the nominal model, which runs anyway; give the other \
             scales alone (e.g. 0.8,1.2)"
        );
    }
    anyhow::ensure!(
        (2..=MAX_HORIZON).contains(&args.horizon),
        "--horizon {}: the MPC's horizon must be 2 to {MAX_HORIZON} samples (its QP is dense, \
         its time a step grows about as the horizon's cube: past a few hundred samples one \
         step takes seconds)",
        args.horizon
    );
    anyhow::ensure!(
        args.r_move > 0.0 && args.r_move.is_finite(),
        "--r-move {}: the weight on valve moves must be a positive, finite number",
        args.r_move
    );
    if let Some(ms) = args.deadline {
        // At most a day: a longer wait is a typo, and past about 10¹⁹ s
        // no clock can hold it.
        anyhow::ensure!(
            ms > 0.0 && ms <= 86_400_000.0,
            "--deadline must be a positive number of milliseconds, at most a day (got {ms})"
        );
    }
    anyhow::ensure!(
        args.max_missing.is_none_or(|n| n >= 1),
        "--max-missing must be at least 1"
    );
    anyhow::ensure!(
        args.max_implausible.is_none_or(|n| n >= 1),
        "--max-implausible must be at least 1"
    );
    if let Some(speed) = args.max_speed {
        anyhow::ensure!(
            speed > 0.0 && speed.is_finite(),
            "--max-speed must be a positive number of mm/s (got {speed})"
        );
    }
    for (flag, r) in [
        ("--pressure-range", &args.pressure_range),
        ("--displacement-range", &args.displacement_range),
    ] {
        if let Some(r) = r {
            anyhow::ensure!(
                r.len() == 2 && r.iter().all(|v| v.is_finite()) && r[0] < r[1],
                "{flag} takes two finite numbers MIN,MAX with MIN < MAX (got {r:?})"
            );
        }
    }
    anyhow::ensure!(
        args.warmup >= 0.0
            && args.duration > 0.0
            && (0.0..args.duration).contains(&args.steady_from),
        "--warmup {} ≥ 0, --duration {} > 0 and 0 ≤ --steady-from {} < --duration: \
         each is in seconds, and a shorter --duration needs a --steady-from below it \
         (its default is {} s)",
        args.warmup,
        args.duration,
        args.steady_from,
        Shape::thesis().steady_from_s
    );
    if let Some(g) = &args.tuned_gains {
        anyhow::ensure!(
            g.len() == 3 && g.iter().all(|v| v.is_finite() && *v >= 0.0),
            "--tuned-gains takes three non-negative numbers kp,ki,kd (got {g:?})"
        );
    }
    Ok(())
}

pub fn run(args: Args) -> anyhow::Result<()> {
    check_args(&args)?;
    let plant = PlantSpec::parse(&args.plant)?;
    if matches!(plant, PlantSpec::Twin) {
        // The link's flags have no link to hold to on the in-process twin:
        // say so rather than run as if they held.
        let given: Vec<&str> = [
            ("--deadline", args.deadline.is_some()),
            ("--pressure-range", args.pressure_range.is_some()),
            ("--displacement-range", args.displacement_range.is_some()),
            ("--max-missing", args.max_missing.is_some()),
            ("--max-speed", args.max_speed.is_some()),
            ("--max-implausible", args.max_implausible.is_some()),
            ("--log", args.log.is_some()),
        ]
        .into_iter()
        .filter_map(|(flag, given)| given.then_some(flag))
        .collect();
        anyhow::ensure!(
            given.is_empty(),
            "{} hold(s) a run on a rig (--plant cmd:... or udp:...); the in-process twin \
             has no link to hold to them",
            given.join(", ")
        );
    } else {
        // Its perturbed runs move the twin's load, which a rig's cannot
        // follow: run on the twin, they would pass as the rig's.
        anyhow::ensure!(
            !args.robustness,
            "--robustness runs the in-process twin at loads 30 % off the design load, which a \
             rig's load cannot follow; on a rig, --hysteresis-scale 0.8,1.2 runs its model-side \
             half, and --robustness without --plant the whole table on the twin"
        );
    }
    let kinds: Vec<Kind> = args.controller.iter().map(|&k| k.into()).collect();
    let designs = kinds.iter().any(|k| k.needs_model()) || args.robustness;
    // Said, not refused: a script may name its record for every run.
    let asked = || {
        args.controller
            .iter()
            .map(|&k| Kind::from(k).label())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let model_based = kinds.iter().any(|k| k.needs_model());
    for (flag, given, used, by) in [
        ("--from", args.from.is_some(), designs, "ff-pid or mpc"),
        (
            "--design-data",
            args.design_data.is_some(),
            designs,
            "ff-pid or mpc",
        ),
        (
            "--hysteresis-scale",
            !args.hysteresis_scale.is_empty(),
            model_based,
            "ff-pid or mpc",
        ),
        (
            "--robustness",
            args.robustness,
            model_based,
            "ff-pid or mpc",
        ),
        (
            "--tuned-gains",
            args.tuned_gains.is_some(),
            kinds.iter().any(|k| k.needs_gains()),
            "pi-tuned or ff-pid",
        ),
        (
            "--design-load",
            args.design_load != DESIGN_LOAD_KG,
            designs,
            "ff-pid or mpc",
        ),
        (
            "--horizon",
            args.horizon != MpcSettings::default().horizon,
            kinds.contains(&Kind::Mpc),
            "mpc",
        ),
        (
            "--r-move",
            args.r_move != MpcSettings::default().r_move,
            kinds.contains(&Kind::Mpc),
            "mpc",
        ),
    ] {
        if given && !used {
            errln!(
                "mckibben: warning: {flag} is not read: none of the controllers asked for ({}) \
                 uses it; add {by} to --controller for one that does",
                asked()
            );
        }
    }
    // The tuning's knobs, where nothing is tuned.
    let tunes = kinds.iter().any(|k| k.needs_gains()) && args.tuned_gains.is_none();
    for (flag, given) in [
        ("--algo", args.algo != TUNING_ALGO),
        ("--pop", args.pop != TUNING_POP),
        ("--gens", args.gens != TUNING_GENS),
    ] {
        if given && !tunes {
            let why = match args.tuned_gains {
                Some(_) => "the gains are given (--tuned-gains)".to_string(),
                None => format!(
                    "none of the controllers asked for ({}) is tuned; pi-tuned and ff-pid are",
                    asked()
                ),
            };
            errln!("mckibben: warning: {flag} is not read: it sets the gain tuning, and {why}");
        }
    }
    // On a rig the twin runs only the design and the tuning.
    if !matches!(plant, PlantSpec::Twin) && !designs && !tunes && !args.effects.is_empty() {
        errln!(
            "mckibben: warning: --effect is not read: it sets the twin, which here runs \
             neither a design (ff-pid, mpc) nor a tuning (pi-tuned, ff-pid), the runs being \
             on the rig"
        );
    }
    // The folders first: runs of minutes must not end on a path that
    // cannot be written (the writers create them for good).
    for (flag, dir) in [("--plot", &args.plot), ("--csv", &args.csv)] {
        if let Some(dir) = dir {
            check_creatable(flag, dir)?;
        }
    }
    // Read before any run: a model that cannot steer the controllers
    // fails at once, not after the twin's checks and the design.
    let given = match &args.from {
        Some(path) if designs => Some(sweep::given_model(path, &|s| {
            errln!("mckibben: note: {s}")
        })?),
        _ => None,
    };
    let mut config = TwinConfig::default();
    config.effects.apply_args(&args.effects)?;
    config.validate()?;
    if matches!(plant, PlantSpec::Twin) {
        check_on_twin(&args, &config, &kinds)?;
        let nyquist = nyquist_rad_s(config.sample_time_s);
        if let Some(w) = args.freq.iter().find(|&&w| w >= nyquist) {
            anyhow::bail!(
                "--freq {w}: the twin samples every {} s, so a reference must stay below \
                 Nyquist's {nyquist:.1} rad/s (π/dt)",
                config.sample_time_s
            );
        }
    }
    // A discrete-time model's poles are per sample: a model on another
    // step than the twin's is refused before the design's seconds of work
    // (a model file's step is known now, a design record's once
    // identified; a rig's once its handshake gives it).
    let step_refused = |dt: f64| -> anyhow::Result<()> {
        if !matches!(plant, PlantSpec::Twin) || same_step(dt, config.sample_time_s) {
            return Ok(());
        }
        let source = match (&args.from, &args.design_data) {
            (Some(p), _) => format!("--from {}", p.display()),
            (None, Some(p)) => format!("--design-data {}", p.display()),
            (None, None) => "the design record".into(),
        };
        anyhow::bail!(
            "{source}: the model steps every {} s, the twin every {} s: a discrete-time \
             model's poles are per sample; give a model fitted on data sampled every {} s",
            tidy_step(dt),
            config.sample_time_s,
            config.sample_time_s
        )
    };
    if let Some(g) = &given {
        step_refused(g.model.base.dt)?;
    }
    let say = |s: String| {
        if !args.json {
            errln!("{s}");
        }
    };
    let design = if designs {
        let request = DesignRequest {
            record: args.design_data.clone(),
            columns: design_columns(args.design_columns.as_deref())?,
            model: given,
            load_kg: args.design_load,
            seed: args.seed,
            horizon: args.horizon,
        };
        let d = sweep::design_for(&request, &config, &|s| errln!("mckibben: note: {s}"))?;
        step_refused(d.model.displacement.dt)?;
        say(d.summary());
        Some(d)
    } else {
        None
    };
    let given = args.tuned_gains.as_ref().map(|g| PiGains {
        kp: g[0],
        ki: g[1],
        kd: g[2],
    });
    let tuning_run = TuningRun {
        algo: args.algo.clone(),
        pop: args.pop,
        gens: args.gens,
        seed: args.seed,
    };
    let tuned = tuning::gains_for(&kinds, given, &tuning_run, &config, &say)?;
    let ing = Ingredients {
        model: design.as_ref().map(|d| d.model.clone()),
        gains: tuned.as_ref().map(|t| t.gains),
        mpc: MpcSettings {
            horizon: args.horizon,
            r_move: args.r_move,
            ..MpcSettings::default()
        },
        limits: ValveLimits::default(),
    };
    let shape = Shape {
        warmup_s: args.warmup,
        duration_s: args.duration,
        steady_from_s: args.steady_from,
        waveform: match args.reference {
            ReferenceArg::Sine => Waveform::Sine,
            ReferenceArg::Steps => Waveform::Steps,
        },
    };
    let (rows, runs) = match plant {
        PlantSpec::Twin => table::on_twin(
            &kinds,
            &args.freq,
            &args.load,
            &args.hysteresis_scale,
            &ing,
            &config,
            args.seed,
            &shape,
            &say,
        )?,
        PlantSpec::Rig(endpoint) => {
            let pair = |r: &Option<Vec<f64>>| r.as_ref().map(|v| (v[0], v[1]));
            let settings = RigRunSettings {
                plant: args.plant.clone(),
                endpoint,
                deadline_ms: args.deadline,
                max_missing: args
                    .max_missing
                    .unwrap_or(RigRunSettings::DEFAULT_MAX_MISSING),
                pressure_range: pair(&args.pressure_range),
                displacement_range: pair(&args.displacement_range),
                max_speed_mm_s: args.max_speed.unwrap_or(Limits::DEFAULT_MAX_SPEED_MM_S),
                max_implausible: args
                    .max_implausible
                    .unwrap_or(RigRunSettings::DEFAULT_MAX_IMPLAUSIBLE),
                log_dir: args.log.clone(),
                interrupt: Arc::new(AtomicBool::new(false)),
            };
            let flag = settings.interrupt.clone();
            // One handler a process; failing to install it only means that
            // Ctrl-C kills the run instead of closing the valve first.
            let _ = ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst));
            let plan = sweep::plan(&kinds, &args.freq, &[f64::NAN], &args.hysteresis_scale);
            control_runs::on_rig(&plan, &settings, &ing, &shape, &say)?
        }
    };
    let robust = if args.robustness {
        let (kinds, freqs) = (&kinds, &args.freq);
        table::robustness(
            kinds,
            freqs,
            args.design_load,
            &ing,
            &config,
            args.seed,
            &shape,
            &say,
        )?
    } else {
        Vec::new()
    };
    // What a row measures that is not the controller at its best, a
    // warning each.
    for (r, episode) in rows.iter().zip(&runs) {
        let run = format!(
            "{} at {} rad/s{}",
            sweep::scaled_label(&r.controller, r.hysteresis_scale),
            r.freq_rad_s,
            r.load_kg.map_or(String::new(), |m| format!(", {m} kg"))
        );
        if r.solver_failures > 0 {
            errln!(
                "mckibben: warning: {run}: {} of the MPC's QP solves failed, and the valve held \
                 its last command at each; its row measures that, not the MPC",
                r.solver_failures
            );
        }
        if r.overrun_steps > 0 {
            errln!(
                "mckibben: warning: {run}: {} of its steps took longer than the sample time \
                 (longest {:.1} ms): on a real-time rig those commands come late and the \
                 measurements queue behind them (shorten the MPC's --horizon, or run a lighter \
                 controller)",
                r.overrun_steps,
                // The clock the steps were counted by: the thread's, the
                // wall's where there is none.
                match r.max_step_cpu_us > 0.0 {
                    true => r.max_step_cpu_us,
                    false => r.max_step_time_us,
                } / 1e3
            );
        }
        // A feedforward pinned at the valve's range most of the run is no
        // feedforward: the PID's integrator takes it up, and the row is the
        // PID's alone (a model whose inverse asks for more than the valve
        // gives).
        let samples = episode.result.t.len();
        if 2 * r.feedforward_at_limit > samples {
            errln!(
                "mckibben: warning: {run}: the feedforward was at the valve's range on {} of \
                 {samples} samples: the model's inverse asks for more than the valve gives, and \
                 the row measures the PID alone",
                r.feedforward_at_limit
            );
        }
        if r.worse_than_holding {
            errln!(
                "mckibben: warning: {run}: its RMS error {:.3} mm is above the {:.3} mm of a \
                 muscle held still at the reference's mean: the loop tracks worse than doing \
                 nothing",
                r.rms_error_mm,
                r.holding_rms_mm
            );
        }
    }
    // The results are printed before the files are written: a write that
    // fails loses none of them.
    if args.json {
        let mpc_ran = kinds.contains(&Kind::Mpc);
        let out = JsonOutput {
            settings: RunSettings::of(&shape, args.seed, mpc_ran.then_some(&ing.mpc)),
            design: design.as_ref().map(DesignJson::of),
            tuned: tuned.as_ref(),
            runs: &rows,
            robustness: &robust,
        };
        outln!("{}", Versioned::new(out).to_string_pretty()?)?;
    } else {
        out!("{}", table::text(&rows, &robust))?;
    }
    // Only now are the files' names known (a run's controller names it):
    // none may replace a file the command read.
    let reads: Vec<(&str, &Path)> = [("--design-data", &args.design_data), ("--from", &args.from)]
        .into_iter()
        .filter_map(|(flag, path)| Some((flag, path.as_deref()?)))
        .collect();
    let stems: Vec<String> = runs
        .iter()
        .map(|r| figures::stem(r, shape.waveform))
        .collect();
    if let Some(dir) = &args.plot {
        let mut names: Vec<String> = stems.iter().map(|s| format!("{s}.svg")).collect();
        names.push(figures::DESIGN_FIGURE.into());
        check_folder("--plot", dir, &names, &reads)?;
        figures::save(dir, &runs, shape.waveform, design.as_ref())?;
    }
    if let Some(dir) = &args.csv {
        let names: Vec<String> = stems.iter().map(|s| format!("{s}.csv")).collect();
        check_folder("--csv", dir, &names, &reads)?;
        table::write_csvs(dir, &runs, shape.waveform)?;
    }
    Ok(())
}
