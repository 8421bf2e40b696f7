//! Whether the estimation data settle the final model's fit on the
//! selection part.
//!
//! The diagnosis' final fit comes from a chain of warm starts, one effect
//! after another; the estimation half may hold fits of the same model as
//! good or better that validate quite differently (as on the Cavatappi
//! muscle: docs/lab/diagnosis.md, "How settled: the final model
//! refitted"). So the final model is fitted again from scratch and the
//! report says whether the fit it states is reproduced.

use serde::Serialize;

use super::fitting::ScoredFit;
use super::likelihood::indistinguishable_up_to;

pub use crate::ident::fit::SETTLED_POINTS;

/// The final model fitted again from scratch, against the final fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Refits {
    /// From-scratch fits of the final model.
    pub fits: usize,
    /// Estimation SSE of the final fit and of the best from-scratch fit.
    pub final_est_sse: f64,
    pub best_est_sse: f64,
    /// Selection fit % of the final fit and of the best from-scratch fit.
    pub final_selection_fit_percent: f64,
    pub best_selection_fit_percent: f64,
    /// Whether the final fit is within the likelihood-ratio test's 95 %
    /// threshold of the lowest estimation SSE (`χ²₁(0.95)·SSE/N`, the
    /// threshold of the profile intervals).
    pub final_tied: bool,
    /// Selection fit % over every fit (the final one included) within
    /// that threshold: the fits the estimation data cannot tell apart.
    pub tied_selection_fit_percent: (f64, f64),
    /// How many fits that is.
    pub tied: usize,
}

/// What [`Refits`] says of the final fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Finding {
    /// The fits the estimation data cannot tell apart, the final one among
    /// them, validate within [`SETTLED_POINTS`] of each other.
    Reproduced,
    /// No refit comes within the threshold: the final fit is the best
    /// estimation fit found, the refits ended in worse basins.
    Best,
    /// A from-scratch fit is better on the estimation half beyond the
    /// threshold: the final fit is not what the estimation data determine.
    Beaten,
    /// The final fit is among the best, but fits as good validate more than
    /// [`SETTLED_POINTS`] apart.
    Unsettled,
}

impl Refits {
    /// Compares the final fit with the from-scratch ones; `fit_percent`
    /// gives a fit's selection fit %, `samples` is the number of
    /// estimation residuals. `None` without a finite from-scratch fit.
    pub fn compare(
        final_fit: &ScoredFit,
        scratch: &[ScoredFit],
        fit_percent: impl Fn(&ScoredFit) -> f64,
        samples: usize,
    ) -> Option<Refits> {
        let best = scratch
            .iter()
            .filter(|f| f.est_sse.is_finite())
            .min_by(|a, b| a.est_sse.total_cmp(&b.est_sse))?;
        let lowest = best.est_sse.min(final_fit.est_sse);
        let threshold = indistinguishable_up_to(lowest, samples);
        let tied: Vec<f64> = std::iter::once(final_fit)
            .chain(scratch)
            .filter(|f| f.est_sse <= threshold)
            .map(&fit_percent)
            .filter(|v| v.is_finite())
            .collect();
        let range = tied
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            });
        Some(Refits {
            fits: scratch.len(),
            final_est_sse: final_fit.est_sse,
            best_est_sse: best.est_sse,
            final_selection_fit_percent: fit_percent(final_fit),
            best_selection_fit_percent: fit_percent(best),
            final_tied: final_fit.est_sse <= threshold,
            tied_selection_fit_percent: range,
            tied: tied.len(),
        })
    }

    pub fn finding(&self) -> Finding {
        let (lo, hi) = self.tied_selection_fit_percent;
        if !self.final_tied {
            Finding::Beaten
        } else if self.tied < 2 {
            Finding::Best
        } else if hi - lo > SETTLED_POINTS {
            Finding::Unsettled
        } else {
            Finding::Reproduced
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fit(est_sse: f64, val: f64) -> ScoredFit {
        // `sel_rmse` carries the validation fit % in these tests.
        ScoredFit {
            params: Vec::new(),
            est_sse,
            sel_rmse: val,
        }
    }

    fn compare(final_fit: ScoredFit, scratch: &[ScoredFit]) -> Refits {
        Refits::compare(&final_fit, scratch, |f| f.sel_rmse, 1000).expect("a scratch fit")
    }

    #[test]
    fn a_final_fit_that_scratch_fits_repeat_is_reproduced() {
        // Threshold: 3.841·100/1000 = 0.38 above the lowest SSE.
        let r = compare(fit(100.0, 88.0), &[fit(100.2, 87.5), fit(130.0, 40.0)]);
        assert_eq!(r.finding(), Finding::Reproduced);
        assert_eq!((r.tied, r.tied_selection_fit_percent), (2, (87.5, 88.0)));
    }

    #[test]
    fn a_final_fit_no_refit_reaches_is_the_best_found() {
        let r = compare(fit(6.46, 87.0), &[fit(7.38, 83.1)]);
        assert_eq!(r.finding(), Finding::Best);
        assert_eq!(r.tied, 1);
    }

    #[test]
    fn a_better_scratch_fit_beats_the_final_one() {
        let r = compare(fit(16.4, 83.4), &[fit(14.7, 51.7), fit(16.5, 80.0)]);
        assert_eq!(r.finding(), Finding::Beaten);
        assert_eq!((r.best_est_sse, r.best_selection_fit_percent), (14.7, 51.7));
        assert!(!r.final_tied);
    }

    #[test]
    fn tied_fits_that_validate_apart_leave_it_unsettled() {
        // 825 estimation samples: threshold 17.89 + 0.083 (the 300 g case).
        let r = Refits::compare(&fit(17.97, 82.0), &[fit(17.89, 61.8)], |f| f.sel_rmse, 825)
            .expect("a scratch fit");
        assert_eq!(r.finding(), Finding::Unsettled);
        assert_eq!(r.tied_selection_fit_percent, (61.8, 82.0));
    }

    #[test]
    fn without_a_finite_scratch_fit_there_is_nothing_to_say() {
        let none = Refits::compare(
            &fit(1.0, 90.0),
            &[fit(f64::INFINITY, 0.0)],
            |f| f.sel_rmse,
            10,
        );
        assert!(none.is_none());
    }
}
