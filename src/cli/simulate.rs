//! `mckibben simulate`: run a model on a generated or recorded input.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use serde::Serialize;

use mckibben::data::csv::{DataError, Gaps, ReadOptions, read_traces_with_notes};
use mckibben::data::signals::{Stair, nyquist_rad_s, samples_in};
use mckibben::data::units::{self, megapascals_in, millimetres_in, unit_of};
use mckibben::data::{Columns, Trace};
use mckibben::ident::{fit_percent, loop_area};
use mckibben::model::check_f32_range;
use mckibben::model::experiment::halves;
use mckibben::model::presets::thesis_params;
use mckibben::model::{Family, FittedBaseline, Model, ModelFile};
use mckibben::report::json::{Named, Versioned};
use mckibben::report::number::significant;
use mckibben::report::{Figure, Panel, Series};

use super::common::{CsvOut, check_distinct};

/// Pressure per volt of valve command used to turn the generated valve
/// signals into a pressure input: the tap supply (0.5 MPa) over the valve's
/// 10 V full scale. A nominal static map, for synthetic inputs only.
const MPA_PER_VOLT: f64 = 0.05;

/// Sample time of a generated input when no model file sets one (s): the
/// twin's 100 Hz (the thesis states none).
const DEFAULT_DT: f64 = 0.01;

/// Length of `--input sine` (s).
const SINE_SECONDS: f64 = 40.0;

/// Simulate a model free-run on an input and write the trace.
///
/// The model input is the muscle pressure (MPa; a generated input is
/// converted to a model file's pressure unit). `--input stair` is the
/// identification staircase of appendix A.1.1 (valve 0–10 V, turned into
/// pressure by a nominal 0.05 MPa/V); `--input sine` a pressure sine
/// 0.25 + 0.2·sin(ω t) MPa; any other value is a CSV file whose input column
/// is used (and whose first output sample starts the simulation; a file
/// with no output column is an input alone, started at rest). A
/// generated input starts the model at rest at its first value: the output
/// that the model, held there with no hysteretic state, keeps.
///
/// Parameters come from `--preset thesis` (tables 1 and 2 with eq. 12's a, b;
/// the default), a model file written by `fit`, `identify` or `diagnose
/// --out` (`--from`), and `--params NAME=VALUE,...` overrides (names as
/// `mckibben simulate --list` shows). Without a model file the simulation
/// runs in deviation coordinates: the input mean of the first half removed,
/// and on a CSV the measured output's too.
///
/// Examples:
///   mckibben simulate --model classic --input stair --out classic.csv
///   mckibben simulate --model generalized --input sine --freq 3 --plot gen.svg
///   mckibben simulate --from out/fit/model.json --input data/stair_7kg.csv --out check.csv
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// Model family.
    #[arg(long, default_value = "classic")]
    model: Family,
    /// Parameter preset (without --from, whose parameters are the model's).
    #[arg(
        long,
        value_enum,
        ignore_case = true,
        default_value = "thesis",
        conflicts_with = "from"
    )]
    preset: Preset,
    /// A model file written by `fit`, `identify --out` or `diagnose --out`
    /// (family, effects, parameters, coordinates; a CSV input is then read
    /// with its columns and time base unless the flags below say otherwise).
    #[arg(long, value_name = "MODEL.json", conflicts_with = "model")]
    from: Option<PathBuf>,
    /// Override parameters, e.g. `--params alpha=0.8,beta=0.01` (an
    /// effect's as `creep.kappa=0.5`).
    #[arg(long, value_delimiter = ',', value_name = "NAME=VALUE")]
    params: Vec<String>,
    /// The input: `stair`, `sine` or a CSV file (`-`: standard input).
    #[arg(long, default_value = "stair")]
    input: String,
    /// Angular frequency of `--input sine` (rad/s), below Nyquist's π/dt
    /// [default: 1].
    #[arg(long, allow_negative_numbers = true)]
    freq: Option<f64>,
    /// Sample time of generated inputs (s): the model file's (its poles
    /// are per sample), else 0.01. With a CSV `--input` that has no time
    /// column: its rows' spacing (s), the first row at 0.
    #[arg(long, allow_negative_numbers = true)]
    dt: Option<f64>,
    /// With a CSV `--input`: the column holding the model input (default:
    /// the model file's, else `pressure`).
    #[arg(long, value_name = "COL")]
    input_col: Option<String>,
    /// With a CSV `--input`: the column whose first value starts the
    /// simulation and that the fit is scored against (default: the model
    /// file's, else `displacement`).
    #[arg(long, value_name = "COL")]
    output_col: Option<String>,
    /// With a CSV `--input`: the time column (default: the model file's,
    /// else `t`).
    #[arg(long, value_name = "COL")]
    time: Option<String>,
    /// With a CSV `--input`: interpolate onto a uniform time base of DT
    /// seconds (default: as the model file's data were read).
    #[arg(long, value_name = "DT")]
    resample: Option<f64>,
    /// With a CSV `--input` that has gaps or a clock that jumps back: cut it
    /// there, as `fit --split-gaps` does, and run piece K (numbered as
    /// `identify FILE --split-gaps` lists them, from 1): a model fitted on
    /// the pieces is checked on each, its second half scored as `fit`
    /// scores that record.
    #[arg(long, value_name = "K", value_parser = crate::cli::common::piece)]
    piece: Option<usize>,
    /// Write the simulated trace to this CSV file: the time, the input and
    /// the simulated output under the model's column names, then the
    /// input file's other columns, the measured output as
    /// `<output>_measured` and, for a Bouc-Wen model without effects, the
    /// hysteretic state `w` (where the file has a column of its name, the
    /// simulated output and `w` get `_simulated`, the measured output a
    /// number: `displacement_measured2`). `-` writes it to standard output,
    /// for a pipe; the summary then goes to standard error.
    #[arg(long, value_parser = crate::cli::common::csv_output, value_name = "FILE.csv")]
    out: Option<CsvOut>,
    /// Draw the trace and the hysteresis loop to this SVG file, the
    /// simulation over the measured output where `--input` is a record.
    #[arg(long, value_parser = crate::cli::common::output_path, value_name = "FILE.svg")]
    plot: Option<PathBuf>,
    /// List the model's parameters and exit: name, symbol, the value the
    /// run would simulate with (the model file's or the thesis' preset,
    /// after any --params), its unit in the model's columns' (`mm/MPa`;
    /// `1`: a pure number) and meaning. A table: with --json, an error (a
    /// model file's `params` holds them for a script).
    #[arg(long, conflicts_with = "json")]
    list: bool,
    /// Print JSON on stdout instead of a summary.
    #[arg(long)]
    json: bool,
}

