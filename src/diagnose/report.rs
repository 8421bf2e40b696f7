//! A [`Diagnosis`] for people (text), scripts (JSON) and eyes (SVG figures).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::accept::{Candidate, gap_closed};
use super::effects::Effect;
use super::explainable::{EffectShare, Explainable, Signature};
use super::interval::SizeInterval;
use super::locate::{Band, Correlation, DatasetShare, Share};
use super::refits::{Finding, Refits};
use super::spectrum::{Peak, Spectrum};
use super::transfer::Transfer;
use super::{Diagnosis, Step};
use crate::model::experiment::Parts;
use crate::report::json::Named;
use crate::report::{Figure, Panel, Series};

/// One entry per effect scored: from the round it was accepted in, else from
/// the last round it was scored in. Accepted effects first (in the order
/// accepted), then the rest by selection RMSE.
pub fn candidate_list(d: &Diagnosis) -> Vec<(&Candidate, bool, usize)> {
    let mut seen: BTreeMap<&'static str, (&Candidate, bool, usize)> = BTreeMap::new();
    for (r, round) in d.selection.rounds.iter().enumerate() {
        for c in &round.candidates {
            let accepted = round.accepted == Some(c.effect);
            let keep = !matches!(seen.get(c.effect.name()), Some((_, true, _)));
            if keep {
                seen.insert(c.effect.name(), (c, accepted, r + 1));
            }
        }
    }
    let mut list: Vec<_> = seen.into_values().collect();
    let pos = |e: Effect| d.selection.verdict.iter().position(|v| *v == e);
    list.sort_by(|a, b| match (pos(a.0.effect), pos(b.0.effect)) {
        (Some(x), Some(y)) => x.cmp(&y),
        (Some(_), None) => std::cmp::Ordering::Less,
        (None, Some(_)) => std::cmp::Ordering::Greater,
        (None, None) => a.0.fit.best.sel_rmse.total_cmp(&b.0.fit.best.sel_rmse),
    });
    list
}

/// An input band's or frequency band's share of the residual.
#[derive(Debug, Serialize)]
pub struct BandJson {
    pub lo: f64,
    pub hi: f64,
    /// Share of the residual energy.
    pub share: f64,
    /// Share of the samples.
    pub sample_share: f64,
}

impl BandJson {
    fn of(b: &Band) -> BandJson {
        BandJson {
            lo: b.lo,
            hi: b.hi,
            share: b.share.energy,
            sample_share: b.share.samples,
        }
    }
}

/// One scored effect (a [`candidate_list`] entry).
#[derive(Debug, Serialize)]
pub struct CandidateJson {
    pub effect: &'static str,
    pub physical: &'static str,
    pub realisation: &'static str,
    pub size: Option<String>,
    pub params: Named,
    pub selection_rmse: f64,
    pub gap_closed: f64,
    pub accepted: bool,
    pub round: usize,
    pub seed_selection_rmse: Vec<f64>,
    /// The candidate's RMSE over the current model's on each selection
    /// block, in order.
    pub block_ratios: Vec<f64>,
    /// Rule 5: the selection RMSE's relative improvement with the block it
    /// gains most on left out (null with one block).
    pub without_best_block: Option<f64>,
    pub delta_bic: f64,
    pub relative_improvement: f64,
    pub reason: String,
    pub signature: &'static str,
}

/// A model's figures on each part (a [`Step`] less its effects).
#[derive(Debug, Serialize)]
pub struct PartsFigures {
    pub val_rmse: f64,
    pub val_fit_percent: f64,
    pub selection_rmse: f64,
    pub selection_fit_percent: f64,
    pub test_rmse: f64,
    pub test_fit_percent: f64,
    pub optimism_points: f64,
}

impl PartsFigures {
    fn of(s: &Step) -> PartsFigures {
        PartsFigures {
            val_rmse: s.val_rmse,
            val_fit_percent: s.val_fit_percent,
            selection_rmse: s.selection_rmse,
            selection_fit_percent: s.selection_fit_percent,
            test_rmse: s.test_rmse,
            test_fit_percent: s.test_fit_percent,
            optimism_points: s.optimism_points,
        }
    }
}

