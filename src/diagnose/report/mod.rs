//! A [`Diagnosis`] for people ([`to_text`]), scripts ([`DiagnosisJson`],
//! the `--json` document) and eyes ([`write_figures`], SVG figures).

mod figures;
mod json;
mod text;

use std::collections::BTreeMap;

pub use figures::{FIGURES, write_figures};
pub use json::*;
pub use text::{baseline_caution, plain_fit_caution, plain_fit_start, to_text, verdict_cautions};

use super::Diagnosis;
use super::accept::Candidate;
use super::effects::Effect;

/// One entry per effect scored: from the round it was accepted in, else from
/// the last round it was scored in. Accepted effects first (in the order
/// accepted), then the rest by selection RMSE.
pub fn candidate_list(d: &Diagnosis) -> Vec<(&Candidate, bool, usize)> {
    let mut seen: BTreeMap<&'static str, (&Candidate, bool, usize)> = BTreeMap::new();
    for (r, round) in d.selection.rounds.iter().enumerate() {
        for c in &round.candidates {
            let accepted = round.accepted == Some(c.effect);
            let keep = !matches!(seen.get(c.effect.name()), Some((_, true, _)));
            if keep {
                seen.insert(c.effect.name(), (c, accepted, r + 1));
            }
        }
    }
    let mut list: Vec<_> = seen.into_values().collect();
    let pos = |e: Effect| d.selection.verdict.iter().position(|v| *v == e);
    list.sort_by(|a, b| match (pos(a.0.effect), pos(b.0.effect)) {
        (Some(x), Some(y)) => x.cmp(&y),
        (Some(_), None) => std::cmp::Ordering::Less,
        (None, Some(_)) => std::cmp::Ordering::Greater,
        (None, None) => a.0.fit.best.sel_rmse.total_cmp(&b.0.fit.best.sel_rmse),
    });
    list
}
