//! The readable report of a diagnosis.

use std::fmt::Write as _;

use super::candidate_list;
use crate::diagnose::accept::gap_closed;
use crate::diagnose::explainable::Signature;
use crate::diagnose::locate::Share;
use crate::diagnose::plain::PlainFit;
use crate::diagnose::refits::Finding;
use crate::diagnose::seeds::{named_counts, runs_naming};
use crate::diagnose::spectrum::Peak;
use crate::diagnose::transfer::Transfer;
use crate::diagnose::{Diagnosis, Effect, PLAIN_FIT_START, Step};
use crate::fit::edge::ActiveBound;
use crate::model::experiment::Parts;
use crate::report::number::significant;

fn pct(v: f64) -> String {
    format!("{:5.1} %", 100.0 * v)
}

/// A step by what it adds to the one before: one accepted effect, or the
/// start model's chain (`diagnose --from`).
fn step_name(before: Option<&Step>, s: &Step) -> String {
    let had = before.map_or(0, |b| b.effects.len());
    if s.effects.is_empty() {
        "baseline".into()
    } else {
        let added: Vec<&str> = s.effects[had..].iter().map(|e| e.name()).collect();
        format!("+ {}", added.join(" + "))
    }
}

/// How the records were split, in words.
fn parts_text(d: &Diagnosis) -> String {
    // Seconds as a reader places them in a record: two significant digits.
    let seconds = |samples: f64| {
        let v = samples * d.dt;
        let decimals = (1 - v.abs().log10().floor() as i32).max(0) as usize;
        format!("{v:.decimals$}")
    };
    let gap = |p: &Parts| match (p.selection.first(), p.test.first()) {
        (Some(s), Some(t)) => t.start.saturating_sub(s.end),
        _ => 0,
    };
    let count = |p: &Parts| p.selection.len() + p.test.len();
    let block = |p: &Parts| {
        let samples = p.selection_len() + p.test_len();
        seconds(samples as f64 / count(p).max(1) as f64)
    };
    let list = |f: &dyn Fn(&Parts) -> String| -> String {
        d.parts.iter().map(f).collect::<Vec<_>>().join(", ")
    };
    let (blocks, gaps) = (
        format!(
            "{} blocks of about {} s{}",
            list(&|p| count(p).to_string()),
            list(&block),
            if d.parts.len() > 1 { " each" } else { "" }
        ),
        format!(
            "{}-sample settling gaps ({} s)",
            list(&|p| gap(p).to_string()),
            list(&|p| seconds(gap(p) as f64))
        ),
    );
    format!(
        "Parts: each record's first half estimates; its second half is cut into {blocks}, \
         selection and test in turn, {gaps} between.\n  Every choice reads \
         the selection blocks ({} samples); the test blocks ({} samples) are read once, after \
         the model is final.",
        d.parts.iter().map(Parts::selection_len).sum::<usize>(),
        d.parts.iter().map(Parts::test_len).sum::<usize>()
    )
}

/// The readable report.
pub fn to_text(d: &Diagnosis) -> String {
    let mut o = String::new();
    header_text(&mut o, d);
    where_text(&mut o, d);
    which_text(&mut o, d);
    how_far_text(&mut o, d);
    how_sure_text(&mut o, d);
    refits_text(&mut o, d);
    as_fit_text(&mut o, d);
    explainable_text(&mut o, d);
    spectrum_text(&mut o, d);
    transfer_text(&mut o, d);
    repeats_text(&mut o, d);
    verdict_text(&mut o, d);
    o
}

/// Where the baseline's loop shape stopped on the edge of the diagnosis'
/// box, what that means, in words (the report's CAUTION, Python's
/// warning); `None` where it did not.
pub fn baseline_caution(d: &Diagnosis) -> Option<String> {
    if d.baseline_on_edge.is_empty() {
        return None;
    }
    let edges: Vec<String> = d
        .baseline_on_edge
        .iter()
        .map(|b| format!("{} ({} bound)", b.param, b.bound.name()))
        .collect();
    Some(format!(
        "the baseline's loop shape ended on the edge of the diagnosis' box: {}. \
         That box holds the thesis' loop shapes, made for a stroke of about 40 mm, in mm or \
         in the length unit the output column's name states (`x_m`, `stroke [cm]`): a \
         sharper loop (a shorter stroke, or an output in another unit that its name does not \
         state) lies outside it, and the effects named from the baseline may then stand in \
         for the loop it could not reach (`fit`, whose box is in the data's own scale, shows \
         the loop)",
        edges.join(", ")
    ))
}

