//! Whether an effect earns its place: the acceptance rule of the forward
//! selection ([`select`](super::select)).
//!
//! **Acceptance rule.** Every figure it reads is on the selection part
//! ([`FitProblem`](crate::fit::problem::FitProblem)); the test part is never read here. Let `R0`
//! be the selection RMSE of the current model and `R1` the candidate's (each
//! fit keeps the seed with the lowest estimation SSE among those that stay
//! finite on the selection part); `s0`, `s1` the seed-to-seed spreads of the
//! selection RMSE (`s0` from refitting the
//! current model with the candidates' seeds and budget, so refitting alone is
//! not mistaken for an effect; spread = 1.4826·MAD over the seeds that reach
//! the best estimation fit, a robust standard deviation of fits the
//! estimation data cannot tell apart); `N` the selection samples, `k` the
//! candidate's extra parameters and `F` the noise-floor estimate. A candidate
//! is accepted only if all five hold:
//! 1. `R0 − R1 > 3·√(s0² + s1²)`: the improvement is clearly beyond seed-to-seed spread;
//!    or, where the current model's seeds scatter too widely on the
//!    selection part for that, every candidate seed the estimation data
//!    cannot tell from its best still beats every such seed of the current
//!    model: `max R1ᵢ + 3·s1 < min R0ⱼ`. A misfit model's fits scatter
//!    most, and a wide spread must not hide an effect that no refit of it
//!    comes near;
//! 2. `ΔBIC = N·ln(R1²/R0²) + k·ln N < −10`: it pays for its parameters
//!    ("very strong" evidence on the Kass–Raftery scale);
//! 3. `(R0 − R1)/R0 ≥ 2 %`: an improvement a user would notice;
//! 4. `R0 > 1.1·F`: there is a gap left to explain (the floor estimate is
//!    good to about 10 %);
//! 5. the gain does not hang on one stretch of the record: with the
//!    selection block where the candidate gains most left out, the rest of
//!    the selection part still improves by rule 3's 2 % (with two blocks or
//!    more). An effect that fits one event of one record carries over to no
//!    other record.
//!
//! Of the candidates that pass, the one with the lowest selection RMSE is
//! accepted; the next round starts from it.

use serde::Serialize;

use super::effects::{Effect, ModelDescription};
use super::fitting::SeededFit;
use super::settings::Settings;
use crate::report::number::significant;

/// Share of the baseline's gap above the noise floor that `rmse` closes, in
/// residual energy: `(R_b² − R²) / (R_b² − F²)`; 0 when the baseline is
/// already at the floor.
pub fn gap_closed(baseline_rmse: f64, rmse: f64, floor: f64) -> f64 {
    let gap = baseline_rmse.powi(2) - floor.powi(2);
    if gap.is_nan() || gap <= 0.0 || !rmse.is_finite() {
        return 0.0;
    }
    (baseline_rmse.powi(2) - rmse.powi(2)) / gap
}

/// Rule 5's measure: the relative improvement of the RMSE over the blocks
/// (SSE `before` and `after` on each) with the block of the largest SSE
/// reduction left out; `None` with fewer than two blocks.
fn without_best_block(before: &[f64], after: &[f64]) -> Option<f64> {
    if before.len() < 2 || before.len() != after.len() {
        return None;
    }
    let best = (0..before.len())
        .max_by(|&i, &j| (before[i] - after[i]).total_cmp(&(before[j] - after[j])))?;
    let rest = |v: &[f64]| -> f64 {
        v.iter()
            .enumerate()
            .filter(|&(j, _)| j != best)
            .map(|(_, e)| e)
            .sum()
    };
    Some(1.0 - (rest(after) / rest(before)).sqrt())
}

/// One candidate of one round.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Candidate {
    pub effect: Effect,
    /// The model the candidate is (current effects plus this one).
    pub model: ModelDescription,
    pub fit: SeededFit,
    /// The candidate's own parameters, by name.
    pub effect_params: Vec<(String, f64)>,
    /// ΔBIC against the current model on the selection part.
    pub delta_bic: f64,
    /// Relative improvement of the selection RMSE against the current model.
    pub relative: f64,
    /// The candidate's RMSE over the current model's on each selection
    /// block.
    pub block_ratios: Vec<f64>,
    /// Rule 5: the relative improvement of the selection RMSE with the
    /// block it gains most on left out (`None` with a single block).
    pub without_best_block: Option<f64>,
    /// Improvement in units of the combined seed spread.
    pub spread_ratio: f64,
    pub passes: bool,
    /// Why it passes or fails, in words.
    pub reason: String,
}

