//! Ridge regression with its penalty chosen by blocked cross-validation: the
//! flexible model behind the explainable bound ([`explainable`](super::explainable)).
//!
//! Every feature is standardised on the training rows and the intercept is
//! not penalised, so one penalty grid suits features of any unit. The folds
//! are contiguous blocks of rows, not a shuffle: neighbouring samples of a
//! time series share their noise and their filter states, and a shuffled
//! fold would score a fit on rows it has nearly seen (Bergmeir & Benítez
//! 2012, "On the use of cross-validation for time series predictor
//! evaluation"). No random draw anywhere: the same rows give the same fit.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// Settings of the fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RidgeSettings {
    /// Contiguous blocks of the cross-validation (5: each fit sees 80 % of
    /// the rows, the usual compromise between bias and variance of the score).
    pub folds: usize,
    /// Penalties tried, relative to the number of training rows on
    /// standardised features: half decades from 1e-6 (nearly least squares)
    /// to 1e3 (nearly the mean alone).
    pub lambdas: Vec<f64>,
}

impl Default for RidgeSettings {
    fn default() -> Self {
        RidgeSettings {
            folds: 5,
            lambdas: (0..=18)
                .map(|i| 10f64.powf(-6.0 + 0.5 * i as f64))
                .collect(),
        }
    }
}

/// A fitted ridge model on some columns of the rows:
/// `ŷ = c + Σ_j w_j·(x_j − m_j)/s_j`.
#[derive(Debug, Clone, PartialEq)]
pub struct Ridge {
    pub lambda: f64,
    /// Mean cross-validated squared error at `lambda`.
    pub cv_mse: f64,
    /// The columns used (non-constant ones of those asked for), their
    /// means, scales and weights.
    cols: Vec<usize>,
    mean: Vec<f64>,
    scale: Vec<f64>,
    intercept: f64,
    weights: Vec<f64>,
}

/// Column means and standard deviations of `rows` (a constant column gets
/// scale 0 and is left out of every fit).
fn moments(rows: &[Vec<f64>], p: usize) -> (Vec<f64>, Vec<f64>) {
    let n = rows.len().max(1) as f64;
    let mut mean = vec![0.0; p];
    for r in rows {
        for (m, v) in mean.iter_mut().zip(r) {
            *m += v / n;
        }
    }
    let mut var = vec![0.0; p];
    for r in rows {
        for ((s, v), m) in var.iter_mut().zip(r).zip(&mean) {
            *s += (v - m).powi(2) / n;
        }
    }
    let scale = var
        .iter()
        .zip(&mean)
        .map(|(&v, m)| {
            // Constant up to rounding: no information, and dividing by it
            // would blow rounding up to unit size.
            let sd = v.sqrt();
            if sd > 1e-12 * (1.0 + m.abs()) {
                sd
            } else {
                0.0
            }
        })
        .collect();
    (mean, scale)
}

/// Gram matrix `ZᵀZ` and `Zᵀt` of the standardised rows `Z` (every column,
/// with a leading 1 for the intercept), accumulated over `range`.
fn gram(
    x: &[Vec<f64>],
    t: &[f64],
    range: std::ops::Range<usize>,
    mean: &[f64],
    scale: &[f64],
) -> (DMatrix<f64>, DVector<f64>) {
    let q = 1 + mean.len();
    let mut g = DMatrix::zeros(q, q);
    let mut b = DVector::zeros(q);
    let mut z = vec![0.0; q];
    for k in range {
        z[0] = 1.0;
        for (j, ((v, m), s)) in x[k].iter().zip(mean).zip(scale).enumerate() {
            z[j + 1] = if *s > 0.0 { (v - m) / s } else { 0.0 };
        }
        for a in 0..q {
            b[a] += z[a] * t[k];
            for c in a..q {
                g[(a, c)] += z[a] * z[c];
            }
        }
    }
    for a in 0..q {
        for c in 0..a {
            g[(a, c)] = g[(c, a)];
        }
    }
    (g, b)
}

/// Solves `(G + λ·n·D)w = b` on the Gram indices `idx` (0, the intercept,
/// first and unpenalised).
fn solve(
    g: &DMatrix<f64>,
    b: &DVector<f64>,
    idx: &[usize],
    lambda: f64,
    n: usize,
) -> Option<DVector<f64>> {
    let q = idx.len();
    let a = DMatrix::from_fn(q, q, |i, j| {
        g[(idx[i], idx[j])]
            + if i == j && i > 0 {
                lambda * n as f64
            } else {
                0.0
            }
    });
    let rhs = DVector::from_fn(q, |i, _| b[idx[i]]);
    a.cholesky().map(|c| c.solve(&rhs))
}

/// A regression problem prepared for fits on any subset of its columns:
/// the Gram matrices of all rows and of each held-out block are computed
/// once, and a subset's are their submatrices.
pub struct Problem<'a> {
    x: &'a [Vec<f64>],
    t: &'a [f64],
    settings: &'a RidgeSettings,
    mean: Vec<f64>,
    scale: Vec<f64>,
    all: (DMatrix<f64>, DVector<f64>),
    held: Vec<(std::ops::Range<usize>, DMatrix<f64>, DVector<f64>)>,
}