impl Args {
    /// Whether `--input` names a generated signal rather than a file.
    fn input_is_generated(&self) -> bool {
        matches!(self.input.as_str(), "stair" | "sine")
    }
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Preset {
    /// Tables 1 (classic) and 2 (generalized) with eq. 12's a, b and no intercept.
    Thesis,
}

#[derive(Debug, Serialize)]
struct Summary {
    model: Family,
    effects: Vec<String>,
    params: Named,
    input: String,
    samples: usize,
    dt: f64,
    /// The model's input and output columns and their units: what the
    /// output range is in, and the run and the file written.
    columns: Columns,
    diverged_at: Option<usize>,
    /// The largest output step a sample within which the model's
    /// hysteresis update settles (`Family::stable_step`), and the first
    /// sample whose step went past it (`Model::overstep`).
    stable_step: Option<f64>,
    stepped_past_at: Option<usize>,
    output_min: f64,
    output_max: f64,
    loop_area: f64,
    /// Free-run fit against the CSV's measured output, whole record and
    /// second half (the validation half `fit` and `diagnose` score).
    fit_percent: Option<f64>,
    val_fit_percent: Option<f64>,
    /// Whether the input file is one the model was fitted on (its SHA-256
    /// is in the model file's provenance): its first half fitted the model.
    fitted_on: bool,
    out: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    check_files_and_flags(&args)?;
    let file = match &args.from {
        Some(path) => Some(ModelFile::load(path).map_err(|e| anyhow::anyhow!("--from: {e:#}"))?),
        None => None,
    };
    let dt = match (args.dt, &file) {
        // A nanosecond to a day, as every command's --dt: a step of 1e308 s
        // made a time column of inf.
        (Some(dt), _) => {
            mckibben::data::sample_time(dt).map_err(|e| anyhow::anyhow!("--dt: {e}"))?
        }
        (None, Some(f)) => f.model()?.base.dt,
        (None, None) => DEFAULT_DT,
    };
    let mut model = match &file {
        Some(f) => f.model()?,
        None => Model::plain(FittedBaseline {
            family: args.model,
            params: thesis_params(args.model),
            input_mean: f64::NAN,
            output_mean: f64::NAN,
            dt,
            input_name: "pressure".into(),
            output_name: "displacement".into(),
        }),
    };
    override_params(&mut model, &args.params)?;
    if args.list {
        // Name, symbol, the value this run would simulate with (the model
        // file's or the thesis' preset, after any --params), its unit in
        // the model's columns' and meaning, in columns as wide as their
        // widest entry.
        let datasets = model.augmented().datasets;
        let mut rows: Vec<(String, &str, &str)> = model
            .base
            .family
            .params()
            .iter()
            .map(|p| (p.name.to_string(), p.symbol, p.meaning))
            .collect();
        for e in model.effects() {
            for p in e.params(datasets) {
                rows.push((format!("{e}.{}", p.name), "", p.meaning));
            }
        }
        let units: Vec<String> = model.units().into_iter().map(|(_, u)| u).collect();
        let width = rows
            .iter()
            .map(|(n, ..)| n.chars().count())
            .max()
            .unwrap_or(0);
        let unit_width = units
            .iter()
            .map(|u| u.chars().count())
            .max()
            .unwrap_or(0)
            .max(4);
        outln!(
            "{:<width$}  {:<4} {:>12}  {:<unit_width$}  meaning",
            "name",
            "",
            "value",
            "unit"
        )?;
        for (((name, symbol, meaning), value), unit) in rows.iter().zip(model.theta()).zip(&units) {
            outln!(
                "{name:<width$}  {symbol:<4} {:>12}  {unit:<unit_width$}  {meaning}",
                significant(value, 6)
            )?;
        }
        return Ok(());
    }
    // A model of several records simulates one: its first's.
    if let (Some(path), Some(e)) = (
        &args.from,
        model.effects().iter().find(|e| !e.applicable(1)),
    ) && !args.json
    {
        errln!(
            "mckibben: note: --from {}: its `{e}` effect fitted a parameter for each record \
             after the first of the {} it was fitted on; a simulation runs the first record's \
             (which has none), so on another record it is off by that record's",
            path.display(),
            model.augmented().datasets
        );
    }
    if let (Some(path), Some(f)) = (&args.from, &file)
        && args.input_is_generated()
    {
        let fitted = f.model()?.base.dt;
        anyhow::ensure!(
            (dt - fitted).abs() <= 1e-9 * fitted,
            "--dt {dt}: the model in {} was fitted at {fitted} s a sample and its poles are \
             per sample; leave --dt out to generate the input at {fitted} s",
            path.display()
        );
    }
    let (mut trace, y0) = input_trace(&args, dt, file.as_ref())?;
    if args.input_is_generated() {
        in_model_units(&mut trace, &model.base.input_name, !args.json)?;
        // The file written reads back as the model's data did: its time
        // under the same name as its input.
        if let Some(time) = file.as_ref().and_then(|f| f.provenance.read.time.clone()) {
            trace.time_name = time;
        }
    }
    let half = (trace.len() / 2).max(1);
    if model.base.input_mean.is_nan() {
        model.base.input_mean = trace.input[..half].iter().sum::<f64>() / half as f64;
    }
    if model.base.output_mean.is_nan() {
        // Deviation coordinates: around the measured output where there is
        // one, so that the preset, which has no intercept, is scored on
        // the record's level, not on zero.
        model.base.output_mean = match y0 {
            Some(_) => trace.output[..half].iter().sum::<f64>() / half as f64,
            None => 0.0,
        };
    }
    let measured = y0.is_some().then(|| trace.output.clone());
    // The file written keeps the measured output beside the simulated one,
    // under a name of its own, as it keeps w.
    if let Some(y) = &measured {
        let name = free_name(&trace, &format!("{}_measured", trace.output_name), None);
        trace.extra.push((name, y.clone()));
    }
    let (samples, sample_time) = (trace.len(), trace.dt());
    let mut run = match y0 {
        Some(y0) => model.simulate_absolute(&trace.input, y0),
        None => model.simulate_from_rest(&trace.input),
    };
    let ran = run
        .diverged_at
        .map_or(run.output.len(), |k| k.min(run.output.len()));
    let overstep = model.overstep(&run.output[..ran]);
    if let Some(k) = run.diverged_at {
        // A trace file and a figure hold finite numbers: keep the samples
        // before the divergence and say where it stopped.
        trace.truncate(k);
        run.output.truncate(k);
        if let Some(w) = &mut run.w {
            w.truncate(k);
        }
    }
    trace.output = run.output.clone();
    // The measured output, kept above, gives its name up; a column of the
    // file may hold the model's (a file whose sensor `displacement` is not
    // the output read).
    trace.output_name.clear();
    trace.output_name = free_name(&trace, &model.base.output_name, Some("simulated"));
    if let Some(w) = &run.w {
        let name = free_name(&trace, "w", Some("simulated"));
        trace.extra.push((name, w.clone()));
    }
    let family = model.base.family;
    let chain: Vec<String> = model
        .effects()
        .iter()
        .map(|e| e.name().to_string())
        .collect();
    let described = if chain.is_empty() {
        format!("{family}")
    } else {
        format!("{family} + {}", chain.join(" + "))
    };
    if let Some(path) = &args.out {
        let mut comments = vec![format!(
            "simulated by mckibben simulate: {described} model, input {}",
            args.input
        )];
        if let Some(k) = run.diverged_at {
            comments.push(format!("diverged at sample {k}: the trace stops before it"));
        }
        let plot = args
            .plot
            .as_ref()
            .map(|p| (p, figure(&trace, measured.as_deref(), &described)));
        path.write(
            &trace,
            &comments,
            plot.as_ref().map(|(p, f)| (p.as_path(), f)),
        )?;
    } else if let Some(path) = &args.plot {
        figure(&trace, measured.as_deref(), &described)
            .save(path)
            .with_context(|| format!("writing --plot {}", path.display()))?;
    }
    let finite: Vec<f64> = trace
        .output
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    let scored = |from: usize| -> Option<f64> {
        let y = measured.as_ref().filter(|_| run.diverged_at.is_none())?;
        let fit = fit_percent(&y[from..], &run.output[from..]);
        fit.is_finite().then_some(fit)
    };
    let summary = Summary {
        model: family,
        effects: chain,
        params: model.named_params().into_iter().collect(),
        // A piece is named as `fit` names it: `file.csv[2]`.
        input: match args.piece {
            Some(k) => format!("{}[{k}]", args.input),
            None => args.input.clone(),
        },
        samples,
        dt: sample_time,
        columns: Columns::of(&model.base.input_name, &model.base.output_name),
        diverged_at: run.diverged_at,
        stable_step: match model.effects().is_empty() {
            true => family.stable_step(&model.base.params),
            false => None,
        },
        stepped_past_at: overstep.map(|(at, _, _)| at),
        output_min: finite.iter().copied().fold(f64::INFINITY, f64::min),
        output_max: finite.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        loop_area: loop_area(&trace.input, &trace.output),
        fit_percent: scored(0),
        val_fit_percent: scored(halves(samples).1.start),
        fitted_on: match (&file, args.input_is_generated()) {
            (Some(f), false) => f.provenance.fitted_on(Path::new(&args.input)),
            _ => false,
        },
        out: args
            .out
            .as_ref()
            .and_then(CsvOut::file)
            .map(Path::to_path_buf),
    };
    if args.json {
        outln!("{}", Versioned::new(&summary).to_string_pretty()?)?;
        return Ok(());
    }
    let start = y0.map(|y0| (y0, trace.input.first().copied().unwrap_or(0.0)));
    print_summary(&args, &summary, &model, &described, overstep, start)
}

/// Samples from the start within which a first overstep is the start's
/// doing: the run steps from the record's first output toward the model's
/// rest.
const START_SAMPLES: usize = 3;

/// The summary for a terminal, on standard output, or on standard error
/// where the trace went to standard output. `start`: the record's first
/// output and input, where the run starts from a measured output.
fn print_summary(
    args: &Args,
    summary: &Summary,
    model: &Model,
    described: &str,
    overstep: Option<(usize, f64, f64)>,
    start: Option<(f64, f64)>,
) -> anyhow::Result<()> {
    let mut report = CsvOut::summary(args.out.as_ref());
    writeln!(
        report,
        "Simulated the {described} model on `{}`: {} samples, dt = {} s",
        summary.input,
        summary.samples,
        mckibben::data::tidy_step(summary.dt)
    )?;
    for (name, value) in model.named_params() {
        // Every digit a value has, but 1e308 as such, not 309 digits.
        writeln!(report, "  {name:<8} {}", mckibben::data::readable(value))?;
    }
    match summary.diverged_at {
        Some(k) => {
            writeln!(
                report,
                "  DIVERGED at sample {k} (state beyond ±1e6 or not finite)"
            )?;
        }
        None => writeln!(
            report,
            "  output range {} .. {}, loop area {}",
            significant(summary.output_min, 3),
            significant(summary.output_max, 3),
            significant(summary.loop_area, 4)
        )?,
    }
    // Past the step the update overshoots: a run that diverged did so
    // from there, and one that ended finite bore a burst there (an output
    // range far past the measured one).
    if let Some((at, step, limit)) = overstep {
        writeln!(
            report,
            "  at sample {at} the output first stepped {} in one sample, past the {} within \
             which the model's discrete hysteresis update settles (`stable_step`, \
             docs/GUIDE.md, \"When not to trust it\"); this record, or its start, moves faster \
             than the model holds{}",
            significant(step, 3),
            significant(limit, 3),
            match summary.diverged_at {
                Some(_) => "",
                None => ", and the run overshoots from there",
            }
        )?;
        // A record at another level than the model's data (another load,
        // a moved sensor zero) starts the run far from its rest, and the
        // first step toward it is the one that oversteps.
        if let (true, Some((y0, u0)), Some(rest)) = (
            at <= START_SAMPLES,
            start,
            start.and_then(|(_, u0)| model.base.rest_output(u0)),
        ) && (y0 - rest).abs() > limit
        {
            writeln!(
                report,
                "  the record's first output, {}, lies {} from where the model rests at its \
                 first input ({} at input {}; its data's mean output {}): a record at another \
                 level than the model's data (another load, a moved sensor zero) starts the run \
                 off its rest; subtract the offset, or fit this record",
                significant(y0, 4),
                significant((y0 - rest).abs(), 3),
                significant(rest, 4),
                significant(u0, 4),
                significant(model.base.output_mean, 4)
            )?;
        }
    }
    // A run that did not diverge scores both; a fit % left out there is
    // an output constant over the half (the measure divides by its spread).
    if let Some(all) = summary.fit_percent {
        let val = match summary.val_fit_percent {
            Some(val) => format!("{val:.2} %"),
            None => "undefined, the output being constant over it".into(),
        };
        match summary.fitted_on {
            false => writeln!(
                report,
                "  fit to the measured output {all:.2} % (its second half alone: {val}, as `fit` \
                 scores its validation half)"
            )?,
            // The whole record holds the half that fitted the model: the
            // second half leads, and what it includes is said.
            true => writeln!(
                report,
                "  fit to the measured output on its second half {val} (over the whole record \
                 {all:.2} %, its first half the one that fitted the model): this is a record \
                 the model was fitted on (its SHA-256 is in the model file); where a \
                 diagnosis or `fit --effects auto` chose the model, the second half holds the \
                 selection part that chose it too, and the diagnosis' test figure is the one \
                 to quote"
            )?,
        }
        if all < 0.0 {
            errln!(
                "mckibben: warning: the model fits this record at {all:.1} %: the record's own \
                 mean level follows it better than the model does"
            );
        }
    }
    if let Some(p) = &args.out {
        writeln!(report, "  trace written to {p}")?;
    }
    if let Some(p) = &args.plot {
        writeln!(report, "  figure written to {}", p.display())?;
    }
    Ok(())
}

/// Refuses flags that contradict each other or name one file twice,
/// before anything runs.
fn check_files_and_flags(args: &Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        !(args.out == Some(CsvOut::Stdout) && args.json),
        "--out - and --json would both write to standard output: give --out a file"
    );
    let mut reads: Vec<(&str, &Path)> = Vec::new();
    if !args.input_is_generated() {
        reads.push(("--input", Path::new(&args.input)));
    }
    if let Some(path) = &args.from {
        reads.push(("--from", path));
    }
    // Standard input is read once: the second would find it empty.
    let stdin = Path::new(mckibben::data::input::STANDARD_INPUT);
    anyhow::ensure!(
        reads.iter().filter(|(_, p)| *p == stdin).count() < 2,
        "--from - and --input - would both read standard input: give one of them a file"
    );
    let mut writes: Vec<(&str, &Path)> = Vec::new();
    if let Some(path) = args.out.as_ref().and_then(CsvOut::file) {
        writes.push(("--out", path));
    }
    if let Some(path) = &args.plot {
        writes.push(("--plot", path));
    }
    check_distinct(&reads, &writes)?;
    anyhow::ensure!(
        args.freq.is_none() || args.input == "sine",
        "--freq sets the frequency of --input sine; --input {} has its own: leave --freq out",
        args.input
    );
    if args.input_is_generated() {
        let csv_only = [
            ("--input-col", args.input_col.is_some()),
            ("--output-col", args.output_col.is_some()),
            ("--time", args.time.is_some()),
            ("--resample", args.resample.is_some()),
            ("--piece", args.piece.is_some()),
        ];
        let given: Vec<&str> = csv_only.iter().filter(|f| f.1).map(|f| f.0).collect();
        anyhow::ensure!(
            given.is_empty(),
            "{} read(s) a CSV --input, and --input {} is generated: leave {} out",
            given.join(", "),
            args.input,
            if given.len() == 1 { "it" } else { "them" }
        );
    }
    Ok(())
}

