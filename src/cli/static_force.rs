//! `mckibben static`: the static force model of §4.2 as a table and a figure.

use std::path::PathBuf;

use anyhow::Context;
use serde::Serialize;

use mckibben::model::static_force::{Braid, max_angle};
use mckibben::report::json::Versioned;
use mckibben::report::{Figure, Panel, Series};

/// Print (and plot) the static force model: force against braid angle or
/// muscle length for a few pressures, in the ideal form (eq. 7) and the form
/// with wall thickness (eq. 9).
///
/// Example: `mckibben static --against length --pressures 0.1,0.3,0.5 --plot force.svg`
#[derive(Debug, clap::Args)]
pub struct Args {
    /// What the force is drawn against: the braid angle ψ (degrees) or the muscle length (mm).
    #[arg(long, value_enum, ignore_case = true, default_value = "angle")]
    against: Against,
    /// Gauge pressures in MPa (tap water: 0.3–0.5).
    #[arg(long, value_delimiter = ',', default_value = "0.1,0.2,0.3,0.4,0.5")]
    pressures: Vec<f64>,
    /// Thread length b (m).
    #[arg(long, default_value_t = Braid::default().thread_length)]
    thread_length: f64,
    /// Turns n of one thread.
    #[arg(long, default_value_t = Braid::default().turns)]
    turns: f64,
    /// Wall thickness t_k of sleeve and tube (mm).
    #[arg(long, default_value_t = Braid::default().thickness * 1e3)]
    thickness_mm: f64,
    /// Number of angles between 5° and the geometric limit (54.7°).
    #[arg(long, default_value_t = 10)]
    points: usize,
    /// Also draw the curves to this SVG file.
    #[arg(long, value_parser = crate::cli::common::output_path, value_name = "FILE")]
    plot: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Against {
    Angle,
    Length,
}

/// The `--json` output.
#[derive(Debug, Serialize)]
struct Output<'a> {
    braid: &'a Braid,
    rows: &'a [Row],
}

#[derive(Debug, Serialize)]
struct Row {
    pressure_mpa: f64,
    angle_deg: f64,
    length_mm: f64,
    force_ideal_n: f64,
    force_thick_n: f64,
}

