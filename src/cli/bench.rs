//! `mckibben bench`: how fast the evaluator scores populations, and how well
//! the chosen backend agrees with the CPU reference.

use std::time::Instant;

use serde::Serialize;

use super::common::{DataArgs, population};
use mckibben::data::signals::MAX_SAMPLES;
use mckibben::eval::agreement::{Agreement, agreement};
use mckibben::eval::cpu::CpuEvaluator;
use mckibben::eval::gpu::calibration::{self, Ceiling, Timed, Variant};
use mckibben::eval::workload::{
    augmented_population, mixed_population, search_space, stair_experiment,
};
use mckibben::eval::{Backend, Evaluator, Problem, open};
use mckibben::model::check_f32_range;
use mckibben::model::effects::{Context, Effect, ModelDescription};
use mckibben::model::presets::THESIS_B;
use mckibben::model::{Experiment, Family};
use mckibben::report::json::Versioned;
use mckibben::search::{Params, Rows};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// Time the batch evaluator: the fitness (SSE) of whole populations on an
/// experiment, as one generation of an optimizer asks for it.
///
/// For each population size: one warm-up call, then the median of
/// `--repeats` calls, parameter upload and score read-back included. The
/// population is drawn from the default search box (thesis bounds; half of
/// it uniform, so it includes diverging candidates, half near the thesis
/// preset). With --effects the model is the family followed by those effect
/// stages (as `diagnose` scores them), each effect's parameters drawn from
/// its box (uniform, or near its neutral value on the near-preset half).
/// The scores are compared with the CPU reference on the same population:
/// maximum relative difference, diverged-in-one-only count, bit-identity
/// and whether the ten and the hundred best candidates are the same.
///
/// --json prints `schema_version` and `rows`, one object per population
/// size (docs/JSON.md): backend ("gpu" or "cpu"),
/// adapter, model (the family and its effects, e.g. "classic +
/// saturation:output"), effects (names), samples, population,
/// candidate_samples_per_s, evals_per_s, median_s (end to end: each
/// call as a fit makes it), min_s and max_s (the fastest and slowest of
/// those calls), kernel_median_s and
/// kernel_candidate_samples_per_s (the kernels alone, from the device's
/// timestamps; null on the CPU and where the adapter offers none), agreement
/// {max_rel_diff, finiteness_mismatches, bit_identical, top10_identical,
/// top100_identical, top100_overlap (how many of the CPU's best hundred
/// are among the backend's best hundred)}, and with --time-reference
/// reference {the same timing fields} (the CPU
/// path timed the same way) and speedup (its median over the backend's),
/// else null for both; ops_per_candidate_sample (the model kernel's f32
/// operations a candidate-sample, counted from its shader; null with
/// effects or a free n), kernel_ops_per_s (the kernels' rate in those
/// operations) and ceiling_share (that rate over the calibrated ceiling).
///
/// On a GPU with timestamp queries, bench first times the calibration
/// kernel (shaders/calibration.wgsl) by the device's clock: loops of known
/// f32 operations a step, as one chain of dependent mul-adds, as eight
/// independent chains (the ceiling) and with pow. --json gives them as
/// calibration {invocations, ceiling_ops_per_s, variants [{variant,
/// ops_per_step, steps, device_s, ops_per_s}]}, null on the CPU; the text
/// output gives a line, --markdown a second table after the first.
///
/// --markdown prints a table for docs/PERFORMANCE.md instead: a header
/// and, per population size, one row for the backend and (with
/// --time-reference) one for the CPU path; columns: model, N, backend,
/// cand-samples/s, evals/s, median s (range), kernel cand-samples/s, kernel
/// median s, share of ceiling, GPU/CPU speed-up, max rel SSE diff, top-100
/// alike; then, where the device was calibrated, a blank line and the
/// calibration's table: model, variant, f32 ops a step, steps,
/// invocations, device s, f32 ops/s (scripts/gpu-check.sh concatenates
/// the rows of each).
///
/// Examples:
///   mckibben bench --synthetic 4000 --backend cpu --model classic --pop 131072
///   mckibben bench run.csv --backend gpu --pop 1000,100000,1000000 --json
///   mckibben bench --backend gpu --effects saturation:output,creep:output --time-reference --markdown
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    #[command(flatten)]
    data: DataArgs,
    /// Score a synthetic stair experiment of this many samples instead of a
    /// data file (the thesis' classic model driven by random pressure steps).
    #[arg(long, value_name = "SAMPLES", conflicts_with = "data")]
    synthetic: Option<usize>,
    /// Model family: linear, classic or generalized.
    #[arg(long, default_value = "classic")]
    model: Family,
    /// Population sizes, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1000,10000,100000", value_parser = population)]
    pop: Vec<usize>,
    /// Where to score: `auto` takes a real GPU if there is one, else the CPU.
    #[arg(long, value_enum, ignore_case = true, default_value_t = Backend::Auto)]
    backend: Backend,
    /// Free the Bouc-Wen exponent n (drawn from [1, 3]) instead of n = 1.
    #[arg(long)]
    free_n: bool,
    /// Timed calls per population (after one warm-up call); the median is reported.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
    repeats: u32,
    /// Seed of the population draw.
    #[arg(long, default_value_t = 1, value_parser = crate::cli::common::seed)]
    seed: u64,
    /// Effect stages after the family, comma-separated catalogue names
    /// (e.g. `saturation:output,creep:output`; `mckibben diagnose --help`
    /// lists them), scored as the diagnosis scores them.
    #[arg(long, value_delimiter = ',', value_name = "LIST")]
    effects: Vec<Effect>,
    /// Also time the CPU path on the same populations (one warm-up call,
    /// median of --repeats) and report the backend's speed-up over it (a
    /// GPU backend's; on the CPU backend there is none to measure).
    #[arg(long)]
    time_reference: bool,
    /// Print JSON on stdout instead of a table.
    #[arg(long, conflicts_with = "markdown")]
    json: bool,
    /// Print a markdown table (header and rows) instead of the text table.
    #[arg(long)]
    markdown: bool,
}

