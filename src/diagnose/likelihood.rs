//! The likelihood-ratio test at 95 % on an estimation SSE: the one
//! threshold below which the estimation data cannot tell two fits apart. The
//! profile intervals (`interval`), the seed spread (`fitting::SeededFit`)
//! and the ties of the final refits (`refits`) all use it, so it sits below
//! them.

/// `χ²` with one degree of freedom, 95 % quantile.
pub(super) const CHI2_1_95: f64 = 3.841;

/// The largest estimation SSE the likelihood-ratio test at 95 % cannot tell
/// from a fit at `best_sse` over `samples` residuals: `best_sse +
/// χ²₁(0.95)·σ̂²`, `σ̂² = best_sse/samples`. Fits below it are ones the
/// estimation data cannot tell apart (the seed spread of
/// `fitting::SeededFit`, the ties of `refits`).
pub(super) fn indistinguishable_up_to(best_sse: f64, samples: usize) -> f64 {
    best_sse + CHI2_1_95 * best_sse / samples.max(1) as f64
}
