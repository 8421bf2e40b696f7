//! `fit`'s own fit of the baseline, scored where the diagnosis' baseline
//! is: whether the diagnosis starts from the best baseline the tool has.
//!
//! The diagnosis fits its baseline in the thesis' box of loop shapes
//! (`FitProblem::diagnosis`), made for a stroke of about 40 mm; `fit`
//! searches a box in the data's own scale. A muscle whose loop lies outside
//! the thesis' box (a braid with much more friction closes its loop within
//! a fraction of a millimetre) leaves the diagnosis' baseline in another,
//! worse basin, often not on the box's edge, and the effects then named
//! stand in for the loop the baseline could not reach. Where `fit`'s fit
//! is the better one on both the estimation halves and the selection part,
//! the diagnosis runs again from it (`super::diagnose_from`) and keeps that
//! run where its warm refit of the baseline still beats the searched one on
//! the selection part ([`PlainFit::started_from`]).

use serde::Serialize;

use super::fitting::ScoredFit;
use super::likelihood::indistinguishable_up_to;
use super::settings::Settings;
use crate::data::Trace;
use crate::fit::objective::{GENERATIONS, POPULATION, staged_plan};
use crate::fit::problem::FitProblem;
use crate::fit::run::run_fit;
use crate::fit::searches::Searches;
use crate::model::effects::ModelDescription;
use crate::model::{Flow, Loop, Model, Switching};
use crate::optim::Algorithm;
use crate::optim::engine::StopRules;

/// `mckibben fit`'s default fit of the baseline's family on the same
/// estimation halves, scored as the diagnosis' baseline is.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlainFit {
    /// Its free-run SSE on the estimation halves, the cost both fits
    /// minimise.
    pub est_sse: f64,
    pub selection_rmse: f64,
    pub selection_fit_percent: f64,
    /// The baseline the diagnosis searched in its own box, which this fit
    /// is judged against, scored the same way.
    pub searched_est_sse: f64,
    pub searched_selection_rmse: f64,
    pub searched_selection_fit_percent: f64,
    /// Whether it beats that baseline on both parts: on the estimation
    /// halves past the likelihood-ratio threshold (the search missed a fit
    /// it could tell apart), and on the selection part by more than an
    /// effect must gain to be named ([`Settings::min_relative`]). The
    /// diagnosis then runs again from it.
    pub beats_baseline: bool,
    /// Where it beats: the selection fit % of the baseline the diagnosis
    /// refitted warm from it.
    pub restarted_selection_fit_percent: Option<f64>,
    /// Whether the diagnosis started from it: that refit kept a gain over
    /// the searched baseline on the selection part of more than
    /// [`Settings::min_relative`]. Where it did not, the diagnosis is the
    /// searched baseline's.
    pub started_from: bool,
}

/// `fit`'s fit of `data`'s family on `traces` (its box, bounded loops, the
/// default switching, population and generations, `settings.seed`: what
/// `mckibben fit` prints for one record), scored on `data`'s estimation
/// halves and selection part and judged against the diagnosis' baseline
/// `baseline`; with the model it fitted, in the records' own coordinates
/// as a `--from` model is. `data` is in those coordinates too, as `fit`'s
/// problem is, so the parameters carry over unchanged; `None` where `fit`
/// could not set its box on these records or every candidate diverged.
pub fn plain_fit(
    traces: &[Trace],
    data: &FitProblem,
    searches: &Searches,
    settings: &Settings,
    baseline: &ScoredFit,
) -> anyhow::Result<Option<(PlainFit, Model)>> {
    let family = data.model.family;
    // The diagnosis' own checks of the records ran already; a box `fit`
    // cannot set here leaves the comparison out, not the diagnosis.
    let Ok(problem) = FitProblem::with_box(
        traces,
        family,
        Flow::Joint,
        None,
        false,
        (Loop::Bounded, Switching::default()),
        &[],
    ) else {
        return Ok(None);
    };
    let plan = staged_plan(
        &problem,
        Algorithm::De.staged_settings(POPULATION),
        POPULATION,
        GENERATIONS,
    );
    let (_, outcome) =
        searches.run(|ev| run_fit(&problem, plan, settings.seed, StopRules::default(), ev))?;
    if outcome.params.is_empty() {
        return Ok(None);
    }
    let scoring = data.with_model(&ModelDescription::new(family, Vec::new(), data.datasets()));
    let est_sse = scoring.est_sse(&outcome.params);
    let selection = scoring.selection(&outcome.params);
    let tells_apart = indistinguishable_up_to(est_sse, scoring.est_samples()) < baseline.est_sse;
    let gains = selection.rmse < (1.0 - settings.min_relative) * baseline.sel_rmse;
    let searched = scoring.selection(&baseline.params);
    let fit = PlainFit {
        est_sse,
        selection_rmse: selection.rmse,
        selection_fit_percent: selection.fit_percent,
        searched_est_sse: baseline.est_sse,
        searched_selection_rmse: baseline.sel_rmse,
        searched_selection_fit_percent: searched.fit_percent,
        beats_baseline: tells_apart && gains,
        restarted_selection_fit_percent: None,
        started_from: false,
    };
    Ok(Some((fit, problem.fitted_model(&outcome.params))))
}
