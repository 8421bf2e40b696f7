//! A given chain fitted as the diagnosis builds its final model: the
//! baseline from scratch, then each effect in turn warm-started from the
//! model before it (the new effect's parameters first, then everything;
//! its size profiled), the first also from scratch through the predictor.
//! No selection: every effect is kept whatever it gains.
//!
//! Why: a search of the whole chain's box from scratch is a lottery that
//! the diagnosis' warm-started rounds do not play. On the Cavatappi
//! 500 g record `fit --effects creep,inertia:ringing,rate` from scratch
//! ended at estimation SSE 27.6 where the diagnosis' chain reached 15.7
//! (docs/RESULTS.md, "The diagnosed model, end to end").

use super::data::Data;
use super::fitting::{Start, fit_seeds, fit_with_effect, scratch_fits};
use super::settings::{Interrupted, Settings, StopFlag};
use super::{Augmented, Effect, model_of};
use crate::data::Trace;
use crate::eval::Backend;
use crate::fit::run::{Fit, FitSettings};
use crate::model::{Family, Flow, Model};

/// Salt of the chain's seeds, apart from the selection's (100 per round)
/// and the refits' (9 000).
const CHAIN_SALT: u64 = 20_000;

/// Fits `family` followed by `effects`, in that order, on `traces` with
/// the diagnosis' `settings`; returns the model with its estimation SSE.
pub fn fit_chain(
    traces: &[Trace],
    family: Family,
    effects: &[Effect],
    settings: &Settings,
) -> anyhow::Result<(Model, f64)> {
    let data = Data::new(traces, settings.blocks)?
        .scored_on(crate::eval::open(settings.backend)?)
        .stopped_by(settings.stop.clone());
    let mut model = Augmented::new(family, Vec::new(), data.datasets());
    let mut best = fit_seeds(&data, &model, Start::Scratch, settings, CHAIN_SALT)?.best;
    for (k, &effect) in effects.iter().enumerate() {
        let salt = CHAIN_SALT + 10 * (k as u64 + 1);
        // As the diagnosis' first round: fits of the first effect's model
        // from scratch among the seeds, which a baseline that compensated
        // for the effect cannot walk back to.
        let scratch = if k == 0 {
            scratch_fits(&data, &model.with(effect), settings, salt + 5)?
        } else {
            Vec::new()
        };
        let (next, fit) = fit_with_effect(
            &data,
            &model,
            &best.params,
            effect,
            settings,
            salt,
            &scratch,
        )?;
        (model, best) = (next, fit.best);
    }
    Ok((model_of(&data, traces, &model, &best.params), best.est_sse))
}

/// `fit` with the chain fitted here as its second start
/// ([`Fit::also_from`]) where it fits effects from scratch: `mckibben fit
/// --effects LIST` and Python's `fit(effects=…)`. Unchanged otherwise (no
/// effects, a warm start, the thesis' flow), and when `stop` is raised
/// while the chain is built. The chain's searches use the diagnosis'
/// settings with the fit's seed, on `backend`.
pub fn with_chain_start(
    fit: Fit,
    trace: &Trace,
    settings: &FitSettings,
    backend: Backend,
    stop: StopFlag,
) -> anyhow::Result<Fit> {
    let task = &fit.task;
    if task.effects.is_empty() || fit.start.is_some() || task.flow != Flow::Joint {
        return Ok(fit);
    }
    let chain_settings = Settings {
        seed: settings.seed,
        backend,
        stop,
        ..Settings::default()
    };
    let (family, effects) = (task.family, task.effects.clone());
    let started = std::time::Instant::now();
    match fit_chain(
        std::slice::from_ref(trace),
        family,
        &effects,
        &chain_settings,
    ) {
        Ok((model, _)) => fit.also_from(&model, started.elapsed().as_secs_f64(), settings),
        Err(e) if e.is::<Interrupted>() => Ok(fit),
        Err(e) => Err(e),
    }
}
