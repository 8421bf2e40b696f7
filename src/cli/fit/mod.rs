//! `mckibben fit`: identify a hysteresis model's parameters with the staged
//! fitting engine (a population search by GA, MFA, PSO or DE, a free-run
//! stage and a Levenberg–Marquardt polish), or with the thesis' flow.

mod args;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use super::common::{check_creatable, check_folder, records};
pub use args::Args;
use args::EffectArg;
use mckibben::data::{Trace, readable, sources};
use mckibben::diagnose::auto::selected_fit;
use mckibben::diagnose::chain::with_chain_start;
use mckibben::eval;
use mckibben::fit::objective::{POPULATION, tries_text, try_groups};
use mckibben::fit::report::{FitReport, Note, files_written};
use mckibben::fit::request::{switching_boxed, switching_misapplied};
use mckibben::fit::run::FitRun;
use mckibben::fit::searches::StopFlag;
use mckibben::model::{Family, ModelFile};
use mckibben::optim::engine::{FreeRun, Observer, StopReason};
use mckibben::optim::history::GenerationRecord;
use mckibben::report::json::Versioned;

/// A progress bar on stderr (hidden when stderr is not a terminal).
pub struct Progress(indicatif::ProgressBar);

impl Progress {
    pub fn new(total: usize, hidden: bool) -> Progress {
        let bar = if hidden {
            indicatif::ProgressBar::hidden()
        } else {
            indicatif::ProgressBar::new(total as u64)
        };
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} gen {pos}/{len} [{bar:30}] {msg} ({elapsed}, eta {eta})",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        Progress(bar)
    }

    pub fn finish(&self) {
        self.0.finish_and_clear();
    }
}

impl Observer for Progress {
    fn record(&mut self, r: &GenerationRecord, _: usize) {
        self.0.set_position(r.generation as u64);
        let best = r.stage_best.map_or("-".into(), |b| format!("{b:.4e}"));
        let measure = match r.measure {
            mckibben::model::Measure::FreeRun => "free run".to_string(),
            mckibben::model::Measure::Ahead { horizon } => format!("{horizon}-step"),
        };
        self.0.set_message(format!(
            "{} ({measure}) best {best}, {} diverged",
            r.stage.name(),
            r.diverged
        ));
    }
}

