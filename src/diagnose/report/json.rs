//! The `--json` document of `diagnose` (docs/JSON.md).

use serde::Serialize;

use super::candidate_list;
use crate::diagnose::accept::gap_closed;
use crate::diagnose::explainable::{EffectShare, Explainable, Signature};
use crate::diagnose::interval::SizeInterval;
use crate::diagnose::locate::{Band, Correlation, DatasetShare};
use crate::diagnose::plain::PlainFit;
use crate::diagnose::refits::{Finding, Refits};
use crate::diagnose::seeds::{NamedCount, SeedRun, named_counts};
use crate::diagnose::spectrum::{Peak, Spectrum};
use crate::diagnose::transfer::Transfer;
use crate::diagnose::{Diagnosis, NotTried, Step};
use crate::fit::edge::ActiveBound;
use crate::model::experiment::Parts;
use crate::report::json::Named;

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
    /// Its free-run SSE on the estimation halves, the cost it minimised.
    pub est_sse: f64,
    #[serde(flatten)]
    pub figures: PartsFigures,
    pub seed_selection_rmse: Vec<f64>,
    /// Loop-shape parameters that ended on or near the edge of the
    /// diagnosis' box (`Diagnosis::baseline_on_edge`).
    pub on_edge: Vec<ActiveBound>,
    /// `fit`'s own fit of the baseline, scored on the selection part
    /// (`Diagnosis::plain_fit`); `null` from a start model.
    pub plain_fit: Option<PlainFit>,
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
    /// The classes that hold far more of the energy than of the samples,
    /// named as the report names them.
    pub over_represented: Vec<String>,
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

/// [`crate::diagnose::as_fit::AsFit`] without its parameter vector (the final model's is `final.params`
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
    /// Their input and output columns and units (`fit --json`'s `columns`).
    pub columns: Option<crate::data::Columns>,
    /// Each dataset's parts, parallel to `datasets`.
    pub parts: Vec<PartsJson>,
    pub noise_floor_rmse: f64,
    pub noise_floor_method: &'static str,
    /// Whether the floor is an upper bound ([`Diagnosis::floor_is_upper_bound`]).
    pub noise_floor_upper_bound: bool,
    #[serde(rename = "where")]
    pub where_: WhereJson,
    pub candidates: Vec<CandidateJson>,
    pub verdict: Vec<&'static str>,
    /// `named`, `none`, `not-explained` or `nothing-tried`.
    pub verdict_kind: &'static str,
    /// What weakens a verdict naming effects ([`super::verdict_cautions`]).
    pub verdict_cautions: Vec<String>,
    /// The model file the selection started from (`--from`), and its
    /// effects, taken as given.
    pub from: Option<String>,
    pub given: Vec<&'static str>,
    /// The effects the selection was asked to try (the default catalogue
    /// or `--effects`'), of which the verdict speaks.
    pub asked: Vec<&'static str>,
    /// Effects asked for that the selection did not try, and why (`load`
    /// where datasets are pieces of one recording).
    pub not_tried: Vec<NotTried>,
    /// Whether the selection stopped at `--max-effects` still accepting.
    pub capped: bool,
    pub steps: Vec<Step>,
    #[serde(rename = "final")]
    pub final_: FinalJson,
    pub explainable: ExplainableJson,
    pub spectrum: SpectrumJson,
    /// The chain fitted on other records (`--transfer`); empty without.
    pub transfers: Vec<Transfer>,
    /// Every run of `--repeat K`, this diagnosis first; `null` without.
    pub repeats: Option<RepeatsJson>,
    pub rule: &'static str,
}

/// The runs of `--repeat K` and how many of them named each effect.
#[derive(Debug, Clone, Serialize)]
pub struct RepeatsJson {
    pub runs: Vec<RunJson>,
    /// How many runs named each effect, by realisation
    /// (`saturation:output`), most often named first.
    pub named: Vec<NamedCount>,
    /// The same by physical effect (`saturation`, in any realisation).
    pub physical: Vec<NamedCount>,
}

/// One run of `--repeat`.
#[derive(Debug, Clone, Serialize)]
pub struct RunJson {
    pub seed: u64,
    pub verdict: Vec<&'static str>,
    pub verdict_kind: &'static str,
    /// Its baseline on its selection part, which its choices read.
    pub baseline_selection_fit_percent: f64,
    /// Its baseline and its final model on the test part, which none of
    /// its choices read.
    pub baseline_test_fit_percent: f64,
    pub final_test_fit_percent: f64,
}

impl RepeatsJson {
    fn of(runs: &[SeedRun]) -> Option<RepeatsJson> {
        (!runs.is_empty()).then(|| RepeatsJson {
            runs: runs
                .iter()
                .map(|r| RunJson {
                    seed: r.seed,
                    verdict: r.named.iter().map(|e| e.name()).collect(),
                    verdict_kind: r.kind,
                    baseline_selection_fit_percent: r.baseline_selection_fit_percent,
                    baseline_test_fit_percent: r.baseline_test_fit_percent,
                    final_test_fit_percent: r.final_test_fit_percent,
                })
                .collect(),
            named: named_counts(runs, false),
            physical: named_counts(runs, true),
        })
    }
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
                est_sse: sel.baseline.best.est_sse,
                figures: PartsFigures::of(base),
                seed_selection_rmse: sel.baseline.seed_sel_rmse.clone(),
                on_edge: d.baseline_on_edge.clone(),
                plain_fit: d.plain_fit.clone(),
            },
            datasets: d.datasets.clone(),
            columns: d.columns.clone(),
            parts: d.parts.iter().map(PartsJson::of).collect(),
            noise_floor_rmse: floor,
            noise_floor_method: "median |second difference of the measured output on the estimation half and the selection blocks| / (0.6745·√6)",
            noise_floor_upper_bound: d.floor_is_upper_bound(),
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
                over_represented: w.over_represented(),
            },
            candidates,
            verdict: d.named().iter().map(|e| e.name()).collect(),
            verdict_kind: d.verdict_kind(),
            verdict_cautions: super::verdict_cautions(d),
            from: d.from.clone(),
            capped: sel.capped,
            given: sel.given.iter().map(|e| e.name()).collect(),
            asked: d.asked.iter().map(|e| e.name()).collect(),
            not_tried: d.not_tried.clone(),
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
            repeats: RepeatsJson::of(&d.repeats),
            rule: "accept iff R0−R1 > 3·√(s0²+s1²) (seed spread), ΔBIC = N·ln(R1²/R0²) + k·ln N < −10, (R0−R1)/R0 ≥ 2 %, and R0 > 1.1·noise floor; a candidate's gain that the model without it reaches from the candidate's parameters is not credited to it (ablation)",
        }
    }
}