/// Throughput of one timed evaluator: end to end (each `evaluate` call as
/// a fit makes it: conversion, upload, kernels, read-back) and, where the
/// device records timestamps, its kernels alone.
#[derive(Debug, Clone, Copy, Serialize)]
struct Timing {
    candidate_samples_per_s: f64,
    evals_per_s: f64,
    median_s: f64,
    /// The fastest and slowest of the same calls: a machine shared with
    /// other work moves the median between runs, and the spread shows it.
    min_s: f64,
    max_s: f64,
    /// The median of the kernels' device time over the same calls; `None`
    /// on the CPU and where the adapter offers no timestamp queries.
    kernel_median_s: Option<f64>,
    kernel_candidate_samples_per_s: Option<f64>,
}

/// The median of one warm-up call and `repeats` timed calls, and the last scores.
fn time(
    evaluator: &mut dyn Evaluator,
    problem: &Problem,
    population: Rows<'_, Params>,
    repeats: u32,
) -> anyhow::Result<(Timing, Vec<f32>)> {
    let n = population.len();
    let mut scores = evaluator.evaluate(problem, population)?;
    let mut times = Vec::with_capacity(repeats as usize);
    let mut kernel_times = Vec::with_capacity(repeats as usize);
    for _ in 0..repeats {
        let start = Instant::now();
        scores = evaluator.evaluate(problem, population)?;
        times.push(start.elapsed().as_secs_f64());
        kernel_times.extend(evaluator.kernel_seconds());
    }
    let median = |mut t: Vec<f64>| {
        t.sort_by(f64::total_cmp);
        t[t.len() / 2]
    };
    let cand_samples = (n * problem.samples()) as f64;
    let (min_s, max_s) = times.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &t| {
        (lo.min(t), hi.max(t))
    });
    let end_to_end = median(times);
    let kernel = (kernel_times.len() == repeats as usize).then(|| median(kernel_times));
    let timing = Timing {
        candidate_samples_per_s: cand_samples / end_to_end,
        evals_per_s: n as f64 / end_to_end,
        median_s: end_to_end,
        min_s,
        max_s,
        kernel_median_s: kernel,
        kernel_candidate_samples_per_s: kernel.map(|k| cand_samples / k),
    };
    Ok((timing, scores.total))
}