impl<'a> Problem<'a> {
    /// `x`: rows in time order; `t`: the targets.
    pub fn new(
        x: &'a [Vec<f64>],
        t: &'a [f64],
        settings: &'a RidgeSettings,
    ) -> anyhow::Result<Problem<'a>> {
        let n = x.len();
        anyhow::ensure!(n == t.len(), "ridge: {n} rows but {} targets", t.len());
        let folds = settings.folds.max(2);
        anyhow::ensure!(
            n >= 2 * folds,
            "ridge: {n} rows are too few for {folds} folds"
        );
        let (mean, scale) = moments(x, x.first().map_or(0, Vec::len));
        let all = gram(x, t, 0..n, &mean, &scale);
        let held = (0..folds)
            .map(|f| {
                let range = f * n / folds..(f + 1) * n / folds;
                let (g, b) = gram(x, t, range.clone(), &mean, &scale);
                (range, g, b)
            })
            .collect();
        Ok(Problem {
            x,
            t,
            settings,
            mean,
            scale,
            all,
            held,
        })
    }

    /// Fits on the columns `cols`, the penalty chosen by blocked
    /// cross-validation over the settings' grid: the one with the lowest
    /// mean squared error on the held-out blocks. `None` if no penalty
    /// gives a finite fit.
    pub fn fit(&self, cols: &[usize]) -> Option<Ridge> {
        let cols: Vec<usize> = cols
            .iter()
            .copied()
            .filter(|&j| self.scale[j] > 0.0)
            .collect();
        let idx: Vec<usize> = std::iter::once(0)
            .chain(cols.iter().map(|j| j + 1))
            .collect();
        let n = self.t.len();
        let (g_all, b_all) = &self.all;
        let mut best: Option<(f64, f64)> = None;
        for &lambda in &self.settings.lambdas {
            let mut sse = 0.0;
            for (range, g_f, b_f) in &self.held {
                let Some(w) = solve(
                    &(g_all - g_f),
                    &(b_all - b_f),
                    &idx,
                    lambda,
                    n - range.len(),
                ) else {
                    sse = f64::INFINITY;
                    break;
                };
                let fit = self.ridge(&cols, &w, lambda, 0.0);
                sse += range
                    .clone()
                    .map(|k| (self.t[k] - fit.predict(&self.x[k])).powi(2))
                    .sum::<f64>();
            }
            let mse = sse / n as f64;
            if mse.is_finite() && best.is_none_or(|(_, m)| mse < m) {
                best = Some((lambda, mse));
            }
        }
        let (lambda, cv_mse) = best?;
        let w = solve(g_all, b_all, &idx, lambda, n)?;
        Some(self.ridge(&cols, &w, lambda, cv_mse))
    }

    fn ridge(&self, cols: &[usize], w: &DVector<f64>, lambda: f64, cv_mse: f64) -> Ridge {
        Ridge {
            lambda,
            cv_mse,
            cols: cols.to_vec(),
            mean: cols.iter().map(|&j| self.mean[j]).collect(),
            scale: cols.iter().map(|&j| self.scale[j]).collect(),
            intercept: w[0],
            weights: w.iter().skip(1).copied().collect(),
        }
    }
}

impl Ridge {
    pub fn predict(&self, row: &[f64]) -> f64 {
        self.intercept
            + self
                .cols
                .iter()
                .zip(&self.mean)
                .zip(&self.scale)
                .zip(&self.weights)
                .map(|(((&j, m), s), w)| w * (row[j] - m) / s)
                .sum::<f64>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// A fit on every column of `x`.
    fn fit_all(x: &[Vec<f64>], t: &[f64]) -> Ridge {
        let settings = RidgeSettings::default();
        let p = x[0].len();
        Problem::new(x, t, &settings)
            .unwrap()
            .fit(&(0..p).collect::<Vec<_>>())
            .unwrap()
    }

    fn draws(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let d = Normal::new(0.0, 1.0).unwrap();
        (0..n).map(|_| d.sample(&mut rng)).collect()
    }

    /// Rows of `p` independent normal features, `n` of them.
    fn rows(n: usize, p: usize, seed: u64) -> Vec<Vec<f64>> {
        let z = draws(n * p, seed);
        z.chunks(p).map(<[f64]>::to_vec).collect()
    }

    #[test]
    fn a_clean_linear_target_is_recovered_with_a_small_penalty() {
        let x = rows(400, 6, 1);
        let w = [1.0, -2.0, 0.5, 0.0, 3.0, -1.0];
        let t: Vec<f64> = x
            .iter()
            .map(|r| 4.0 + r.iter().zip(&w).map(|(a, b)| a * b).sum::<f64>())
            .collect();
        let fit = fit_all(&x, &t);
        assert!(fit.lambda <= 1e-4, "λ {}", fit.lambda);
        let probe = [0.3, -1.0, 2.0, 5.0, 0.1, 0.0];
        let want = 4.0 + probe.iter().zip(&w).map(|(a, b)| a * b).sum::<f64>();
        assert!(
            (fit.predict(&probe) - want).abs() < 1e-3,
            "{}",
            fit.predict(&probe)
        );
    }

    #[test]
    fn a_target_unrelated_to_the_features_gets_a_large_penalty() {
        let x = rows(400, 20, 2);
        let t = draws(400, 3);
        let fit = fit_all(&x, &t);
        assert!(fit.lambda >= 1.0, "λ {}", fit.lambda);
        // Predictions shrink to about the mean.
        let mean = t.iter().sum::<f64>() / t.len() as f64;
        let spread = rows(50, 20, 4)
            .iter()
            .map(|r| (fit.predict(r) - mean).abs())
            .fold(0.0, f64::max);
        assert!(spread < 0.2, "{spread}");
    }

    #[test]
    fn constant_and_collinear_columns_do_not_break_the_fit() {
        let x: Vec<Vec<f64>> = rows(200, 2, 5)
            .into_iter()
            .map(|r| vec![r[0], 2.0 * r[0], 7.0, r[1]])
            .collect();
        let t: Vec<f64> = x.iter().map(|r| r[0] + r[3]).collect();
        let fit = fit_all(&x, &t);
        let got = fit.predict(&[1.0, 2.0, 7.0, 1.0]);
        assert!((got - 2.0).abs() < 1e-2, "{got}");
    }
}
