//! Which effect: fit the baseline, then every catalogued effect as an
//! addition to it, score each on the selection part, accept by a stated rule
//! and repeat on the remainder (forward selection).
//! The acceptance rule is [`accept`](super::accept)'s.

use rayon::prelude::*;
use serde::Serialize;

use super::accept::{Candidate, Yardstick, judge_all};
use super::effects::{Effect, ModelDescription};
use super::fitting::{
    ScoredFit, SeededFit, Start, fit_seeds, fit_seeds_with, fit_with_effect, scratch_fits,
};
use super::hints;
use super::settings::Settings;
use crate::fit::problem::FitProblem;
use crate::fit::searches::Searches;
use crate::model::Family;

/// How many times a round may replace the current model by a better refit
/// found through a candidate (see [`select`]).
pub const MAX_REBASES: usize = 2;

/// Seed salt of the start model's refit (`diagnose --from`), apart from the
/// baseline's (0) and the rounds' (100 per round).
const GIVEN_SALT: u64 = 1;

/// One round of forward selection.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Round {
    /// The current model refitted with the candidates' budget.
    pub current: SeededFit,
    /// Fits of the current model (without the new effect) that beat it on
    /// the estimation part and replaced it, in order: `current` itself when
    /// its seeds found a better fit, then refits started from a passing
    /// candidate's parameters; the candidates are judged against the last.
    pub rebased: Vec<SeededFit>,
    /// Candidates by validation RMSE, best first.
    pub candidates: Vec<Candidate>,
    pub accepted: Option<Effect>,
}

/// The result of the selection.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Selection {
    pub baseline_model: ModelDescription,
    pub baseline: SeededFit,
    /// The effects of the model the selection started from (`diagnose
    /// --from`): taken as given, not judged; the rounds add to them.
    pub given: Vec<Effect>,
    /// That model refitted warm on these data (`None` without effects).
    pub given_fit: Option<SeededFit>,
    pub rounds: Vec<Round>,
    /// Accepted effects in the order accepted.
    pub verdict: Vec<Effect>,
    /// Whether the selection stopped at [`Settings::max_effects`] with its
    /// last round still accepting: more effects might have passed.
    pub capped: bool,
    pub final_model: ModelDescription,
    pub final_fit: ScoredFit,
}

