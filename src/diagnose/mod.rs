//! Diagnosis of the sim-to-real gap: where the fitted model misses
//! ([`locate`]), which unmodelled effect of the catalogue explains it
//! ([`effects`], chosen by [`select`] under [`accept`]'s rule, each model
//! fitted by [`fitting`] on the halves of the data), and how far the model
//! gets with it, relative to a noise-floor estimate; whether the estimation
//! data settle the final fit ([`refits`]); how much of the gap is
//! explainable at all ([`explainable`], a [`ridge`] model of the residual)
//! and where the residual's spectrum peaks ([`spectrum`]). [`blind`] checks
//! the whole chain on data from a generator with its own equations for
//! every effect, [`selftest`] on data made with the catalogue's own, and
//! [`selftest_run`] runs either over the cases asked for; [`report`] turns
//! a [`Diagnosis`] into text, JSON and figures.

pub mod accept;
pub mod as_fit;
pub mod auto;
pub mod blind;
pub mod chain;
pub use crate::model::effects;
pub mod explainable;
pub mod fitting;
pub mod hints;
pub mod interval;
mod likelihood;
pub mod locate;
pub mod plain;
pub mod refits;
pub mod report;
pub mod ridge;
pub mod seeds;
pub mod select;
pub mod selftest;
pub mod selftest_run;
pub mod settings;
pub mod spectrum;
pub mod transfer;

use serde::Serialize;

pub use effects::{Effect, ModelDescription};
pub use select::Selection;
pub use settings::{Interrupted, Settings};

use crate::data::{Trace, same_step, sources};
use crate::fit::edge::{ActiveBound, active_bounds};
use crate::fit::problem::{FitProblem, settle_samples};
use crate::fit::searches::Searches;
use crate::model::coords::shape_range;
use crate::model::experiment::Parts;
use crate::model::{Family, Model};
use crate::search::Side;

/// One model along the way (the baseline, then after each accepted effect),
/// scored on each part of the records.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Step {
    /// Effects of the model (empty: the baseline).
    pub effects: Vec<Effect>,
    /// Free-run RMSE and fit % over the whole second half (selection, test
    /// and the gaps between): `fit`'s validation figure, the one `simulate
    /// --from` reproduces. It mixes what chose the model with what did not.
    pub val_rmse: f64,
    pub val_fit_percent: f64,
    /// On the selection part, which every choice of the diagnosis read.
    pub selection_rmse: f64,
    pub selection_fit_percent: f64,
    /// On the test part, which no choice read.
    pub test_rmse: f64,
    pub test_fit_percent: f64,
    /// The selection fit less the test fit, in points: how much the choice
    /// flattered the model.
    pub optimism_points: f64,
    /// Share of the baseline's gap above the noise floor closed (residual
    /// energy), on the selection part.
    pub gap_closed: f64,
    /// The same on the test part: how far the gap shrinks on data no
    /// choice saw.
    pub test_gap_closed: f64,
}

