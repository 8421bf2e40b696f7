//! Fit measures.

/// MATLAB's `compare` fit: `100·(1 − ‖y − ŷ‖ / ‖y − mean(y)‖)` in percent.
/// `NaN` when `y` is constant (the measure is undefined) or lengths differ.
pub fn fit_percent(y: &[f64], y_hat: &[f64]) -> f64 {
    if y.len() != y_hat.len() || y.is_empty() {
        return f64::NAN;
    }
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let err: f64 = y
        .iter()
        .zip(y_hat)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    let spread: f64 = y.iter().map(|a| (a - mean).powi(2)).sum::<f64>().sqrt();
    if spread == 0.0 {
        f64::NAN
    } else {
        100.0 * (1.0 - err / spread)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perfect_and_mean_predictions() {
        let y = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(fit_percent(&y, &y), 100.0);
        assert!((fit_percent(&y, &[2.5; 4])).abs() < 1e-12);
        assert!(fit_percent(&[1.0; 3], &[1.0; 3]).is_nan());
        assert!((rmse(&y, &[2.0, 3.0, 4.0, 5.0]) - 1.0).abs() < 1e-12);
    }
}