/// Where the diagnosis started from `fit`'s own fit of the baseline, which
/// beat the baseline it searched on the estimation half and on the
/// selection part ([`PlainFit::started_from`]):
/// why, in words (the report's line under *Baseline*); `None` where it
/// did not.
pub fn plain_fit_start(d: &Diagnosis) -> Option<String> {
    let plain = d.plain_fit.as_ref().filter(|p| p.started_from)?;
    Some(format!(
        "{}. That search missed a basin `fit` reaches (a sharper loop, say: a braid with more \
         friction closes its loop within a fraction of a millimetre), and effects named from \
         it would stand in for the miss, so the diagnosis started again from `fit`'s fit, \
         refitted warm in a box widened to hold it (as `diagnose --from` its model.json): the \
         baseline above and everything below are from that start",
        plain_fit_beats(d, plain)
    ))
}

/// Where `fit`'s own fit of the baseline beat the searched one but the
/// diagnosis, started from it, lost that gain in its warm refit, and kept
/// the searched baseline: what that means, in words (the report's
/// CAUTION, Python's warning); `None` otherwise.
pub fn plain_fit_caution(d: &Diagnosis) -> Option<String> {
    let plain = d
        .plain_fit
        .as_ref()
        .filter(|p| p.beats_baseline && !p.started_from)?;
    Some(format!(
        "{}. Started again from it, the diagnosis' warm refit of the baseline scored the \
         selection part at {restarted}, no longer more than 2 % better in RMSE than the searched \
         baseline, so the diagnosis kept the searched one. The effects named from it may stand \
         in for the basin `fit` reached: compare them with `fit`'s model before trusting them",
        plain_fit_beats(d, plain),
        restarted = plain
            .restarted_selection_fit_percent
            .map_or("no finite figure".to_string(), |f| format!("{f:.1} %")),
    ))
}

/// How `fit`'s fit of the baseline beat the searched one, in words.
fn plain_fit_beats(d: &Diagnosis, plain: &PlainFit) -> String {
    format!(
        "`mckibben fit`'s {family} fit of the same estimation half{s}, in its box in the data's \
         own scale, fits that half better than the baseline searched among the thesis' loop \
         shapes, made for a stroke of about 40 mm (SSE {plain_sse:.1} against {searched_sse:.1}, \
         past the likelihood-ratio threshold), and scores the selection part at {fit:.1} % \
         against {searched_fit:.1} %, {lower:.1} % lower in RMSE: more than an effect must gain \
         to be named",
        family = d.family,
        s = if d.datasets.len() > 1 { "s" } else { "" },
        plain_sse = plain.est_sse,
        searched_sse = plain.searched_est_sse,
        fit = plain.selection_fit_percent,
        searched_fit = plain.searched_selection_fit_percent,
        lower = 100.0 * (1.0 - plain.selection_rmse / plain.searched_selection_rmse),
    )
}

/// What the report found that weakens a verdict naming effects, each in
/// words (the text's "Read it with care", JSON `verdict_cautions`, which
/// Python's `Diagnosis.document` holds); empty where the verdict names
/// none. The acceptance
/// rule judges each effect on the selection part; these are what it
/// cannot see: a baseline that could not reach the record's loop, a size
/// the data leave open, a chain that does not carry to other records.
pub fn verdict_cautions(d: &Diagnosis) -> Vec<String> {
    if d.named().is_empty() {
        return Vec::new();
    }
    let mut out = Vec::new();
    if !d.baseline_on_edge.is_empty() {
        out.push(
            "the baseline's loop shape ended on its box's edge (the report's CAUTION under \
             Baseline): the named effects may stand in for the loop it could not reach"
                .to_string(),
        );
    }
    if plain_fit_caution(d).is_some() {
        out.push(
            "`fit`'s own fit of the baseline fits the estimation half and scores the selection \
             part better than the diagnosis' baseline (the report's CAUTION under Baseline): the \
             named effects may stand in for the basin that baseline missed"
                .to_string(),
        );
    }
    for s in d
        .size_intervals
        .iter()
        .filter(|s| (s.lo_at_edge || s.hi_at_edge) && d.named().contains(&s.effect))
    {
        out.push(format!(
            "the data do not bound {}'s size within its box (HOW SURE: {} reaches the box's \
             edge)",
            s.effect.name(),
            s.param
        ));
    }
    let collapsed: Vec<&str> = d
        .transfers
        .iter()
        .filter(|t| t.collapses)
        .map(|t| t.dataset.as_str())
        .collect();
    if !collapsed.is_empty() {
        out.push(format!(
            "the chain collapses on {} of the {} other records (TRANSFER: {}): it describes \
             this record more than the muscle",
            collapsed.len(),
            d.transfers.len(),
            collapsed.join(", ")
        ));
    }
    out
}