/// Everything the diagnosis found (`report::DiagnosisJson` is its `--json`
/// document).
#[derive(Debug, Clone)]
pub struct Diagnosis {
    pub family: Family,
    /// Where the selection started (`diagnose --from`; the command puts the
    /// model file's name here), [`PLAIN_FIT_START`] where it started from
    /// `fit`'s own fit of the baseline, `None` from scratch.
    pub from: Option<String>,
    pub datasets: Vec<String>,
    /// The datasets' input and output columns and their units: what the
    /// RMSEs and the parameters are in.
    pub columns: Option<crate::data::Columns>,
    /// Each dataset's estimation, selection and test samples.
    pub parts: Vec<Parts>,
    /// Sample time of the first dataset (s), for sizes in time.
    pub dt: f64,
    pub noise_floor_rmse: f64,
    /// The lag-1 correlation of the output's second difference over the
    /// same samples ([`locate::second_difference_lag1`]): past
    /// [`locate::SMOOTHNESS_LAG1`] the floor is an upper bound.
    pub noise_floor_lag1: f64,
    /// Where the baseline misses.
    pub locate: locate::Where,
    pub selection: Selection,
    /// Baseline, then the model after each accepted effect.
    pub steps: Vec<Step>,
    /// How well the data pin each accepted effect's size in the final model.
    pub size_intervals: Vec<interval::SizeInterval>,
    /// The final model fitted again from scratch: whether the estimation
    /// data settle its validation fit (`None` with `--scratch-seeds 0`).
    pub refits: Option<refits::Refits>,
    /// How much of the baseline's gap a flexible model of its residual
    /// closes, each named effect's share of that, and the verdict.
    pub explainable: explainable::Explainable,
    /// Welch spectra (and peaks) of the validation residual of the baseline
    /// and of the final model; `None` where the validation part is too short.
    pub spectrum: Option<spectrum::Spectrum>,
    pub final_spectrum: Option<spectrum::Spectrum>,
    /// Second-half predictions `(t, input, measured, baseline, final)` per dataset (absolute units).
    pub curves: Vec<Curves>,
    /// The baseline and the final model, as a model file holds them.
    pub baseline_model: Model,
    pub final_model: Model,
    /// The final chain as `fit --effects` fits it (one record, from
    /// scratch; [`as_fit::refit`]), and the final model's parameters: its,
    /// where it scored better on the selection part, else the selection's.
    pub as_fit: Option<as_fit::AsFit>,
    pub final_params: Vec<f64>,
    /// The effects the selection was asked to try: the default catalogue,
    /// or those `--effects` named.
    pub asked: Vec<Effect>,
    /// Effects asked for that the selection did not try, and why.
    pub not_tried: Vec<NotTried>,
    /// The chain fitted on other records of the muscle (`--transfer`,
    /// [`transfer::transfer`]); empty unless asked for.
    pub transfers: Vec<transfer::Transfer>,
    /// The baseline's loop-shape parameters that ended on or near the edge
    /// of the diagnosis' box (`loop_shape_on_edge`).
    pub baseline_on_edge: Vec<ActiveBound>,
    /// `fit`'s own fit of the baseline on the same estimation halves,
    /// scored on the selection part ([`plain::plain_fit`]); where it beats
    /// the searched baseline, the diagnosis may have started from it
    /// ([`plain::PlainFit::started_from`]). `None` from a
    /// start model (`--from`: its coordinates are not the records' own)
    /// or where that fit diverged.
    pub plain_fit: Option<plain::PlainFit>,
    /// Every run of `--repeat K` ([`seeds::repeat`]), this diagnosis first
    /// and then the same from the next `K − 1` seeds; empty unless asked
    /// for.
    pub repeats: Vec<seeds::SeedRun>,
}

/// Second-half curves of one dataset, for figures.
#[derive(Debug, Clone)]
pub struct Curves {
    pub name: String,
    pub t: Vec<f64>,
    pub input: Vec<f64>,
    pub measured: Vec<f64>,
    pub baseline: Vec<f64>,
    pub last: Vec<f64>,
}

impl Diagnosis {
    pub fn baseline(&self) -> &Step {
        &self.steps[0]
    }

    pub fn last(&self) -> &Step {
        self.steps.last().expect("at least the baseline")
    }

    /// The effects the diagnosis names as causes: the accepted ones, unless
    /// the verdict is "not explained by the catalogue". Then the signals
    /// demonstrably explain something the accepted effects do not have the
    /// shape of, and those effects are fits, not causes: naming them would
    /// be a wrong name (they stay in the final model and in
    /// `selection.verdict`, in the order they were accepted).
    pub fn named(&self) -> &[Effect] {
        if self.explainable.not_explained {
            &[]
        } else {
            &self.selection.verdict
        }
    }

    /// Whether the noise floor is an upper bound: the output's second
    /// difference follows the signal, so the floor counts part of it.
    pub fn floor_is_upper_bound(&self) -> bool {
        self.noise_floor_lag1 > locate::SMOOTHNESS_LAG1
    }

    /// Whether the effects asked for leave out some of the default
    /// catalogue's: a verdict then speaks of those effects, not of the
    /// catalogue.
    pub fn narrowed(&self) -> bool {
        Effect::by_default().iter().any(|e| !self.asked.contains(e))
    }

    /// `named` when the diagnosis names effects, `none` when no effect
    /// passed, `not-explained` when the effects asked for do not explain
    /// the gap, `nothing-tried` when no effect was tried (`--max-effects 0`,
    /// or none could be tried on the record).
    pub fn verdict_kind(&self) -> &'static str {
        if self.selection.rounds.is_empty() {
            "nothing-tried"
        } else if self.explainable.not_explained {
            "not-explained"
        } else if self.selection.verdict.is_empty() {
            "none"
        } else {
            "named"
        }
    }
}