/// The markdown table's header (`--markdown`).
const MARKDOWN_HEADER: &str = "| model | N | backend | cand-samples/s | evals/s | median s (range) | kernel cand-samples/s | kernel median s | share of ceiling | GPU/CPU speed-up | max rel SSE diff | top-100 alike |\n\
                               |---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|---|";

/// The calibration's markdown table (`--markdown`, after the first).
const CALIBRATION_HEADER: &str = "| model | variant | f32 ops a step | steps | invocations | device s | f32 ops/s |\n\
                                  |---|---|---:|---:|---:|---:|---:|";

/// The calibration's markdown rows, each named by the run's `model`.
fn calibration_rows(model: &str, ceiling: &Ceiling) -> String {
    ceiling
        .variants
        .iter()
        .map(|t| {
            format!(
                "| {model} | {} | {} | {} | {} | {:.3e} | {:.3e} |",
                t.variant.name(),
                t.ops_per_step,
                t.steps,
                ceiling.invocations,
                t.device_s,
                t.ops_per_s
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The median time of a call and, over more than one call, the range.
fn spread(t: &Timing) -> String {
    if t.min_s == t.max_s {
        return format!("{:.3e}", t.median_s);
    }
    format!("{:.3e} ({:.3e}–{:.3e})", t.median_s, t.min_s, t.max_s)
}

/// A share as a percentage, `—` where there is none.
fn percent(share: Option<f64>) -> String {
    share.map_or("—".to_string(), |s| format!("{:.1} %", 100.0 * s))
}

/// The markdown rows of one population size: the backend's, then the CPU
/// reference's when it was timed.
fn markdown_rows(row: &Row) -> String {
    let a = &row.agreement;
    let diff = if a.bit_identical {
        "0 (bit-identical)".to_string()
    } else {
        let mut s = format!("{:.2e}", a.max_rel_diff);
        if a.finiteness_mismatches > 0 {
            s += &format!("; {} diverged on one side only", a.finiteness_mismatches);
        }
        s
    };
    let best = row.population.min(100);
    let alike = format!(
        "{} ({}/{best})",
        if a.top100_identical { "yes" } else { "no" },
        a.top100_overlap
    );
    let line = |backend: &str, t: &Timing, share: &str, speedup: &str, diff: &str, alike: &str| {
        let or_dash = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.3e}"));
        format!(
            "| {} | {} | {backend} | {:.3e} | {:.3e} | {} | {} | {} | {share} | {speedup} | {diff} | {alike} |",
            row.model,
            row.population,
            t.candidate_samples_per_s,
            t.evals_per_s,
            spread(t),
            or_dash(t.kernel_candidate_samples_per_s),
            or_dash(t.kernel_median_s)
        )
    };
    let mut out = line(
        row.backend,
        &row.timing,
        &percent(row.ceiling_share),
        &row.speedup.map_or("—".to_string(), |s| format!("{s:.2}×")),
        &diff,
        &alike,
    );
    if let Some(r) = &row.reference {
        out += "\n";
        out += &line("cpu", r, "—", "1×", "reference", "reference");
    }
    out
}

/// The `--json` output: the calibration, and one row per population size.
#[derive(Debug, Serialize)]
struct Output<'a> {
    calibration: Option<CalibrationJson<'a>>,
    rows: &'a [Row],
}

/// The calibration as `--json` gives it: the ceiling beside every variant.
#[derive(Debug, Serialize)]
struct CalibrationJson<'a> {
    invocations: u32,
    ceiling_ops_per_s: f64,
    variants: &'a [Timed],
}

impl<'a> From<&'a Ceiling> for CalibrationJson<'a> {
    fn from(c: &'a Ceiling) -> Self {
        CalibrationJson {
            invocations: c.invocations,
            ceiling_ops_per_s: c.ceiling_ops_per_s(),
            variants: &c.variants,
        }
    }
}

