//! `mckibben bench`: how fast the evaluator scores populations, and how well
//! the chosen backend agrees with the CPU reference.

use std::time::Instant;

use serde::Serialize;

use super::common::DataArgs;
use mckibben::eval::agreement::{Agreement, agreement};
use mckibben::eval::cpu::CpuEvaluator;
use mckibben::eval::workload::{mixed_population, search_space, stair_experiment};
use mckibben::eval::{Backend, Evaluator, Problem, open};
use mckibben::model::{Experiment, Family};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// Time the batch evaluator: the fitness (SSE) of whole populations on an
/// experiment, as one generation of an optimizer asks for it.
///
/// For each population size: one warm-up call, then the median of
/// `--repeats` calls, parameter upload and score read-back included. The
/// population is drawn from the default search box (thesis bounds; half of
/// it uniform, so it includes diverging candidates, half near the thesis
/// preset). The scores are compared with the CPU reference on the same
/// population: maximum relative difference, diverged-in-one-only count,
/// bit-identity and whether the ten best candidates are the same.
///
/// Examples:
///   mckibben bench --synthetic 4000 --backend cpu --model classic --pop 131072
///   mckibben bench run.csv --backend gpu --pop 1000,100000,1000000 --json
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
    #[arg(long, value_delimiter = ',', default_value = "1000,10000,100000")]
    pop: Vec<usize>,
    /// Where to score: `auto` takes a real GPU if there is one, else the CPU.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    backend: Backend,
    /// Free the Bouc-Wen exponent n (drawn from [1, 3]) instead of n = 1.
    #[arg(long)]
    free_n: bool,
    /// Timed calls per population (after one warm-up call); the median is reported.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
    repeats: u32,
    /// Seed of the population draw.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print JSON on stdout instead of a table.
    #[arg(long)]
    json: bool,
}

/// One population's result; the keys of `--json`.
#[derive(Debug, Serialize)]
struct Row {
    backend: &'static str,
    adapter: String,
    samples: usize,
    population: usize,
    candidate_samples_per_s: f64,
    evals_per_s: f64,
    median_s: f64,
    agreement: Agreement,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.pop.iter().all(|&n| n > 0),
        "--pop: every population size must be at least 1"
    );
    let experiments: Vec<Experiment> = match args.synthetic {
        Some(n) => {
            anyhow::ensure!(n >= 2, "--synthetic: at least 2 samples");
            vec![stair_experiment(n, args.seed)]
        }
        None => args
            .data
            .load()?
            .iter()
            .map(|t| Experiment::with_means_of(t, mckibben::model::experiment::halves(t.len()).0))
            .collect(),
    };
    let problem = Problem::new(args.model, experiments);
    let mut evaluator = open(args.backend)?;
    let backend = if evaluator.adapter().is_some() {
        "gpu"
    } else {
        "cpu"
    };
    let adapter = evaluator.adapter().unwrap_or_else(|| evaluator.describe());
    if !args.json {
        println!("backend: {}", evaluator.describe());
        println!(
            "{} model, {} samples in {} experiment(s){}",
            args.model,
            problem.samples(),
            problem.experiments.len(),
            match (args.model, args.free_n) {
                (Family::Linear, _) => "",
                (_, true) => ", n free",
                (_, false) => ", n = 1",
            }
        );
        println!(
            "{:>10}  {:>12}  {:>11}  {:>10}  agreement with the CPU path",
            "population", "cand-samp/s", "evals/s", "median s"
        );
    }
    let space = search_space(args.model, &problem.experiments[0], args.free_n);
    let mut reference = CpuEvaluator::new();
    let mut rows = Vec::new();
    for &n in &args.pop {
        let population = mixed_population(&space, n, &mut ChaCha8Rng::seed_from_u64(args.seed));
        let mut scores = evaluator.evaluate(&problem, &population)?;
        let mut times = Vec::with_capacity(args.repeats as usize);
        for _ in 0..args.repeats {
            let start = Instant::now();
            scores = evaluator.evaluate(&problem, &population)?;
            times.push(start.elapsed().as_secs_f64());
        }
        times.sort_by(f64::total_cmp);
        let median = times[times.len() / 2];
        let want = reference.evaluate(&problem, &population)?;
        let row = Row {
            backend,
            adapter: adapter.clone(),
            samples: problem.samples(),
            population: n,
            candidate_samples_per_s: (n * problem.samples()) as f64 / median,
            evals_per_s: n as f64 / median,
            median_s: median,
            agreement: agreement(&scores.total, &want.total),
        };
        if !args.json {
            let a = &row.agreement;
            println!(
                "{:>10}  {:>12.3e}  {:>11.3e}  {:>10.3e}  {}, top-10 {}, max rel diff {:.2e}, {} finiteness mismatches",
                n,
                row.candidate_samples_per_s,
                row.evals_per_s,
                median,
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
                a.max_rel_diff,
                a.finiteness_mismatches
            );
        }
        rows.push(row);
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    }
    Ok(())
}