/// What [`Diagnosis::from`] says where the diagnosis started from `fit`'s
/// own fit of the baseline ([`plain::PlainFit::started_from`]).
pub const PLAIN_FIT_START: &str = "`mckibben fit`'s fit of the baseline";

/// Seed salt of the final model's from-scratch refits, far from the
/// selection's (100 per round, `select::select`).
const REFIT_SALT: u64 = 9_000;

/// Runs the whole diagnosis on `traces`: each fitted on its first half,
/// every choice made on the selection blocks of its second half, the test
/// blocks read once at the end ([`FitProblem`]).
pub fn diagnose(
    traces: &[Trace],
    family: Family,
    effects: &[Effect],
    settings: &Settings,
) -> anyhow::Result<Diagnosis> {
    diagnose_from(traces, family, effects, settings, None)
}

/// [`diagnose`], the selection started from `from` (`diagnose --from`): its
/// baseline and chain refitted warm in its own coordinates, the rounds
/// trying the rest of `effects` ([`select::select`]).
pub fn diagnose_from(
    traces: &[Trace],
    family: Family,
    effects: &[Effect],
    settings: &Settings,
    from: Option<&Model>,
) -> anyhow::Result<Diagnosis> {
    anyhow::ensure!(
        family != Family::Linear,
        "the baseline must be a hysteresis model: classic or generalized"
    );
    if let Some(m) = from {
        for t in traces {
            m.check_data(t)?;
        }
    }
    let data = FitProblem::diagnosis(traces, family, from, settings.blocks)?;
    let searches = settings.searches()?;
    data.check_parts()?;
    let start = match from {
        Some(m) => Some(start_of(m, family, data.datasets())?),
        None => None,
    };
    let (floor, floor_lag1) = noise_floor_of(&data);
    let start_ref = start.as_ref().map(|(m, theta)| (m, theta.as_slice()));
    let asked = effects.to_vec();
    let (effects, not_tried) = tried_effects(traces, effects, from);
    let selection = select::select(
        &data, &searches, family, &effects, settings, floor, start_ref,
    )?;
    check_baseline(&selection, family, traces)?;
    let baseline_on_edge = loop_shape_on_edge(&data, &selection.baseline.best.params);
    let plain = match from {
        None => {
            settings
                .progress
                .say("fitting the baseline as `fit` does, to compare");
            plain::plain_fit(traces, &data, &searches, settings, &selection.baseline.best)?
        }
        Some(_) => None,
    };
    // A search in the thesis' loop shapes that missed the basin `fit`
    // reaches would leave the effects to stand in for the miss: start
    // again from `fit`'s fit, as `--from` its model would. The restart
    // refits that baseline warm on the estimation half, and the refit can
    // trade the gain on the selection part away (a lower SSE there, a
    // worse loop elsewhere): kept only where the gain holds.
    let mut plain_fit = None;
    if let Some((mut fit, model)) = plain {
        if fit.beats_baseline {
            settings.progress.say(
                "`fit`'s baseline beats the one searched among the thesis' loop shapes: \
                 diagnosing again from it",
            );
            let mut d = diagnose_from(traces, family, &asked, settings, Some(&model))?;
            let restarted = &d.selection.baseline.best;
            fit.restarted_selection_fit_percent = Some(d.baseline().selection_fit_percent);
            fit.started_from =
                restarted.sel_rmse < (1.0 - settings.min_relative) * fit.searched_selection_rmse;
            if fit.started_from {
                d.from = Some(PLAIN_FIT_START.to_string());
                d.plain_fit = Some(fit);
                return Ok(d);
            }
            settings.progress.say(
                "refitted from `fit`'s baseline, the diagnosis' baseline lost its gain on the \
                 selection part: keeping the searched one",
            );
        }
        plain_fit = Some(fit);
    }

    // The final chain as `fit --effects` fits it: the final parameters
    // when it scores better on the selection part.
    let last = data.with_model(&selection.final_model);
    settings
        .progress
        .say("fitting the final chain as `fit --effects` does, and its size intervals");
    let as_fit = as_fit_of(&last, traces, &selection, settings, from)?;
    let final_params: Vec<f64> = match &as_fit {
        Some(a) if a.kept => a.params.clone(),
        _ => selection.final_fit.params.clone(),
    };

    let models = models_along_the_way(&data, &selection, family, &final_params);
    // The test part is read here, once, after every choice is made.
    let steps = steps_of(&data, &models, floor);

    let size_intervals = selection
        .verdict
        .iter()
        .map(|&e| interval::size_interval(&last, &searches, &final_params, e))
        .collect::<anyhow::Result<_>>()?;
    let refits = refits_of(&data, &last, &searches, settings, &final_params)?;

    let ia = family.linear_indices()[0];
    let base_model = &selection.baseline_model;
    let base = &selection.baseline.best;
    let first = data.with_model(base_model);
    let segments = selection_segments(traces, &first, &base.params);
    let final_segments = selection_segments(traces, &last, &final_params);
    let min_len = segments.iter().map(|s| s.residual.len()).min().unwrap_or(0);
    let settle = settle_samples(base.params[ia], min_len);
    let place = locate::analyse(&segments, settle);
    let spectrum = residual_spectrum(&segments);
    let final_spectrum = residual_spectrum(&final_segments);

    let base_pred = first.predict(&base.params);
    let bound = explainable_bound(traces, &data, &base_pred, floor)?;
    let remaining = explainable::signature(
        &locate::analyse(&final_segments, settle),
        final_spectrum
            .as_ref()
            .and_then(|s| s.peaks.first().copied()),
    );
    let mut explainable = explainable::judge(bound, &steps, remaining, settings.floor_margin);
    // With no effect tried, nothing was found wanting: the verdict says
    // nothing of the catalogue, not that it fails to explain the gap.
    explainable.not_explained &= !selection.rounds.is_empty();

    let last_pred = last.predict(&final_params);
    let curves = curves_of(traces, &data, &base_pred, &last_pred);
    let baseline_model = first.fitted_model(&base.params);
    let final_model = last.fitted_model(&final_params);
    Ok(Diagnosis {
        from: from.map(|_| "the start model".to_string()),
        baseline_model,
        final_model,
        family,
        datasets: traces.iter().map(|t| t.source.clone()).collect(),
        columns: traces.first().map(Trace::columns),
        parts: data.parts.clone(),
        dt: data.records.ctx[0].dt,
        noise_floor_rmse: floor,
        noise_floor_lag1: floor_lag1,
        locate: place,
        selection,
        steps,
        size_intervals,
        refits,
        explainable,
        spectrum,
        final_spectrum,
        curves,
        as_fit,
        final_params,
        asked,
        not_tried,
        transfers: Vec::new(),
        baseline_on_edge,
        plain_fit,
        repeats: Vec::new(),
    })
}