#[derive(Debug, Serialize)]
pub struct BaselineJson {
    pub model: &'static str,
    pub params: Named,
    #[serde(flatten)]
    pub figures: PartsFigures,
    pub seed_selection_rmse: Vec<f64>,
}

/// A record's three parts: `[start, end)` sample ranges.
#[derive(Debug, Serialize)]
pub struct PartsJson {
    pub estimation: Vec<[usize; 2]>,
    pub selection: Vec<[usize; 2]>,
    pub test: Vec<[usize; 2]>,
}

impl PartsJson {
    fn of(p: &Parts) -> PartsJson {
        let pairs = |v: &[std::ops::Range<usize>]| v.iter().map(|r| [r.start, r.end]).collect();
        PartsJson {
            estimation: pairs(std::slice::from_ref(&p.estimation)),
            selection: pairs(&p.selection),
            test: pairs(&p.test),
        }
    }
}

#[derive(Debug, Serialize)]
pub struct BranchJson {
    pub rising: f64,
    pub falling: f64,
    pub steady: f64,
}

#[derive(Debug, Serialize)]
pub struct AfterStepJson {
    pub transient: f64,
    pub settled: f64,
}

/// Where the baseline's validation residual lies.
#[derive(Debug, Serialize)]
pub struct WhereJson {
    pub rmse: f64,
    pub branch: BranchJson,
    pub branch_sample_share: BranchJson,
    pub input_band: Vec<BandJson>,
    pub after_step: AfterStepJson,
    pub after_step_sample_share: AfterStepJson,
    pub settle_samples: usize,
    pub frequency_hz: Vec<BandJson>,
    pub dataset: Vec<DatasetShare>,
    pub whiteness: Correlation,
    pub cross_correlation: Correlation,
}

/// The refits as the diagnosis measured them, and what they find.
#[derive(Debug, Serialize)]
pub struct RefitsJson {
    #[serde(flatten)]
    pub refits: Refits,
    pub finding: Finding,
}

#[derive(Debug, Serialize)]
pub struct FinalJson {
    /// The effects of the final model, in the order accepted.
    pub model: Vec<&'static str>,
    pub params: Named,
    #[serde(flatten)]
    pub figures: PartsFigures,
    pub gap_closed: f64,
    pub test_gap_closed: f64,
    pub size_intervals: Vec<SizeInterval>,
    pub refits: Option<RefitsJson>,
    /// The final chain as `fit --effects` fits it (null with several
    /// datasets or `--from`).
    pub as_fit: Option<AsFitJson>,
}

/// [`super::as_fit::AsFit`] without its parameter vector (the final model's is `final.params`
/// when it was kept).
#[derive(Debug, Serialize)]
pub struct AsFitJson {
    pub est_sse: f64,
    pub selection_rmse: f64,
    pub selection_fit_rmse: f64,
    pub val_fit_percent: f64,
    pub kept: bool,
}

#[derive(Debug, Serialize)]
pub struct ExplainableJson {
    pub bound_rmse: f64,
    pub baseline_rmse: f64,
    pub gap_closable: f64,
    pub lambda: f64,
    pub features: usize,
    pub groups: Vec<&'static str>,
    /// Each named effect's share of the closable gap, by effect name.
    pub effect_shares: Named<Option<f64>>,
    /// Each named effect's share of the gap closed, by effect name.
    pub effect_gap_closed: Named,
    pub catalogue_share: Option<f64>,
    pub not_explained: bool,
    pub signature: Option<Signature>,
    pub method: &'static str,
}

#[derive(Debug, Serialize)]
pub struct SpectrumJson {
    pub segment: Option<usize>,
    pub segments: Option<usize>,
    pub bin_hz: Option<f64>,
    pub peaks: Vec<Peak>,
    pub final_peaks: Vec<Peak>,
}