/// Applies `--params NAME=VALUE` overrides, baseline or effect parameters.
fn override_params(model: &mut Model, assignments: &[String]) -> anyhow::Result<()> {
    if assignments.is_empty() {
        return Ok(());
    }
    let names = model.augmented().param_names();
    let mut theta = model.theta();
    let mut seen: Vec<&str> = Vec::new();
    for assignment in assignments {
        let (name, value) = assignment
            .split_once('=')
            .with_context(|| format!("--params: `{assignment}` is not NAME=VALUE"))?;
        anyhow::ensure!(
            !seen.contains(&name.trim()),
            "--params: `{}` is given twice: give each parameter one value",
            name.trim()
        );
        seen.push(name.trim());
        let i = names
            .iter()
            .position(|n| n == name.trim())
            .with_context(|| {
                format!(
                    "--params: the {} model has no parameter `{name}`; it has {}",
                    model.base.family,
                    names.join(", ")
                )
            })?;
        theta[i] = value
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .with_context(|| format!("--params {name}: `{value}` is not a finite number"))?;
        if model.base.family.exponent_index() == Some(i)
            && let Some(why) = Family::exponent_refused(theta[i])
        {
            anyhow::bail!("--params {name}={}: {why}", value.trim());
        }
    }
    let d = model.base.family.dim();
    model.base.params = theta[..d].to_vec();
    if let Some(chain) = &mut model.chain {
        chain.params = theta[d..].to_vec();
    }
    Ok(())
}

