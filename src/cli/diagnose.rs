//! `mckibben diagnose`: where the fitted model misses, which unmodelled
//! effect causes it, and how far the model gets with it.

use std::path::{Path, PathBuf};

use anyhow::Context;

use mckibben::data::{mixed_steps, tidy_step};
use mckibben::diagnose::report::{DiagnosisJson, FIGURES, to_text, write_figures};
use mckibben::diagnose::settings::Progress;
use mckibben::diagnose::transfer::{check_others, transfer};
use mckibben::diagnose::{Effect, Settings, diagnose_from};
use mckibben::diagnose::{seeds, selftest_run};
use mckibben::eval::Backend;
use mckibben::model::{Family, ModelFile};
use mckibben::names::UnknownName;
use mckibben::report::json::Versioned;

use super::common::{ModelArg, MultiDataArgs, check_creatable, check_folder};

/// The model files `--out` writes: the baseline and the final model.
const OUT_FILES: [&str; 2] = ["baseline.json", "model.json"];

/// Diagnose the sim-to-real gap of a fitted hysteresis model.
///
/// Fits the baseline on the first half of each DATA file and cuts the
/// second half into blocks that alternate between a selection part, which
/// every choice below reads, and a test part, read once the model is final
/// (--blocks). Then reports WHERE the free-run residual lies (input branch,
/// input level, transient or settled, frequency, dataset; whiteness and
/// residual–input tests), WHICH effect of the catalogue (delay, deadzone,
/// saturation, asymmetry, inertia, backlash, creep, rate, load, softening,
/// set), in which
/// realisation (e.g. `delay:input-lag`, a first-order lag on the input;
/// `inertia:ringing`, a hanging load that rings after each input step),
/// explains it —
/// each fitted as an addition to the baseline with several seeds and accepted
/// only if it beats the seed-to-seed spread, pays for its parameters, is
/// not a better refit of the model without it, does not owe its gain to one
/// block, and the model still misses by more than the noise — HOW FAR the
/// error falls on the selection part and on the test part (the figures to
/// quote; their difference is the choice's optimism), against a
/// noise-floor estimate, HOW SURE each named effect's size is (a 95 %
/// profile-likelihood interval) and whether the final fit is REFITTED
/// alike when the final model is fitted again from scratch, HOW MUCH of
/// the gap is explainable at all (a ridge model of the residual from the
/// input's lags, filters, rate and branch, each named effect reported as a
/// share of it; "not explained by
/// the catalogue", and then no effect named, when it is large and the
/// effects close little of it or leave more than twice what it leaves),
/// the residual's spectrum with its peaks (e.g. a load ringing after
/// steps) and, with --transfer, how much of the gap the chain closes on
/// other records. "None of the catalogued effects explains the remaining
/// gap" is a valid answer.
///
/// The baseline's loop shapes are searched in the thesis' box, made for a
/// stroke of about 40 mm, in mm or in the length unit that the --output
/// column's name states (`disp_m`, `x [cm]`, `stroke_um`); a column whose
/// name states none is taken in mm, with a note.
///
/// Example: `mckibben diagnose data/stair_4.5kg.csv --report out/`
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    data: MultiDataArgs,
    /// Baseline model family. [default: classic, or the --from model's]
    #[arg(long, value_enum, ignore_case = true)]
    baseline: Option<ModelArg>,
    // The help lists the catalogue as `model::effects` declares it.
    #[arg(long, value_delimiter = ',', value_parser = parse_effect, help = format!(
        "Effects to try, comma-separated (default: the whole catalogue, every realisation: {})",
        Effect::help_list()
    ))]
    effects: Vec<Effect>,
    /// Seed of every random draw (fits are reproducible for a given seed).
    #[arg(long, default_value_t = 1, value_parser = crate::cli::common::seed)]
    seed: u64,
    /// Seeds per candidate fit; their spread is the yardstick of the acceptance rule.
    #[arg(long, default_value_t = Settings::default().seeds)]
    seeds: usize,
    /// Generations of each candidate fit (population 30); the baseline gets
    /// 600 generations of 40 with 12 seeds. Every fit then ends with a
    /// Levenberg–Marquardt polish of its best point. Fewer is faster and
    /// less certain.
    #[arg(long, visible_alias = "gens", default_value_t = Settings::default().generations, value_parser = crate::cli::common::generations)]
    generations: usize,
    /// Extra seeds of each first-round candidate fitted from scratch (the
    /// baseline's budget, through the multi-step-ahead prediction error
    /// first): they find a model with the effect that a warm start from a
    /// baseline which compensates the effect cannot reach. The final model
    /// is refitted from scratch as many times (REFITTED), and once as `fit
    /// --effects` fits it (AS FIT). 0 is faster and leaves all three out.
    #[arg(long, default_value_t = Settings::default().scratch_seeds)]
    scratch_seeds: usize,
    /// At most this many effects are added, one a round. Each round fits
    /// every remaining candidate, so one more round costs about a third
    /// more time; the report says when the selection stopped here rather
    /// than because nothing passed (a record with several unmodelled
    /// effects, e.g. a muscle that creeps, saturates and rings, may need
    /// more).
    #[arg(long, default_value_t = Settings::default().max_effects)]
    max_effects: usize,
    /// Blocks the second half of each file is cut into, in turn selection
    /// (every choice of the diagnosis reads them) and test (read once, when
    /// the model is final: the figures no choice saw), with a settling gap
    /// of three time constants between neighbours; each must keep at least
    /// 32 samples. By default each file gets the fewest blocks that give
    /// both parts its input's levels and rising and falling branches in
    /// nearly the same proportions (read from the input alone).
    #[arg(long)]
    blocks: Option<usize>,
    /// Other records of the same muscle (e.g. other loads or specimens, read
    /// with the same column flags and sampled alike): after the diagnosis,
    /// the baseline is fitted on every OTHER's first half as `fit` fits it,
    /// and the final model's chain carried there as `fit --carry` carries
    /// it (the effects' dynamics, poles, delays, how fast steps fall, held
    /// at the diagnosed values; their sizes fitted there), each scored on
    /// its second half, which no choice of the diagnosis saw. The report
    /// (TRANSFER) says how much of the baseline's gap the chain closes on
    /// each, whether the effects belong to the muscle or to one recording,
    /// and beside it the chain refitted from its names alone (`fit --effects
    /// CHAIN`). Where the carried chain falls below the plain fit
    /// (COLLAPSES), its leading links are carried alone, one link fewer at a
    /// time, and the report names the first link that does not carry over.
    #[arg(long, value_name = "OTHER", num_args = 1.., conflicts_with = "self_test")]
    transfer: Vec<PathBuf>,
    /// Run the whole diagnosis K times, from --seed, --seed + 1, …, and
    /// report (REPEATED) what each run named and how many runs named each
    /// effect. Where the baseline has several basins the data cannot tell
    /// apart, the named effects can change with the seed: an effect that
    /// only some runs name is the seed's, not the data's. The rest of the
    /// report, the figures and the models are the first run's. Costs K
    /// diagnoses.
    #[arg(long, value_name = "K", default_value_t = 1,
          value_parser = clap::value_parser!(u16).range(1..), conflicts_with = "self_test")]
    repeat: u16,
    /// Where the searches score their populations: `cpu` (the batched,
    /// multi-threaded CPU path), `gpu` (the WGSL kernels on the best adapter,
    /// lavapipe included: the same numbers, bit for bit, where the adapter
    /// does not fuse multiply-adds) or `auto` (a hardware GPU if there is
    /// one, else the CPU). The CPU is the default: the diagnosis' populations
    /// (30–40 candidates) are too small to fill a GPU.
    #[arg(long, value_enum, ignore_case = true, default_value_t = Backend::Cpu)]
    backend: Backend,
    /// Print JSON instead of the report.
    #[arg(long)]
    json: bool,
    /// Write the figures (measured output against the baseline and the
    /// final model, residual over time, over the hysteresis loop,
    /// breakdowns, residual spectrum) to this folder.
    #[arg(long, value_parser = crate::cli::common::output_path, value_name = "DIR")]
    report: Option<PathBuf>,
    /// Write the baseline and the final model as model files to this
    /// folder (baseline.json, model.json), for `simulate --from`, `fit
    /// --from` and `control --from`.
    #[arg(long, value_parser = crate::cli::common::output_path, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Start the selection from a model file (e.g. an earlier `--out`'s
    /// model.json, or `fit`'s): its baseline and effects are refitted warm
    /// on DATA in the model's coordinates instead of the baseline from
    /// scratch, the diagnosis' box widened to hold its baseline (`fit`'s
    /// box is in the data's own scale, and its loop can lie past the
    /// thesis' shapes), and the rounds try the rest of the catalogue on top
    /// of them. DATA is read as the model's data were (columns, time column,
    /// --resample) unless flags say otherwise, and must have the model's
    /// units and sample time. Faster than a diagnosis from scratch
    /// (timings: docs/DIAGNOSIS.md, "Knobs"); meant for records of the same
    /// muscle under the same conditions, since the chain is kept.
    #[arg(long, value_name = "MODEL.json", conflicts_with = "self_test")]
    from: Option<PathBuf>,
    /// Instead of diagnosing DATA, check the diagnosis itself on data with
    /// known effects, generated from the nominal model fitted to DATA.
    /// `--self-test` (or `=independent`): a generator with its own equations,
    /// never the catalogue's, realises every physical effect in two or
    /// three ways (e.g. lag as a pure delay, an input lag, an output lag) on
    /// DATA's input and on a multisine, at two sizes, plus a control on each
    /// and two pairs, an effect outside the catalogue (a sensor's
    /// cross-talk), which must be called "not explained by the catalogue",
    /// and the softening and the set on pulse trains, whose driver must be
    /// named (91 cases, classic baseline only); prints the
    /// confusion table and each case's verdict. `--self-test=catalogue`: the
    /// withheld-effect check, whose data come from the catalogue's own
    /// effect equations (every effect at two sizes, a control, a two-effect
    /// case), then the twin check (one twin effect on vs off, gap attributed
    /// vs gap that disappears).
    #[arg(long, value_enum, ignore_case = true, num_args = 0..=1, require_equals = true,
          default_missing_value = "independent", value_name = "KIND")]
    self_test: Option<SelfTest>,
    /// With --self-test: run only the cases whose name contains one of
    /// these strings (comma-separated, e.g. `stair,control`).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "TEXT",
        requires = "self_test"
    )]
    cases: Vec<String>,
    /// With --self-test: exit with status 1 after the report when fewer
    /// than N of the cases run pass, for a script or CI job that guards
    /// the diagnosis (the report is printed either way). Without it a
    /// self-test exits 0 whatever its cases did: some fail by design
    /// (docs/DIAGNOSIS.md, "Measured results").
    #[arg(long, value_name = "N", requires = "self_test")]
    min_pass: Option<usize>,
}

