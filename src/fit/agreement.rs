//! How sure a fit is: whether its independent tries end in one basin.
//!
//! A try reaches the basin of the best estimation SSE with some probability
//! `p`; `K` tries find it with probability `1 − (1 − p)^K`. One fit cannot
//! measure `p`, but it can say how many of its tries ended where the best
//! did: within the likelihood-ratio threshold of the best estimation SSE
//! (the estimation half cannot tell those apart at 95 %), and in how many
//! distinct basins the others ended. Most tries agreeing means the search
//! finds that basin easily; one try of many means it was found by luck,
//! and a larger population (more tries) may find a better one.

use serde::Serialize;

use crate::ident::fit::indistinguishable_up_to;
use crate::optim::engine::TryEnd;

/// The tries of a fit, compared.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Agreement {
    /// Independent tries the fit ran.
    pub tries: usize,
    /// Of them, those that ended within the likelihood-ratio threshold of
    /// the best estimation SSE (the best one included).
    pub agreeing: usize,
    /// The distinct basins the other tries ended in: their estimation SSEs,
    /// grouped where they lie within each other's threshold, as each
    /// group's lowest, best first.
    pub other_basins: Vec<f64>,
    /// Tries that found no model that stays bounded (every candidate
    /// diverged).
    pub diverged: usize,
    /// The threshold: the estimation SSE a model may have and still be
    /// indistinguishable from the best.
    pub threshold: f64,
    /// The best model of the lowest other basin, against the fit's own
    /// ([`Agreement::with_runner_up`]); `None` where every try agreed.
    pub runner_up: Option<RunnerUp>,
}

/// The lowest other basin's best model: how close it scored on the
/// estimation half, and how far it runs from the fit's model where neither
/// was fitted. Two basins whose estimation SSEs lie close while their runs
/// part widely are a choice the estimation half barely makes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RunnerUp {
    /// Its estimation SSE.
    pub sse: f64,
    /// The RMS of the difference between its free run and the fit's over
    /// the validation halves (output units), from the records' inputs
    /// alone: no measurement there is read. `+∞` where its run diverges.
    #[serde(with = "crate::optim::inf_serde::one_f64")]
    pub apart_rmse: f64,
}

/// At most this share of tries agreeing is a fit to run again with more
/// tries ([`Agreement::unsure`]).
pub const UNSURE_SHARE: f64 = 0.5;

impl Agreement {
    /// The agreement of tries that ended at `ends`, on an estimation part of
    /// `samples` residuals. `None` for a single try: it has nothing to
    /// agree with.
    pub fn of(ends: &[TryEnd], samples: usize) -> Option<Agreement> {
        if ends.len() < 2 {
            return None;
        }
        let mut sse: Vec<f64> = ends
            .iter()
            .filter(|e| !e.params.is_empty() && e.sse.is_finite())
            .map(|e| e.sse)
            .collect();
        sse.sort_by(f64::total_cmp);
        let diverged = ends.len() - sse.len();
        let Some(&best) = sse.first() else {
            return Some(Agreement {
                tries: ends.len(),
                agreeing: 0,
                other_basins: Vec::new(),
                diverged,
                threshold: f64::INFINITY,
                runner_up: None,
            });
        };
        let threshold = indistinguishable_up_to(best, samples);
        let agreeing = sse.iter().filter(|&&s| s <= threshold).count();
        let mut other_basins: Vec<f64> = Vec::new();
        for &s in &sse[agreeing..] {
            match other_basins.last() {
                Some(&lowest) if s <= indistinguishable_up_to(lowest, samples) => {}
                _ => other_basins.push(s),
            }
        }
        Some(Agreement {
            tries: ends.len(),
            agreeing,
            other_basins,
            diverged,
            threshold,
            runner_up: None,
        })
    }

    /// With [`Agreement::runner_up`]: of the tries `ends` outside the
    /// threshold, the lowest one's model, run beside the fit's `best` by
    /// `apart` (the RMS of the two free runs' difference where neither was
    /// fitted).
    pub fn with_runner_up(
        mut self,
        ends: &[TryEnd],
        best: &[f64],
        apart: impl Fn(&[f64], &[f64]) -> f64,
    ) -> Agreement {
        self.runner_up = ends
            .iter()
            .filter(|e| !e.params.is_empty() && e.sse.is_finite() && e.sse > self.threshold)
            .min_by(|a, b| a.sse.total_cmp(&b.sse))
            .map(|e| RunnerUp {
                sse: e.sse,
                apart_rmse: apart(&e.params, best),
            });
        self
    }