/// One population's result; the keys of `--json`'s rows.
#[derive(Debug, Serialize)]
struct Row {
    backend: &'static str,
    adapter: String,
    model: String,
    effects: Vec<Effect>,
    samples: usize,
    population: usize,
    #[serde(flatten)]
    timing: Timing,
    agreement: Agreement,
    reference: Option<Timing>,
    speedup: Option<f64>,
    /// The model kernel's `f32` operations a candidate-sample, where they
    /// are a fixed count (`calibration::ops_per_candidate_sample`).
    ops_per_candidate_sample: Option<u32>,
    /// The kernels' rate in those operations, from the device's clock.
    kernel_ops_per_s: Option<f64>,
    /// `kernel_ops_per_s` over the calibrated ceiling.
    ceiling_share: Option<f64>,
    /// The share of the population whose free run diverged (a score that
    /// is not finite): such a run stops at its first non-finite sample, so
    /// a population of mostly diverging candidates scores faster than a
    /// fit's, whose candidates mostly run the whole record.
    diverged_share: f64,
}

/// A share of the candidates past which `bench` warns that its rate
/// overstates a fit's: the draw's uniform half diverges mostly by design
/// (about two thirds of the whole on the shipped stair), but nearly all is a
/// population the data's units put outside the thesis' box.
const MOSTLY_DIVERGED: f64 = 0.9;

/// What a run scores: the problem, its model with the effects' constants
/// of each dataset, and the model's label for the tables.
struct Workload {
    problem: Problem,
    model: ModelDescription,
    contexts: Vec<Context>,
    label: String,
}

/// The experiments `args` name and the model scored on them, checked.
fn workload(args: &Args) -> anyhow::Result<Workload> {
    let experiments: Vec<Experiment> = match args.synthetic {
        Some(n) => {
            anyhow::ensure!(
                (2..=MAX_SAMPLES).contains(&n),
                "--synthetic {n}: at least 2 samples and at most {MAX_SAMPLES} (as many as a \
                 record may hold)"
            );
            vec![stair_experiment(n, args.seed)]
        }
        None => {
            let traces = args.data.load()?;
            // As fit's: values whose errors overflow the f32 kernels would
            // give a box no candidate can be drawn from.
            for t in &traces {
                check_f32_range(t)?;
            }
            traces
                .iter()
                .map(|t| {
                    Experiment::with_means_of(t, mckibben::model::experiment::halves(t.len()).0)
                })
                .collect()
        }
    };
    let datasets = experiments.len();
    if let Some(why) = Effect::chain_conflict(&args.effects) {
        anyhow::bail!("--effects {why}");
    }
    if let Some(e) = args.effects.iter().find(|e| !e.applicable(datasets)) {
        anyhow::bail!(
            "--effects: `{e}` needs at least two datasets (data files), this run has {datasets}"
        );
    }
    if args.model == Family::Linear && !args.effects.is_empty() {
        anyhow::bail!(
            "--effects: effect stages follow a hysteretic family (classic or generalized), not linear"
        );
    }
    let mut problem = Problem::new(args.model, experiments);
    // The effects' constants per dataset, as the diagnosis builds them: the
    // side a rising input drives the output to is the sign of the prior's
    // gain (the thesis' here, as the search box below).
    let model = ModelDescription::new(args.model, args.effects.clone(), datasets);
    let contexts: Vec<Context> = problem
        .experiments
        .iter()
        .map(|e| Context::of(e, THESIS_B >= 0.0))
        .collect();
    if !args.effects.is_empty() {
        problem = problem.with_effects(args.effects.clone(), contexts.clone());
    }
    let label = if args.effects.is_empty() {
        args.model.to_string()
    } else {
        let names: Vec<&str> = args.effects.iter().map(|e| e.name()).collect();
        format!("{} + {}", args.model, names.join(", "))
    };
    Ok(Workload {
        problem,
        model,
        contexts,
        label,
    })
}

