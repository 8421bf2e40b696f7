//! How far two backends' scores of the same population agree.

use serde::Serialize;

/// The agreement of scores with reference scores (the CPU path's).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Agreement {
    /// Largest `|s − r| / |r|` over candidates finite in both.
    pub max_rel_diff: f64,
    /// Candidates finite in one and not the other (diverged in one only).
    pub finiteness_mismatches: usize,
    /// Every score has the reference's bits.
    pub bit_identical: bool,
    /// The ten best candidates (ties by index) are the same, in the same order.
    pub top10_identical: bool,
}

/// Compares `scores` with `reference` (same population, same order).
pub fn agreement(scores: &[f32], reference: &[f32]) -> Agreement {
    assert_eq!(scores.len(), reference.len(), "score counts differ");
    let mut max_rel_diff = 0.0f64;
    let mut finiteness_mismatches = 0;
    for (&s, &r) in scores.iter().zip(reference) {
        if s.is_finite() != r.is_finite() {
            finiteness_mismatches += 1;
        } else if r.is_finite() && s != r {
            let rel = (s as f64 - r as f64).abs() / (r as f64).abs().max(f64::MIN_POSITIVE);
            max_rel_diff = max_rel_diff.max(rel);
        }
    }
    Agreement {
        max_rel_diff,
        finiteness_mismatches,
        bit_identical: scores
            .iter()
            .zip(reference)
            .all(|(s, r)| s.to_bits() == r.to_bits()),
        top10_identical: best(scores, 10) == best(reference, 10),
    }
}

/// Indices of the `k` lowest scores, ascending; `+∞` and NaN sort last, ties by index.
pub fn best(scores: &[f32], k: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..scores.len()).collect();
    let key = |i: usize| {
        if scores[i].is_nan() {
            f32::INFINITY
        } else {
            scores[i]
        }
    };
    order.sort_by(|&a, &b| key(a).total_cmp(&key(b)).then(a.cmp(&b)));
    order.truncate(k);
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_scores_agree_fully() {
        let s = [3.0, f32::INFINITY, 1.0, 2.0];
        let a = agreement(&s, &s);
        assert!(a.bit_identical && a.top10_identical);
        assert_eq!((a.max_rel_diff, a.finiteness_mismatches), (0.0, 0));
    }

    #[test]
    fn differences_are_counted() {
        let r = [1.0, 2.0, 4.0, 8.0];
        let s = [1.0, 2.5, f32::INFINITY, 8.0];
        let a = agreement(&s, &r);
        assert!(!a.bit_identical);
        assert_eq!(a.finiteness_mismatches, 1);
        assert_eq!(a.max_rel_diff, 0.25);
        assert!(!a.top10_identical, "candidate 2 fell from third to last");
        assert!(agreement(&[1.0, 2.5, 4.0, 8.0], &r).top10_identical);
        assert!(!agreement(&[2.0, 1.0, 4.0, 8.0], &r).top10_identical);
    }

    #[test]
    fn nan_and_infinity_rank_last() {
        assert_eq!(
            best(&[f32::NAN, 2.0, f32::INFINITY, 1.0], 4),
            vec![3, 1, 0, 2]
        );
    }
}