/// What was diagnosed, how it was split, the baseline and the floor.
fn header_text(o: &mut String, d: &Diagnosis) {
    let base = d.baseline();
    let _ = writeln!(
        o,
        "Diagnosis of the sim-to-real gap ({} baseline) on {}",
        d.family,
        d.datasets.join(", ")
    );
    let _ = writeln!(o, "{}", parts_text(d));
    let _ = writeln!(
        o,
        "Baseline: selection fit {:.1} % (RMSE {}), test fit {:.1} % (RMSE {}); noise floor ≈ {} (from second differences of the measured output, test part left out){}",
        base.selection_fit_percent,
        significant(base.selection_rmse, 4),
        base.test_fit_percent,
        significant(base.test_rmse, 4),
        significant(d.noise_floor_rmse, 4),
        // Every figure below pools them as this one does.
        match d.datasets.len() {
            1 => String::new(),
            n => format!("; the {n} records' parts pooled, each about its own mean"),
        }
    );
    if d.floor_is_upper_bound() {
        let _ = writeln!(
            o,
            "  The noise floor is an upper bound here: the output's second difference follows \
             the signal, not the noise (its lag-1 correlation {:.2}, where noise on a smooth \
             response gives −0.67), so the floor counts motion at the sample scale as noise; \
             where the fit's error comes near it, the shares of the gap above it and the stop \
             near it read high",
            d.noise_floor_lag1
        );
    }
    if let Some(caution) = baseline_caution(d) {
        let _ = writeln!(o, "  CAUTION: {caution}");
    }
    if let Some(caution) = plain_fit_caution(d) {
        let _ = writeln!(o, "  CAUTION: {caution}");
    }
    if let Some(why) = plain_fit_start(d) {
        let _ = writeln!(o, "Started from {PLAIN_FIT_START}: {why}");
    } else if let Some(from) = &d.from {
        let names: Vec<&str> = d.selection.given.iter().map(|e| e.name()).collect();
        let _ = writeln!(
            o,
            "Started from {from}: its baseline{} refitted warm on these data; the rounds try the rest of the catalogue",
            if names.is_empty() {
                String::new()
            } else {
                format!(
                    " and its effects ({}, taken as given, not judged)",
                    names.join(", ")
                )
            }
        );
    }
}

/// WHERE: the breakdown of the baseline's residual and its tests.
fn where_text(o: &mut String, d: &Diagnosis) {
    let w = &d.locate;
    let _ = writeln!(
        o,
        "\nWHERE the baseline misses on the selection part (share of residual energy vs share of samples):"
    );
    for (name, s) in w.classes() {
        let _ = writeln!(
            o,
            "  {name:<28} energy {}   samples {}{}",
            pct(s.energy),
            pct(s.samples),
            if s.over_represented() {
                "  <-- over-represented"
            } else {
                ""
            }
        );
    }
    for (name, c) in [
        ("residual whiteness (99 %)", &w.whiteness),
        ("residual–input independence (99 %)", &w.cross_correlation),
    ] {
        let _ = writeln!(
            o,
            "  {name}: {} ({} of {} lags outside ±{:.3}; peak {:.3} at lag {})",
            if c.passes { "passes" } else { "FAILS" },
            c.outside,
            c.values.len(),
            c.bound,
            c.peak,
            c.peak_lag
        );
    }
}

