//! Fit measures.

/// MATLAB's `compare` fit: `100·(1 − ‖y − ŷ‖ / ‖y − mean(y)‖)` in percent.
/// `NaN` when `y` is constant (the measure is undefined) or lengths differ.
pub fn fit_percent(y: &[f64], y_hat: &[f64]) -> f64 {
    pooled_fit_percent(&[(y, y_hat)])
}

/// The fit of several records `(y, ŷ)` as one figure: `100·(1 − ‖y − ŷ‖ /
/// ‖y − mean‖)` over all their samples, each record's deviations taken from
/// its own mean. One mean for all would count the records' different
/// levels (a load, a sensor's zero) as output the model explains, and a
/// record the model misses would hide behind the others. One record:
/// [`fit_percent`]'s figure, bit for bit. `NaN` where every record is
/// constant, a record's lengths differ, or there is none. Constant means
/// to the rounding of its values: a sensor frozen at 7.5 mm, in
/// coordinates about another mean, spreads by the rounding of that mean
/// alone (10⁻¹² of the values), which would divide the error into a fit
/// of −10¹⁶ %.
pub fn pooled_fit_percent(records: &[(&[f64], &[f64])]) -> f64 {
    if records.is_empty()
        || records
            .iter()
            .any(|(y, y_hat)| y.len() != y_hat.len() || y.is_empty())
    {
        return f64::NAN;
    }
    let err: f64 = records
        .iter()
        .flat_map(|(y, y_hat)| y.iter().zip(y_hat.iter()))
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    let spread: f64 = records
        .iter()
        .flat_map(|(y, _)| {
            let mean = y.iter().sum::<f64>() / y.len() as f64;
            y.iter().map(move |a| (a - mean).powi(2))
        })
        .sum::<f64>()
        .sqrt();
    let level: f64 = records
        .iter()
        .flat_map(|(y, _)| y.iter().map(|a| a * a))
        .sum::<f64>()
        .sqrt();
    if spread <= CONSTANT_TO * level {
        f64::NAN
    } else {
        100.0 * (1.0 - err / spread)
    }
}

/// The spread about the mean, as a share of the values' own size, below
/// which an output counts as constant ([`pooled_fit_percent`]): far below
/// any sensor's resolution (a nanometre in a metre), far above the
/// rounding of a mean of doubles (about 10⁻¹⁵ a sample).
const CONSTANT_TO: f64 = 1e-9;

/// The warning a validation half owes its user where its output is
/// constant (`which`: "" for one record, " of FILE, …" for some of several):
/// the fit % is undefined there, and the RMSE alone checks only a level.
pub fn constant_validation_warning(which: &str) -> String {
    format!(
        "the output is constant over the validation half{which}: its fit % is undefined (it \
         divides by the output's spread), and its RMSE says only how near the model holds that \
         one level; validate on a record whose second half moves"
    )
}

/// A validation fit % as the reports print it, to `decimals`: `None` is a
/// run that diverged, or, where its RMSE is finite (`scored`), an output
/// constant over the half, where the measure is undefined.
pub fn fit_percent_text(fit: Option<f64>, scored: bool, decimals: usize) -> String {
    match (fit, scored) {
        (Some(v), _) => format!("{v:.decimals$} %"),
        (None, true) => "undefined".into(),
        (None, false) => "diverged".into(),
    }
}

/// Root-mean-square difference.
pub fn rmse(y: &[f64], y_hat: &[f64]) -> f64 {
    if y.len() != y_hat.len() || y.is_empty() {
        return f64::NAN;
    }
    (y.iter()
        .zip(y_hat)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        / y.len() as f64)
        .sqrt()
}

/// `χ²` with one degree of freedom, 95 % quantile.
pub const CHI2_1_95: f64 = 3.841;

/// Validation fit-% points within which two fits count as the same answer:
/// the diagnosis' refits (`diagnose::refits`) and `fit --from` against its
/// start judge by it.
pub const SETTLED_POINTS: f64 = 2.0;