/// The loop-shape parameters of `params`, `data`'s baseline, that ended on
/// or near ([`crate::fit::edge::NEAR_EDGE`]) the edge of the diagnosis'
/// box. That box is the thesis' hull, loop shapes made for its muscle's
/// stroke of about 40 mm, in mm or the length unit the output column's
/// name states ([`crate::fit::problem::shape_per_output_unit`]): a sharper
/// loop (a shorter stroke, an output in an unstated unit other than mm)
/// lies outside it, and a baseline stopped at its edge leaves the effects
/// named from it to stand in for the loop.
/// The classic `β`'s floor, 0, is the bounded class's own edge, where a
/// loop may rightly sit, and is left out.
fn loop_shape_on_edge(data: &FitProblem, params: &[f64]) -> Vec<ActiveBound> {
    let family = data.model.family;
    let shape: Vec<String> = family.params()[shape_range(family)]
        .iter()
        .map(|p| p.name.to_string())
        .collect();
    active_bounds(data, params)
        .into_iter()
        .filter(|b| shape.contains(&b.param))
        .filter(|b| !(family == Family::Classic && b.param == "beta" && b.bound == Side::Lower))
        .collect()
}

/// An effect of the catalogue the diagnosis was asked to try and left out,
/// and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NotTried {
    pub effect: Effect,
    pub why: &'static str,
}