impl Args {
    /// The baseline family asked for: classic unless `--baseline` says.
    fn family(&self) -> Family {
        self.baseline.map_or(Family::Classic, Family::from)
    }
}

/// Which self-test `--self-test` runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum SelfTest {
    /// Cases from a generator with its own equations (docs/DIAGNOSIS.md,
    /// "The independent self-test").
    Independent,
    /// Cases made with the catalogue's own effect equations, and the twin check.
    Catalogue,
}

fn parse_effect(s: &str) -> Result<Effect, UnknownName> {
    s.parse()
}

pub fn run(mut args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.seeds >= 1, "--seeds must be at least 1");
    for (k, e) in args.effects.iter().enumerate() {
        anyhow::ensure!(
            !args.effects[..k].contains(e),
            "--effects names `{e}` twice: each effect is tried once"
        );
    }
    // An empty text is in every name: `--cases control,` ran all 91.
    anyhow::ensure!(
        args.cases.iter().all(|c| !c.trim().is_empty()),
        "--cases {}: an empty item would pick every case; name each part of the cases' names \
         to run, comma-separated",
        args.cases.join(",")
    );
    anyhow::ensure!(
        args.blocks.is_none_or(|b| b >= 2),
        "--blocks must be at least 2 (one selection and one test block)"
    );
    let from = match &args.from {
        Some(path) => {
            let file = ModelFile::load(path).map_err(|e| anyhow::anyhow!("--from: {e:#}"))?;
            args.data.columns = args.data.columns.or_as_read_for(&file);
            let model = file.model()?;
            let family = args.baseline.map_or(model.base.family, Family::from);
            anyhow::ensure!(
                family == model.base.family,
                "--baseline {family}: the --from model {} is {}",
                path.display(),
                model.base.family
            );
            Some(model)
        }
        None => None,
    };
    let family = args.family();
    let effects = if args.effects.is_empty() {
        Effect::by_default()
    } else {
        args.effects.clone()
    };
    let mut settings = Settings {
        seeds: args.seeds,
        generations: args.generations,
        scratch_seeds: args.scratch_seeds,
        max_effects: args.max_effects,
        blocks: args.blocks,
        seed: args.seed,
        backend: args.backend,
        ..Settings::default()
    };
    {
        let stop = settings.stop.clone();
        // A second handler cannot be installed in one process; a failure
        // only means Ctrl-C kills instead of stopping with a message.
        let _ = ctrlc::set_handler(move || stop.raise());
    }
    let traces = args.data.load()?;
    if let Some(note) = mckibben::diagnose::assumed_unit_note(&traces) {
        errln!("mckibben: note: {note}");
    }
    if let Some(kind) = args.self_test {
        let trace = traces.first().context("no data")?;
        let mut progress = |line: &str| {
            if !args.json {
                errln!("{line}");
            }
        };
        match kind {
            SelfTest::Catalogue => {
                let run = selftest_run::catalogue(
                    trace,
                    family,
                    &effects,
                    &settings,
                    &args.cases,
                    &mut progress,
                )?;
                show(args.json, run.json(), run.to_text())?;
                enough_passed(args.min_pass, run.passed(), run.outcomes.len())?;
            }
            SelfTest::Independent => {
                let run = selftest_run::independent(
                    trace,
                    family,
                    &effects,
                    &settings,
                    &args.cases,
                    &mut progress,
                )?;
                show(args.json, run.json(), run.to_text())?;
                enough_passed(args.min_pass, run.passed(), run.outcomes.len())?;
            }
        }
        return Ok(());
    }
    // Where the diagnosis stands, for the minutes it runs (the self-tests'
    // many diagnoses say only their cases).
    if !args.json {
        let started = std::time::Instant::now();
        settings.progress = Progress::to(move |stage| {
            errln!("[{:>4.0} s] {stage} ...", started.elapsed().as_secs_f64());
        });
    }
    // Read and checked before the diagnosis, so that a bad file or folder
    // fails at once, not after it.
    let others = if args.transfer.is_empty() {
        Vec::new()
    } else {
        args.data
            .columns
            .load(&args.transfer)
            .context("--transfer")?
    };
    // Checked again by the diagnosis; here before any folder is made, with
    // the flag that resamples.
    if let Some(why) = mixed_steps(&traces) {
        anyhow::bail!("{why} (--resample {})", tidy_step(traces[0].dt()));
    }
    let family = from.as_ref().map_or(family, |m| m.base.family);
    check_others(family, &traces, &others, &settings).context("--transfer")?;
    let mut reads: Vec<(&str, &Path)> = args
        .data
        .data
        .iter()
        .map(|p| ("DATA", p.as_path()))
        .collect();
    reads.extend(args.transfer.iter().map(|p| ("--transfer", p.as_path())));
    reads.extend(args.from.iter().map(|p| ("--from", p.as_path())));
    if let Some(dir) = &args.out {
        check_folder("--out", dir, &OUT_FILES.map(String::from), &reads)?;
    }
    if let Some(dir) = &args.report {
        check_folder("--report", dir, &FIGURES.map(String::from), &reads)?;
    }
    for (flag, dir) in [("--out", &args.out), ("--report", &args.report)] {
        if let Some(dir) = dir {
            check_creatable(flag, dir)?;
        }
    }
    // A model fitted in other units of the same kinds as the records'
    // (psi for kPa, mm for m) is read in theirs.
    let from = from.map(|m| {
        let (m, notes) = m.in_units_of(&traces[0], "the --from model");
        notes.iter().for_each(|n| errln!("mckibben: note: {n}"));
        m
    });
    let mut d = diagnose_from(&traces, family, &effects, &settings, from.as_ref()).map_err(
        |e| match &args.from {
            Some(path) => e.context(format!("--from {}", path.display())),
            None => e,
        },
    )?;
    if let Some(path) = &args.from {
        d.from = Some(path.display().to_string());
    }
    if !others.is_empty() {
        if !args.json {
            errln!(
                "fitting the baseline and the chain on {} other record(s) (--transfer) ...",
                others.len()
            );
        }
        d.transfers = transfer(&d, &others, &settings)?;
    }
    let repeats = usize::from(args.repeat);
    d.repeats = seeds::repeat(
        &d,
        &traces,
        &effects,
        &settings,
        from.as_ref(),
        repeats,
        &mut |seed| {
            if !args.json {
                errln!("diagnosing again from seed {seed} (--repeat {repeats}) ...");
            }
        },
    )?;
    if let Some(dir) = &args.out {
        let provenance = args.data.provenance(Some(args.seed))?;
        mckibben::data::create_dir_all(dir)
            .with_context(|| format!("cannot create --out {}", dir.display()))?;
        for (name, model) in OUT_FILES
            .into_iter()
            .zip([&d.baseline_model, &d.final_model])
        {
            ModelFile::new(model, None, provenance.clone())
                .save(&dir.join(name))
                .with_context(|| format!("--out {}", dir.display()))?;
        }
    }
    let figures = match &args.report {
        Some(dir) => mckibben::data::create_dir_all(dir)
            .map_err(anyhow::Error::from)
            .and_then(|()| write_figures(&d, dir))
            .with_context(|| format!("--report {}", dir.display()))?,
        None => Vec::new(),
    };
    if args.json {
        outln!(
            "{}",
            Versioned::new(DiagnosisJson::of(&d)).to_string_pretty()?
        )?;
    } else {
        out!("{}", to_text(&d))?;
        for f in figures {
            outln!("figure written to {}", f.display())?;
        }
    }
    Ok(())
}

