//! ARX least squares, as MATLAB's `arx` with the thesis' conventions.
//!
//! Model, with `a` signs as eq. 12 writes them:
//! `y(k) = Σ_{i=1..na} a_i·y(k−i) + Σ_{j=1..nb} b_j·u(k−nk−j+1)`.
//! Orders (1, 1, 1) give eq. 12: `y(k) = a·y(k−1) + b·u(k−1)`.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::fit::{fit_percent, rmse};
use crate::data::Trace;
use crate::model::LinearPrior;
use crate::model::bounds::level_reach;
use crate::model::experiment::halves;

/// Orders of an ARX model: poles `na`, zeros+1 `nb`, input delay `nk`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ArxOrders {
    pub na: usize,
    pub nb: usize,
    pub nk: usize,
}

impl Default for ArxOrders {
    /// One pole, one zero, one sample of delay: the thesis' choice (§4.3.1).
    fn default() -> Self {
        ArxOrders {
            na: 1,
            nb: 1,
            nk: 1,
        }
    }
}

impl ArxOrders {
    /// Samples of history a prediction needs (saturating: orders from a
    /// flag can be any `usize`, and a count that wraps would pass the
    /// length checks).
    pub fn lag(&self) -> usize {
        self.na
            .max(self.nk.saturating_add(self.nb.saturating_sub(1)))
    }
}

#[derive(Debug, Error, PartialEq)]
pub enum IdentError {
    #[error("ARX orders need na ≥ 0, nb ≥ 1 (got na={na}, nb={nb}, nk={nk})")]
    Orders { na: usize, nb: usize, nk: usize },
    #[error(
        "{data}: {len} samples are too few for ARX orders (na={na}, nb={nb}, nk={nk}); need at least {need}"
    )]
    TooShort {
        data: String,
        len: usize,
        need: usize,
        na: usize,
        nb: usize,
        nk: usize,
    },
    #[error(
        "{data}: the input `{column}` is constant over the estimation half, so nothing about the dynamics can be learnt from it"
    )]
    ConstantInput { data: String, column: String },
    #[error(
        "{data}: the output `{column}` is constant over the estimation half, so there is no response to identify"
    )]
    ConstantOutput { data: String, column: String },
    #[error(
        "{data}: the input `{input}` and the output `{output}` hold the same values: name the measured response with --output"
    )]
    SameColumns {
        data: String,
        input: String,
        output: String,
    },
    #[error(
        "{data}: the least-squares problem is singular: the regressors are linearly dependent, \
         or their sizes lie more than 10 decades apart (root mean square of the output {output_rms:.3e}, \
         of the input {input_rms:.3e}: check the units, and for a value far from the rest){hint}"
    )]
    Singular {
        data: String,
        output_rms: f64,
        input_rms: f64,
        /// Lower orders to try, where there are any.
        hint: String,
    },
    #[error("no data to identify from")]
    NoData,
}

/// An identified ARX model in deviation coordinates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Arx {
    pub orders: ArxOrders,
    /// Output coefficients `a_1..a_na`.
    pub a: Vec<f64>,
    /// Input coefficients `b_1..b_nb`.
    pub b: Vec<f64>,
}

impl Arx {
    /// Least squares on deviation data `u`, `y` (means already removed).
    pub fn estimate(
        source: &str,
        u: &[f64],
        y: &[f64],
        orders: ArxOrders,
    ) -> Result<Arx, IdentError> {
        let ArxOrders { na, nb, nk } = orders;
        if nb == 0 {
            return Err(IdentError::Orders { na, nb, nk });
        }
        let lag = orders.lag();
        let cols = na.saturating_add(nb);
        let need = lag.saturating_add(cols).saturating_add(1);
        if y.len() < need {
            return Err(IdentError::TooShort {
                data: source.into(),
                len: y.len(),
                need,
                na,
                nb,
                nk,
            });
        }
        let rows = y.len() - lag;
        let phi = DMatrix::from_fn(rows, cols, |r, c| {
            let k = r + lag;
            if c < na {
                y[k - 1 - c]
            } else {
                u[k - nk - (c - na)]
            }
        });
        let target = DVector::from_fn(rows, |r, _| y[r + lag]);
        let svd = phi.svd(true, true);
        let smax = svd.singular_values.max();
        let smin = svd.singular_values.min();
        let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
        let singular = || IdentError::Singular {
            data: source.into(),
            output_rms: rms(y),
            input_rms: rms(u),
            hint: if cols > 2 {
                "; or try lower orders".into()
            } else {
                String::new()
            },
        };
        // NaN singular values count as singular.
        let conditioned = smin > smax * 1e-10;
        if !conditioned {
            return Err(singular());
        }
        let theta = svd.solve(&target, smax * 1e-12).map_err(|_| singular())?;
        Ok(Arx {
            orders,
            a: theta.as_slice()[..na].to_vec(),
            b: theta.as_slice()[na..].to_vec(),
        })
    }