/// WHICH: the rebases, then every candidate with the rule that decided it.
fn which_text(o: &mut String, d: &Diagnosis) {
    let base = d.baseline();
    let _ = writeln!(
        o,
        "\nWHICH effect (selection RMSE; accepted = passes every rule):"
    );
    for n in &d.not_tried {
        let _ = writeln!(o, "  not tried: {} ({})", n.effect.name(), n.why);
    }
    for (i, r) in d.selection.rounds.iter().enumerate() {
        for f in &r.rebased {
            let _ = writeln!(
                o,
                "  round {}: a refit of the current model (from its own seeds or from a \
                 candidate's parameters) reached a better estimation fit (SSE {}, selection \
                 RMSE {}); it became the current model and the round was judged from it",
                i + 1,
                significant(f.best.est_sse, 1),
                significant(f.best.sel_rmse, 4)
            );
        }
    }
    for (c, accepted, round) in candidate_list(d) {
        let params: Vec<String> = c
            .effect_params
            .iter()
            .map(|(n, v)| format!("{n}={}", significant(*v, 4)))
            .collect();
        let _ = writeln!(
            o,
            "  {:<2} {:<17} RMSE {}  gap closed {}  [{}]  round {round}: {}",
            if accepted { "✔" } else { " " },
            c.effect.name(),
            significant(c.fit.best.sel_rmse, 4),
            pct(gap_closed(
                base.selection_rmse,
                c.fit.best.sel_rmse,
                d.noise_floor_rmse
            )),
            params.join(", "),
            c.reason
        );
        let values: Vec<f64> = c.effect_params.iter().map(|(_, v)| *v).collect();
        let size = c.effect.size_text(&values, d.dt);
        let _ = writeln!(
            o,
            "     {}: {}{}; signature: {}",
            c.effect.physical(),
            c.effect.realisation(),
            size.map_or(String::new(), |s| format!(", {s}")),
            c.effect.signature()
        );
    }
}

/// HOW FAR: each step on the selection and the test part.
fn how_far_text(o: &mut String, d: &Diagnosis) {
    let _ = writeln!(
        o,
        "\nHOW FAR (fit % on the selection part, which chose the effects, and on the test part,\n  \
         which no choice saw; optimism = selection − test, in points; the gap closed is on the test part):"
    );
    let names: Vec<String> = (0..d.steps.len())
        .map(|i| step_name(i.checked_sub(1).map(|j| &d.steps[j]), &d.steps[i]))
        .collect();
    // One column for every step, however long its effect's name.
    let width = names
        .iter()
        .map(|n| n.chars().count())
        .max()
        .unwrap_or(0)
        .max(14);
    for (s, name) in d.steps.iter().zip(&names) {
        let _ = writeln!(
            o,
            "  {name:<width$} selection {:5.1} %  test {:5.1} %  optimism {:+5.1}  gap closed {}",
            s.selection_fit_percent,
            s.test_fit_percent,
            s.optimism_points,
            pct(s.test_gap_closed)
        );
    }
}

/// HOW SURE: the size intervals of the named effects.
fn how_sure_text(o: &mut String, d: &Diagnosis) {
    if d.size_intervals.is_empty() {
        return;
    }
    let _ = writeln!(
        o,
        "\nHOW SURE (95 % profile-likelihood interval of each named effect's size in the final model;\n  it assumes white residuals and describes only the basin the fit ended in, so it is too\n  narrow when the whiteness test fails or the search missed a better basin):"
    );
    for s in &d.size_intervals {
        let edge = |at: bool| if at { " (box edge: not bounded)" } else { "" };
        let _ = writeln!(
            o,
            "  {:<10} {} = {}  [{}{}, {}{}]  (±{})",
            s.effect.name(),
            s.param,
            significant(s.value, 4),
            significant(s.lo, 4),
            edge(s.lo_at_edge),
            significant(s.hi, 4),
            edge(s.hi_at_edge),
            significant(0.5 * (s.hi - s.lo), 4)
        );
    }
}

/// The effects the selection was asked to try, by name.
fn asked_names(d: &Diagnosis) -> String {
    let names: Vec<&str> = d.asked.iter().map(|e| e.name()).collect();
    names.join(", ")
}

