//! `mckibben twin`: run an experiment on the rig twin and write its CSV.

use std::path::PathBuf;

use anyhow::Context;

use mckibben::data::Trace;
use mckibben::report::{Figure, Panel, Series};
use mckibben::twin::experiment::{Kind, RunSpec};

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
/// Examples:
///   mckibben twin --experiment stair --load 4.5 --seed 1 --out data/stair_4.5kg.csv
///   mckibben twin --experiment sine --freq 3 --load 7 --out sine.csv
///   mckibben twin --experiment stair --effect friction=0 --effect noise=0 --out ideal.csv
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// Which experiment to run.
    #[arg(long, value_enum, default_value = "stair")]
    experiment: ExperimentArg,
    /// Hanging load in kg (thesis: 4.5 or 7).
    #[arg(long, default_value_t = 4.5)]
    load: f64,
    /// Seed of the sensor noise (and of the multisine's phases).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Angular frequency of the sine reference in rad/s (thesis: 1, 2, 3).
    #[arg(long, value_name = "RAD_S", default_value_t = 1.0)]
    freq: f64,
    /// Scale a non-ideal effect: 1 = as documented, 0 = off, 2 = twice as
    /// large. Repeatable. Names:
    ///   friction      braid friction (Maxwell-slip break-away forces)
    ///   deadband      valve dead band width
    ///   spool_lag     valve spool time constant
    ///   compliance    hose and bladder compliance (0 leaves water's bulk modulus)
    ///   endstop       end-stop contact stiffness and damping
    ///   noise         sensor noise
    ///   quantization  sensor quantization step
    ///   thickness     wall thickness t_k of eq. 9 (0 gives eq. 7)
    #[arg(long = "effect", value_name = "NAME=VALUE", verbatim_doc_comment)]
    effects: Vec<String>,
    /// Write the CSV here (atomically).
    #[arg(long, value_name = "FILE.csv")]
    out: PathBuf,
    /// Also draw the run to this SVG file: pressure and displacement against
    /// time (thesis figure 3) and displacement against pressure (figure 4).
    #[arg(long, value_name = "FILE.svg")]
    plot: Option<PathBuf>,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum ExperimentArg {
    Stair,
    Sine,
    Multisine,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let spec = RunSpec {
        kind: match args.experiment {
            ExperimentArg::Stair => Kind::Stair,
            ExperimentArg::Sine => Kind::Sine,
            ExperimentArg::Multisine => Kind::Multisine,
        },
        load_kg: args.load,
        seed: args.seed,
        freq_rad_s: args.freq,
        effects: args.effects.clone(),
    };
    let trace = spec.run().map_err(anyhow::Error::msg)?;
    spec.write_csv(&args.out, &trace)?;
    println!(
        "{}: {} samples, dt = {} s ({})",
        args.out.display(),
        trace.len(),
        trace.dt(),
        spec.command()
    );
    if let Some(path) = &args.plot {
        figure(&trace, &spec)
            .save(path)
            .with_context(|| format!("cannot write --plot {}", path.display()))?;
        println!("figure written to {}", path.display());
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