/// The `--json` document of `diagnose` (docs/JSON.md), without its
/// `schema_version` (see [`crate::report::json::Versioned`]).
#[derive(Debug, Serialize)]
pub struct DiagnosisJson {
    pub baseline: BaselineJson,
    pub datasets: Vec<String>,
    /// Each dataset's parts, parallel to `datasets`.
    pub parts: Vec<PartsJson>,
    pub noise_floor_rmse: f64,
    pub noise_floor_method: &'static str,
    #[serde(rename = "where")]
    pub where_: WhereJson,
    pub candidates: Vec<CandidateJson>,
    pub verdict: Vec<&'static str>,
    /// `named`, `none` or `not-explained`.
    pub verdict_kind: &'static str,
    /// The model file the selection started from (`--from`), and its
    /// effects, taken as given.
    pub from: Option<String>,
    pub given: Vec<&'static str>,
    /// Whether the selection stopped at `--max-effects` still accepting.
    pub capped: bool,
    pub steps: Vec<Step>,
    #[serde(rename = "final")]
    pub final_: FinalJson,
    pub explainable: ExplainableJson,
    pub spectrum: SpectrumJson,
    /// The chain fitted on other records (`--transfer`); empty without.
    pub transfers: Vec<Transfer>,
    pub rule: &'static str,
}

