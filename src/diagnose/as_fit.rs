//! The final chain fitted as `fit --effects` fits it: `fit`'s search from
//! scratch in its own box, and its warm start from the diagnosis' own fit,
//! the lower estimation SSE kept ([`FitRun::also_from`]). It is a second
//! candidate for the final parameters, chosen, like every other choice, on
//! the selection part.
//!
//! Why: the diagnosis reaches its final fit through warm-started rounds
//! with small populations, and `fit` searches a thousand candidates from
//! scratch. Where the estimation half does not settle the model, the two
//! land in different basins of nearly the same estimation SSE that
//! validate points apart (as on the Cavatappi 300 g record:
//! docs/ARCHITECTURE.md, "Warm starts"). A user who refits the
//! verdict with `fit --effects` gets `fit`'s; the report gives both, and
//! the final model is whichever scores better on the selection part.

use serde::Serialize;

use super::settings::Settings;
use super::transfer::run_stoppable;
use crate::data::Trace;
use crate::fit::problem::FitProblem;
use crate::fit::run::{FitRun, FitTarget};
use crate::fit::settings::FitSettings;
use crate::model::Model;

/// The final chain as `fit --effects` fits it, against the selection's fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AsFit {
    /// Its parameters (the diagnosis' vector layout).
    pub params: Vec<f64>,
    /// Its free-run SSE on the estimation half.
    pub est_sse: f64,
    /// Its RMSE on the selection part, and the selection's own fit's.
    pub selection_rmse: f64,
    pub selection_fit_rmse: f64,
    /// Its fit % over the second half: what `fit --effects` reports.
    pub val_fit_percent: f64,
    /// Whether it scored better on the selection part and became the final
    /// model.
    pub kept: bool,
}

/// The final model of `problem` (fitted by the selection at `params`,
/// `saved` as a model file holds it) fitted again as `fit --effects` fits
/// it on the problem's one record; `None` where `fit` cannot fit it so (several records, or a
/// chain with an effect one record cannot hold) or where its result is
/// not a model the diagnosis admits. The diagnosis' `settings` give the
/// seed, the backend and the stop flag.
pub fn refit(
    problem: &FitProblem,
    trace: &Trace,
    (params, saved): (&[f64], &Model),
    settings: &Settings,
) -> anyhow::Result<Option<AsFit>> {
    let model = &problem.model;
    if problem.datasets() != 1 || !model.effects.iter().all(|e| e.applicable(1)) {
        return Ok(None);
    }
    let fit_settings = FitSettings::staged(settings.seed);
    let what = FitTarget::chain(model.family, &model.effects);
    let fit = FitRun::new(
        std::slice::from_ref(trace),
        &what,
        &fit_settings,
        None,
        None,
        &|_| (),
    )?
    .also_from(saved, 0.0, &fit_settings)?;
    let (_, outcome) = run_stoppable(fit, settings)?;
    let theta = outcome.params;
    if theta.len() != params.len() || !problem.admits(&theta) {
        return Ok(None);
    }
    let selection_rmse = problem.selection_rmse(&theta);
    let selection_fit_rmse = problem.selection_rmse(params);
    Ok(Some(AsFit {
        est_sse: problem.est_sse(&theta),
        val_fit_percent: problem.validate(&theta).fit_percent,
        kept: selection_rmse < selection_fit_rmse,
        selection_rmse,
        selection_fit_rmse,
        params: theta,
    }))
}