/// The note a diagnosis of `traces` owes its user where the first record's
/// output column names no length unit: the loop-shape box, made for a
/// stroke of about 40 mm, then takes it in mm, and a record in metres
/// gets another verdict.
pub fn assumed_unit_note(traces: &[Trace]) -> Option<String> {
    let first = traces.first()?;
    let output = &first.output_name;
    if crate::data::units::stated_length_in_mm(output).is_some() {
        return None;
    }
    Some(format!(
        "the output column `{output}` names no length unit, so the diagnosis' loop-shape box, \
         made for a stroke of about 40 mm, takes it in mm (its first record spans {}); if it \
         is in another, name the unit (`{output}_m`, `{output} [cm]`)",
        crate::report::number::significant(crate::data::range(&first.output), 3)
    ))
}

/// The effects of `effects` the selection tries on `traces`, and those it
/// leaves out, with why:
/// - an effect named (not the default catalogue's, which tries what
///   applies and leaves the rest silently) that needs more datasets than
///   there are (`load`, a gain for each dataset after the first);
/// - one whose physical effect `from`'s chain already holds (`--from`);
/// - `load` where two datasets are pieces of one recording
///   (`--split-gaps`): they share its muscle and its load, and a gain
///   between them would name a change of the muscle between the pieces (a
///   set, a softening) as a change of load.
fn tried_effects(
    traces: &[Trace],
    effects: &[Effect],
    from: Option<&Model>,
) -> (Vec<Effect>, Vec<NotTried>) {
    let mut recordings: Vec<&str> = traces
        .iter()
        .filter_map(|t| t.cut_from.as_deref())
        .collect();
    let pieces = recordings.len();
    recordings.sort_unstable();
    recordings.dedup();
    let one_recording = recordings.len() < pieces;
    let held = from.map_or(&[][..], |m| m.effects());
    // The default catalogue tries what applies; an effect named yourself
    // that cannot apply is said.
    let named = effects != Effect::by_default().as_slice();
    let (mut tried, mut not_tried) = (Vec::new(), Vec::new());
    for &effect in effects {
        let why = if !effect.applicable(traces.len()) {
            if !named {
                continue;
            }
            Some("it is a difference between datasets, and there is one: give two or more files")
        } else if held.iter().any(|h| h.physical() == effect.physical()) {
            Some("the --from model's chain holds it already")
        } else if effect == Effect::Load && one_recording {
            Some("some datasets are pieces of one recording (cut at its gaps): they share its load")
        } else {
            None
        };
        match why {
            Some(why) => not_tried.push(NotTried { effect, why }),
            None => tried.push(effect),
        }
    }
    (tried, not_tried)
}

/// An error where the baseline diverges on the selection part for every
/// seed: then there is no gap to diagnose, and the error says what to try.
fn check_baseline(selection: &Selection, family: Family, traces: &[Trace]) -> anyhow::Result<()> {
    anyhow::ensure!(
        selection.baseline.best.sel_rmse.is_finite(),
        "the {family} baseline fitted on the estimation half diverges on the selection part \
         for every seed ({}), so there is no gap to diagnose; try fewer datasets at a time, \
         more --seeds, or the other --baseline",
        sources(traces)
    );
    Ok(())
}

/// The final chain of `selection` refitted as `fit --effects` fits it, on
/// `last`, its problem: left out, like the refits, with `--scratch-seeds
/// 0`, and from a start model (`--from`, or `fit`'s fit of the baseline
/// started again from), since `fit` fits in the record's own coordinates,
/// not the start model's.
fn as_fit_of(
    last: &FitProblem,
    traces: &[Trace],
    selection: &Selection,
    settings: &Settings,
    from: Option<&Model>,
) -> anyhow::Result<Option<as_fit::AsFit>> {
    let saved = last.fitted_model(&selection.final_fit.params);
    Ok(match from {
        None if settings.scratch_seeds > 0 => as_fit::refit(
            last,
            &traces[0],
            (&selection.final_fit.params, &saved),
            settings,
        )?,
        _ => None,
    })
}