/// The plain-text lines before the table: the backend, the workload and
/// the device's ceiling.
fn print_header(
    args: &Args,
    workload: &Workload,
    describe: &str,
    ceiling: Option<&Ceiling>,
) -> anyhow::Result<()> {
    let problem = &workload.problem;
    outln!("backend: {describe}")?;
    outln!(
        "{} model, {} samples in {} experiment(s){}",
        workload.label,
        problem.samples(),
        problem.experiments.len(),
        match (args.model, args.free_n) {
            (Family::Linear, _) => "",
            (_, true) => ", n free",
            (_, false) => ", n = 1",
        }
    )?;
    if let Some(c) = ceiling {
        let rate = |v| c.ops_per_s(v).unwrap_or(f64::NAN);
        outln!(
            "device ceiling (calibration kernel, device clock): {:.3e} f32 ops/s in {} independent mul-add chains; {:.3e} in one dependent chain; {:.3e} with pow",
            rate(Variant::Independent),
            calibration::CHAINS,
            rate(Variant::Dependent),
            rate(Variant::Pow)
        )?;
    }
    outln!(
        "{:>10}  {:>12}  {:>11}  {:>10}  {}",
        "population",
        "cand-samp/s",
        "evals/s",
        "median s (range)",
        if ceiling.is_some() {
            "agreement with the CPU path"
        } else {
            // Scored by the CPU path itself: the check cannot fail here
            // (the lanes' bits against `model::sse` are the tests').
            "agreement with the CPU path (the path itself here: a check for a GPU backend)"
        }
    )
}