/// What a candidate is judged against: the current model's selection RMSE
/// `r0`, its SSE on each selection block, its seed spread `s0` and the
/// lowest selection RMSE of its fits the estimation data cannot tell apart
/// (`r0` among them), and the noise-floor estimate.
#[derive(Debug, Clone)]
pub struct Yardstick {
    pub r0: f64,
    pub blocks: Vec<f64>,
    pub s0: f64,
    pub r0_lowest: f64,
    pub floor: f64,
}

/// Judges every candidate fit (with its SSE on each selection block)
/// against the yardstick, best selection RMSE first.
pub fn judge_all(
    fits: &[(Effect, ModelDescription, SeededFit, Vec<f64>)],
    yardstick: &Yardstick,
    n: f64,
    settings: &Settings,
) -> Vec<Candidate> {
    let mut candidates: Vec<Candidate> = fits
        .iter()
        .map(|(e, m, f, blocks)| {
            Candidate::judge(*e, m.clone(), f.clone(), blocks, yardstick, n, settings)
        })
        .collect();
    candidates.sort_by(|a, b| a.fit.best.sel_rmse.total_cmp(&b.fit.best.sel_rmse));
    candidates
}

impl Candidate {
    /// Scores `fit` of `model` (the current model plus `effect`), whose SSE
    /// on each selection block is `blocks`, against the current model's
    /// ([`Yardstick`]) by the acceptance rule; `n` selection samples.
    pub fn judge(
        effect: Effect,
        model: ModelDescription,
        fit: SeededFit,
        blocks: &[f64],
        yardstick: &Yardstick,
        n: f64,
        settings: &Settings,
    ) -> Candidate {
        let Yardstick { r0, s0, floor, .. } = *yardstick;
        let datasets = model.datasets;
        let r1 = fit.best.sel_rmse;
        let k = effect.dim(datasets) as f64;
        let (delta_bic, relative) = if r1.is_finite() {
            (n * (r1 * r1 / (r0 * r0)).ln() + k * n.ln(), (r0 - r1) / r0)
        } else {
            (f64::INFINITY, f64::NEG_INFINITY)
        };
        let spread = (s0 * s0 + fit.spread * fit.spread).sqrt();
        let spread_ratio = if spread > 0.0 {
            (r0 - r1) / spread
        } else if r1 < r0 {
            f64::INFINITY
        } else {
            0.0
        };
        let beyond_every_refit = fit.indistinguishable.highest
            + settings.spread_factor * fit.spread
            < yardstick.r0_lowest;
        let rule1 = r0 - r1 > settings.spread_factor * spread || beyond_every_refit;
        let rule2 = delta_bic < settings.bic_threshold;
        let rule3 = relative >= settings.min_relative;
        let rule4 = r0 > settings.floor_margin * floor;
        let block_ratios: Vec<f64> = blocks
            .iter()
            .zip(&yardstick.blocks)
            .map(|(e1, e0)| (e1 / e0).sqrt())
            .collect();
        let without_best_block = without_best_block(&yardstick.blocks, blocks);
        let rule5 = without_best_block.is_none_or(|g| g >= settings.min_relative);
        let passes = rule1 && rule2 && rule3 && rule4 && rule5 && r1.is_finite();
        let mut why = Vec::new();
        if !rule1 {
            why.push(format!(
                "improvement {} is within {}× the seed spread {}",
                significant(r0 - r1, 3),
                settings.spread_factor,
                significant(spread, 3)
            ));
        }
        if !rule2 {
            why.push(format!(
                "ΔBIC {delta_bic:.1} does not pay for {k} parameter(s)"
            ));
        }
        if !rule3 {
            why.push(format!(
                "relative improvement {:.1} % is below {:.1} %",
                100.0 * relative,
                100.0 * settings.min_relative
            ));
        }
        if !rule4 {
            why.push(format!(
                "the current model ({}) is within {:.0} % of the noise floor {}",
                significant(r0, 3),
                100.0 * (settings.floor_margin - 1.0),
                significant(floor, 3)
            ));
        }
        if let Some(g) = without_best_block.filter(|_| !rule5) {
            why.push(format!(
                "its gain hangs on one selection block: without it the selection RMSE \
                 improves by {:.1} %",
                100.0 * g
            ));
        }
        let reason = if !r1.is_finite() {
            "the best fit on the estimation part diverges on the selection part".to_string()
        } else if passes {
            format!(
                "improves selection RMSE by {:.1} % ({:.1}× the seed spread, ΔBIC {:.0})",
                100.0 * relative,
                spread_ratio,
                delta_bic
            )
        } else {
            why.join("; ")
        };
        let at = model.offset_of(effect).expect("effect in model");
        let effect_params = effect
            .params(datasets)
            .into_iter()
            .zip(&fit.best.params[at..])
            .map(|(p, &v)| (p.name, v))
            .collect();
        Candidate {
            effect,
            model,
            fit,
            effect_params,
            delta_bic,
            relative,
            block_ratios,
            without_best_block,
            spread_ratio,
            passes,
            reason,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::fitting::{RmseSpan, ScoredFit};
    use crate::model::Family;

    /// A candidate with a delay reaching selection RMSE `r1` (on each of two
    /// equal blocks) with seed spread `s1`, judged against `r0`, `s0` and
    /// the floor with `n` selection samples under the default rule.
    fn judged(r1: f64, s1: f64, (r0, s0, floor): (f64, f64, f64), n: f64) -> Candidate {
        judged_on_blocks(r1, s1, (r0, s0, floor), n, &[r1 * r1, r1 * r1])
    }

    fn judged_on_blocks(
        r1: f64,
        s1: f64,
        (r0, s0, floor): (f64, f64, f64),
        n: f64,
        blocks: &[f64],
    ) -> Candidate {
        judged_against(r1, s1, (r0, s0, r0, floor), n, blocks)
    }

    /// As [`judged_on_blocks`], with the lowest selection RMSE `r0_lowest`
    /// of the current model's indistinguishable fits.
    fn judged_against(
        r1: f64,
        s1: f64,
        (r0, s0, r0_lowest, floor): (f64, f64, f64, f64),
        n: f64,
        blocks: &[f64],
    ) -> Candidate {
        let model = ModelDescription::new(Family::Classic, vec![Effect::Delay], 1);
        let fit = SeededFit {
            best: ScoredFit {
                params: vec![0.5; model.dim()],
                est_sse: 1.0,
                sel_rmse: r1,
            },
            seed_sel_rmse: vec![r1],
            spread: s1,
            indistinguishable: RmseSpan::of(&[r1]),
        };
        let yardstick = Yardstick {
            r0,
            blocks: vec![r0 * r0, r0 * r0],
            s0,
            r0_lowest,
            floor,
        };
        Candidate::judge(
            Effect::Delay,
            model,
            fit,
            blocks,
            &yardstick,
            n,
            &Settings::default(),
        )
    }

    #[test]
    fn a_clear_cheap_noticeable_gain_above_the_floor_passes() {
        let c = judged(0.8, 0.01, (1.0, 0.01, 0.1), 2000.0);
        assert!(c.passes, "{}", c.reason);
        let bic = 2000.0 * (0.64f64).ln() + 2000f64.ln();
        assert!((c.delta_bic - bic).abs() < 1e-9, "{}", c.delta_bic);
        assert!((c.relative - 0.2).abs() < 1e-12);
        assert!((c.spread_ratio - 0.2 / 2e-4f64.sqrt()).abs() < 1e-9);
        assert_eq!(c.effect_params, vec![("d".to_string(), 0.5)]);
    }

    #[test]
    fn each_rule_alone_can_refuse_and_says_why() {
        // 1: a gain within three seed spreads.
        let c = judged(0.8, 0.1, (1.0, 0.1, 0.1), 2000.0);
        assert!(
            !c.passes && c.reason.contains("seed spread"),
            "{}",
            c.reason
        );
        assert!(!c.reason.contains("ΔBIC") && !c.reason.contains("relative"));
        // 2: too few samples to pay for a parameter (ΔBIC = +1.8).
        let c = judged(0.97, 0.001, (1.0, 0.001, 0.1), 20.0);
        assert!(!c.passes && c.reason.starts_with("ΔBIC"), "{}", c.reason);
        // 3: a real but unnoticeable gain of 1 %.
        let c = judged(0.99, 1e-4, (1.0, 1e-4, 0.1), 1e5);
        assert!(
            !c.passes && c.reason.starts_with("relative improvement 1.0 %"),
            "{}",
            c.reason
        );
        // 4: the current model is already within 10 % of the noise floor.
        let c = judged(0.8, 0.01, (1.0, 0.01, 0.95), 2000.0);
        assert!(
            !c.passes && c.reason.contains("of the noise floor"),
            "{}",
            c.reason
        );
        // 5: a large pooled gain made on one block while the other gains
        // 1 % (SSE per block; the current model's is 1 on each).
        let blocks = [0.25, 0.99f64.powi(2)];
        let c = judged_on_blocks(0.8, 0.01, (1.0, 0.01, 0.1), 2000.0, &blocks);
        assert!(
            !c.passes
                && c.reason
                    .starts_with("its gain hangs on one selection block"),
            "{}",
            c.reason
        );
        assert!((c.block_ratios[0] - 0.5).abs() < 1e-12);
        assert!((c.block_ratios[1] - 0.99).abs() < 1e-12);
        assert!((c.without_best_block.unwrap() - 0.01).abs() < 1e-12);
    }

    #[test]
    fn leaving_out_the_best_block_leaves_the_others_pooled() {
        // Three blocks: the largest SSE reduction (block 1) is left out.
        let g = without_best_block(&[4.0, 9.0, 1.0], &[1.0, 1.0, 1.0]).unwrap();
        assert!((g - (1.0 - (2.0f64 / 5.0).sqrt())).abs() < 1e-12, "{g}");
        assert_eq!(without_best_block(&[4.0], &[1.0]), None);
    }

    #[test]
    fn a_wide_spread_of_the_current_model_hides_no_gain_that_no_refit_of_it_comes_near() {
        // The current model's indistinguishable fits score 1.0 to 2.0 on the
        // selection part (r0 = 1.5, spread 0.74): a candidate at 0.3 gains
        // 1.2, within three spreads, yet below every one of those fits.
        let c = judged_against(0.3, 0.01, (1.5, 0.74, 1.0, 0.1), 2000.0, &[0.09, 0.09]);
        assert!(c.passes, "{}", c.reason);
        // One at 0.9 with a spread of 0.05 comes within three of its spreads
        // of the best refit (1.0): rule 1 refuses it.
        let c = judged_against(0.9, 0.05, (1.5, 0.74, 1.0, 0.1), 2000.0, &[0.81, 0.81]);
        assert!(
            !c.passes && c.reason.contains("seed spread"),
            "{}",
            c.reason
        );
    }

    #[test]
    fn a_candidate_that_diverges_on_validation_never_passes() {
        let c = judged(f64::INFINITY, 0.0, (1.0, 0.0, 0.1), 2000.0);
        assert!(!c.passes);
        assert!(c.reason.contains("diverges"), "{}", c.reason);
    }

    #[test]
    fn candidates_are_ranked_by_validation_rmse() {
        let model = ModelDescription::new(Family::Classic, vec![Effect::Delay], 1);
        let fit = |r: f64| SeededFit {
            best: ScoredFit {
                params: vec![0.5; model.dim()],
                est_sse: 1.0,
                sel_rmse: r,
            },
            seed_sel_rmse: vec![r],
            spread: 0.0,
            indistinguishable: RmseSpan::of(&[r]),
        };
        let fits = vec![
            (Effect::Delay, model.clone(), fit(0.9), vec![0.81]),
            (
                Effect::Delay,
                model.clone(),
                fit(f64::INFINITY),
                vec![f64::INFINITY],
            ),
            (Effect::Delay, model.clone(), fit(0.7), vec![0.49]),
        ];
        let yardstick = Yardstick {
            r0: 1.0,
            blocks: vec![1.0],
            s0: 0.0,
            r0_lowest: 1.0,
            floor: 0.1,
        };
        let ranked = judge_all(&fits, &yardstick, 2000.0, &Settings::default());
        let order: Vec<f64> = ranked.iter().map(|c| c.fit.best.sel_rmse).collect();
        assert_eq!(order, vec![0.7, 0.9, f64::INFINITY]);
    }

    #[test]
    fn the_gap_closed_is_a_share_of_the_energy_above_the_floor() {
        assert_eq!(gap_closed(2.0, 1.0, 1.0), 1.0);
        assert!((gap_closed(2.0, 1.5, 1.0) - (4.0 - 2.25) / 3.0).abs() < 1e-12);
        // At the floor there is no gap to close; a diverged model closes none.
        assert_eq!(gap_closed(1.0, 0.5, 1.0), 0.0);
        assert_eq!(gap_closed(2.0, f64::INFINITY, 1.0), 0.0);
    }
}
