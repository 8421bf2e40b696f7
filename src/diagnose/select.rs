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
    settings.progress.say(&format!(
        "fitting the {family} baseline ({} seeds)",
        settings.baseline_seeds
    ));
    let baseline = fit_seeds(
        &data.with_model(&baseline_model),
        searches,
        baseline_start,
        settings,
        0,
    )?;
    let mut state = SelectionState {
        model: baseline_model.clone(),
        params: baseline.best.params.clone(),
        final_fit: baseline.best.clone(),
        baseline,
    };
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
        state.model = model.clone();
        state.params = fit.best.params.clone();
        state.final_fit = fit.best.clone();
        given_fit = Some(fit);
    }
    let selecting = Selecting {
        data,
        searches,
        settings,
        floor,
        n: data.selection_samples().max(2) as f64,
    };
    let mut rounds = Vec::new();
    let mut verdict = Vec::new();
    for round in 0..settings.max_effects {
        let remaining = remaining_effects(data, effects, &state);
        if remaining.is_empty() {
            break;
        }
        let names: Vec<String> = remaining.iter().map(|e| e.to_string()).collect();
        settings.progress.say(&format!(
            "round {}: trying {} on the current model",
            round + 1,
            names.join(", ")
        ));
        let round = selecting.round(&mut state, &remaining, round)?;
        verdict.extend(round.accepted);
        let accepted = round.accepted;
        rounds.push(round);
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
        baseline: state.baseline,
        rounds,
        verdict,
        final_model: state.model,
        final_fit: state.final_fit,
    })
}

/// Where the selection stands between rounds: the current model, its
/// parameters and best fit, and the baseline's fits, which a round replaces
/// where it finds a better fit of the baseline.
struct SelectionState {
    model: ModelDescription,
    params: Vec<f64>,
    final_fit: ScoredFit,
    baseline: SeededFit,
}

impl SelectionState {
    /// Takes `fit` of the current model as its best, when it is better on
    /// the estimation part and scores on the selection part: a better fit
    /// of the model the round started from, and of the baseline when the
    /// model has no effects yet. Returns whether it did.
    fn rebase(&mut self, fit: &SeededFit) -> bool {
        if !(fit.best.est_sse < self.final_fit.est_sse && fit.best.sel_rmse.is_finite()) {
            return false;
        }
        self.params = fit.best.params.clone();
        self.final_fit = fit.best.clone();
        if self.model.effects.is_empty() {
            self.baseline = fit.clone();
        }
        true
    }
}

/// What every round of the selection reads and none changes.
struct Selecting<'a> {
    data: &'a FitProblem,
    searches: &'a Searches,
    settings: &'a Settings,
    floor: f64,
    /// The selection part's samples (at least two), for the rule.
    n: f64,
}

/// The effects a round tries on `state`'s model: one realisation of each
/// physical effect at a time, those that apply to the data's datasets, and
/// those looked for only where the residual rings (the ringing) only where
/// it does (a spectrum per round, so only when one is among the effects).
fn remaining_effects(data: &FitProblem, effects: &[Effect], state: &SelectionState) -> Vec<Effect> {
    let rings = effects.iter().any(|&e| hints::only_on_a_peak(e))
        && hints::residual_rings(&data.with_model(&state.model), &state.params);
    effects
        .iter()
        .copied()
        .filter(|e| {
            !state
                .model
                .effects
                .iter()
                .any(|m| m.physical() == e.physical())
                && e.applicable(data.datasets())
                && (!hints::only_on_a_peak(*e) || rings)
        })
        .collect()
}