/// The noise floor the rule compares against: a property of the sensor,
/// measured on every sample but the test part's (the estimation half and
/// the selection blocks; the blocks alone are too few on a short record,
/// where steps inflate the second differences).
fn noise_floor_of(data: &FitProblem) -> (f64, f64) {
    let outputs: Vec<Vec<f64>> = data
        .records
        .whole
        .iter()
        .zip(&data.parts)
        .flat_map(|(w, p)| {
            std::iter::once(&p.estimation)
                .chain(&p.selection)
                .map(|r| w.y[r.clone()].iter().map(|&v| v as f64).collect())
        })
        .collect();
    let refs: Vec<&[f64]> = outputs.iter().map(|v| v.as_slice()).collect();
    (
        locate::noise_floor(&refs),
        locate::second_difference_lag1(&refs),
    )
}

/// The models along the way, each with its parameters: the baseline, the
/// start model where the selection started from one, then the model after
/// each accepted effect, each with the best fit of it any later round
/// found, the last with the final parameters.
fn models_along_the_way<'a>(
    data: &FitProblem,
    selection: &'a Selection,
    family: Family,
    final_params: &'a [f64],
) -> Vec<(ModelDescription, &'a [f64])> {
    let base_model = &selection.baseline_model;
    let base = &selection.baseline.best;
    let mut models: Vec<(ModelDescription, &[f64])> = vec![(base_model.clone(), &base.params)];
    if let Some(given) = &selection.given_fit {
        // The first round may have found a better fit of the start model.
        let fit = selection
            .rounds
            .first()
            .and_then(|round| round.rebased.last())
            .map_or(&given.best, |f| &f.best);
        let model = ModelDescription::new(family, selection.given.clone(), data.datasets());
        models.push((model, &fit.params));
    }
    for (r, round) in selection.rounds.iter().enumerate() {
        if let Some(c) = round
            .candidates
            .iter()
            .find(|c| Some(c.effect) == round.accepted)
        {
            // The next round may have found a better fit of this model.
            let fit = selection
                .rounds
                .get(r + 1)
                .and_then(|next| next.rebased.last())
                .map_or(&c.fit.best, |f| &f.best);
            models.push((c.model.clone(), &fit.params));
        }
    }
    if let Some(last) = models.last_mut() {
        last.1 = final_params;
    }
    models
}

/// The final model fitted again from scratch on `last`, its problem,
/// against its final parameters: whether the estimation data settle its
/// validation fit.
fn refits_of(
    data: &FitProblem,
    last: &FitProblem,
    searches: &Searches,
    settings: &Settings,
    final_params: &[f64],
) -> anyhow::Result<Option<refits::Refits>> {
    let scratch = fitting::scratch_fits(last, searches, settings, REFIT_SALT)?;
    let final_fit = fitting::ScoredFit {
        est_sse: last.est_sse(final_params),
        sel_rmse: last.selection_rmse(final_params),
        params: final_params.to_vec(),
    };
    Ok(refits::Refits::compare(
        &final_fit,
        &scratch,
        |f| last.selection(&f.params).fit_percent,
        data.est_samples(),
    ))
}

/// Where `theta` of `problem` misses, on the selection blocks: one segment
/// of input and residual per block, named after its trace.
fn selection_segments(
    traces: &[Trace],
    problem: &FitProblem,
    theta: &[f64],
) -> Vec<locate::Segment> {
    problem
        .selection_residuals(theta)
        .into_iter()
        .map(|(i, r, residual)| locate::Segment {
            name: traces[i].source.clone(),
            dt: traces[i].dt(),
            input: traces[i].input[r].to_vec(),
            residual,
        })
        .collect()
}

/// How much of the baseline's gap a flexible model of its residual closes:
/// the bound from the baseline's predictions `base_pred` over the records.
fn explainable_bound(
    traces: &[Trace],
    data: &FitProblem,
    base_pred: &[Vec<f32>],
    floor: f64,
) -> anyhow::Result<explainable::Bound> {
    let as_f64 = |v: &[f32]| v.iter().map(|&x| x as f64).collect::<Vec<f64>>();
    let (pred, meas): (Vec<_>, Vec<_>) = base_pred
        .iter()
        .zip(&data.records.whole)
        .map(|(p, w)| (as_f64(p), as_f64(&w.y)))
        .unzip();
    let signals: Vec<explainable::Signals> = traces
        .iter()
        .enumerate()
        .map(|(i, t)| explainable::Signals {
            input: &t.input,
            prediction: &pred[i],
            measured: &meas[i],
            est_end: data.parts[i].estimation.end,
            scored: &data.parts[i].selection,
        })
        .collect();
    explainable::bound(&signals, floor, &ridge::RidgeSettings::default())
}

