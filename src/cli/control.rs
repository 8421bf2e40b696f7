//! `mckibben control`: closed-loop sine tracking (chapter 6) on the rig twin
//! in process, or on a rig behind the line protocol. This file parses and
//! checks the flags and prints; the work is `control::{sweep, tuning, table,
//! figures}`'s and `rig::control_runs`'.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use super::common::{check_creatable, check_folder, population};
use mckibben::control::figures;
use mckibben::control::reference::Waveform;
use mckibben::control::session::{
    self, ControlPlan, DESIGN_LOAD_KG, Outcome, TUNING_ALGO, TUNING_GENS, TUNING_POP,
};
use mckibben::control::sweep::{self, DesignColumns, GivenModel, Kind, Shape};
use mckibben::control::table;
use mckibben::control::{MpcSettings, PiGains};
use mckibben::optim::stop::StopFlag;
use mckibben::report::json::Versioned;
use mckibben::rig::Limits;
use mckibben::rig::control_runs::{self, PlantSpec, RigRunSettings};

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
/// and so does Ctrl-C. On the twin, Ctrl-C stops before the next run (in
/// the PID's tuning, after the current generation): nothing is printed or
/// written, and the command exits with status 130.
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
    /// A model fitted in other units (`p_kPa`, `x_m`) is converted to MPa
    /// and mm, its effects too, with a note.
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

/// `--design-columns`' four names (the defaults without it), or why not.
fn design_columns(names: Option<&[String]>) -> anyhow::Result<DesignColumns> {
    names.map_or(Ok(DesignColumns::default()), DesignColumns::from_names)
}

/// The plan the flags ask for, its values unchecked
/// ([`ControlPlan::check`]).
fn plan_of(args: &Args, model: Option<GivenModel>) -> anyhow::Result<ControlPlan> {
    let tuned_gains = match &args.tuned_gains {
        Some(g) => {
            let [kp, ki, kd] = g[..] else {
                anyhow::bail!(
                    "--tuned-gains takes three non-negative numbers kp,ki,kd (got {g:?})"
                );
            };
            Some(PiGains { kp, ki, kd })
        }
        None => None,
    };
    Ok(ControlPlan {
        kinds: args.controller.iter().map(|&k| k.into()).collect(),
        freqs: args.freq.clone(),
        loads: args.load.clone(),
        hysteresis_scales: args.hysteresis_scale.clone(),
        robustness: args.robustness,
        design_record: args.design_data.clone(),
        design_columns: design_columns(args.design_columns.as_deref())?,
        model,
        design_load_kg: args.design_load,
        tuned_gains,
        algo: args.algo.clone(),
        pop: args.pop,
        gens: args.gens,
        mpc: MpcSettings {
            horizon: args.horizon,
            r_move: args.r_move,
            ..MpcSettings::default()
        },
        shape: Shape {
            warmup_s: args.warmup,
            duration_s: args.duration,
            steady_from_s: args.steady_from,
            waveform: match args.reference {
                ReferenceArg::Sine => Waveform::Sine,
                ReferenceArg::Steps => Waveform::Steps,
            },
        },
        effects: args.effects.clone(),
        seed: args.seed,
        stop: StopFlag::default(),
    })
}

/// The flags of a run on a rig.
fn check_rig_args(args: &Args) -> anyhow::Result<()> {
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
    Ok(())
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut plan = plan_of(&args, None)?;
    plan.check()?;
    check_rig_args(&args)?;
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
    let kinds = &plan.kinds;
    let designs = plan.designs();
    // Said, not refused: a script may name its record for every run.
    for w in plan.unread(args.from.as_ref().map(|_| "--from")) {
        errln!("mckibben: warning: {w}");
    }
    let tunes = plan.tunes();
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
    plan.model = match &args.from {
        Some(path) if designs => Some(sweep::given_model(path, &|s| {
            errln!("mckibben: note: {s}")
        })?),
        _ => None,
    };
    let config = plan.twin_config()?;
    if matches!(plant, PlantSpec::Twin) {
        plan.check_on_twin(&config)?;
    }
    let say = |s: String| {
        if !args.json {
            errln!("{s}");
        }
    };
    let note = |s: String| errln!("mckibben: note: {s}");
    let on_twin = matches!(plant, PlantSpec::Twin);
    if on_twin {
        let stop = plan.stop.clone();
        // One handler a process (a rig's closes its valve instead):
        // failing to install it only means that Ctrl-C kills the runs
        // instead of stopping them between two.
        let _ = ctrlc::set_handler(move || stop.raise());
    }
    let prepared = plan.prepare(&config, on_twin, &say, &note)?;
    let (rows, runs, robust) = match plant {
        PlantSpec::Twin => plan.run_on_twin(&prepared, &config, &say)?,
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
            let specs = sweep::plan(kinds, &plan.freqs, &[f64::NAN], &plan.hysteresis_scales);
            let (rows, runs) =
                control_runs::on_rig(&specs, &settings, &prepared.ingredients, &plan.shape, &say)?;
            (rows, runs, Vec::new())
        }
    };
    let outcome = Outcome {
        prepared,
        rows,
        runs,
        robust,
    };
    // What a row measures that is not the controller at its best.
    for w in session::warnings(&outcome.rows, &outcome.runs) {
        errln!("mckibben: warning: {w}");
    }
    // The results are printed before the files are written: a write that
    // fails loses none of them.
    if args.json {
        outln!(
            "{}",
            Versioned::new(outcome.json(&plan)).to_string_pretty()?
        )?;
    } else {
        out!("{}", table::text(&outcome.rows, &outcome.robust))?;
    }
    // Only now are the files' names known (a run's controller names it):
    // none may replace a file the command read.
    let reads: Vec<(&str, &Path)> = [("--design-data", &args.design_data), ("--from", &args.from)]
        .into_iter()
        .filter_map(|(flag, path)| Some((flag, path.as_deref()?)))
        .collect();
    let stems: Vec<String> = outcome
        .runs
        .iter()
        .map(|r| figures::stem(r, plan.shape.waveform))
        .collect();
    if let Some(dir) = &args.plot {
        let mut names: Vec<String> = stems.iter().map(|s| format!("{s}.svg")).collect();
        names.push(figures::DESIGN_FIGURE.into());
        check_folder("--plot", dir, &names, &reads)?;
        figures::save(
            dir,
            &outcome.runs,
            plan.shape.waveform,
            outcome.prepared.design.as_ref(),
        )?;
    }
    if let Some(dir) = &args.csv {
        let names: Vec<String> = stems.iter().map(|s| format!("{s}.csv")).collect();
        check_folder("--csv", dir, &names, &reads)?;
        table::write_csvs(dir, &outcome.runs, plan.shape.waveform)?;
    }
    Ok(())
}