/// One row of the plain-text table.
fn print_row(row: &Row) -> anyhow::Result<()> {
    let (a, timing) = (&row.agreement, &row.timing);
    outln!(
        "{:>10}  {:>12.3e}  {:>11.3e}  {:>10}  {}, top-10 {}, top-100 {} ({} of {} shared), max rel diff {:.2e}, {} finiteness mismatches, {} diverged{}",
        row.population,
        timing.candidate_samples_per_s,
        timing.evals_per_s,
        spread(timing),
        if a.bit_identical {
            "bit-identical"
        } else {
            "not bit-identical"
        },
        if a.top10_identical {
            "identical"
        } else {
            "differs"
        },
        if a.top100_identical {
            "identical"
        } else {
            "differs"
        },
        a.top100_overlap,
        row.population.min(100),
        a.max_rel_diff,
        a.finiteness_mismatches,
        percent(Some(row.diverged_share)),
        match (&row.reference, row.speedup) {
            (Some(r), Some(x)) => format!(
                "; CPU path {:.3e} cand-samples/s, speed-up {x:.2}×",
                r.candidate_samples_per_s
            ),
            _ => String::new(),
        } + &match (row.kernel_ops_per_s, row.ceiling_share) {
            (Some(ops), Some(share)) => format!(
                "; kernels {ops:.3e} f32 ops/s, {} of the ceiling",
                percent(Some(share))
            ),
            _ => String::new(),
        }
    )
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.pop.iter().all(|&n| n > 0),
        "--pop: every population size must be at least 1"
    );
    anyhow::ensure!(
        !args.free_n || args.model.exponent_index().is_some(),
        "--free-n frees the Bouc-Wen exponent n, and --model {} has none",
        args.model
    );
    let workload = workload(&args)?;
    let (problem, label) = (&workload.problem, &workload.label);
    let mut evaluator = open(args.backend)?;
    let backend = if evaluator.adapter().is_some() {
        "gpu"
    } else {
        "cpu"
    };
    let adapter = evaluator.adapter().unwrap_or_else(|| evaluator.describe());
    // The reference is the CPU path: timed against itself, its "speed-up"
    // would be noise presented as a figure.
    let time_reference = args.time_reference && backend == "gpu";
    if args.time_reference && !time_reference {
        errln!(
            "mckibben: note: --time-reference times the CPU path against a GPU's; the backend \
             here is the CPU, so there is no speed-up to measure"
        );
    }
    // The device's ceiling, in the same run as the model's kernels.
    let ceiling = evaluator.calibrate(calibration::Sizing::default())?;
    let ops_per_candidate_sample =
        calibration::ops_per_candidate_sample(args.model, !args.effects.is_empty(), !args.free_n);
    if args.markdown {
        outln!("{MARKDOWN_HEADER}")?;
    } else if !args.json {
        print_header(&args, &workload, &evaluator.describe(), ceiling.as_ref())?;
    }
    let space = search_space(args.model, &problem.experiments[0], args.free_n);
    let mut reference = CpuEvaluator::new();
    let mut rows = Vec::new();
    for &n in &args.pop {
        let mut rng = ChaCha8Rng::seed_from_u64(args.seed);
        let population = if args.effects.is_empty() {
            mixed_population(&space, n, &mut rng)
        } else {
            let (model, context) = (&workload.model, &workload.contexts[0]);
            augmented_population(model, &space, context, n, &mut rng)
        };
        let population = problem.rows(&population);
        let (timing, scores) = time(evaluator.as_mut(), problem, population, args.repeats)?;
        let (reference_timing, want) = if time_reference {
            let (t, want) = time(&mut reference, problem, population, args.repeats)?;
            (Some(t), want)
        } else {
            (None, reference.evaluate(problem, population)?.total)
        };
        let kernel_ops_per_s = timing
            .kernel_candidate_samples_per_s
            .zip(ops_per_candidate_sample)
            .map(|(rate, ops)| rate * f64::from(ops));
        let row = Row {
            backend,
            adapter: adapter.clone(),
            model: label.clone(),
            effects: args.effects.clone(),
            samples: problem.samples(),
            population: n,
            timing,
            agreement: agreement(&scores, &want),
            speedup: reference_timing.map(|r| r.median_s / timing.median_s),
            reference: reference_timing,
            ops_per_candidate_sample,
            kernel_ops_per_s,
            ceiling_share: kernel_ops_per_s
                .zip(ceiling.as_ref())
                .map(|(rate, c)| rate / c.ceiling_ops_per_s()),
            diverged_share: scores.iter().filter(|s| !s.is_finite()).count() as f64 / n as f64,
        };
        if row.diverged_share > MOSTLY_DIVERGED {
            errln!(
                "mckibben: warning: --pop {n}: {} of the drawn candidates diverged, and a \
                 diverging run stops early, so the rate overstates a fit's; the candidates are \
                 drawn from the thesis' box, in MPa and mm: data in other units (Pa, m) draw \
                 nearly only diverging ones",
                percent(Some(row.diverged_share))
            );
        }
        if args.markdown {
            outln!("{}", markdown_rows(&row))?;
        } else if !args.json {
            print_row(&row)?;
        }
        rows.push(row);
    }
    if args.json {
        let output = Output {
            calibration: ceiling.as_ref().map(CalibrationJson::from),
            rows: &rows,
        };
        outln!("{}", Versioned::new(output).to_string_pretty()?)?;
    } else if let (true, Some(c)) = (args.markdown, &ceiling) {
        outln!("\n{CALIBRATION_HEADER}\n{}", calibration_rows(label, c))?;
    }
    Ok(())
}