/// The verdict and the lines that qualify it.
fn verdict_text(o: &mut String, d: &Diagnosis) {
    let x = &d.explainable;
    if d.selection.rounds.is_empty() {
        let _ = writeln!(
            o,
            "\nVerdict: nothing was tried (--max-effects 0, or none of the effects asked for \
             could be tried on this record: see WHICH), so this says nothing of the catalogue."
        );
    } else if x.not_explained {
        let closed = d.last().gap_closed;
        let (by, best) = match d.narrowed() {
            true => (
                format!("the effects tried ({})", asked_names(d)),
                "their best model",
            ),
            false => ("the catalogue".to_string(), "the catalogue's best model"),
        };
        // A selection the cap stopped while it still accepted says so here,
        // not only below: one more round may change this verdict.
        let by = match d.selection.capped {
            true => format!(
                "{by} within --max-effects {} (the last round still accepted one)",
                d.selection.rounds.len()
            ),
            false => by,
        };
        let _ = writeln!(
            o,
            "\nVerdict: not explained by {by}. A flexible model of the signals closes {} of the \
             gap above the noise floor and leaves {}; {best} closes {} ({} of the flexible \
             model's) and leaves {}.",
            pct(x.bound.gap_closable).trim(),
            pct(1.0 - x.bound.gap_closable).trim(),
            pct(closed).trim(),
            pct(x.catalogue_share.unwrap_or(0.0)).trim(),
            pct(1.0 - closed).trim()
        );
        if !d.selection.verdict.is_empty() {
            let fitted: Vec<_> = d.selection.verdict.iter().map(|e| e.name()).collect();
            let _ = writeln!(
                o,
                "  Its effects ({}) are fits to part of the gap, not its cause: none is named.",
                fitted.join(", ")
            );
        }
        if let Some(sig) = &x.signature {
            let _ = writeln!(o, "  What is left lies {}.", signature_text(sig));
        }
    } else if d.selection.verdict.is_empty() {
        let which = match d.narrowed() {
            true => format!("the effects tried ({})", asked_names(d)),
            false => "the catalogued effects".to_string(),
        };
        let _ = writeln!(o, "\nVerdict: none of {which} explains the remaining gap.");
    } else {
        // With --repeat, how many runs named each effect, in this
        // realisation and in any: the verdict says how far it is the data's.
        let named_by = |e: &Effect| {
            if d.repeats.is_empty() {
                return String::new();
            }
            let (these, any) = runs_naming(&d.repeats, *e);
            let k = d.repeats.len();
            if these == any {
                format!("; named by {these} of {k} runs")
            } else {
                format!(
                    "; named by {these} of {k} runs, {} in any realisation by {any}",
                    e.physical().name()
                )
            }
        };
        let names: Vec<_> = d
            .selection
            .verdict
            .iter()
            .map(|e| format!("{} ({}{})", e.physical(), e.realisation(), named_by(e)))
            .collect();
        let _ = writeln!(
            o,
            "\nVerdict: {} (closes {} of the gap above the noise floor on the test part, {} on the \
             selection part that chose it).",
            names.join(", then "),
            pct(d.last().test_gap_closed).trim(),
            pct(d.last().gap_closed).trim()
        );
        let cautions = verdict_cautions(d);
        if !cautions.is_empty() {
            let _ = writeln!(o, "Read it with care: {}.", cautions.join("; "));
        }
    }
    if d.selection.capped {
        let n = d.selection.rounds.len();
        let _ = writeln!(
            o,
            "The selection stopped at {n} effects (--max-effects {n}) with its last round still \
             accepting one: more may pass (--max-effects {}).",
            n + 1
        );
    }
    if let Some(p) = d.final_spectrum.as_ref().and_then(|s| s.peaks.first()) {
        let _ = writeln!(
            o,
            "The final model's residual still has {}: a periodic component none of the named effects reproduces.",
            peak_text(p)
        );
    }
    if let Some(r) = &d.refits {
        let (lo, hi) = r.tied_selection_fit_percent;
        match r.finding() {
            Finding::Reproduced | Finding::Best => {}
            Finding::Beaten => {
                let _ = writeln!(
                    o,
                    "The estimation data do not settle the final fit: the same model refitted from scratch \
                     fits the estimation half better and scores {:.1} % on the selection part (see REFITTED).",
                    r.best_selection_fit_percent
                );
            }
            Finding::Unsettled => {
                let _ = writeln!(
                    o,
                    "The estimation data do not settle the final fit: fits of the same model they cannot \
                     tell apart score between {lo:.1} and {hi:.1} % on the selection part (see REFITTED)."
                );
            }
        }
    }
    if d.repeats.is_empty() {
        // One run cannot tell its seed's choices from the data's.
        let _ = writeln!(
            o,
            "This is one run, from one seed: where the baseline has basins the data cannot tell \
             apart, another seed may name other effects (--repeat 3 runs three seeds and counts \
             the names)."
        );
    }
}