    /// Free-run simulation on input `u`, the first `lag` outputs taken from
    /// `y_init` (measured), as MATLAB's `compare` with measured initial values.
    pub fn simulate(&self, u: &[f64], y_init: &[f64]) -> Vec<f64> {
        let ArxOrders { na, nb, nk } = self.orders;
        let lag = self.orders.lag().min(u.len());
        let mut y: Vec<f64> = y_init[..lag].to_vec();
        for k in lag..u.len() {
            let mut v = 0.0;
            for i in 0..na {
                v += self.a[i] * y[k - 1 - i];
            }
            for j in 0..nb {
                v += self.b[j] * u[k - nk - j];
            }
            y.push(v);
        }
        y
    }

    /// Static gain `Σb / (1 − Σa)`.
    pub fn dc_gain(&self) -> f64 {
        self.b.iter().sum::<f64>() / (1.0 - self.a.iter().sum::<f64>())
    }
}

/// The thesis' identification: means of the estimation half removed, ARX on
/// the first half, free-run fit on the second.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Identification {
    pub source: String,
    pub arx: Arx,
    pub input_mean: f64,
    pub output_mean: f64,
    pub samples: usize,
    pub dt: f64,
    /// Fit % (MATLAB `compare`) of the free-run simulation on the estimation half.
    pub estimation_fit_percent: f64,
    /// Fit % on the validation half, simulated from the half's own first
    /// samples (MATLAB `compare` on the validation data): the number the
    /// thesis reports.
    pub validation_fit_percent: f64,
    pub validation_rmse: f64,
    /// Fit % on the validation half of the simulation run on from the
    /// record's first sample: how `fit` scores its ARX yardstick and
    /// `simulate` a model, which carries the estimation half's end state
    /// into the validation half.
    pub continued_validation_fit_percent: f64,
}

pub fn identify(trace: &Trace, orders: ArxOrders) -> Result<Identification, IdentError> {
    // Each half needs the samples an estimate does (Arx::estimate), and is
    // checked first: a half of one sample is "constant" too.
    let need = orders
        .lag()
        .saturating_add(orders.na)
        .saturating_add(orders.nb)
        .saturating_add(1)
        .saturating_mul(2);
    if trace.len() < need {
        let ArxOrders { na, nb, nk } = orders;
        return Err(IdentError::TooShort {
            data: trace.source.clone(),
            len: trace.len(),
            need,
            na,
            nb,
            nk,
        });
    }
    let (est, val) = halves(trace.len());
    let est_len = est.len();
    let input_mean = trace.input[est.clone()].iter().sum::<f64>() / est_len.max(1) as f64;
    let output_mean = trace.output[est.clone()].iter().sum::<f64>() / est_len.max(1) as f64;
    let u: Vec<f64> = trace.input.iter().map(|p| p - input_mean).collect();
    let y: Vec<f64> = trace.output.iter().map(|l| l - output_mean).collect();
    if est_len > 0 && u[est.clone()].iter().all(|&v| v == u[est.start]) {
        return Err(IdentError::ConstantInput {
            data: trace.source.clone(),
            column: trace.input_name.clone(),
        });
    }
    if est_len > 0 && y[est.clone()].iter().all(|&v| v == y[est.start]) {
        return Err(IdentError::ConstantOutput {
            data: trace.source.clone(),
            column: trace.output_name.clone(),
        });
    }
    if trace.input == trace.output {
        return Err(IdentError::SameColumns {
            data: trace.source.clone(),
            input: trace.input_name.clone(),
            output: trace.output_name.clone(),
        });
    }
    let arx = Arx::estimate(&trace.source, &u[est.clone()], &y[est.clone()], orders)?;
    let sim_est = arx.simulate(&u[est.clone()], &y[est.clone()]);
    let sim_val = arx.simulate(&u[val.clone()], &y[val.clone()]);
    let sim_whole = arx.simulate(&u, &y);
    Ok(Identification {
        source: trace.source.clone(),
        arx,
        input_mean,
        output_mean,
        samples: trace.len(),
        dt: trace.dt(),
        estimation_fit_percent: fit_percent(&y[est], &sim_est),
        validation_fit_percent: fit_percent(&y[val.clone()], &sim_val),
        validation_rmse: rmse(&y[val.clone()], &sim_val),
        continued_validation_fit_percent: fit_percent(&y[val.clone()], &sim_whole[val]),
    })
}

