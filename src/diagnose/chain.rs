//! A given chain fitted as the diagnosis builds its final model: the
//! baseline from scratch, then each effect in turn warm-started from the
//! model before it (the new effect's parameters first, then everything;
//! its size profiled), the first also from scratch through the predictor.
//! No selection: every effect is kept whatever it gains.
//!
//! Why: a search of the whole chain's box from scratch is a lottery that
//! the diagnosis' warm-started rounds do not play: on the Cavatappi
//! 500 g record `fit --effects creep,inertia:ringing,rate` from scratch
//! ends far above the estimation SSE the diagnosis' chain reaches
//! (docs/RESULTS.md, "The diagnosed model, end to end").

use super::Effect;
use super::fitting::{Start, fit_seeds, fit_with_effect, scratch_fits};
use super::settings::{Interrupted, Settings};
use crate::data::Trace;
use crate::eval::Backend;
use crate::fit::problem::FitProblem;
use crate::fit::run::FitRun;
use crate::fit::searches::StopFlag;
use crate::fit::settings::FitSettings;
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
    let mut problem = FitProblem::diagnosis(traces, family, None, settings.blocks)?;
    let searches = settings.searches()?;
    let mut best = fit_seeds(&problem, &searches, Start::Scratch, settings, CHAIN_SALT)?.best;
    for (k, &effect) in effects.iter().enumerate() {
        let salt = CHAIN_SALT + 10 * (k as u64 + 1);
        // As the diagnosis' first round: fits of the first effect's model
        // from scratch among the seeds, which a baseline that compensated
        // for the effect cannot walk back to.
        let scratch = if k == 0 {
            scratch_fits(
                &problem.with_model(&problem.model.with(effect)),
                &searches,
                settings,
                salt + 5,
            )?
        } else {
            Vec::new()
        };
        let (next, fit) = fit_with_effect(
            &problem,
            &searches,
            &best.params,
            effect,
            settings,
            salt,
            &scratch,
        )?;
        (problem, best) = (next, fit.best);
    }
    Ok((problem.fitted_model(&best.params), best.est_sse))
}

/// `fit` with the chain fitted here as its second start
/// ([`FitRun::also_from`]) where it fits effects from scratch: `mckibben fit
/// --effects LIST` and Python's `fit(effects=…)`. Unchanged otherwise (no
/// effects, a warm start, the thesis' flow), and without the second start
/// when `stop` is raised or the fit's time budget runs out while the chain
/// is built (the seconds spent are the fit's all the same:
/// [`FitRun::built_in_s`]). The chain's searches use the diagnosis'
/// settings with the fit's seed, on `backend`.
pub fn with_chain_start(
    fit: FitRun,
    traces: &[Trace],
    settings: &FitSettings,
    backend: Backend,
    stop: StopFlag,
) -> anyhow::Result<FitRun> {
    let problem = &fit.problem;
    if problem.model.effects.is_empty() || fit.start.is_some() || problem.flow != Flow::Joint {
        return Ok(fit);
    }
    // The build's own flag, raised by `stop` or at the end of the budget;
    // `stop` itself is the caller's, never raised here.
    let build = StopFlag::default();
    let chain_settings = Settings {
        seed: settings.seed,
        backend,
        stop: build.clone(),
        ..Settings::default()
    };
    let (family, effects) = (problem.model.family, problem.model.effects.clone());
    let started = std::time::Instant::now();
    let done = std::sync::atomic::AtomicBool::new(false);
    let built = std::thread::scope(|scope| {
        scope.spawn(|| {
            let budget = settings.stops.time_budget_s;
            while !done.load(std::sync::atomic::Ordering::SeqCst) {
                let spent = started.elapsed().as_secs_f64();
                if stop.raised() || budget.is_some_and(|b| spent >= b) {
                    build.raise();
                    return;
                }
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
        });
        let built = fit_chain(traces, family, &effects, &chain_settings);
        done.store(true, std::sync::atomic::Ordering::SeqCst);
        built
    });
    let built_in_s = started.elapsed().as_secs_f64();
    match built {
        Ok((model, _)) => fit.also_from(&model, built_in_s, settings),
        Err(e) if e.is::<Interrupted>() => {
            let mut fit = fit;
            fit.built_in_s = built_in_s;
            Ok(fit)
        }
        Err(e) => Err(e),
    }
}