/// `name`, or where the trace has a column of that name already,
/// `name_MARK` (a simulated column: `displacement_simulated`), then that
/// or `name` numbered from 2 (`displacement_measured2`): a column the
/// written file can be read back with, whose name says what it holds.
fn free_name(trace: &Trace, name: &str, mark: Option<&str>) -> String {
    let taken = |n: &str| {
        n == trace.input_name || n == trace.output_name || trace.extra.iter().any(|(e, _)| e == n)
    };
    let marked = mark.map_or(name.to_string(), |m| format!("{name}_{m}"));
    std::iter::once(name.to_string())
        .chain(mark.map(|_| marked.clone()))
        .chain((2..).map(|k| format!("{marked}{k}")))
        .find(|n| !taken(n))
        .expect("an unbounded search finds a free name")
}

/// A generated input (MPa) in the model's input unit: converted where the
/// model's input column states another pressure unit (a model fitted in kPa
/// run on MPa is a thousand times off); for a model of the valve voltage
/// (V), the stair's valve command it was made from; an error where the
/// column states a unit that is neither; a column stating none is taken at
/// its word.
fn in_model_units(trace: &mut Trace, column: &str, say: bool) -> anyhow::Result<()> {
    let Some(unit) = unit_of(column) else {
        return Ok(());
    };
    if unit == "V"
        && let Some(valve) = trace.column("valve_in")
    {
        trace.input = valve.to_vec();
        if say {
            errln!(
                "mckibben: note: the {}'s valve command (V) drives the model's input `{column}`",
                trace.source
            );
        }
        trace.input_name = column.to_string();
        return Ok(());
    }
    let per_unit = megapascals_in(&unit).with_context(|| {
        format!(
            "--input {}: a generated input is a pressure in MPa, and the model's input `{column}` \
             is in {unit}; pass a CSV file as --input",
            trace.source
        )
    })?;
    if unit != "MPa" {
        for v in &mut trace.input {
            *v /= per_unit;
        }
        if say {
            errln!(
                "mckibben: note: the {}'s pressures are converted from MPa to {unit}, the unit of \
                 the model's input `{column}`",
                trace.source
            );
        }
    }
    trace.input_name = column.to_string();
    Ok(())
}