impl Selecting<'_> {
    /// Round `round` of forward selection over `remaining`: the current
    /// model refitted for the seed spread of "no new effect", every
    /// candidate fitted and judged ([`Selecting::judge_candidates`]), and
    /// the best passing one, if any, accepted into `state`.
    fn round(
        &self,
        state: &mut SelectionState,
        remaining: &[Effect],
        round: usize,
    ) -> anyhow::Result<Round> {
        let remaining_models: Vec<ModelDescription> =
            remaining.iter().map(|&e| state.model.with(e)).collect();
        let salt = 100 * (round as u64 + 1);
        // The first round adds fits from scratch, computed once per model
        // (slot 0 the current model's, slot i + 1 the i-th candidate's).
        let first_round = state.model.effects.is_empty();
        let scratch = if first_round {
            self.scratch_fits(&state.model, &remaining_models, salt)?
        } else {
            vec![Vec::new(); remaining.len() + 1]
        };
        let refit = Start::Warm {
            params: &state.params,
            new_from: state.params.len(),
        };
        let current = fit_seeds_with(
            &self.data.with_model(&state.model),
            self.searches,
            refit,
            self.settings,
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
        if state.rebase(&current) {
            rebased.push(current.clone());
        }
        let yardstick = Yardstick {
            r0: state.final_fit.sel_rmse,
            blocks: self.data.with_model(&state.model).block_sse(&state.params),
            s0: current.spread,
            r0_lowest: current
                .indistinguishable
                .lowest
                .min(state.final_fit.sel_rmse),
            floor: self.floor,
        };
        let candidates =
            self.judge_candidates(state, remaining, &scratch, salt, yardstick, &mut rebased)?;
        let accepted = candidates.iter().find(|c| c.passes).map(|c| c.effect);
        if let Some(c) = candidates.iter().find(|c| c.passes) {
            state.model = c.model.clone();
            state.params = c.fit.best.params.clone();
            state.final_fit = c.fit.best.clone();
        }
        Ok(Round {
            current,
            rebased,
            candidates,
            accepted,
        })
    }

    /// The first round's fits from scratch of the current model (slot 0)
    /// and of each of `remaining_models` (slot i + 1). Every fit has its own
    /// seed, so fits run side by side give the same numbers as one after
    /// the other.
    fn scratch_fits(
        &self,
        model: &ModelDescription,
        remaining_models: &[ModelDescription],
        salt: u64,
    ) -> anyhow::Result<Vec<Vec<ScoredFit>>> {
        let models: Vec<&ModelDescription> =
            std::iter::once(model).chain(remaining_models).collect();
        (0..models.len())
            .into_par_iter()
            .map(|slot| {
                scratch_fits(
                    &self.data.with_model(models[slot]),
                    self.searches,
                    self.settings,
                    salt + 50 + slot as u64,
                )
            })
            .collect()
    }

    /// Fits and judges every candidate of `remaining` against `yardstick`,
    /// with the ablation of [`select`]: while the best passing candidate's
    /// parameters lead to a better fit of the current model without it (at
    /// most [`MAX_REBASES`] times), that fit becomes the current model, is
    /// pushed to `rebased`, and the round is judged again from it. Returns
    /// the last judgement's candidates.
    fn judge_candidates(
        &self,
        state: &mut SelectionState,
        remaining: &[Effect],
        scratch: &[Vec<ScoredFit>],
        salt: u64,
        mut yardstick: Yardstick,
        rebased: &mut Vec<SeededFit>,
    ) -> anyhow::Result<Vec<Candidate>> {
        let mut ablations = 0;
        loop {
            let salt = salt + 10 * ablations as u64;
            let fits: Vec<(Effect, ModelDescription, SeededFit, Vec<f64>)> = (0..remaining.len())
                .into_par_iter()
                .map(|i| {
                    let effect = remaining[i];
                    let salt = salt + 1 + i as u64;
                    let (candidate, fit) = fit_with_effect(
                        &self.data.with_model(&state.model),
                        self.searches,
                        &state.params,
                        effect,
                        self.settings,
                        salt,
                        &scratch[i + 1],
                    )?;
                    let blocks = candidate.block_sse(&fit.best.params);
                    Ok((effect, candidate.model, fit, blocks))
                })
                .collect::<anyhow::Result<_>>()?;
            let candidates = judge_all(&fits, &yardstick, self.n, self.settings);
            let Some(best) = candidates.iter().find(|c| c.passes) else {
                return Ok(candidates);
            };
            if ablations >= MAX_REBASES {
                return Ok(candidates);
            }
            let ablated = fit_seeds(
                &self.data.with_model(&state.model),
                self.searches,
                Start::Warm {
                    params: &best.fit.best.params[..state.params.len()],
                    new_from: state.params.len(),
                },
                self.settings,
                salt + 10,
            )?;
            // A better fit of the current model: judge the round again
            // from it, candidates refitted from there.
            if !state.rebase(&ablated) {
                return Ok(candidates);
            }
            yardstick = Yardstick {
                r0: ablated.best.sel_rmse,
                blocks: self.data.with_model(&state.model).block_sse(&state.params),
                s0: ablated.spread,
                r0_lowest: ablated.indistinguishable.lowest.min(ablated.best.sel_rmse),
                floor: self.floor,
            };
            rebased.push(ablated);
            ablations += 1;
        }
    }
}