/// Second-half curves of every dataset in absolute units: the measured
/// output, the baseline's prediction `base_pred` and the final model's
/// `last_pred`.
fn curves_of(
    traces: &[Trace],
    data: &FitProblem,
    base_pred: &[Vec<f32>],
    last_pred: &[Vec<f32>],
) -> Vec<Curves> {
    traces
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let s = data.records.val_start[i];
            let ym = data.records.whole[i].y_mean;
            Curves {
                name: t.source.clone(),
                t: t.t[s..].to_vec(),
                input: t.input[s..].to_vec(),
                measured: t.output[s..].to_vec(),
                baseline: base_pred[i][s..].iter().map(|&v| v as f64 + ym).collect(),
                last: last_pred[i][s..].iter().map(|&v| v as f64 + ym).collect(),
            }
        })
        .collect()
}

/// Each of `models` (the baseline first) scored on every part: the second
/// half, the selection part and, read here for the first time, the test
/// part; the gap each closes measured from the baseline's on each part.
fn steps_of(data: &FitProblem, models: &[(ModelDescription, &[f64])], floor: f64) -> Vec<Step> {
    let scored: Vec<_> = models
        .iter()
        .map(|(m, theta)| {
            let problem = data.with_model(m);
            (
                m.effects.clone(),
                problem.validate(theta),
                problem.selection(theta),
                problem.test(theta),
            )
        })
        .collect();
    let (base_sel, base_test) = (scored[0].2.rmse, scored[0].3.rmse);
    scored
        .into_iter()
        .map(|(effects, val, sel, test)| Step {
            effects,
            val_rmse: val.rmse,
            val_fit_percent: val.fit_percent,
            selection_rmse: sel.rmse,
            selection_fit_percent: sel.fit_percent,
            test_rmse: test.rmse,
            test_fit_percent: test.fit_percent,
            optimism_points: sel.fit_percent - test.fit_percent,
            gap_closed: accept::gap_closed(base_sel, sel.rmse, floor),
            test_gap_closed: accept::gap_closed(base_test, test.rmse, floor),
        })
        .collect()
}

/// The start of a selection from `model`: its chain over `datasets`
/// datasets and its parameters; an error where it cannot start one here.
fn start_of(
    model: &Model,
    family: Family,
    datasets: usize,
) -> anyhow::Result<(ModelDescription, Vec<f64>)> {
    anyhow::ensure!(
        model.base.family == family,
        "the start model is {}, the baseline asked for {family}",
        model.base.family
    );
    let augmented = ModelDescription::new(family, model.effects().to_vec(), datasets);
    let theta = model.theta();
    anyhow::ensure!(
        theta.len() == augmented.dim(),
        "the start model was fitted on {} datasets together (its `load` effect has a gain for \
         each); diagnose it with as many files",
        model.chain.as_ref().map_or(1, |c| c.datasets)
    );
    Ok((augmented, theta))
}

/// Welch spectrum of the residual of `segments`, those sampled at the first
/// one's rate (within 1 %) averaged together.
fn residual_spectrum(segments: &[locate::Segment]) -> Option<spectrum::Spectrum> {
    let dt = segments.first()?.dt;
    let series: Vec<&[f64]> = segments
        .iter()
        .filter(|s| same_step(s.dt, dt))
        .map(|s| s.residual.as_slice())
        .collect();
    spectrum::welch(&series, dt, &spectrum::Settings::default())
}

#[cfg(test)]
mod tests {
    use super::{Effect, FitProblem, Side, Trace, loop_shape_on_edge, tried_effects};
    use crate::model::Family;

    /// The diagnosis' problem on a short stair-like record.
    fn problem() -> FitProblem {
        let p: Vec<f64> = (0..800).map(|k| 0.1 * ((k / 100) % 4) as f64).collect();
        // A first-order lag, with a ripple that keeps the regressors apart.
        let mut y = vec![0.0; p.len()];
        for k in 1..p.len() {
            y[k] = 0.9 * y[k - 1] + 4.0 * p[k - 1] + 0.01 * (k as f64 * 0.7).sin();
        }
        FitProblem::diagnosis(
            &[Trace::uniform("stair", 0.1, p, y)],
            Family::Classic,
            None,
            None,
        )
        .unwrap()
    }