/// A file's input and measured output in the model's units where the file's
/// column names state others of the same kind in so many words (a pressure
/// in psi for a model in MPa, a stroke in m for one in mm; not the shipped
/// data's plain `pressure`, MPa by convention only): converted, renamed to
/// the model's columns, and each said in a note. Other units, and a column
/// whose model name the file holds already, are left for
/// [`Model::check_data`] to refuse.
fn file_in_model_units(
    trace: &mut Trace,
    input: &str,
    output: &str,
    measured: bool,
) -> Vec<String> {
    let taken = |trace: &Trace, name: &str| trace.extra.iter().any(|(n, _)| n == name);
    let mut notes = Vec::new();
    let mut convert =
        |values: &mut Vec<f64>, name: &mut String, model: &str, size: fn(&str) -> Option<f64>| {
            let Some(pair) = units::between(name, model, size) else {
                return;
            };
            let (from, to, factor) = (&pair.record, &pair.model, pair.to_model());
            for v in values.iter_mut() {
                *v *= factor;
            }
            notes.push(format!(
                "{}: `{name}` is converted from {from} to {to}, the unit of the model's `{model}` \
             (×{}); the run, its scores and the file written are in {to}",
                trace.source,
                mckibben::data::readable(factor)
            ));
            *name = model.to_string();
        };
    if !taken(trace, input) {
        convert(
            &mut trace.input,
            &mut trace.input_name,
            input,
            megapascals_in,
        );
    }
    if measured && !taken(trace, output) {
        convert(
            &mut trace.output,
            &mut trace.output_name,
            output,
            millimetres_in,
        );
    }
    notes
}