pub fn run(mut args: Args) -> anyhow::Result<()> {
    let start = match &args.from {
        Some(path) => Some(ModelFile::load(path).map_err(|e| anyhow::anyhow!("--from: {e:#}"))?),
        None => None,
    };
    let carried = match &args.carry {
        Some(path) => Some(ModelFile::load(path).map_err(|e| anyhow::anyhow!("--carry: {e:#}"))?),
        None => None,
    };
    if let Some(file) = start.as_ref().or(carried.as_ref()) {
        args.data.columns = args.data.columns.or_as_read_for(file);
    }
    // A parameter a record (one per load) is the diagnosis' to fit: a fit
    // fits one model for all its records.
    for (flag, path, file) in [
        ("--from", &args.from, &start),
        ("--carry", &args.carry, &carried),
    ] {
        if let (Some(path), Some(file)) = (path, file)
            && let Some(e) = file.model()?.effects().iter().find(|e| !e.applicable(1))
        {
            anyhow::bail!(
                "{flag} {}: its `{e}` effect fits a parameter for each record it was fitted \
                 on (one per load), and `fit` fits one model for all its records: refit it \
                 with `mckibben diagnose FILES --from {}`",
                path.display(),
                path.display()
            );
        }
    }
    if let Some([EffectArg::Auto]) = args.effects.as_deref() {
        let unread = args.unread_by_auto();
        anyhow::ensure!(
            unread.is_empty(),
            "--effects auto runs the diagnosis' own selection, its searches set by the seed \
             alone: {} would not be read; leave {} out (`mckibben diagnose` has the \
             selection's own knobs)",
            unread.join(", "),
            if unread.len() == 1 { "it" } else { "them" }
        );
        let family = args.model.map_or(Family::Classic, Family::from);
        let [trace] = &records(args.data.load()?, args.data.columns.resample.is_some())?[..] else {
            anyhow::bail!(
                "--effects auto runs the diagnosis' selection on one record: give one file \
                 (`mckibben diagnose` takes several)"
            );
        };
        out_folder(&args, 1)?;
        return run_auto(&args, family, trace);
    }
    let request = args.request()?;
    // Printed as they come, and kept for the report (`fit --json`'s
    // `notes`), where a script reads them.
    let early = std::cell::RefCell::new(Vec::new());
    let note = |s: String| {
        if !args.json {
            errln!("mckibben: note: {s}");
        }
        early.borrow_mut().push(Note::plain(s));
    };
    // α is a share (eq. 13: α of the restoring force elastic, 1 − α
    // hysteretic); a box past [0, 1] is the user's to ask for, and the
    // command says what it leaves.
    for b in request.bounds.iter().filter(|b| b.name == "alpha") {
        if b.lower < 0.0 || b.upper > 1.0 {
            let given = match b.lower == b.upper {
                true => format!("alpha = {}", readable(b.lower)),
                false => format!("alpha in [{}, {}]", readable(b.lower), readable(b.upper)),
            };
            note(format!(
                "{given} reaches past [0, 1]: alpha is the elastic share of the restoring force \
                 (eq. 13), and past it one part enters with the opposite sign (above 1 the \
                 hysteretic, below 0 the elastic)"
            ));
        }
    }
    let flag = if carried.is_some() {
        "--carry"
    } else {
        "--from"
    };
    let traces = records(args.data.load()?, args.data.columns.resample.is_some())?;
    // A model fitted in other units of the same kinds as the records'
    // (psi for kPa, mm for m) is read in theirs, its recorded bounds too.
    let given = match start.as_ref().or(carried.as_ref()) {
        Some(file) => {
            let (file, notes) = file
                .in_units_of(&traces[0], "the start model")
                .map_err(|e| anyhow::anyhow!("{flag}: {e:#}"))?;
            notes.into_iter().for_each(note);
            Some(file)
        }
        None => None,
    };
    let resolved = request
        .resolve(given.as_ref())
        .map_err(|e| anyhow::anyhow!("{flag}: {e:#}"))?;
    let (what, start_model) = (resolved.what, resolved.start);
    if let Some(why) = switching_misapplied(what.family, args.switching) {
        anyhow::bail!("--switch {why}: leave --switch out, or fit --model generalized");
    }
    if let Some(why) = switching_boxed(args.switching, &request.bounds) {
        anyhow::bail!("--switch {why}: give one of them");
    }
    out_folder(&args, traces.len())?;
    for trace in &traces {
        if let Some(period) = mckibben::data::signals::period_of(&trace.input) {
            note(format!(
                "{}: its input repeats every {period} samples ({} s): the validation half runs \
                 the excitation the estimation half was fitted on, so its fit says how the model \
                 reproduces that excitation, not another; validate on another record as well \
                 (`simulate --from` the model on it)",
                trace.source,
                readable((period as f64 * trace.dt() * 1e6).round() / 1e6)
            ));
        }
    }
    if let Some(model) = &resolved.carried {
        for trace in &traces {
            model
                .check_data(trace)
                .map_err(|e| anyhow::anyhow!("--carry: {e:#}"))?;
        }
    }

    let fit = FitRun::new(
        &traces,
        &what,
        &args.settings(),
        start_model.as_ref(),
        args.checkpoint.as_deref(),
        &note,
    )?;
    let mut evaluator = eval::open(args.backend)?;
    let backend = evaluator.describe();
    let interrupt = Arc::new(AtomicBool::new(false));
    let chain_stop = StopFlag::default();
    {
        let (flag, chain) = (interrupt.clone(), chain_stop.clone());
        // A second handler cannot be installed in one process; a failure
        // only means Ctrl-C kills instead of stopping cleanly.
        let _ = ctrlc::set_handler(move || {
            flag.store(true, Ordering::SeqCst);
            chain.raise();
        });
    }
    if !what.effects.is_empty() && start_model.is_none() && !args.json {
        errln!(
            "building the chain one effect at a time, as the diagnosis does: the fit's second start"
        );
    }
    let mut fit = with_chain_start(fit, &traces, &args.settings(), args.backend, chain_stop)?;
    if !args.json {
        announce(&args, &fit, &traces, &backend);
    }
    let mut progress = Progress::new(fit.engine.planned_generations(), args.json);
    let (outcome, widened) = fit.run(
        evaluator.as_mut(),
        &mut [&mut progress],
        Some(&interrupt),
        args.checkpoint.as_deref(),
    )?;
    progress.finish();
    if outcome.evaluations == 0 {
        // Nothing to report: writing a result of no model beside the last
        // run's model.json would leave --out describing two fits, and a
        // zero exit would let a script go on with the old model.
        let said = format!(
            "{}: nothing was written to {}{}",
            fit.unscored(outcome.stop),
            args.out.display(),
            resumes(&args)
        );
        return Err(match outcome.stop {
            StopReason::Interrupted => Interrupted(said).into(),
            _ => anyhow::anyhow!(said),
        });
    }
    let mut report = FitReport::of(&fit, (&outcome, &widened), &backend, &traces);
    let mut after = report.after_notes(fit.start_scores());
    if let Some(why) = &outcome.checkpoint_error {
        after.push(Note {
            level: "warning",
            text: format!(
                "{why}: the fit went on without it and its result is whole, but it cannot be \
                 resumed from that checkpoint"
            ),
        });
    }
    report.notes = early.take();
    report.notes.extend(after.iter().cloned());
    let provenance = args.data.provenance(Some(fit.engine.seed))?;
    let found = !outcome.params.is_empty();
    // A fit without a model writes nothing: its result.json and history
    // beside an earlier fit's model.json would leave --out describing two
    // fits. A write that fails still lets the report below be printed.
    let written = match found {
        true => report.write(
            &args.out,
            (&fit, &outcome.params),
            &traces,
            &what.bounds,
            provenance,
        ),
        false => Ok(()),
    };
    if args.json {
        outln!("{}", Versioned::new(&report).to_string_pretty()?)?;
    } else {
        let free = fit.problem.space.free();
        let fixed: Vec<bool> = (0..fit.problem.space.dim())
            .map(|i| !free.contains(&i))
            .collect();
        out!("{}", report.to_text(&fixed))?;
        for Note { level, text } in &after {
            errln!("mckibben: {level}: {text}");
        }
    }
    written?;
    anyhow::ensure!(found, "{}", all_diverged(&args, !what.bounds.is_empty()));
    if outcome.stop == StopReason::Interrupted {
        return Err(Interrupted(format!(
            "interrupted (Ctrl-C): the best so far is written to {}{}",
            args.out.display(),
            resumes(&args)
        ))
        .into());
    }
    Ok(())
}