impl DiagnosisJson {
    /// The `--json` document of `d`.
    pub fn of(d: &Diagnosis) -> DiagnosisJson {
        let sel = &d.selection;
        let base = d.baseline();
        let w = &d.locate;
        let floor = d.noise_floor_rmse;
        let candidates: Vec<CandidateJson> = candidate_list(d)
            .into_iter()
            .map(|(c, accepted, round)| {
                let values: Vec<f64> = c.effect_params.iter().map(|(_, v)| *v).collect();
                CandidateJson {
                    effect: c.effect.name(),
                    physical: c.effect.physical().name(),
                    realisation: c.effect.realisation(),
                    size: c.effect.size_text(&values, d.dt),
                    params: c.effect_params.iter().map(|(n, v)| (n, *v)).collect(),
                    selection_rmse: c.fit.best.sel_rmse,
                    gap_closed: gap_closed(base.selection_rmse, c.fit.best.sel_rmse, floor),
                    accepted,
                    round,
                    seed_selection_rmse: c.fit.seed_sel_rmse.clone(),
                    block_ratios: c.block_ratios.clone(),
                    without_best_block: c.without_best_block,
                    delta_bic: c.delta_bic,
                    relative_improvement: c.relative,
                    reason: c.reason.clone(),
                    signature: c.effect.signature(),
                }
            })
            .collect();
        let last = d.last();
        let x = &d.explainable;
        fn by_effect<T>(x: &Explainable, f: fn(&EffectShare) -> T) -> Named<T> {
            x.effect_shares
                .iter()
                .map(|e| (e.effect.name(), f(e)))
                .collect()
        }
        let peaks = |s: &Option<Spectrum>| s.as_ref().map_or(Vec::new(), |s| s.peaks.clone());
        DiagnosisJson {
            baseline: BaselineJson {
                model: d.family.name(),
                params: Named::zip(&sel.baseline_model.param_names(), &sel.baseline.best.params),
                figures: PartsFigures::of(base),
                seed_selection_rmse: sel.baseline.seed_sel_rmse.clone(),
            },
            datasets: d.datasets.clone(),
            parts: d.parts.iter().map(PartsJson::of).collect(),
            noise_floor_rmse: floor,
            noise_floor_method: "median |second difference of the measured output on the selection blocks| / (0.6745·√6)",
            where_: WhereJson {
                rmse: w.rmse,
                branch: BranchJson {
                    rising: w.branch.rising.energy,
                    falling: w.branch.falling.energy,
                    steady: w.branch.steady.energy,
                },
                branch_sample_share: BranchJson {
                    rising: w.branch.rising.samples,
                    falling: w.branch.falling.samples,
                    steady: w.branch.steady.samples,
                },
                input_band: w.input_band.iter().map(BandJson::of).collect(),
                after_step: AfterStepJson {
                    transient: w.after_step.transient.energy,
                    settled: w.after_step.settled.energy,
                },
                after_step_sample_share: AfterStepJson {
                    transient: w.after_step.transient.samples,
                    settled: w.after_step.settled.samples,
                },
                settle_samples: w.after_step.settle_samples,
                frequency_hz: w.frequency.iter().map(BandJson::of).collect(),
                dataset: w.dataset.clone(),
                whiteness: w.whiteness.clone(),
                cross_correlation: w.cross_correlation.clone(),
            },
            candidates,
            verdict: d.named().iter().map(|e| e.name()).collect(),
            verdict_kind: if x.not_explained {
                "not-explained"
            } else if sel.verdict.is_empty() {
                "none"
            } else {
                "named"
            },
            from: d.from.clone(),
            capped: sel.capped,
            given: sel.given.iter().map(|e| e.name()).collect(),
            steps: d.steps.clone(),
            final_: FinalJson {
                model: sel.final_model.effects.iter().map(|e| e.name()).collect(),
                params: Named::zip(&sel.final_model.param_names(), &d.final_params),
                figures: PartsFigures::of(last),
                gap_closed: last.gap_closed,
                test_gap_closed: last.test_gap_closed,
                size_intervals: d.size_intervals.clone(),
                refits: d.refits.as_ref().map(|r| RefitsJson {
                    refits: r.clone(),
                    finding: r.finding(),
                }),
                as_fit: d.as_fit.as_ref().map(|a| AsFitJson {
                    est_sse: a.est_sse,
                    selection_rmse: a.selection_rmse,
                    selection_fit_rmse: a.selection_fit_rmse,
                    val_fit_percent: a.val_fit_percent,
                    kept: a.kept,
                }),
            },
            explainable: ExplainableJson {
                bound_rmse: x.bound.bound_rmse,
                baseline_rmse: x.bound.baseline_rmse,
                gap_closable: x.bound.gap_closable,
                lambda: x.bound.lambda,
                features: x.bound.features,
                groups: x.bound.groups.clone(),
                effect_shares: by_effect(x, |e| e.share),
                effect_gap_closed: by_effect(x, |e| e.gap_closed),
                catalogue_share: x.catalogue_share,
                not_explained: x.not_explained,
                signature: x.signature.clone(),
                method: "ridge regression of the baseline's residual on groups of features (lags, Laguerre and low-pass filters, rate and branch of the input, lags and level terms of the baseline's prediction; never the measured output), groups added forward and the penalty chosen by 5-fold blocked CV on the estimation half, scored on the selection part",
            },
            spectrum: SpectrumJson {
                segment: d.spectrum.as_ref().map(|s| s.segment),
                segments: d.spectrum.as_ref().map(|s| s.segments),
                bin_hz: d.spectrum.as_ref().and_then(|s| s.hz.get(1).copied()),
                peaks: peaks(&d.spectrum),
                final_peaks: peaks(&d.final_spectrum),
            },
            transfers: d.transfers.clone(),
            rule: "accept iff R0−R1 > 3·√(s0²+s1²) (seed spread), ΔBIC = N·ln(R1²/R0²) + k·ln N < −10, (R0−R1)/R0 ≥ 2 %, and R0 > 1.1·noise floor; a candidate's gain that the model without it reaches from the candidate's parameters is not credited to it (ablation)",
        }
    }
}

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
    let Some(p) = d.parts.first() else {
        return String::new();
    };
    let blocks = p.selection.len() + p.test.len();
    let gap = match (p.selection.first(), p.test.first()) {
        (Some(s), Some(t)) => t.start.saturating_sub(s.end),
        _ => 0,
    };
    format!(
        "Parts: each record's first half estimates; its second half is cut into {blocks} blocks, \
         selection and test in turn ({gap}-sample settling gaps between).\n  Every choice reads \
         the selection blocks ({} samples); the test blocks ({} samples) are read once, after \
         the model is final.",
        d.parts.iter().map(Parts::selection_len).sum::<usize>(),
        d.parts.iter().map(Parts::test_len).sum::<usize>()
    )
}