/// `--min-pass`'s check, once the report is out: at least `min` of the
/// `total` cases run passed.
fn enough_passed(min: Option<usize>, passed: usize, total: usize) -> anyhow::Result<()> {
    match min {
        Some(min) if passed < min => anyhow::bail!(
            "--min-pass {min}: {passed} of {total} cases passed{}",
            if min > total {
                " (fewer cases ran than must pass: check --cases)"
            } else {
                ""
            }
        ),
        _ => Ok(()),
    }
}

/// A self-test's report: its `--json` document, else its text.
fn show(json: bool, document: impl serde::Serialize, text: String) -> anyhow::Result<()> {
    if json {
        outln!("{}", Versioned::new(document).to_string_pretty()?)?;
    } else {
        out!("{text}")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::enough_passed;

    /// `--min-pass` fails only short of its count, and says when fewer
    /// cases ran than it asks to pass (a `--cases` filter), since no run
    /// could meet it then.
    #[test]
    fn min_pass_fails_only_short_of_its_count() {
        assert!(enough_passed(None, 0, 91).is_ok());
        assert!(enough_passed(Some(87), 87, 91).is_ok());
        let short = enough_passed(Some(88), 87, 91).unwrap_err().to_string();
        assert_eq!(short, "--min-pass 88: 87 of 91 cases passed");
        let filtered = enough_passed(Some(5), 4, 4).unwrap_err().to_string();
        assert!(filtered.ends_with("(fewer cases ran than must pass: check --cases)"));
    }
}
