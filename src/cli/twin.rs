//! `mckibben twin`: run an experiment on the rig twin and write its CSV.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;

use mckibben::data::Trace;
use mckibben::report::{Figure, Panel, Series};
use mckibben::twin::experiment::{DEFAULT_FREQ_RAD_S, Kind, RunSpec};

use super::common::{CsvOut, check_distinct};

/// Run an experiment on the rig twin, a physically based simulator of the
/// thesis' tap-water rig (two proportional valves, water column, braided
/// muscle with friction, hanging load, sensors; see docs/TWIN.md), and write
/// the recording as CSV: t, pressure (MPa gauge), displacement (mm,
/// contraction positive from the rest length under the load), valve_in,
/// valve_out (V), load_kg, and reference (mm) for the sine.
/// The same arguments always give the same bytes.
///
/// Experiments: `stair` — the identification staircase of appendix A.1.1 on
/// the input valve (output valve at 10 − u), 0→10→0 V in 1 V steps of 1 s,
/// twice (40 s); `sine` — the thesis' PI (Table 22) tracking
/// r(t) = 30 + 10·sin(ω t) mm for 40 s; `multisine` — 5 ± 4 V, 8 sines
/// 0.02–1 Hz with phases from the seed, 40 s.
///
/// `mckibben twin serve` plays the rig over the line protocol instead
/// (see `mckibben help twin serve`).
///
/// Examples:
///   mckibben twin --experiment stair --load 4.5 --seed 1 --out data/stair_4.5kg.csv
///   mckibben twin --experiment sine --freq 3 --load 7 --out sine.csv
///   mckibben twin --experiment stair --effect friction=0 --effect noise=0 --out ideal.csv
///   mckibben twin serve --load 4.5 --udp 127.0.0.1:9000 --realtime
#[derive(Debug, clap::Args)]
#[command(
    verbatim_doc_comment,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