/// The most angles `--points` may ask for: a curve needs hundreds, and a
/// typo of a few more digits should not run for minutes.
const MAX_POINTS: usize = 100_000;

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        (2..=MAX_POINTS).contains(&args.points),
        "--points must be 2 to {MAX_POINTS} (got {})",
        args.points
    );
    for (flag, value) in [
        ("--thread-length", args.thread_length),
        ("--turns", args.turns),
    ] {
        anyhow::ensure!(
            value > 0.0 && value.is_finite(),
            "{flag} must be positive (got {value})"
        );
    }
    anyhow::ensure!(
        args.thickness_mm >= 0.0 && args.thickness_mm.is_finite(),
        "--thickness-mm must be zero or more (got {})",
        args.thickness_mm
    );
    anyhow::ensure!(
        !args.pressures.is_empty(),
        "--pressures needs at least one value"
    );
    // Eq. 7 and 9 hold for an inflated muscle: below ambient the sleeve
    // buckles instead of pushing.
    if let Some(p) = args
        .pressures
        .iter()
        .find(|p| !(**p >= 0.0 && p.is_finite()))
    {
        anyhow::bail!("--pressures: {p} MPa is not a gauge pressure of zero or more");
    }
    // In MPa, as the shipped data's pressure: a muscle works well under
    // 10, so a larger value is most likely kPa or psi, and its kilonewtons
    // a unit's mistake.
    if let Some(p) = args
        .pressures
        .iter()
        .find(|p| **p > mckibben::data::csv::IMPLAUSIBLE_MPA)
    {
        errln!(
            "mckibben: note: --pressures {}: the pressures are in MPa, and a muscle works well \
             under {} MPa; if it is in kPa or psi, convert it (300 kPa is 0.3)",
            mckibben::data::readable(*p),
            mckibben::data::csv::IMPLAUSIBLE_MPA
        );
    }
    let braid = Braid {
        thread_length: args.thread_length,
        turns: args.turns,
        thickness: args.thickness_mm * 1e-3,
    };
    // Eq. 9 takes the wall inside the braid's diameter: a wall as thick as
    // the widest muscle's radius leaves no bore to inflate.
    let widest_radius_mm = braid.diameter(std::f64::consts::FRAC_PI_2) / 2.0 * 1e3;
    // Said from the braid's side: the wall is often the default, and the
    // braid the flags just given.
    use mckibben::data::readable;
    anyhow::ensure!(
        args.thickness_mm < widest_radius_mm,
        "--thread-length {} and --turns {} give a muscle whose widest radius, b/(2πn) = {} mm, \
         is no wider than its wall (--thickness-mm {}): the wall must be thinner, to leave a \
         bore to inflate",
        readable(args.thread_length),
        readable(args.turns),
        readable(widest_radius_mm),
        readable(args.thickness_mm),
    );
    let (lo, hi) = (5f64.to_radians(), max_angle());
    let angles: Vec<f64> = (0..args.points)
        .map(|i| lo + (hi - lo) * i as f64 / (args.points - 1) as f64)
        .collect();
    let mut rows = Vec::new();
    for &p in &args.pressures {
        for &psi in &angles {
            rows.push(Row {
                pressure_mpa: p,
                angle_deg: psi.to_degrees(),
                length_mm: braid.length(psi) * 1e3,
                force_ideal_n: braid.force_ideal(p * 1e6, psi),
                force_thick_n: braid.force_thick(p * 1e6, psi),
            });
        }
    }
    // Values far outside a muscle's (a thread of 10³⁰⁰ m, 10⁻³⁰⁰ turns) can
    // overflow the formulas: say which, rather than print inf or NaN.
    if let Some(r) = rows.iter().find(|r| {
        ![r.length_mm, r.force_ideal_n, r.force_thick_n]
            .iter()
            .all(|v| v.is_finite())
    }) {
        anyhow::bail!(
            // `{:?}` writes 1e300 where `{}` writes 301 digits.
            "the force at {:?} MPa and ψ = {:.1}° is not a finite number (length {:?} mm, ideal \
             force {} N, with the wall {} N): --pressures, --thread-length {:?} and --turns {:?} \
             are too far from a muscle's for double precision",
            r.pressure_mpa,
            r.angle_deg,
            r.length_mm,
            r.force_ideal_n,
            r.force_thick_n,
            args.thread_length,
            args.turns
        );
    }
    if let Some(path) = &args.plot {
        figure(&rows, &args)
            .save(path)
            .with_context(|| format!("writing --plot {}", path.display()))?;
    }
    if args.json {
        outln!(
            "{}",
            Versioned::new(Output {
                braid: &braid,
                rows: &rows
            })
            .to_string_pretty()?
        )?;
        return Ok(());
    }
    outln!(
        "Static force (eq. 7 ideal, eq. 9 with t_k = {:.2} mm); b = {} m, n = {}",
        args.thickness_mm,
        braid.thread_length,
        braid.turns
    )?;
    outln!(
        "{:>9} {:>9} {:>10} {:>12} {:>12}",
        "p (MPa)",
        "ψ (°)",
        "L (mm)",
        "F eq.7 (N)",
        "F eq.9 (N)"
    )?;
    for r in &rows {
        outln!(
            "{:>9.3} {:>9.2} {:>10.1} {:>12.1} {:>12.1}",
            r.pressure_mpa,
            r.angle_deg,
            r.length_mm,
            r.force_ideal_n,
            r.force_thick_n
        )?;
    }
    if let Some(path) = &args.plot {
        outln!("figure written to {}", path.display())?;
    }
    Ok(())
}

fn figure(rows: &[Row], args: &Args) -> Figure {
    let mut ideal = Panel::new("Eq. 7: ideal", x_label(args.against), "force (N)");
    let mut thick = Panel::new(
        "Eq. 9: with wall thickness",
        x_label(args.against),
        "force (N)",
    );
    for &p in &args.pressures {
        let mine: Vec<&Row> = rows.iter().filter(|r| r.pressure_mpa == p).collect();
        let x: Vec<f64> = mine
            .iter()
            .map(|r| match args.against {
                Against::Angle => r.angle_deg,
                Against::Length => r.length_mm,
            })
            .collect();
        ideal.series.push(Series::line(
            format!("{p} MPa"),
            x.clone(),
            mine.iter().map(|r| r.force_ideal_n).collect(),
        ));
        thick.series.push(Series::line(
            format!("{p} MPa"),
            x,
            mine.iter().map(|r| r.force_thick_n).collect(),
        ));
    }
    Figure::new("McKibben static force model")
        .with(ideal)
        .with(thick)
}

fn x_label(a: Against) -> &'static str {
    match a {
        Against::Angle => "braid angle ψ (°)",
        Against::Length => "muscle length L (mm)",
    }
}