/// The final model refitted from scratch, and what that says of its fit.
fn refits_text(o: &mut String, d: &Diagnosis) {
    let Some(r) = &d.refits else {
        return;
    };
    let (lo, hi) = r.tied_selection_fit_percent;
    let _ = writeln!(
        o,
        "\nREFITTED: the final model fitted {} times from scratch (fits within the likelihood-ratio\n  \
         threshold of the lowest estimation SSE are ones the estimation data cannot tell apart):",
        r.fits
    );
    let _ = writeln!(
        o,
        "  final fit        estimation SSE {}  selection fit {:5.1} %",
        significant(r.final_est_sse, 4),
        r.final_selection_fit_percent
    );
    let _ = writeln!(
        o,
        "  best refit       estimation SSE {}  selection fit {:5.1} %",
        significant(r.best_est_sse, 4),
        r.best_selection_fit_percent
    );
    let said = match r.finding() {
        Finding::Reproduced => format!(
            "reproduced: the {} fits the estimation data cannot tell apart score {lo:.1}–{hi:.1} % on the selection part",
            r.tied
        ),
        Finding::Best => "the best estimation fit found: no refit came within the threshold of it \
                          (they ended in basins worse on the estimation half)"
            .to_string(),
        Finding::Beaten => format!(
            "not settled: a refit fits the estimation half better than the final fit and scores \
             {:.1} % on the selection part; the final fit's {:.1} % is the basin the search ended in",
            r.best_selection_fit_percent, r.final_selection_fit_percent
        ),
        Finding::Unsettled => format!(
            "not settled: {} fits the estimation data cannot tell apart score between {lo:.1} and {hi:.1} % on the selection part",
            r.tied
        ),
    };
    let _ = writeln!(o, "  {said}");
}

/// The final chain as `fit --effects` fits it.
fn as_fit_text(o: &mut String, d: &Diagnosis) {
    let Some(a) = &d.as_fit else {
        return;
    };
    let _ = writeln!(
        o,
        "\nAS FIT: the final chain fitted as `fit --effects` fits it (its search from scratch and its\n  \
         warm start from this fit, the lower estimation SSE kept): estimation SSE {}, selection\n  \
         RMSE {} against this fit's {}, second-half fit {:.1} %; {}",
        significant(a.est_sse, 4),
        significant(a.selection_rmse, 4),
        significant(a.selection_fit_rmse, 4),
        a.val_fit_percent,
        if a.kept {
            "it scores better on the selection part and is the final model"
        } else {
            "this fit scores better on the selection part and stays the final model"
        }
    );
}

fn peak_text(p: &Peak) -> String {
    format!(
        "a peak at {:.2} Hz ({:.1}× its flanks' background, {} of the residual energy)",
        p.hz,
        p.prominence,
        pct(p.energy_share).trim()
    )
}

/// The signature of the residual the catalogue leaves, in words.
fn signature_text(s: &Signature) -> String {
    let on = |sh: &Share| {
        format!(
            "{} of the energy on {} of the samples",
            pct(sh.energy).trim(),
            pct(sh.samples).trim()
        )
    };
    let mut parts = vec![
        format!(
            "at input {:.4}–{:.4} ({})",
            s.level.lo,
            s.level.hi,
            on(&s.level.share)
        ),
        format!("on the {} branch ({})", s.branch, on(&s.branch_share)),
        format!(
            "at {:.3}–{:.3} Hz ({} of the energy)",
            s.band.lo,
            s.band.hi,
            pct(s.band.share.energy).trim()
        ),
    ];
    if let Some(p) = &s.peak {
        parts.push(format!("with {}", peak_text(p)));
    }
    parts.join(", ")
}

