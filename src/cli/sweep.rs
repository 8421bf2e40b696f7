//! `mckibben sweep`: what a larger population buys, on generated cases
//! with a known truth.

use super::common::{given_once, population};
use mckibben::eval::{self, Backend};
use mckibben::fit::objective::{groups_of, tries_text, try_populations};
use mckibben::fit::problem::Overshoot;
use mckibben::fit::sweep::{
    CaseFit, MATRIX_SEED, PopulationRow, cases, fit_case, markdown_table, matrix_size, summarize,
};
use mckibben::model::Family;
use mckibben::report::json::Versioned;
use serde::Serialize;

/// Fit the generated cases with a known truth at several populations: what
/// more compute buys, on this machine and backend.
///
/// The cases are the classic matrix (20 cases, #1000–#1019) and the
/// generalized one (30, #1000–#1029) of `fit::cases`: truths of the bounded
/// class drawn on their own priors, stair, multisine and mixed inputs of
/// 8 000–12 000 samples with noise, some in kPa→m or psi→mm. Each case is
/// fitted with `mckibben fit`'s defaults at each population (a population
/// of 2000 or more runs independent tries of 1000 and 100) and judged
/// against its truth: it passes when its validation RMSE is within 5 % of
/// the truth's (or, where the estimation half cannot reach the truth, when
/// it fits that half as well as the truth polished there). These cases
/// chose some of the fit's defaults (the tries of 100 among them); with
/// --matrix 5000 (or any other seed) the same kinds of cases are drawn
/// afresh, numbered #5000 on, and check them on data that chose nothing.
///
/// Per family and population it prints one row: tries a fit, fits that pass,
/// fits within 5 %, p (the share of single tries that would pass alone,
/// tries of both sizes together), how often a fit whose tries
/// mostly agreed (more than half) or hardly agreed missed the truth, and the
/// wall time a fit. With several --seeds, the pass counts are of the first
/// seed and p counts every seed's tries.
///
/// Each case takes seconds at N = 1000 and about ten times longer at
/// N = 10000 on the CPU (2 cores: 1.3 s and 13 s a classic case, 5 s and
/// 61 s a generalized one); a progress line a fit goes to stderr.
///
/// --json prints `schema_version`, `backend`, `matrix` (the seed), `rows` (one object a family
/// and population: family, n, cases, tries, pass, within_5_percent,
/// single_tries_passing, single_tries, agreed, agreed_missed, few_agreed,
/// few_agreed_missed, mean_seconds, min_seconds, max_seconds) and `fits`
/// (one object a fit: family, case, name, n, seed, passes, ratio, sse,
/// tries, try_populations, agreeing, seconds). --markdown prints the table
/// for docs/PERFORMANCE.md with the backend in each row. A table of another
/// --matrix than 1000 starts with a line that names it.
///
/// Examples:
///   mckibben sweep --pop 1000,10000 --family classic
///   mckibben sweep --pop 100 --cases 1008,1012 --seeds 1,2,3 --json
///   mckibben sweep --pop 100000 --backend gpu --family generalized --cases 1019
///   mckibben sweep --pop 1000,10000 --family generalized --matrix 5000
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// Populations, comma-separated (each at least 4).
    #[arg(long, value_delimiter = ',', default_value = "100,1000,10000", value_parser = population)]
    pop: Vec<usize>,
    /// Families, comma-separated: classic, generalized.
    #[arg(long, value_delimiter = ',', default_value = "classic,generalized")]
    family: Vec<Family>,
    /// Only the cases of these numbers, comma-separated (e.g. `1008,1012`;
    /// a number past a family's matrix picks none of its cases).
    #[arg(long, value_delimiter = ',', value_name = "NUMBERS")]
    cases: Option<Vec<u64>>,
    /// The seed the cases are drawn from, and their first number: 1000
    /// gives the cases of the figures in docs/RESULTS.md; another (say
    /// 5000) draws other truths, records and noise of the same kinds, that
    /// no choice of this tool has seen: a check of a claim on data that did
    /// not shape it.
    #[arg(long, value_name = "SEED", default_value_t = MATRIX_SEED, value_parser = matrix_seed)]
    matrix: u64,
    /// Fit seeds, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1", value_parser = crate::cli::common::seed)]
    seeds: Vec<u64>,
    /// Where to score: `auto` takes a real GPU if there is one, else the CPU.
    #[arg(long, value_enum, ignore_case = true, default_value_t = Backend::Auto)]
    backend: Backend,
    /// Whether the fits admit a loop whose update overshoots on the steps
    /// its record takes, as `fit --overshoot`.
    #[arg(long, value_enum, ignore_case = true, default_value_t = Overshoot::Allow)]
    overshoot: Overshoot,
    /// Machine-readable output on stdout.
    #[arg(long, conflicts_with = "markdown")]
    json: bool,
    /// The table as Markdown rows for docs/PERFORMANCE.md.
    #[arg(long)]
    markdown: bool,
}