pub struct Args {
    #[command(subcommand)]
    command: Option<TwinCommand>,
    /// Which experiment to run.
    #[arg(long, value_enum, ignore_case = true, default_value = "stair")]
    experiment: ExperimentArg,
    /// Hanging load in kg (thesis: 4.5 or 7).
    #[arg(long, default_value_t = 4.5)]
    load: f64,
    /// Seed of the sensor noise (and of the multisine's phases).
    #[arg(long, default_value_t = 1, value_parser = crate::cli::common::seed)]
    seed: u64,
    /// Angular frequency of the sine reference in rad/s (thesis: 1, 2, 3), below
    /// Nyquist's π/dt (314 rad/s at the twin's 0.01 s); `--experiment sine`
    /// only [default: 1].
    #[arg(long, value_name = "RAD_S")]
    freq: Option<f64>,
    /// Scale a non-ideal effect: 1 = as documented, 0 = off, 2 = twice as
    /// large. Repeatable. Names (the first eight default to 1):
    ///   friction      braid friction (Maxwell-slip break-away forces)
    ///   deadband      valve dead band width
    ///   spool_lag     valve spool time constant
    ///   compliance    hose and bladder compliance (0 leaves water's bulk modulus)
    ///   endstop       end-stop contact stiffness and damping
    ///   noise         sensor noise
    ///   quantization  sensor quantization step
    ///   thickness     wall thickness t_k of eq. 9 (0 gives eq. 7)
    /// These two default to 0 (off), so that the default runs keep the
    /// numbers published from them; turn them on with e.g. creep=1:
    ///   creep         the bladder's slow creep (10 % of the rubber's
    ///                 stiffness relaxing in 5 s; scale < 10, and the
    ///                 softer rubber must carry the load: up to about 7
    ///                 at 4.5 kg, 6 at 7 kg)
    ///   ringing       the load ringing on the muscle's stiffness
    ///                 (√(k/m)/2π, 6–9 Hz here), scales its excitation
    ///                 (a scale whose swing would leave the muscle
    ///                 slack is refused; about 2 and up on fast moves)
    #[arg(long = "effect", value_name = "NAME=VALUE", verbatim_doc_comment)]
    effects: Vec<String>,
    /// Write the CSV here (atomically); `-` writes it to standard output,
    /// for a pipe, and the summary line to standard error.
    #[arg(long, value_parser = crate::cli::common::csv_output, value_name = "FILE.csv", required = true)]
    out: Option<CsvOut>,
    /// Also draw the run to this SVG file: pressure and displacement against
    /// time (thesis figure 3) and displacement against pressure (figure 4).
    #[arg(long, value_parser = crate::cli::common::output_path, value_name = "FILE.svg")]
    plot: Option<PathBuf>,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum ExperimentArg {
    Stair,
    Sine,
    Multisine,
}

#[derive(Debug, clap::Subcommand)]
enum TwinCommand {
    #[command(about = "Play the rig over the line protocol (stdin/stdout or UDP) for a controller")]
    Serve(ServeArgs),
}

/// Play the rig for a controller over the line protocol of
/// docs/RIG_PROTOCOL.md: on stdin/stdout (so that `mckibben control --plant
/// "cmd:mckibben twin serve ..."` runs it as a child process) or on a UDP
/// port. Each HELLO starts a session on a fresh twin (same load, same seed),
/// at rest until the first command. Lockstep by default — the twin advances
/// a sample when its command arrives, as fast as the controller goes, with
/// the numbers of an in-process run; with --realtime it keeps wall-clock
/// time, sends each measurement at its tick and holds the last command when
/// the next one is late. Session reports go to stderr.
///
/// Faults (--fault, repeatable) test a controller's handling of a bad rig:
///   drop@K        never send measurement K
///   delay@K=MS    send measurement K MS milliseconds late
///   garble@K      send a malformed line instead of measurement K
///   stale@K       send measurement K with the time stamp of sample K−10
///   repeat@K      send measurement K−1 again instead of K
///
/// Examples:
///   mckibben twin serve --load 4.5 --seed 1
///   mckibben twin serve --load 7 --udp 127.0.0.1:9000 --realtime
///   mckibben control --controller mpc --freq 3 --plant "cmd:mckibben twin serve --fault drop@500"
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct ServeArgs {
    /// Hanging load in kg.
    #[arg(long, default_value_t = 4.5)]
    load: f64,
    /// Seed of the sensor noise.
    #[arg(long, default_value_t = 1, value_parser = crate::cli::common::seed)]
    seed: u64,
    /// Scale a non-ideal effect (as `mckibben twin --effect`; creep and
    /// ringing default to 0, the others to 1). Repeatable.
    #[arg(long = "effect", value_name = "NAME=VALUE")]
    effects: Vec<String>,
    /// Keep wall-clock time (one sample every dt) instead of lockstep.
    #[arg(long)]
    realtime: bool,
    /// Serve on this UDP address (HOST:PORT; port 0 picks a free one, printed
    /// on stderr) instead of stdin/stdout.
    #[arg(long, value_name = "HOST:PORT")]
    udp: Option<String>,
    /// Inject a fault into the measurements (see above). Repeatable.
    #[arg(long = "fault", value_name = "KIND@K[=MS]")]
    faults: Vec<String>,
    /// End a session that receives nothing for this many seconds.
    #[arg(long, default_value_t = 10.0, value_name = "S")]
    idle_timeout: f64,
}

fn serve(args: ServeArgs) -> anyhow::Result<()> {
    use mckibben::rig::serve::{Fault, Pace, ServeSettings};
    use mckibben::rig::{Link, StdioLink, UdpLink};
    let faults = args
        .faults
        .iter()
        .map(|f| {
            f.parse::<Fault>()
                .map_err(|e| anyhow::anyhow!("--fault {e}"))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    // At most a day: a longer wait is a typo, and past about 10¹⁹ s no
    // clock can hold it.
    anyhow::ensure!(
        args.idle_timeout > 0.0 && args.idle_timeout <= 86_400.0,
        "--idle-timeout must be a positive number of seconds, at most a day (got {})",
        args.idle_timeout
    );
    let probe = RunSpec {
        kind: Kind::Stair,
        load_kg: args.load,
        seed: args.seed,
        freq_rad_s: 1.0,
        effects: args.effects.clone(),
    };
    // Checks the load and the effects as `twin` does.
    let config = probe.checked_config()?;
    let settings = ServeSettings {
        config,
        load_kg: args.load,
        seed: args.seed,
        pace: if args.realtime {
            Pace::RealTime
        } else {
            Pace::Lockstep
        },
        faults,
        idle_timeout: std::time::Duration::from_secs_f64(args.idle_timeout),
    };
    let mut link: Box<dyn Link> = match &args.udp {
        Some(addr) => {
            use std::net::ToSocketAddrs;
            let a = addr
                .to_socket_addrs()
                .with_context(|| format!("--udp {addr}: not a HOST:PORT"))?
                .next()
                .ok_or_else(|| anyhow::anyhow!("--udp {addr}: no address"))?;
            let link = UdpLink::serve(a).with_context(|| format!("--udp {addr}: cannot bind"))?;
            errln!("twin serve: listening on udp {}", link.local_addr()?);
            Box::new(link)
        }
        None => Box::new(StdioLink::new()),
    };
    mckibben::rig::serve::serve(link.as_mut(), &settings, |r| {
        errln!(
            "twin serve: session ended after {} samples ({}); late commands: {}",
            r.samples,
            r.end,
            r.late_commands
        )
    })
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(TwinCommand::Serve(s)) = args.command {
        return serve(s);
    }
    let out = args.out.clone().expect("clap requires --out");
    if let (Some(csv), Some(plot)) = (out.file(), &args.plot) {
        check_distinct(&[], &[("--out", csv), ("--plot", plot)])?;
    }
    anyhow::ensure!(
        args.freq.is_none() || matches!(args.experiment, ExperimentArg::Sine),
        "--freq sets the sine's frequency: --experiment sine"
    );
    let spec = RunSpec {
        kind: match args.experiment {
            ExperimentArg::Stair => Kind::Stair,
            ExperimentArg::Sine => Kind::Sine,
            ExperimentArg::Multisine => Kind::Multisine,
        },
        load_kg: args.load,
        seed: args.seed,
        freq_rad_s: args.freq.unwrap_or(DEFAULT_FREQ_RAD_S),
        effects: args.effects.clone(),
    };
    let trace = spec.run()?;
    let plot = args.plot.as_ref().map(|p| (p, figure(&trace, &spec)));
    out.write(
        &trace,
        &spec.comments(),
        plot.as_ref().map(|(p, f)| (p.as_path(), f)),
    )?;
    let summary = format!(
        "{out}: {} samples, dt = {} s ({})",
        trace.len(),
        trace.dt(),
        spec.command()
    );
    let mut report = CsvOut::summary(Some(&out));
    writeln!(report, "{summary}")?;
    if let Some(path) = &args.plot {
        writeln!(report, "figure written to {}", path.display())?;
    }
    Ok(())
}

/// Thesis figures 3 and 4 for one run.
fn figure(trace: &Trace, spec: &RunSpec) -> Figure {
    let title = format!(
        "Twin, {} at {} kg (seed {})",
        spec.kind.as_str(),
        spec.load_kg,
        spec.seed
    );
    let mut displacement = Panel::new("Displacement", "t (s)", "displacement (mm)").with(
        Series::line("displacement", trace.t.clone(), trace.output.clone()),
    );
    if let Some(r) = trace.column("reference") {
        displacement = displacement.with(Series::line("reference", trace.t.clone(), r.to_vec()));
    }
    Figure::new(title)
        .with(
            Panel::new("Pressure", "t (s)", "pressure (MPa gauge)").with(Series::line(
                "pressure",
                trace.t.clone(),
                trace.input.clone(),
            )),
        )
        .with(displacement)
        .with(
            Panel::new("Hysteresis", "pressure (MPa gauge)", "displacement (mm)").with(
                Series::points(
                    "every 4th sample",
                    trace.input.iter().step_by(4).copied().collect(),
                    trace.output.iter().step_by(4).copied().collect(),
                ),
            ),
        )
}
