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
    /// The hundred best candidates (ties by index) are the same, in the same
    /// order: whether a backend ranks the best of a population alike.
    pub top100_identical: bool,
    /// How many of the reference's hundred best are among the scores'
    /// hundred best (in any order; at most the population size).
    pub top100_overlap: usize,
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
    // The best ten are the first ten of the best hundred (one total order).
    let (got, want) = (best(scores, 100), best(reference, 100));
    let ten = |v: &[usize]| v[..v.len().min(10)].to_vec();
    let top100_overlap = {
        let mut sorted = want.clone();
        sorted.sort_unstable();
        got.iter()
            .filter(|i| sorted.binary_search(i).is_ok())
            .count()
    };
    Agreement {
        max_rel_diff,
        finiteness_mismatches,
        bit_identical: scores
            .iter()
            .zip(reference)
            .all(|(s, r)| s.to_bits() == r.to_bits()),
        top10_identical: ten(&got) == ten(&want),
        top100_identical: got == want,
        top100_overlap,
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
    let cmp = |a: &usize, b: &usize| key(*a).total_cmp(&key(*b)).then(a.cmp(b));
    // A total order (ties by index), so selecting the k smallest and sorting
    // them gives the full sort's first k: O(N) rather than O(N log N) for
    // the millions of candidates `mckibben bench` compares.
    if k < order.len() {
        order.select_nth_unstable_by(k, cmp);
        order.truncate(k);
    }
    order.sort_unstable_by(cmp);
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_scores_agree_fully() {
        let s = [3.0, f32::INFINITY, 1.0, 2.0];
        let a = agreement(&s, &s);
        assert!(a.bit_identical && a.top10_identical && a.top100_identical);
        assert_eq!((a.max_rel_diff, a.finiteness_mismatches), (0.0, 0));
        assert_eq!(a.top100_overlap, 4, "all four candidates");
    }

    #[test]
    fn the_best_hundred_are_compared_past_the_tenth() {
        let r: Vec<f32> = (0..300).map(|i| i as f32).collect();
        // Swap the 50th and 51st best: the best ten agree, the best hundred
        // hold the same members in another order.
        let mut s = r.clone();
        s.swap(50, 51);
        let a = agreement(&s, &r);
        assert!(a.top10_identical && !a.top100_identical);
        assert_eq!(a.top100_overlap, 100);
        // Push the 100th best out of the best hundred: one member differs.
        let mut s = r.clone();
        s[99] = 1000.0;
        let a = agreement(&s, &r);
        assert!(a.top10_identical && !a.top100_identical);
        assert_eq!(a.top100_overlap, 99);
    }

    #[test]
    fn selecting_the_best_matches_a_full_sort() {
        let scores: Vec<f32> = (0..1000u32)
            .map(|i| match i % 7 {
                0 => f32::NAN,
                1 => f32::INFINITY,
                _ => ((i * 7919) % 101) as f32,
            })
            .collect();
        let mut all: Vec<usize> = (0..scores.len()).collect();
        let key = |i: usize| {
            if scores[i].is_nan() {
                f32::INFINITY
            } else {
                scores[i]
            }
        };
        all.sort_by(|&a, &b| key(a).total_cmp(&key(b)).then(a.cmp(&b)));
        for k in [0, 1, 10, 100, 999, 1000, 2000] {
            assert_eq!(best(&scores, k), all[..k.min(1000)], "k = {k}");
        }
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