/// What the data say about scale, for the boxes of `fit` and the
/// diagnosis alike: the first-order ARX pole and gain on the first trace's
/// estimation half ([`identify`]); the largest absolute input and output
/// (each at most [`crate::model::bounds::LEVEL_REACH`] times its span),
/// the output's range and its extremes over the estimation halves of all
/// of `traces`; and the first estimation half's output mean (absolute
/// units). Only the estimation halves are read: a box or a range taken
/// from the validation half would let the data a fit is scored on shape
/// the fit.
pub fn linear_prior(traces: &[Trace]) -> Result<LinearPrior, IdentError> {
    let first = traces.first().ok_or(IdentError::NoData)?;
    let id = identify(first, ArxOrders::default())?;
    fn estimation(t: &Trace) -> std::ops::Range<usize> {
        halves(t.len()).0
    }
    let estimation_halves = |column: fn(&Trace) -> &[f64]| -> Vec<f64> {
        traces
            .iter()
            .flat_map(|t| column(t)[estimation(t)].iter().copied())
            .collect()
    };
    let inputs = estimation_halves(|t| &t.input);
    let outputs = estimation_halves(|t| &t.output);
    let (est_output_min, est_output_max) = outputs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    let first_est = &first.output[estimation(first)];
    Ok(LinearPrior {
        a: id.arx.a[0],
        b: id.arx.b[0],
        max_abs_input: level_reach(&inputs),
        max_abs_output: level_reach(&outputs),
        output_range: crate::data::range(&outputs),
        est_output_min,
        est_output_max,
        output_mean: first_est.iter().sum::<f64>() / first_est.len() as f64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A record with no response, or whose output is its input, is named
    /// for what it is, not reported as a singular least-squares problem.
    #[test]
    fn a_record_with_nothing_to_identify_says_which_column() {
        let input: Vec<f64> = (0..400).map(|k| (k as f64 * 0.05).sin()).collect();
        let flat = Trace::uniform("flat.csv", 0.01, input.clone(), vec![4.5; 400]);
        let err = identify(&flat, ArxOrders::default())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("the output `displacement` is constant"),
            "{err}"
        );
        let same = Trace::uniform("same.csv", 0.01, input.clone(), input);
        let err = identify(&same, ArxOrders::default())
            .unwrap_err()
            .to_string();
        assert!(err.contains("hold the same values"), "{err}");
    }

    /// A record too short for its orders says so before anything else (a
    /// half of one sample is constant too), and one whose columns lie
    /// decades apart says their sizes, not only that it is singular.
    #[test]
    fn a_short_record_or_columns_decades_apart_say_so() {
        let two = Trace::uniform("two.csv", 0.01, vec![0.1, 0.2], vec![1.0, 2.0]);
        let err = identify(&two, ArxOrders::default()).unwrap_err();
        assert!(
            matches!(
                err,
                IdentError::TooShort {
                    len: 2,
                    need: 8,
                    ..
                }
            ),
            "{err}"
        );
        let input: Vec<f64> = (0..400).map(|k| (k as f64 * 0.05).sin()).collect();
        let output: Vec<f64> = (0..400).map(|k| 1e14 * (k as f64 * 0.07).cos()).collect();
        let apart = Trace::uniform("apart.csv", 0.01, input, output);
        let err = identify(&apart, ArxOrders::default())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("singular")
                && err.contains("of the output 7.")
                && !err.contains("lower orders"),
            "{err}"
        );
    }

    /// Orders as large as a flag can give are too long a history, not an
    /// index past the record (the lag wrapped round and passed the check).
    #[test]
    fn orders_past_any_record_are_an_error_not_a_wrap() {
        let input: Vec<f64> = (0..400).map(|k| (k as f64 * 0.05).sin()).collect();
        let output: Vec<f64> = input.iter().map(|u| 2.0 * u).collect();
        let trace = Trace::uniform("x.csv", 0.01, input, output);
        for orders in [
            ArxOrders {
                na: 1,
                nb: 1,
                nk: usize::MAX,
            },
            ArxOrders {
                na: usize::MAX,
                nb: 1,
                nk: 1,
            },
            ArxOrders {
                na: 1,
                nb: usize::MAX,
                nk: 1,
            },
        ] {
            let err = identify(&trace, orders).unwrap_err();
            assert!(
                matches!(err, IdentError::TooShort { .. }),
                "{orders:?}: {err}"
            );
        }
    }
}