/// A fit stopped by Ctrl-C, with what it wrote: the command ends as an
/// interrupted program does ([`super::interrupted`]), so that a script
/// running it stops instead of going on with a partial fit.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Interrupted(String);

/// How to go on with a fit that stopped early: its checkpoint, if it has one.
fn resumes(args: &Args) -> String {
    args.checkpoint.as_ref().map_or(String::new(), |c| {
        format!("; `--checkpoint {}` resumes it", c.display())
    })
}

/// Why a fit that found no stable candidate may have found none: the data,
/// the values the user held, or a population too small to try many.
fn all_diverged(args: &Args, held: bool) -> String {
    let held = if held {
        ", and the values --fix and --bound hold (an unstable pole diverges)"
    } else {
        ""
    };
    // A few random candidates in a wide box can all be unstable: the
    // population is then the first suspect, not the data.
    let few = if args.pop < POPULATION {
        format!(
            "; with --pop {} few candidates were tried: a larger population (the default is \
             {POPULATION}) may find a stable one",
            args.pop
        )
    } else {
        String::new()
    };
    format!(
        "every candidate diverged: nothing was written to {} (what it held is untouched); \
         check the data's units and columns{held}{few}",
        args.out.display()
    )
}

/// Checks that `--out` can be a folder before the fit runs
/// ([`check_creatable`]; the fit's writer creates it for good), and that
/// the fit's files there would replace none it reads (`files_written`).
fn out_folder(args: &Args, records: usize) -> anyhow::Result<()> {
    let out = args.out.as_path();
    let mut reads: Vec<(&str, &std::path::Path)> = args
        .data
        .data
        .iter()
        .map(|p| ("DATA", p.as_path()))
        .collect();
    // The checkpoint too: the fit would write its model over it.
    for (flag, path) in [
        ("--from", &args.from),
        ("--carry", &args.carry),
        ("--checkpoint", &args.checkpoint),
    ] {
        if let Some(path) = path {
            reads.push((flag, path));
        }
    }
    check_folder("--out", out, &files_written(records), &reads)?;
    check_creatable("--out", out)
}