fn explainable_text(o: &mut String, d: &Diagnosis) {
    let x = &d.explainable;
    let b = &x.bound;
    let _ = writeln!(
        o,
        "\nHOW MUCH is explainable at all (ridge model of the baseline's residual from lags and filters\n  \
         of the input, its rate and branch and the baseline's prediction, never the measured output;\n  \
         groups of features chosen and λ = {:.0e} by blocked cross-validation on the estimation half):\n  \
         signals used: {}",
        b.lambda,
        if b.groups.is_empty() {
            "none (a constant only)".to_string()
        } else {
            b.groups.join(", ")
        }
    );
    let _ = writeln!(
        o,
        "  selection RMSE {} → {}: a flexible model closes {} of the gap above the noise floor{}",
        significant(b.baseline_rmse, 4),
        significant(b.bound_rmse, 4),
        pct(b.gap_closable),
        if b.gap_closable < 0.0 {
            " (below zero: the regression, chosen on the estimation half, does worse than the \
             baseline on the selection part, so it bounds nothing here)"
        } else {
            ""
        }
    );
    let of_bound = |v: Option<f64>| {
        v.map_or("— (the bound is too small to share out)".into(), |v| {
            format!("{} of the explainable", pct(v))
        })
    };
    for e in &x.effect_shares {
        let _ = writeln!(
            o,
            "  {:<12} closes {} of the gap = {}",
            e.effect.name(),
            pct(e.gap_closed),
            of_bound(e.share)
        );
    }
    let _ = writeln!(
        o,
        "  {:<12} closes {} of the gap = {}{}",
        "all named",
        pct(d.last().gap_closed),
        of_bound(x.catalogue_share),
        if x.catalogue_share.is_some_and(|s| s > 1.0) {
            " (above 100 %: the effects reach what the regression cannot)"
        } else {
            ""
        }
    );
}

/// Which leading links of a chain that collapses on a record carry over
/// there, and the first that does not.
fn carried_text(t: &Transfer) -> String {
    let names = |effects: &[Effect]| {
        effects
            .iter()
            .map(|e| e.name())
            .collect::<Vec<_>>()
            .join(", ")
    };
    match &t.carries {
        Some(c) => format!(
            "{} carr{} over ({:.1} %); {} does not",
            names(&c.effects),
            if c.effects.len() == 1 { "ies" } else { "y" },
            c.val_fit_percent,
            t.chain[c.effects.len()].name()
        ),
        None => format!(
            "not even its first link ({}) carries over",
            t.chain.first().map_or("none", |e| e.name())
        ),
    }
}

/// The chain's parameters its fit on another record left on their box's
/// edge, in words (`None` without any).
fn edges_text(on_edge: &[ActiveBound]) -> Option<String> {
    if on_edge.is_empty() {
        return None;
    }
    let each: Vec<String> = on_edge
        .iter()
        .map(|b| format!("{} ({})", b.param, b.bound.name()))
        .collect();
    Some(format!(
        "on their box's edge there: {} (the record pushed the effect as far as it goes)",
        each.join(", ")
    ))
}