    /// Whether at most [`UNSURE_SHARE`] of the tries agree: the best basin
    /// was found by few of them, and more tries may find a better one.
    pub fn unsure(&self) -> bool {
        (self.agreeing as f64) <= UNSURE_SHARE * self.tries as f64
    }

    /// What a user should do about it, where the tries mostly disagree.
    pub fn advice(&self) -> Option<String> {
        self.unsure().then(|| {
            format!(
                "only {} of {} tries ended in the best basin: it was found by few, and more \
                 tries (a larger --pop) may find a lower estimation SSE",
                self.agreeing, self.tries
            )
        })
    }

    /// One line for a terminal.
    pub fn to_text(&self) -> String {
        let others = match self.other_basins.len() {
            0 => String::new(),
            n => format!(
                "; the others ended in {n} other basin{} (lowest estimation SSE {})",
                if n == 1 { "" } else { "s" },
                self.other_basins
                    .iter()
                    .take(4)
                    .map(|s| format!("{s:.4}"))
                    .collect::<Vec<_>>()
                    .join(", ")
                    + if n > 4 { ", …" } else { "" }
            ),
        };
        let diverged = match self.diverged {
            0 => String::new(),
            n => format!("; {n} found no bounded model"),
        };
        format!(
            "{} of {} tries ended within the likelihood-ratio threshold of the best \
             estimation SSE (at an SSE of {:.4} or less){others}{diverged}",
            self.agreeing, self.tries, self.threshold
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn end(sse: f64) -> TryEnd {
        TryEnd {
            params: if sse.is_finite() {
                vec![1.0]
            } else {
                Vec::new()
            },
            sse,
            cut_gain: None,
        }
    }

    #[test]
    fn tries_within_the_threshold_agree_and_the_rest_group_into_basins() {
        // 1000 residuals: the threshold is 0.3841 % above the best.
        let ends: Vec<TryEnd> = [10.0, 10.03, 10.5, 10.51, 12.0, f64::INFINITY, 10.02]
            .into_iter()
            .map(end)
            .collect();
        let a = Agreement::of(&ends, 1000).unwrap();
        assert_eq!(a.tries, 7);
        assert_eq!(a.agreeing, 3, "{a:?}");
        assert_eq!(a.other_basins, vec![10.5, 12.0], "{a:?}");
        assert_eq!(a.diverged, 1);
        assert!((a.threshold - 10.03841).abs() < 1e-9, "{a:?}");
        assert!(a.unsure(), "3 of 7");
        assert!(a.advice().unwrap().starts_with("only 3 of 7 tries"));
        assert!(a.to_text().starts_with("3 of 7 tries"), "{}", a.to_text());
        // The figure beside the best is the threshold, and says so.
        let at_most = format!("(at an SSE of {:.4} or less)", a.threshold);
        assert!(a.to_text().contains(&at_most), "{}", a.to_text());
        let sure = Agreement::of(&[end(5.0), end(5.001), end(9.0)], 1000).unwrap();
        assert!(!sure.unsure() && sure.advice().is_none(), "{sure:?}");
        assert!(
            Agreement::of(&[end(5.0)], 1000).is_none(),
            "one try agrees with nothing"
        );
    }

    /// The runner-up is the lowest try outside the threshold, whatever the
    /// order the tries ran in, and its model goes to `apart` beside the
    /// fit's; where every try agreed there is none.
    #[test]
    fn the_runner_up_is_the_lowest_try_outside_the_threshold() {
        let tagged = |sse: f64, tag: f64| TryEnd {
            params: vec![tag],
            ..end(sse)
        };
        let ends = [
            tagged(12.0, 1.0),
            tagged(10.0, 2.0),
            tagged(10.5, 3.0),
            tagged(10.02, 4.0),
            end(f64::INFINITY),
        ];
        let best = [2.0];
        let a = Agreement::of(&ends, 1000)
            .unwrap()
            .with_runner_up(&ends, &best, |other, fit| 10.0 * other[0] + fit[0]);
        assert_eq!(
            a.runner_up,
            Some(RunnerUp {
                sse: 10.5,
                apart_rmse: 32.0
            })
        );
        let all = [tagged(10.0, 2.0), tagged(10.02, 4.0)];
        let none =
            Agreement::of(&all, 1000)
                .unwrap()
                .with_runner_up(&all, &best, |_, _| unreachable!());
        assert_eq!(none.runner_up, None);
    }
}