/// Fits the baseline, then runs forward selection over `effects`.
///
/// **Ablation.** Before the best passing candidate is accepted, the current
/// model is refitted without the effect, started from the candidate's own
/// parameters. A misspecified fit can end in a basin it cannot leave alone,
/// and a candidate's refit (warm-started, with one more parameter to move
/// along) may find a better one: then most of the candidate's gain is the
/// current model's, reached from a new start. If that refit is better on the
/// estimation part than the current model, it becomes the current model
/// (`Round::rebased`) and the round is judged again against it; the effect
/// is credited only with what the model without it cannot reach from the
/// same place. At most [`MAX_REBASES`] times a round.
///
/// **A start.** With `from` (a model and its parameters in `data`'s
/// coordinates, `diagnose --from`), the baseline is refitted warm from the
/// model's baseline parameters instead of from scratch, the model's chain
/// is refitted warm and becomes the current model, and the rounds go on
/// from it with the rest of `effects`.
pub fn select(
    data: &FitProblem,
    searches: &Searches,
    family: Family,
    effects: &[Effect],
    settings: &Settings,
    floor: f64,
    from: Option<(&ModelDescription, &[f64])>,
) -> anyhow::Result<Selection> {
    let baseline_model = ModelDescription::new(family, Vec::new(), data.datasets());
    let d = family.dim();
    let baseline_start = match from {
        Some((_, theta)) => Start::Warm {
            params: &theta[..d],
            new_from: d,
        },
        None => Start::Scratch,
    };
    let mut baseline = fit_seeds(
        &data.with_model(&baseline_model),
        searches,
        baseline_start,
        settings,
        0,
    )?;
    let mut current_model = baseline_model.clone();
    let mut current_params = baseline.best.params.clone();
    let mut final_fit = baseline.best.clone();
    let mut given_fit = None;
    if let Some((model, theta)) = from.filter(|(m, _)| !m.effects.is_empty()) {
        let start = Start::Warm {
            params: theta,
            new_from: theta.len(),
        };
        let fit = fit_seeds(
            &data.with_model(model),
            searches,
            start,
            settings,
            GIVEN_SALT,
        )?;
        current_model = model.clone();
        current_params = fit.best.params.clone();
        final_fit = fit.best.clone();
        given_fit = Some(fit);
    }
    let mut rounds = Vec::new();
    let mut verdict = Vec::new();
    let n = data.selection_samples().max(2) as f64;
    for round in 0..settings.max_effects {
        // Some effects (the ringing) are looked for only where the residual
        // rings (a spectrum per round, so only when one is among the effects).
        let rings = effects.iter().any(|&e| hints::only_on_a_peak(e))
            && hints::residual_rings(&data.with_model(&current_model), &current_params);
        let remaining: Vec<Effect> = effects
            .iter()
            .copied()
            // One realisation of each physical effect at a time.
            .filter(|e| {
                !current_model
                    .effects
                    .iter()
                    .any(|m| m.physical() == e.physical())
                    && e.applicable(data.datasets())
                    && (!hints::only_on_a_peak(*e) || rings)
            })
            .collect();
        if remaining.is_empty() {
            break;
        }
        let remaining_models: Vec<ModelDescription> =
            remaining.iter().map(|&e| current_model.with(e)).collect();
        let salt = 100 * (round as u64 + 1);
        let refit = Start::Warm {
            params: &current_params,
            new_from: current_params.len(),
        };
        // The first round adds fits from scratch, computed once per model
        // (slot 0 the current model's, slot i + 1 the i-th candidate's).
        let first_round = current_model.effects.is_empty();
        // Every fit has its own seed, so fits run side by side give the
        // same numbers as one after the other.
        let scratch: Vec<Vec<ScoredFit>> = if first_round {
            let models: Vec<&ModelDescription> = std::iter::once(&current_model)
                .chain(&remaining_models)
                .collect();
            (0..models.len())
                .into_par_iter()
                .map(|slot| {
                    scratch_fits(
                        &data.with_model(models[slot]),
                        searches,
                        settings,
                        salt + 50 + slot as u64,
                    )
                })
                .collect::<anyhow::Result<_>>()?
        } else {
            vec![Vec::new(); remaining.len() + 1]
        };
        let current = fit_seeds_with(
            &data.with_model(&current_model),
            searches,
            refit,
            settings,
            salt,
            &scratch[0],
        )?;
        let mut rebased: Vec<SeededFit> = Vec::new();
        // The refit gives the seed spread of "no new effect". Its seeds (and
        // in the first round its fits from scratch) may also reach a better
        // estimation fit of the current model than the one accepted: then
        // that is the current model, as after an ablation below (it happens
        // on the self-test: docs/lab/diagnosis.md, "Which: the effects
        // catalogue", the paragraph after "Ablation").
        if current.best.est_sse < final_fit.est_sse && current.best.sel_rmse.is_finite() {
            current_params = current.best.params.clone();
            final_fit = current.best.clone();
            if first_round {
                baseline = current.clone();
            }
            rebased.push(current.clone());
        }
        let mut yardstick = Yardstick {
            r0: final_fit.sel_rmse,
            blocks: data.with_model(&current_model).block_sse(&current_params),
            s0: current.spread,
            floor,
        };
        let mut ablations = 0;
        let candidates = loop {
            let salt = salt + 10 * ablations as u64;
            let fits: Vec<(Effect, ModelDescription, SeededFit, Vec<f64>)> = (0..remaining.len())
                .into_par_iter()
                .map(|i| {
                    let effect = remaining[i];
                    let salt = salt + 1 + i as u64;
                    let (candidate, fit) = fit_with_effect(
                        &data.with_model(&current_model),
                        searches,
                        &current_params,
                        effect,
                        settings,
                        salt,
                        &scratch[i + 1],
                    )?;
                    let blocks = candidate.block_sse(&fit.best.params);
                    Ok((effect, candidate.model, fit, blocks))
                })
                .collect::<anyhow::Result<_>>()?;
            let candidates = judge_all(&fits, &yardstick, n, settings);
            let Some(best) = candidates.iter().find(|c| c.passes) else {
                break candidates;
            };
            if ablations >= MAX_REBASES {
                break candidates;
            }
            let ablated = fit_seeds(
                &data.with_model(&current_model),
                searches,
                Start::Warm {
                    params: &best.fit.best.params[..current_params.len()],
                    new_from: current_params.len(),
                },
                settings,
                salt + 10,
            )?;
            if !(ablated.best.est_sse < final_fit.est_sse && ablated.best.sel_rmse.is_finite()) {
                break candidates;
            }
            // A better fit of the current model: judge the round again
            // from it, candidates refitted from there.
            current_params = ablated.best.params.clone();
            final_fit = ablated.best.clone();
            if current_model.effects.is_empty() {
                baseline = ablated.clone();
            }
            yardstick = Yardstick {
                r0: ablated.best.sel_rmse,
                blocks: data.with_model(&current_model).block_sse(&current_params),
                s0: ablated.spread,
                floor,
            };
            rebased.push(ablated);
            ablations += 1;
        };
        let accepted = candidates.iter().find(|c| c.passes).map(|c| c.effect);
        if let Some(c) = candidates.iter().find(|c| c.passes) {
            current_model = c.model.clone();
            current_params = c.fit.best.params.clone();
            final_fit = c.fit.best.clone();
            verdict.push(c.effect);
        }
        rounds.push(Round {
            current,
            rebased,
            candidates,
            accepted,
        });
        if accepted.is_none() {
            break;
        }
    }
    Ok(Selection {
        capped: rounds.len() == settings.max_effects
            && rounds.last().is_some_and(|r| r.accepted.is_some()),
        given: from.map_or(Vec::new(), |(m, _)| m.effects.clone()),
        given_fit,
        baseline_model,
        baseline,
        rounds,
        verdict,
        final_model: current_model,
        final_fit,
    })
}