/// The input trace and, for a file, its first measured output.
fn input_trace(
    args: &Args,
    dt: f64,
    saved: Option<&ModelFile>,
) -> anyhow::Result<(Trace, Option<f64>)> {
    match args.input.as_str() {
        "stair" => {
            let stair = Stair::default();
            samples_in(stair.duration_s(), dt)
                .map_err(|why| anyhow::anyhow!("--dt {dt}: {why}"))?;
            let valve = stair.generate(dt);
            let p = valve.iter().map(|v| v * MPA_PER_VOLT).collect();
            let mut trace = Trace::uniform("stair", dt, p, vec![0.0; valve.len()]);
            trace.extra.push(("valve_in".into(), valve));
            Ok((trace, None))
        }
        "sine" => {
            let freq = args.freq.unwrap_or(1.0);
            anyhow::ensure!(freq > 0.0, "--freq must be positive (rad/s)");
            let nyquist = nyquist_rad_s(dt);
            anyhow::ensure!(
                freq < nyquist,
                "--freq {freq}: with --dt {dt} a sine must stay below Nyquist's {nyquist:.1} \
                 rad/s (π/dt); above, its samples show a slower sine"
            );
            let n =
                samples_in(SINE_SECONDS, dt).map_err(|why| anyhow::anyhow!("--dt {dt}: {why}"))?;
            let p = (0..n)
                .map(|k| 0.25 + 0.2 * (freq * k as f64 * dt).sin())
                .collect();
            Ok((Trace::uniform("sine", dt, p, vec![0.0; n]), None))
        }
        file => {
            let path = PathBuf::from(file);
            // `-` is standard input, as every command's DATA reads it.
            if !path.exists() && file != mckibben::data::input::STANDARD_INPUT {
                bail!(
                    "--input: `{file}` is neither `stair`, `sine`, an existing CSV file nor `-` \
                     (standard input)"
                );
            }
            let defaults = ReadOptions::default();
            let read = saved.map(|f| f.provenance.read.clone()).unwrap_or_default();
            let column = |flag: &Option<String>, saved: Option<&String>, default: &String| {
                flag.clone()
                    .or_else(|| saved.cloned())
                    .unwrap_or_else(|| default.clone())
            };
            let resample = args.resample.or(read.resample);
            let opts = ReadOptions {
                input: column(
                    &args.input_col,
                    saved.map(|f| &f.data.input.column),
                    &defaults.input,
                ),
                output: column(
                    &args.output_col,
                    saved.map(|f| &f.data.output.column),
                    &defaults.output,
                ),
                time: column(&args.time, read.time.as_ref(), &defaults.time),
                dt: args.dt,
                untimed_dt: if args.time.is_some() { None } else { read.dt },
                gaps: match (resample, args.piece) {
                    (Some(dt), None) => Gaps::Resample(dt),
                    (None, None) => Gaps::Reject,
                    (Some(dt), Some(_)) => Gaps::SplitResample(dt),
                    (None, Some(_)) => Gaps::Split,
                },
            };
            // simulate's own `--input` names the signal; its columns are
            // --input-col and --output-col.
            let read = |opts: &ReadOptions| {
                read_traces_with_notes(&path, opts).map_err(|e| match e {
                    DataError::MissingColumn {
                        path,
                        line,
                        role,
                        column,
                        available,
                        flag,
                    } => DataError::MissingColumn {
                        flag: match flag {
                            "--input" => "--input-col",
                            "--output" => "--output-col",
                            other => other,
                        },
                        path,
                        line,
                        role,
                        column,
                        available,
                    },
                    // simulate runs one experiment: one piece of a file cut.
                    other => other.with_time_hint(
                        "simulate runs one experiment: run one piece with --piece K \
                         (`mckibben identify FILE --split-gaps` lists them)",
                        "pass --resample DT to interpolate onto a uniform step, or run one \
                         piece with --piece K (`mckibben identify FILE --split-gaps` lists them)",
                    ),
                })
            };
            // A file with no output column (none named) is an input alone:
            // the run starts at rest and nothing is scored.
            let ((mut traces, notes), measured) = match read(&opts) {
                Err(DataError::MissingColumn { role: "output", .. })
                    if args.output_col.is_none() =>
                {
                    let input_only = ReadOptions {
                        output: opts.input.clone(),
                        ..opts
                    };
                    (read(&input_only)?, false)
                }
                read => (read?, true),
            };
            for note in notes {
                errln!("mckibben: note: {note}");
            }
            let mut trace = match args.piece {
                // A file without a cut is its one piece.
                Some(k) => {
                    let numbered = format!("[{k}]");
                    let whole = traces.len() == 1 && traces[0].cut_from.is_none();
                    let at = traces
                        .iter()
                        .position(|t| t.source.ends_with(&numbered))
                        .or(whole.then_some(0).filter(|_| k == 1));
                    let Some(at) = at else {
                        let kept: Vec<String> = match whole {
                            true => vec!["[1] (it has no gap)".into()],
                            false => traces
                                .iter()
                                .filter_map(|t| {
                                    t.source.rfind('[').map(|i| t.source[i..].to_string())
                                })
                                .collect(),
                        };
                        bail!("--piece {k}: {file} has the pieces {}", kept.join(", "));
                    };
                    traces.swap_remove(at)
                }
                None => traces.remove(0),
            };
            if !measured {
                trace.output_name = saved.map_or(defaults.output, |f| f.data.output.column.clone());
                // A model's output column under another name (`disp_mm`
                // for `disp (mm)`) read as an input alone, silently.
                if saved.is_some() {
                    errln!(
                        "mckibben: note: {file} has no column `{}` (the model's output), so the \
                         run starts at rest and nothing is scored; name the measured output with \
                         --output-col",
                        trace.output_name
                    );
                }
            }
            let (input, output) = saved.map_or(("pressure", "displacement"), |f| {
                (f.data.input.column.as_str(), f.data.output.column.as_str())
            });
            for note in file_in_model_units(&mut trace, input, output, measured) {
                errln!("mckibben: note: {note}");
            }
            // Values the f32 simulation cannot sum, or an output past the
            // bound a state diverges at, are refused as `fit` refuses them
            // (the simulation ran on, and its file could not be written):
            // in the units the run is in, after any conversion.
            if measured {
                check_f32_range(&trace)?;
            }
            match saved {
                Some(saved) => saved.model()?.check_data(&trace)?,
                // The thesis' preset is in the shipped data's units: on a
                // `pressure_kPa` column it diverged without a word.
                None => mckibben::model::file::check_units(
                    "the thesis' preset's",
                    "pressure",
                    "displacement",
                    &trace,
                )?,
            }
            let y0 = trace.output.first().copied().filter(|_| measured);
            Ok((trace, y0))
        }
    }
}

fn figure(trace: &Trace, measured: Option<&[f64]>, described: &str) -> Figure {
    let mut output = Panel::new("output", "t (s)", &trace.output_name);
    let mut hysteresis = Panel::new("hysteresis loop", &trace.input_name, &trace.output_name);
    // The measured output first, so that the simulation is drawn over it:
    // a reader compares the two where the fit % is printed.
    if let Some(y) = measured {
        let y = y[..trace.len()].to_vec();
        output = output.with(Series::line("measured", trace.t.clone(), y.clone()));
        hysteresis = hysteresis.with(Series::points("measured", trace.input.clone(), y));
    }
    Figure::new(format!("{described} model, simulated"))
        .with(
            Panel::new("input", "t (s)", &trace.input_name).with(Series::line(
                &trace.input_name,
                trace.t.clone(),
                trace.input.clone(),
            )),
        )
        .with(output.with(Series::line(
            "simulated",
            trace.t.clone(),
            trace.output.clone(),
        )))
        .with(hysteresis.with(Series::line(
            "simulated",
            trace.input.clone(),
            trace.output.clone(),
        )))
}