/// The largest estimation SSE the likelihood-ratio test at 95 % cannot tell
/// from a fit at `best_sse` over `samples` residuals: `best_sse +
/// χ²₁(0.95)·σ̂²`, `σ̂² = best_sse/samples`. Fits below it are ones the
/// estimation data cannot tell apart (the diagnosis' seed spread and refits,
/// the generated cases' second pass rule).
pub fn indistinguishable_up_to(best_sse: f64, samples: usize) -> f64 {
    best_sse + CHI2_1_95 * best_sse / samples.max(1) as f64
}

/// Area enclosed by the input–output path `(u(k), y(k))`, closed back to its
/// start (shoelace formula, absolute value). A rate-independent hysteresis
/// traversed by a stair up and down encloses a loop of non-zero area; a
/// static or linear-and-slow map encloses (almost) none.
pub fn loop_area(u: &[f64], y: &[f64]) -> f64 {
    let n = u.len().min(y.len());
    if n < 3 {
        return 0.0;
    }
    let twice: f64 = (0..n)
        .map(|k| {
            let j = (k + 1) % n;
            u[k] * y[j] - u[j] * y[k]
        })
        .sum();
    0.5 * twice.abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perfect_and_mean_predictions() {
        let y = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(fit_percent(&y, &y), 100.0);
        assert!((fit_percent(&y, &[2.5; 4])).abs() < 1e-12);
        assert!(fit_percent(&[1.0; 3], &[1.0; 3]).is_nan());
        // Constant in coordinates about another mean: its spread is the
        // mean's rounding, not a motion to score against.
        let frozen = vec![7.5 - 10.973269; 2000];
        assert!(
            frozen
                .iter()
                .map(|v| v - frozen.iter().sum::<f64>() / 2000.0)
                .any(|d| d != 0.0)
        );
        assert!(fit_percent(&frozen, &[0.0; 2000]).is_nan());
        // A motion of a micrometre on an offset of 250 mm is still one.
        let small: Vec<f64> = (0..2000)
            .map(|k| 250.0 + 1e-3 * (k as f64 * 0.01).sin())
            .collect();
        assert!(fit_percent(&small, &small) == 100.0);
        assert!((rmse(&y, &[2.0, 3.0, 4.0, 5.0]) - 1.0).abs() < 1e-12);
    }

    /// Records at different levels pool without their levels counting as
    /// explained: a record the model meets only at its mean pulls the pooled
    /// fit down as far as its share of the spread, not to nothing.
    #[test]
    fn pooled_records_count_each_ones_spread_about_its_own_mean() {
        let (near, far) = ([0.0, 1.0, 0.0, 1.0], [100.0, 101.0, 100.0, 101.0]);
        let pooled = pooled_fit_percent(&[(&near, &near), (&far, &[100.5; 4])]);
        let expected = 100.0 * (1.0 - 1.0 / 2f64.sqrt());
        assert!((pooled - expected).abs() < 1e-12, "{pooled}");
        // One mean for both would have called it 99 %.
        let joined: Vec<f64> = near.iter().chain(&far).copied().collect();
        let predicted: Vec<f64> = near.iter().chain(&[100.5; 4]).copied().collect();
        assert!(fit_percent(&joined, &predicted) > 99.0);
        assert_eq!(
            pooled_fit_percent(&[(&near, &[0.5; 4])]),
            fit_percent(&near, &[0.5; 4])
        );
        assert!(pooled_fit_percent(&[]).is_nan());
    }

    #[test]
    fn unit_square_and_a_line() {
        assert_eq!(loop_area(&[0.0, 1.0, 1.0, 0.0], &[0.0, 0.0, 1.0, 1.0]), 1.0);
        assert_eq!(loop_area(&[0.0, 1.0, 2.0, 1.0], &[0.0, 1.0, 2.0, 1.0]), 0.0);
    }
}
