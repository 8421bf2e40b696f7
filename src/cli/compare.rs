//! `mckibben compare`: the thesis' Table 21 redone, what large populations
//! buy, the thesis' methods against the baseline at equal budgets over many
//! seeds, the two flows, and the cross-load check of §4.10.

use std::path::{Path, PathBuf};

use anyhow::Context;

use super::common::{ColumnArgs, DataArgs, check_folder, given_once, one_trace, population};
use mckibben::data::{Trace, same_samples, same_step, tidy_step, write_all_atomic};
use mckibben::eval::{self, Backend};
use mckibben::fit::compare::{Report, Settings, Study, markdown};
use mckibben::optim::mfa;
use mckibben::report::json::Versioned;

/// What `--out` receives.
const OUT_FILES: [&str; 2] = ["compare.json", "compare.md"];

/// Compare the optimizers on one experiment (the shipped 4.5 kg stair by
/// default), as Markdown tables (and JSON with --json):
///
/// 1. the thesis' Table 21: every algorithm × both models × N = 10, 20, 30
///    at G = 30, with total and per-generation time, final SSE and
///    validation fit %; then the same at N = 1e3, 1e4, 1e5 (--sizes). The
///    thesis' algorithm settings on the joint flow (a, b, c, x0 fitted in
///    the data's box), where the algorithms compete on one problem; the
///    thesis' own flow is in 3;
/// 2. equal population budgets over --seeds seeds (median, min, max, a
///    diverged seed counted as the worst, and how many diverged): the
///    thesis-faithful GA, MFA, PSO, the documented fixes of GA and MFA, and
///    differential evolution, each one search on the free run as the thesis
///    does; then the staged fit of `mckibben fit` with each update rule,
///    whose free-run stage and polish add evaluations (their mean per seed
///    is shown);
/// 3. the joint flow (a, b, c, x0 fitted; staged fit) against the thesis'
///    flow (a, b at the ARX estimate, no intercept; same staged fit);
/// 4. the cross-load check (§4.10): fitted on this data with the default
///    staged fit, scored on --cross (default: data/stair_7kg.csv beside the
///    default data), and back; every row on the scored file's second half,
///    so a model's own file is scored where its fit did not look.
///
/// The MFA's all-pairs move costs O(N²·d) per generation; above
/// --mfa-all-pairs-max fireflies it moves towards the 10 brightest only
/// (marked `mfa*`).
///
/// Example: mckibben compare --sizes 1000,10000 --seeds 10
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    #[command(flatten)]
    data: DataArgs,
    /// The thesis' population sizes (Table 21).
    #[arg(long, value_delimiter = ',', default_value = "10,20,30", value_parser = population)]
    thesis_sizes: Vec<usize>,
    /// Large population sizes to add to Table 21 (`--sizes 0`: none).
    #[arg(long, value_delimiter = ',', default_value = "1000,10000,100000", value_parser = population)]
    sizes: Vec<usize>,
    /// Generations for Table 21 (the thesis used 30).
    #[arg(long, default_value_t = 30, value_parser = crate::cli::common::generations)]
    gens: usize,
    /// Seeds for the equal-budget table (0: skip it).
    #[arg(long, default_value_t = 10)]
    seeds: u64,
    /// Population and generations of the equal-budget table.
    #[arg(long, default_value_t = 500, value_parser = population)]
    budget_pop: usize,
    #[arg(long, default_value_t = 100, value_parser = crate::cli::common::generations)]
    budget_gens: usize,
    /// Largest N at which the MFA moves every firefly towards all brighter ones.
    #[arg(long, default_value_t = mfa::ALL_PAIRS_MAX)]
    mfa_all_pairs_max: usize,
    /// Second experiment for the cross-load check.
    #[arg(long, value_name = "FILE")]
    cross: Option<PathBuf>,
    /// Where populations are scored (see `fit --help`).
    #[arg(long, value_enum, ignore_case = true, default_value = "auto")]
    backend: Backend,
    /// Folder for compare.md and compare.json.
    #[arg(long, value_parser = crate::cli::common::output_path, value_name = "DIR", default_value = "out/compare")]
    out: PathBuf,
    /// Print JSON on stdout instead of Markdown.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let settings = Settings {
        thesis_sizes: args.thesis_sizes.clone(),
        sizes: args.sizes.clone(),
        gens: args.gens,
        seeds: args.seeds,
        budget_pop: args.budget_pop,
        budget_gens: args.budget_gens,
        mfa_all_pairs_max: args.mfa_all_pairs_max,
    };
    let twice = "Table 21 would hold its rows twice";
    given_once("--thesis-sizes", &args.thesis_sizes, twice)?;
    given_once("--sizes", &args.sizes, twice)?;
    settings.check()?;
    let trace = one_trace(args.data.load()?, args.data.columns.resample.is_some())?;
    // Read before the study, so that a bad --cross fails at once, not
    // after minutes of fits.
    let other = cross_trace(&args)?;
    if let Some(other) = &other {
        anyhow::ensure!(
            !same_samples(&trace, other),
            "--cross {}: it holds the samples of {}: the cross-load check scores the fits on \
             another record (the other load); give one",
            other.source,
            trace.source
        );
        let dt = trace.dt();
        anyhow::ensure!(
            same_step(other.dt(), dt),
            "--cross {}: sampled every {} s, {} every {} s: a model's poles are per sample, so \
             the cross-load check needs one step (--resample {})",
            other.source,
            tidy_step(other.dt()),
            trace.source,
            tidy_step(dt),
            tidy_step(dt)
        );
    }
    // The folder too: a study of minutes must not end on a path that
    // cannot be written, nor write its report over the records it reads.
    let data = match &args.data.data {
        Some(path) => path.clone(),
        None => super::common::default_data()?,
    };
    let mut reads: Vec<(&str, &Path)> = vec![("DATA", &data)];
    reads.extend(args.cross.iter().map(|p| ("--cross", p.as_path())));
    check_folder("--out", &args.out, &OUT_FILES.map(String::from), &reads)?;
    super::common::check_creatable("--out", &args.out)?;
    let mut evaluator = eval::open(args.backend)?;
    let backend = evaluator.describe();
    errln!("comparing on {} [{backend}]", trace.source);
    let progress = |s: String| errln!("{s}");
    let mut study = Study::new(&trace, &settings, evaluator.as_mut())?;
    let table21 = study.table21(&progress)?;
    let budget = study.budget(&progress)?;
    let flows = study.flows(&progress)?;
    let cross_load = match other {
        Some(other) => study.cross_load(&other, &flows, &progress)?,
        None => Vec::new(),
    };
    let report = Report {
        data: trace.source.clone(),
        columns: trace.columns(),
        backend,
        table21,
        budget,
        flows: flows.rows,
        cross_load,
    };
    let md = markdown(&report, &settings);
    let json = Versioned::new(&report).to_string_pretty()?;
    // Printed even where a write fails: minutes of study are not lost.
    let [json_file, md_file] = OUT_FILES.map(|name| args.out.join(name));
    let written = write_all_atomic(&[(&json_file, json.as_bytes()), (&md_file, md.as_bytes())])
        .with_context(|| format!("cannot write into {}", args.out.display()));
    if args.json {
        outln!("{json}")?;
    } else {
        out!("{md}")?;
    }
    written
}

/// The second experiment: --cross, or the 7 kg stair beside the default data.
fn cross_trace(args: &Args) -> anyhow::Result<Option<Trace>> {
    let path = match (&args.cross, &args.data.data) {
        (Some(p), _) => p.clone(),
        (None, None) => {
            let default = super::common::default_data()?;
            let sibling = default.with_file_name("stair_7kg.csv");
            if !sibling.is_file() {
                errln!(
                    "mckibben: note: no {} for the cross-load check",
                    sibling.display()
                );
                return Ok(None);
            }
            sibling
        }
        (None, Some(_)) => {
            errln!(
                "mckibben: note: no cross-load check: name the other load's record with --cross FILE"
            );
            return Ok(None);
        }
    };
    let cols: &ColumnArgs = &args.data.columns;
    let other = DataArgs {
        data: Some(path),
        columns: cols.clone(),
    };
    let flag = match args.cross {
        Some(_) => "--cross",
        None => "the cross-load check's default record",
    };
    let trace = other
        .load()
        .and_then(|t| one_trace(t, cols.resample.is_some()))
        .map_err(|e| anyhow::anyhow!("{flag}: {e}"))?;
    Ok(Some(trace))
}