/// Every run of `--repeat` and how often each effect was named.
fn repeats_text(o: &mut String, d: &Diagnosis) {
    let runs = &d.repeats;
    if runs.is_empty() {
        return;
    }
    let k = runs.len();
    let _ = writeln!(
        o,
        "\nREPEATED from {k} seeds (--repeat {k}; each run a whole diagnosis, this report the first's;\n  \
         its baseline and its final model on its test part, which none of its choices read):"
    );
    let verdicts: Vec<String> = runs
        .iter()
        .map(|r| match r.kind {
            "named" => r
                .named
                .iter()
                .map(|e| e.name())
                .collect::<Vec<_>>()
                .join(", "),
            "none" => "no effect named".into(),
            "nothing-tried" => "nothing tried".into(),
            _ if d.narrowed() => "not explained by the effects tried".into(),
            _ => "not explained by the catalogue".into(),
        })
        .collect();
    let width = verdicts
        .iter()
        .map(|v| v.chars().count())
        .max()
        .unwrap_or(0);
    for (r, verdict) in runs.iter().zip(&verdicts) {
        let _ = writeln!(
            o,
            "  seed {:<4} {verdict:<width$}  baseline {:5.1} %  final {:5.1} %",
            r.seed, r.baseline_test_fit_percent, r.final_test_fit_percent
        );
    }
    let counts = |physical: bool| -> String {
        named_counts(runs, physical)
            .iter()
            .map(|n| format!("{} {} of {k}", n.effect, n.runs))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let (named, physical) = (counts(false), counts(true));
    if named.is_empty() {
        let _ = writeln!(o, "  no run named an effect");
        return;
    }
    let _ = writeln!(o, "  named: {named}");
    let _ = writeln!(o, "  by physical effect, in any realisation: {physical}");
    let unanimous = runs.iter().all(|r| r.named == runs[0].named);
    let _ = writeln!(
        o,
        "  {}",
        if unanimous {
            "Every run named the same effects in the same order."
        } else {
            "An effect that only some runs name is the seed's choice among basins the data \
             cannot tell apart, not the data's."
        }
    );
}

/// The chain on other records (`--transfer`).
fn transfer_text(o: &mut String, d: &Diagnosis) {
    let Some(first) = d.transfers.first() else {
        return;
    };
    let chain: Vec<&str> = first.chain.iter().map(|e| e.name()).collect();
    let _ = writeln!(
        o,
        "\nTRANSFER: the baseline (`fit`) and the chain ({}) carried as `fit --carry` carries it (its\n  \
         dynamics held: {}; its sizes fitted there), each fitted on every other record's first half\n  \
         and scored on its second, which no choice saw; `names only`: the chain refitted from its\n  \
         names alone (`fit --effects`), its dynamics fitted on that first half too:",
        if chain.is_empty() {
            "no effect".to_string()
        } else {
            chain.join(", ")
        },
        if first.dynamics_held.is_empty() {
            "none".to_string()
        } else {
            first
                .dynamics_held
                .iter()
                .map(|h| format!("{} {}", h.param, significant(h.value, 4)))
                .collect::<Vec<_>>()
                .join(", ")
        }
    );
    let width = d
        .transfers
        .iter()
        .map(|t| t.dataset.chars().count())
        .max()
        .unwrap_or(0);
    for t in &d.transfers {
        let verdict = if !t.chain_val_fit_percent.is_finite() {
            "  COLLAPSES: the chain has no finite fit here"
        } else if t.collapses {
            "  COLLAPSES: below the plain fit"
        } else {
            ""
        };
        let _ = writeln!(
            o,
            "  {:<width$}  baseline {:5.1} %  carried {:5.1} %  gap closed {}  names only {:5.1} %{verdict}",
            t.dataset,
            t.baseline_val_fit_percent,
            t.chain_val_fit_percent,
            pct(t.gap_closed),
            t.names_only_val_fit_percent
        );
        if t.collapses {
            let _ = writeln!(o, "  {:<width$}  {}", "", carried_text(t));
            if let Some(edges) = edges_text(&t.chain_on_edge) {
                let _ = writeln!(o, "  {:<width$}  {edges}", "");
            }
        }
    }
    if d.transfers.iter().any(|t| t.collapses) {
        let _ = writeln!(
            o,
            "  A chain that collapses on another record holds something of this recording, not of the\n  \
             muscle: read it as a description of this record."
        );
    }
}

fn spectrum_text(o: &mut String, d: &Diagnosis) {
    let Some(s) = &d.spectrum else {
        let _ = writeln!(
            o,
            "\nSPECTRUM: the selection blocks are too short for a Welch spectrum."
        );
        return;
    };
    let _ = writeln!(
        o,
        "\nSPECTRUM of the selection residual (Welch: {} Hann segments of {} samples, {:.3} Hz bins;\n  \
         a peak stands ≥ 4× above the background of its flanks):",
        s.segments,
        s.segment,
        s.hz.get(1).copied().unwrap_or(f64::NAN)
    );
    for (name, spec) in [
        ("baseline", &d.spectrum),
        ("final model", &d.final_spectrum),
    ] {
        let peaks = spec.as_ref().map_or(&[][..], |s| s.peaks.as_slice());
        if peaks.is_empty() {
            let _ = writeln!(o, "  {name:<12} no peak");
        }
        for p in peaks {
            let _ = writeln!(o, "  {name:<12} {}", peak_text(p));
        }
    }
}