/// The readable report.
pub fn to_text(d: &Diagnosis) -> String {
    let mut o = String::new();
    let w = &d.locate;
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
        "Baseline: selection fit {:.1} % (RMSE {:.4}), test fit {:.1} % (RMSE {:.4}); noise floor ≈ {:.4} (from second differences of the measured selection output)",
        base.selection_fit_percent,
        base.selection_rmse,
        base.test_fit_percent,
        base.test_rmse,
        d.noise_floor_rmse
    );
    if let Some(from) = &d.from {
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
    let _ = writeln!(
        o,
        "\nWHERE the baseline misses on the selection part (share of residual energy vs share of samples):"
    );
    let row = |o: &mut String, name: &str, s: &Share| {
        let flag = if s.energy > 1.5 * s.samples && s.energy > 0.1 {
            "  <-- over-represented"
        } else {
            ""
        };
        let _ = writeln!(
            o,
            "  {name:<28} energy {}   samples {}{flag}",
            pct(s.energy),
            pct(s.samples)
        );
    };
    row(&mut o, "input rising", &w.branch.rising);
    row(&mut o, "input falling", &w.branch.falling);
    row(&mut o, "input steady", &w.branch.steady);
    for b in &w.input_band {
        row(&mut o, &format!("input {:.4}–{:.4}", b.lo, b.hi), &b.share);
    }
    row(
        &mut o,
        &format!(
            "transient (≤{} samples after step)",
            w.after_step.settle_samples
        ),
        &w.after_step.transient,
    );
    row(&mut o, "settled", &w.after_step.settled);
    // For frequency bands the second share is of the periodogram's bins.
    for b in &w.frequency {
        row(
            &mut o,
            &format!("{:.3}–{:.3} Hz (bins)", b.lo, b.hi),
            &b.share,
        );
    }
    if w.dataset.len() > 1 {
        for ds in &w.dataset {
            row(&mut o, &ds.name, &ds.share);
        }
    }
    let test = |o: &mut String, name: &str, c: &super::locate::Correlation| {
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
    };
    test(&mut o, "residual whiteness (99 %)", &w.whiteness);
    test(
        &mut o,
        "residual–input independence (99 %)",
        &w.cross_correlation,
    );

    let _ = writeln!(
        o,
        "\nWHICH effect (selection RMSE; accepted = passes every rule):"
    );
    for (i, r) in d.selection.rounds.iter().enumerate() {
        for f in &r.rebased {
            let _ = writeln!(
                o,
                "  round {}: a refit of the current model (from its own seeds or from a \
                 candidate's parameters) reached a better estimation fit (SSE {:.1}, selection \
                 RMSE {:.4}); it became the current model and the round was judged from it",
                i + 1,
                f.best.est_sse,
                f.best.sel_rmse
            );
        }
    }
    for (c, accepted, round) in candidate_list(d) {
        let params: Vec<String> = c
            .effect_params
            .iter()
            .map(|(n, v)| format!("{n}={v:.4}"))
            .collect();
        let _ = writeln!(
            o,
            "  {:<2} {:<17} RMSE {:.4}  gap closed {}  [{}]  round {round}: {}",
            if accepted { "✔" } else { " " },
            c.effect.name(),
            c.fit.best.sel_rmse,
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
    if !d.size_intervals.is_empty() {
        let _ = writeln!(
            o,
            "\nHOW SURE (95 % profile-likelihood interval of each named effect's size in the final model;\n  it assumes white residuals and describes only the basin the fit ended in, so it is too\n  narrow when the whiteness test fails or the search missed a better basin):"
        );
        for s in &d.size_intervals {
            let edge = |at: bool| if at { " (box edge: not bounded)" } else { "" };
            let _ = writeln!(
                o,
                "  {:<10} {} = {:.4}  [{:.4}{}, {:.4}{}]  (±{:.4})",
                s.effect.name(),
                s.param,
                s.value,
                s.lo,
                edge(s.lo_at_edge),
                s.hi,
                edge(s.hi_at_edge),
                0.5 * (s.hi - s.lo)
            );
        }
    }
    refits_text(&mut o, d);
    as_fit_text(&mut o, d);
    explainable_text(&mut o, d);
    spectrum_text(&mut o, d);
    transfer_text(&mut o, d);
    let x = &d.explainable;
    if x.not_explained {
        let closed = d.last().gap_closed;
        let _ = writeln!(
            o,
            "\nVerdict: not explained by the catalogue. A flexible model of the signals closes {} \
             of the gap above the noise floor and leaves {}; the catalogue's best model closes {} \
             ({} of the flexible model's) and leaves {}.",
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
        let _ = writeln!(
            o,
            "\nVerdict: none of the catalogued effects explains the remaining gap."
        );
    } else {
        let names: Vec<_> = d
            .selection
            .verdict
            .iter()
            .map(|e| format!("{} ({})", e.physical(), e.realisation()))
            .collect();
        let _ = writeln!(
            o,
            "\nVerdict: {} (closes {} of the gap above the noise floor on the test part, {} on the \
             selection part that chose it).",
            names.join(", then "),
            pct(d.last().test_gap_closed).trim(),
            pct(d.last().gap_closed).trim()
        );
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
    o
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
        "  final fit        estimation SSE {:.4}  selection fit {:5.1} %",
        r.final_est_sse, r.final_selection_fit_percent
    );
    let _ = writeln!(
        o,
        "  best refit       estimation SSE {:.4}  selection fit {:5.1} %",
        r.best_est_sse, r.best_selection_fit_percent
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
         warm start from this fit, the lower estimation SSE kept): estimation SSE {:.4}, selection\n  \
         RMSE {:.4} against this fit's {:.4}, second-half fit {:.1} %; {}",
        a.est_sse,
        a.selection_rmse,
        a.selection_fit_rmse,
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
        "  selection RMSE {:.4} → {:.4}: a flexible model closes {} of the gap above the noise floor",
        b.baseline_rmse,
        b.bound_rmse,
        pct(b.gap_closable)
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

/// The chain on other records (`--transfer`).
fn transfer_text(o: &mut String, d: &Diagnosis) {
    let Some(first) = d.transfers.first() else {
        return;
    };
    let chain: Vec<&str> = first.chain.iter().map(|e| e.name()).collect();
    let _ = writeln!(
        o,
        "\nTRANSFER: the baseline (`fit`) and the chain ({}) (`fit --effects`) fitted on each other\n  \
         record's first half and scored on its second, which no choice saw:",
        if chain.is_empty() {
            "no effect".to_string()
        } else {
            chain.join(", ")
        }
    );
    let width = d
        .transfers
        .iter()
        .map(|t| t.dataset.chars().count())
        .max()
        .unwrap_or(0);
    for t in &d.transfers {
        let _ = writeln!(
            o,
            "  {:<width$}  baseline {:5.1} %  with the chain {:5.1} %  gap closed {}",
            t.dataset,
            t.baseline_val_fit_percent,
            t.chain_val_fit_percent,
            pct(t.gap_closed)
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

/// Writes the figures into `dir`; returns their paths.
pub fn write_figures(d: &Diagnosis, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create --report directory {}: {e}", dir.display()))?;
    let mut out = Vec::new();
    let mut save = |name: &str, fig: Figure| -> anyhow::Result<()> {
        let p = dir.join(name);
        fig.save(&p)?;
        out.push(p);
        Ok(())
    };
    let mut time = Figure::new("Second-half residual over time");
    let mut lp = Figure::new("Residual over the hysteresis loop");
    let mut out_panel = Panel::new("output vs input", "input", "output");
    let mut res_panel = Panel::new("residual vs input", "input", "residual");
    let final_label = if d.selection.verdict.is_empty() {
        "baseline (no effect accepted)".to_string()
    } else {
        let names: Vec<_> = d.selection.verdict.iter().map(|e| e.name()).collect();
        format!("with {}", names.join(" + "))
    };
    for c in &d.curves {
        let rb: Vec<f64> = c
            .measured
            .iter()
            .zip(&c.baseline)
            .map(|(m, b)| m - b)
            .collect();
        let rl: Vec<f64> = c.measured.iter().zip(&c.last).map(|(m, b)| m - b).collect();
        time = time.with(
            Panel::new(c.name.clone(), "time (s)", "measured − simulated")
                .with(Series::line("baseline", c.t.clone(), rb.clone()))
                .with(Series::line(final_label.clone(), c.t.clone(), rl)),
        );
        out_panel.series.push(Series::line(
            format!("{} measured", c.name),
            c.input.clone(),
            c.measured.clone(),
        ));
        out_panel.series.push(Series::line(
            format!("{} baseline", c.name),
            c.input.clone(),
            c.baseline.clone(),
        ));
        res_panel.series.push(Series::points(
            format!("{} baseline residual", c.name),
            c.input.clone(),
            rb,
        ));
    }
    save("diagnose_residual.svg", time)?;
    // What a person checks first: does the final model follow the record?
    let mut fit = Figure::new("Measured output against the models (second half)");
    for c in &d.curves {
        fit = fit.with(
            Panel::new(c.name.clone(), "time (s)", "output")
                .with(Series::line("measured", c.t.clone(), c.measured.clone()))
                .with(Series::line("baseline", c.t.clone(), c.baseline.clone()))
                .with(Series::line(
                    final_label.clone(),
                    c.t.clone(),
                    c.last.clone(),
                )),
        );
    }
    save("diagnose_fit.svg", fit)?;
    lp = lp.with(out_panel).with(res_panel);
    save("diagnose_loop.svg", lp)?;

    let w = &d.locate;
    let pair = |title: &str, xlabel: &str, x: Vec<f64>, shares: Vec<Share>| {
        Panel::new(title, xlabel, "share")
            .with(Series::line(
                "residual energy",
                x.clone(),
                shares.iter().map(|s| s.energy).collect(),
            ))
            .with(Series::line(
                "samples",
                x,
                shares.iter().map(|s| s.samples).collect(),
            ))
    };
    let fig = Figure::new("Where the residual energy lies")
        .with(pair(
            "branch: 0 rising, 1 falling, 2 steady; 3 transient, 4 settled",
            "class",
            (0..5).map(f64::from).collect(),
            vec![
                w.branch.rising,
                w.branch.falling,
                w.branch.steady,
                w.after_step.transient,
                w.after_step.settled,
            ],
        ))
        .with(pair(
            "input level (quintile bands, centre)",
            "input",
            w.input_band.iter().map(|b| 0.5 * (b.lo + b.hi)).collect(),
            w.input_band.iter().map(|b| b.share).collect(),
        ))
        .with(pair(
            "frequency band (geometric centre)",
            "frequency (Hz)",
            w.frequency.iter().map(|b| (b.lo * b.hi).sqrt()).collect(),
            w.frequency.iter().map(|b| b.share).collect(),
        ));
    save("diagnose_breakdown.svg", fig)?;

    if let Some(base) = &d.spectrum {
        let mut panel = Panel::new(
            "Welch spectrum of the selection residual (peaks marked)",
            "frequency (Hz)",
            "power density",
        )
        .log_y();
        for (name, spec) in [
            ("baseline", Some(base)),
            (final_label.as_str(), d.final_spectrum.as_ref()),
        ] {
            let Some(spec) = spec else { continue };
            panel.series.push(Series::line(
                name,
                spec.hz[1..].to_vec(),
                spec.power[1..].to_vec(),
            ));
            if !spec.peaks.is_empty() {
                let at = |hz: f64| {
                    spec.power[((hz / spec.hz[1]).round() as usize).min(spec.power.len() - 1)]
                };
                panel.series.push(Series::points(
                    format!("{name}: peaks"),
                    spec.peaks.iter().map(|p| p.hz).collect(),
                    spec.peaks.iter().map(|p| at(p.hz)).collect(),
                ));
            }
        }
        save(
            "diagnose_spectrum.svg",
            Figure::new("Residual spectrum").with(panel),
        )?;
    }
    Ok(out)
}