/// The line that says what is about to run: the model, the algorithm and
/// its size, the stages, the data and the backend.
fn announce(args: &Args, fit: &FitRun, traces: &[Trace], backend: &str) {
    let engine = &fit.engine;
    // A warm start has no global stage: its first is the free run's.
    let (algo, population, generations) = match (&engine.plan.global, &engine.plan.free_run) {
        (Some(g), _) => (g.algorithm(), engine.plan.population(), g.generations),
        (None, Some(f)) => (FreeRun::ALGORITHM, f.population, f.generations),
        (None, None) => (FreeRun::ALGORITHM, 0, 0),
    };
    let stages: Vec<&str> = engine.stages().iter().map(|s| s.name()).collect();
    let model = fit
        .problem
        .model
        .effects
        .iter()
        .fold(fit.problem.model.family.to_string(), |m, e| {
            format!("{m} + {e}")
        });
    let from = match (&args.from, &args.carry) {
        (Some(p), _) => format!(", warm start from {}", p.display()),
        (_, Some(p)) => format!(", the chain of {} carried", p.display()),
        _ => String::new(),
    };
    let tries = match engine.plan.tries {
        1 => String::new(),
        _ => format!(" in {}", tries_text(&try_groups(&engine.plan))),
    };
    errln!(
        "fitting {model} with {algo} (N = {population}{tries}, G = {generations}, seed {}; stages {}{from}) on {} [{}]",
        engine.seed,
        stages.join(" → "),
        sources(traces),
        backend
    );
}

/// `--effects auto`: the diagnosis' forward selection over the whole
/// catalogue on `trace` (its settings, with this command's seed and
/// backend); writes and reports its final model as a fit's.
fn run_auto(args: &Args, family: Family, trace: &Trace) -> anyhow::Result<()> {
    if !args.json {
        errln!(
            "fitting {family} with the effects the diagnosis selects from its catalogue \
             (seed {}) on {}",
            args.seed,
            trace.source
        );
    }
    let (model, mut report) = selected_fit(trace, family, args.seed, args.backend)?;
    report.write_model(
        &args.out,
        &model,
        trace,
        args.data.provenance(Some(args.seed))?,
    )?;
    if args.json {
        outln!("{}", Versioned::new(&report).to_string_pretty()?)?;
        return Ok(());
    }
    outln!(
        "{family} fit of {} with the diagnosis' effects: {}",
        trace.source,
        if report.effects.is_empty() {
            "none".to_string()
        } else {
            report.effects.join(", ")
        }
    )?;
    for (name, value) in &report.params.0 {
        outln!("  {name:<7} {value:>14.6}")?;
    }
    let show = |v: Option<f64>| v.map_or("diverged".to_string(), |v| format!("{v:.4}"));
    // An RMSE says its unit where the output column's name states one.
    let unit = trace.columns().output.unit_tail();
    let rmse = |v: Option<f64>| match v {
        Some(_) => format!("{}{unit}", show(v)),
        None => show(v),
    };
    outln!("  SSE (estimation)     {}", show(report.sse))?;
    let scored = report.val_rmse.is_some();
    let percent = mckibben::ident::fit::fit_percent_text(report.val_fit_percent, scored, 4);
    outln!(
        "  validation fit       {percent}   (RMSE {}; the second half, the selection part that \
         chose the effects included)",
        rmse(report.val_rmse)
    )?;
    if let Some(parts) = &report.diagnosis_parts {
        outln!(
            "  test fit             {}   (RMSE {}; the second half's test part, which no choice \
             read: the figure to quote)",
            mckibben::ident::fit::fit_percent_text(
                parts.test_fit_percent,
                parts.test_rmse.is_some(),
                4
            ),
            rmse(parts.test_rmse)
        )?;
    }
    if report.val_fit_percent.is_none() && scored {
        errln!(
            "mckibben: warning: {}",
            mckibben::ident::fit::constant_validation_warning("")
        );
    }
    for note in &report.notes {
        errln!("mckibben: {}: {}", note.level, note.text);
    }
    outln!(
        "  {:.2} s; `mckibben diagnose` gives the selection's report; wrote model.json, \
         result.json and figures to {}",
        report.seconds,
        args.out.display()
    )?;
    Ok(())
}