    #[test]
    fn a_baseline_loop_shape_on_the_boxs_edge_is_flagged_but_not_the_class_floor() {
        let data = problem();
        let (lower, upper) = (&data.space.lower, &data.space.upper);
        let [beta, gamma] = ["beta", "gamma"].map(|n| Family::Classic.index_of(n).unwrap());
        let mut params = data.centre();
        params[beta] = lower[beta];
        assert_eq!(lower[beta], 0.0, "the bounded class's floor");
        // Inside the box but for β on its floor: nothing to say.
        assert!(loop_shape_on_edge(&data, &params).is_empty());
        params[gamma] = upper[gamma];
        let edges = loop_shape_on_edge(&data, &params);
        assert_eq!(edges.len(), 1, "{edges:?}");
        assert_eq!(
            (edges[0].param.as_str(), edges[0].bound),
            ("gamma", Side::Upper)
        );
        // The linear part's edges are not the loop's.
        params[gamma] = 0.5 * (lower[gamma] + upper[gamma]);
        let ia = Family::Classic.linear_indices()[0];
        params[ia] = upper[ia];
        assert!(loop_shape_on_edge(&data, &params).is_empty());
    }

    /// A short trace, cut from `recording` where that is given.
    fn piece(source: &str, recording: Option<&str>) -> Trace {
        Trace {
            cut_from: recording.map(String::from),
            ..Trace::uniform(source, 0.01, vec![0.0; 4], vec![0.0; 4])
        }
    }

    #[test]
    fn load_is_not_tried_between_pieces_of_one_recording() {
        let effects = [Effect::Delay, Effect::Load, Effect::Set];
        // Two files, whole or each one piece: a load per file is tried.
        for traces in [
            vec![piece("a.csv", None), piece("b.csv", None)],
            vec![piece("a.csv[1]", Some("a.csv")), piece("b.csv", None)],
            vec![
                piece("a.csv[2]", Some("a.csv")),
                piece("b.csv[1]", Some("b.csv")),
            ],
        ] {
            let (tried, not_tried) = tried_effects(&traces, &effects, None);
            assert_eq!(tried, effects);
            assert!(not_tried.is_empty());
        }
        // Two pieces of one file: its load is one, whatever else is there.
        let traces = [
            piece("a.csv[1]", Some("a.csv")),
            piece("b.csv", None),
            piece("a.csv[2]", Some("a.csv")),
        ];
        let (tried, not_tried) = tried_effects(&traces, &effects, None);
        assert_eq!(tried, [Effect::Delay, Effect::Set]);
        assert_eq!(not_tried.len(), 1);
        assert_eq!(not_tried[0].effect, Effect::Load);
        assert!(not_tried[0].why.contains("pieces of one recording"));
        // Nothing to leave out where `load` was not asked for.
        let (tried, not_tried) = tried_effects(&traces, &[Effect::Set], None);
        assert_eq!((tried, not_tried.len()), (vec![Effect::Set], 0));
    }

    /// What cannot be tried is said, not skipped: a load on one dataset,
    /// and an effect the `--from` model's chain holds already.
    #[test]
    fn effects_that_cannot_be_tried_are_named_with_why() {
        let one = [piece("a.csv", None)];
        // The default catalogue leaves `load` out on one file without a word.
        let (tried, not_tried) = tried_effects(&one, &Effect::by_default(), None);
        assert!(!tried.contains(&Effect::Load) && not_tried.is_empty());
        let (tried, not_tried) = tried_effects(&one, &[Effect::Load, Effect::Set], None);
        assert_eq!(tried, [Effect::Set]);
        assert_eq!(not_tried.len(), 1);
        assert!(
            not_tried[0].why.contains("there is one"),
            "{}",
            not_tried[0].why
        );
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures/generalized_creep_before_x_s.json");
        let model = crate::model::ModelFile::load(&path)
            .unwrap()
            .model()
            .unwrap();
        let creep = model.effects()[0];
        let (tried, not_tried) = tried_effects(&one, &[creep, Effect::Set], Some(&model));
        assert_eq!(tried, [Effect::Set]);
        assert_eq!(not_tried[0].effect, creep);
        assert!(not_tried[0].why.contains("--from"), "{}", not_tried[0].why);
    }
}