#[derive(Serialize)]
struct Output<'a> {
    backend: String,
    matrix: u64,
    overshoot: Overshoot,
    rows: &'a [PopulationRow],
    fits: &'a [CaseFit],
}

/// A `--matrix` seed: a seed whose cases' numbers (it, and on) are seeds
/// too, exact in the JSON as every seed is.
fn matrix_seed(s: &str) -> Result<u64, String> {
    let seed = crate::cli::common::seed(s)?;
    let last = [Family::Classic, Family::Generalized]
        .map(matrix_size)
        .into_iter()
        .max()
        .unwrap_or(0) as u64;
    let most = mckibben::optim::streams::MAX_SEED - (last - 1);
    if seed > most {
        return Err(format!(
            "at most {most}: the cases are numbered from the seed on, and the last of {last} \
             must be a seed too (at most 2^53 - 1)"
        ));
    }
    Ok(seed)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // A value given twice would fit the same cases twice and count each
    // pass twice.
    let twice = "each case would be fitted, and counted, twice";
    given_once("--pop", &args.pop, twice)?;
    given_once("--family", &args.family, twice)?;
    given_once("--seeds", &args.seeds, twice)?;
    given_once("--cases", args.cases.as_deref().unwrap_or_default(), twice)?;
    if let Some(&n) = args.pop.iter().find(|&&n| n < 4) {
        anyhow::bail!("--pop: every population must be at least 4 (got {n})");
    }
    if args.family.contains(&Family::Linear) {
        anyhow::bail!("--family: the cases are hysteretic: classic or generalized, not linear");
    }
    let picked: Vec<_> = args
        .family
        .iter()
        .flat_map(|&f| cases(f, args.matrix, args.cases.as_deref()))
        .collect();
    if picked.is_empty() {
        let ranges: Vec<String> = args
            .family
            .iter()
            .map(|&f| {
                let last = args.matrix + matrix_size(f) as u64 - 1;
                format!("{f}: {}–{last}", args.matrix)
            })
            .collect();
        anyhow::bail!(
            "--cases: no case of the {} matrix of --matrix {} has these numbers ({})",
            args.family
                .iter()
                .map(|f| f.to_string())
                .collect::<Vec<_>>()
                .join(" or "),
            args.matrix,
            ranges.join(", ")
        );
    }
    // A population from two tries on is whole tries, as `fit` runs it: the
    // rows say the population that ran.
    let mut pops: Vec<usize> = Vec::new();
    for &n in &args.pop {
        let populations = try_populations(n);
        let ran: usize = populations.iter().sum();
        if ran != n {
            errln!(
                "mckibben: note: --pop {n} runs {ran} candidates ({}), as `fit --pop {n}` does",
                tries_text(&groups_of(&populations))
            );
        }
        if !pops.contains(&ran) {
            pops.push(ran);
        }
    }
    let mut evaluator = eval::open(args.backend)?;
    let backend = evaluator.describe();
    errln!("backend: {backend}");
    let mut fits = Vec::new();
    for &n in &pops {
        for case in &picked {
            for &seed in &args.seeds {
                let fit = fit_case(case, (n, seed), args.overshoot, evaluator.as_mut())?;
                errln!("{fit}");
                fits.push(fit);
            }
        }
    }
    let rows = summarize(&fits);
    if args.json {
        let output = Output {
            backend,
            matrix: args.matrix,
            overshoot: args.overshoot,
            rows: &rows,
            fits: &fits,
        };
        outln!("{}", Versioned::new(output).to_string_pretty()?)?;
        return Ok(());
    }
    let kind = if evaluator.adapter().is_some() {
        "gpu"
    } else {
        "cpu"
    };
    // A table of other cases than the documented ones says so, wherever
    // it is pasted.
    if args.matrix != MATRIX_SEED {
        outln!("Cases of --matrix {} (#{} on):\n", args.matrix, args.matrix)?;
    }
    // The rows count the lowest seed's fits as the cases' own.
    if let (true, Some(first)) = (args.seeds.len() > 1, args.seeds.iter().min()) {
        let seeds: Vec<String> = args.seeds.iter().map(u64::to_string).collect();
        outln!(
            "Seeds {}: pass, within 5 %, the agreement columns and the time are seed {first}'s \
             fits; p counts every seed's tries.\n",
            seeds.join(", ")
        )?;
    }
    outln!("{}", markdown_table(&rows, args.markdown.then_some(kind)))?;
    Ok(())
}
