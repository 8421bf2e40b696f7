//! ARX least squares, as MATLAB's `arx` with the thesis' conventions.
//!
//! Model, with `a` signs as eq. 12 writes them:
//! `y(k) = Σ_{i=1..na} a_i·y(k−i) + Σ_{j=1..nb} b_j·u(k−nk−j+1)`.
//! Orders (1, 1, 1) give eq. 12: `y(k) = a·y(k−1) + b·u(k−1)`.

use std::ops::Range;

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::fit::{fit_percent, pooled_fit_percent, rmse};
use crate::data::Trace;
use crate::model::bounds::level_reach;
use crate::model::experiment::halves;
use crate::model::{Family, FittedBaseline, LinearPrior, ModelFile};

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
    #[error(
        "{data}: the column `{column}` reaches {reach:e} from its mean: its squares overflow \
         double precision, and every figure would be infinite; rescale the column (for example \
         Pa to MPa, or m to mm)"
    )]
    TooLarge {
        data: String,
        column: String,
        reach: f64,
    },
    #[error("no data to identify from")]
    NoData,
    /// Records one model cannot take together (other sample times,
    /// other columns, one record twice): the reason.
    #[error("{0}")]
    Unlike(String),
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
    /// The largest modulus of the model's poles, the roots of
    /// `z^na − a_1·z^(na−1) − … − a_na` (the eigenvalues of its companion
    /// matrix): at 1 or past it the free run does not settle, it drifts or
    /// grows without bound. 0 for a model without poles.
    pub fn largest_pole(&self) -> f64 {
        let na = self.a.len();
        if na == 0 {
            return 0.0;
        }
        let companion = DMatrix::from_fn(na, na, |i, j| match i {
            0 => self.a[j],
            _ => f64::from(j + 1 == i),
        });
        companion
            .complex_eigenvalues()
            .iter()
            .map(|z| z.norm())
            .fold(0.0, f64::max)
    }

    /// Least squares on deviation data `u`, `y` (means already removed).
    pub fn estimate(
        source: &str,
        u: &[f64],
        y: &[f64],
        orders: ArxOrders,
    ) -> Result<Arx, IdentError> {
        Arx::estimate_on(source, &[(u, y)], orders)
    }

    /// Least squares over several stretches of deviation data `(u, y)`
    /// (MATLAB's `arx` on `merge`d experiments): each stretch gives the
    /// rows its own history allows, and no regressor reaches from one
    /// stretch into the next, where the records are not continuous.
    pub fn estimate_on(
        source: &str,
        stretches: &[(&[f64], &[f64])],
        orders: ArxOrders,
    ) -> Result<Arx, IdentError> {
        let ArxOrders { na, nb, nk } = orders;
        if nb == 0 {
            return Err(IdentError::Orders { na, nb, nk });
        }
        let lag = orders.lag();
        let cols = na.saturating_add(nb);
        let len: usize = stretches.iter().map(|(_, y)| y.len()).sum();
        let rows: usize = stretches
            .iter()
            .map(|(_, y)| y.len().saturating_sub(lag))
            .sum();
        if rows <= cols {
            return Err(IdentError::TooShort {
                data: source.into(),
                len,
                need: lag.saturating_add(cols).saturating_add(1),
                na,
                nb,
                nk,
            });
        }
        // (stretch, sample) of each row.
        let at: Vec<(usize, usize)> = stretches
            .iter()
            .enumerate()
            .flat_map(|(s, (_, y))| (lag..y.len()).map(move |k| (s, k)))
            .collect();
        let phi = DMatrix::from_fn(rows, cols, |r, c| {
            let (s, k) = at[r];
            let (u, y) = stretches[s];
            if c < na {
                y[k - 1 - c]
            } else {
                u[k - nk - (c - na)]
            }
        });
        let target = DVector::from_fn(rows, |r, _| {
            let (s, k) = at[r];
            stretches[s].1[k]
        });
        let svd = phi.svd(true, true);
        let smax = svd.singular_values.max();
        let smin = svd.singular_values.min();
        let rms = |input: bool| {
            let squares: f64 = stretches
                .iter()
                .flat_map(|&(u, y)| if input { u } else { y })
                .map(|x| x * x)
                .sum();
            (squares / len as f64).sqrt()
        };
        let singular = || IdentError::Singular {
            data: source.into(),
            output_rms: rms(false),
            input_rms: rms(true),
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
}

/// The thesis' identification: means of the estimation half removed, ARX on
/// the first half, free-run fit on the second. Of several records (one
/// muscle, several experiments): one model for all, as MATLAB's `arx` on
/// `merge`d data; see [`identify_jointly`].
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
    /// Each record's own scores, where there are several (the figures
    /// above then pool them, [`pooled_fit_percent`]); empty for one.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub records: Vec<RecordArxScore>,
}

impl Identification {
    /// The first-order model (`--na 1 --nb 1 --nk 1`, eq. 12) as the linear
    /// family that `fit`, `simulate` and `control` read, on the columns of
    /// `trace` (the record, or the first of several, it was identified
    /// on); `None` for other orders, which no model file holds.
    pub fn first_order_model(&self, trace: &Trace) -> Option<FittedBaseline> {
        (self.arx.orders == ArxOrders::default()).then(|| FittedBaseline {
            family: Family::Linear,
            params: vec![self.arx.a[0], self.arx.b[0], 0.0, 0.0],
            input_mean: self.input_mean,
            output_mean: self.output_mean,
            dt: self.dt,
            input_name: trace.input_name.clone(),
            output_name: trace.output_name.clone(),
        })
    }
}

/// `identify --json`'s document for one identification: its figures and,
/// for the first order, its model file.
#[derive(Debug, Serialize)]
pub struct IdentifyJson<'a> {
    #[serde(flatten)]
    pub identification: &'a Identification,
    /// The first-order model as a model file (what `fit`, `simulate` and
    /// `control` read), when the orders are (1, 1, 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model: Option<ModelFile>,
}

/// One record's scores under a model identified on several.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordArxScore {
    pub data: String,
    pub samples: usize,
    pub estimation_fit_percent: f64,
    pub validation_fit_percent: f64,
    pub validation_rmse: f64,
    pub continued_validation_fit_percent: f64,
}

pub fn identify(trace: &Trace, orders: ArxOrders) -> Result<Identification, IdentError> {
    identify_jointly(std::slice::from_ref(trace), orders)
}

/// One ARX model for several records of one muscle, each split in halves:
/// the means of all estimation halves together removed (one operating
/// point, as one model file holds), least squares over every estimation
/// half ([`Arx::estimate_on`]), and each record simulated on its own. The
/// figures pool the records, each record's deviations about its own mean
/// ([`pooled_fit_percent`]); `records` gives each one's. One record: the
/// thesis' identification, and no `records`.
pub fn identify_jointly(traces: &[Trace], orders: ArxOrders) -> Result<Identification, IdentError> {
    let first = traces.first().ok_or(IdentError::NoData)?;
    if let Some(why) =
        crate::data::mixed_steps(traces).or_else(|| crate::data::unlike_records(traces))
    {
        return Err(IdentError::Unlike(why));
    }
    // Each half needs the samples an estimate does (Arx::estimate), and is
    // checked first: a half of one sample is "constant" too.
    let need = orders
        .lag()
        .saturating_add(orders.na)
        .saturating_add(orders.nb)
        .saturating_add(1)
        .saturating_mul(2);
    for trace in traces {
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
    }
    let source = crate::data::sources(traces);
    let estimation = |column: fn(&Trace) -> &[f64]| -> Vec<f64> {
        traces
            .iter()
            .flat_map(|t| column(t)[halves(t.len()).0].iter().copied())
            .collect()
    };
    let (est_u, est_y) = (estimation(|t| &t.input), estimation(|t| &t.output));
    let input_mean = est_u.iter().sum::<f64>() / est_u.len() as f64;
    let output_mean = est_y.iter().sum::<f64>() / est_y.len() as f64;
    let constant = |v: &[f64]| v.iter().all(|&x| x == v[0]);
    if constant(&est_u) {
        return Err(IdentError::ConstantInput {
            data: source,
            column: first.input_name.clone(),
        });
    }
    if constant(&est_y) {
        return Err(IdentError::ConstantOutput {
            data: source,
            column: first.output_name.clone(),
        });
    }
    if let Some(trace) = traces.iter().find(|t| t.input == t.output) {
        return Err(IdentError::SameColumns {
            data: trace.source.clone(),
            input: trace.input_name.clone(),
            output: trace.output_name.clone(),
        });
    }
    let deviations: Vec<(Vec<f64>, Vec<f64>)> = traces
        .iter()
        .map(|t| {
            (
                t.input.iter().map(|p| p - input_mean).collect(),
                t.output.iter().map(|l| l - output_mean).collect(),
            )
        })
        .collect();
    // The sums of squares over every sample must stay finite.
    let samples: usize = traces.iter().map(Trace::len).sum();
    let limit = f64::MAX.sqrt() / (samples as f64).sqrt() * 1e-3;
    for (trace, (u, y)) in traces.iter().zip(&deviations) {
        for (column, values) in [(&trace.input_name, u), (&trace.output_name, y)] {
            // A NaN deviation (about a mean whose sum overflowed) is past it too.
            let reach = match values.iter().any(|v| v.is_nan()) {
                true => f64::INFINITY,
                false => values.iter().fold(0.0f64, |m, v| m.max(v.abs())),
            };
            if reach > limit {
                return Err(IdentError::TooLarge {
                    data: trace.source.clone(),
                    column: column.clone(),
                    reach,
                });
            }
        }
    }
    let stretches: Vec<(&[f64], &[f64])> = deviations
        .iter()
        .map(|(u, y)| {
            let est = halves(y.len()).0;
            (&u[est.clone()], &y[est])
        })
        .collect();
    let arx = Arx::estimate_on(&source, &stretches, orders)?;
    // Per record: (y, simulated) on the estimation half, the validation
    // half from its own first samples, and the validation half of the
    // run from the record's first sample. A half's first `lag` samples
    // start its simulation as measured, so they are not scored: a fit
    // that counted them would grow towards 100 % with the delay `nk`.
    let lag = orders.lag();
    let runs: Vec<[(&[f64], Vec<f64>); 3]> = deviations
        .iter()
        .map(|(u, y)| {
            let (est, val) = halves(y.len());
            let whole = arx.simulate(u, y);
            let simulated = |half: Range<usize>| {
                let run = arx.simulate(&u[half.clone()], &y[half.clone()]);
                (&y[half.start + lag..half.end], run[lag..].to_vec())
            };
            [
                simulated(est),
                simulated(val.clone()),
                (&y[val.clone()], whole[val].to_vec()),
            ]
        })
        .collect();
    let pooled = |which: usize| {
        let pairs: Vec<(&[f64], &[f64])> = runs
            .iter()
            .map(|r| (r[which].0, r[which].1.as_slice()))
            .collect();
        pooled_fit_percent(&pairs)
    };
    let (val_y, val_sim): (Vec<f64>, Vec<f64>) = runs
        .iter()
        .flat_map(|r| r[1].0.iter().copied().zip(r[1].1.iter().copied()))
        .unzip();
    let records = if traces.len() > 1 {
        traces
            .iter()
            .zip(&runs)
            .map(|(t, [est, val, continued])| RecordArxScore {
                data: t.source.clone(),
                samples: t.len(),
                estimation_fit_percent: fit_percent(est.0, &est.1),
                validation_fit_percent: fit_percent(val.0, &val.1),
                validation_rmse: rmse(val.0, &val.1),
                continued_validation_fit_percent: fit_percent(continued.0, &continued.1),
            })
            .collect()
    } else {
        Vec::new()
    };
    Ok(Identification {
        source,
        arx,
        input_mean,
        output_mean,
        samples: traces.iter().map(Trace::len).sum(),
        dt: first.dt(),
        estimation_fit_percent: pooled(0),
        validation_fit_percent: pooled(1),
        validation_rmse: rmse(&val_y, &val_sim),
        continued_validation_fit_percent: pooled(2),
        records,
    })
}

/// What the data say about scale, for the boxes of `fit` and the
/// diagnosis alike: the first-order ARX pole and gain on the first trace's
/// estimation half ([`identify`]), or where that pole is not in [0, 1)
/// those of the best stable first-order free run there
/// ([`stable_output_error`]); the largest absolute input and output
/// (each at most [`crate::model::bounds::LEVEL_REACH`] times its span),
/// the output's range and its extremes over the estimation halves of all
/// of `traces`; and the first estimation half's output mean (absolute
/// units). Only the estimation halves are read: a box or a range taken
/// from the validation half would let the data a fit is scored on shape
/// the fit.
pub fn linear_prior(traces: &[Trace]) -> Result<LinearPrior, IdentError> {
    let first = traces.first().ok_or(IdentError::NoData)?;
    let id = identify(first, ArxOrders::default())?;
    fn estimation(t: &Trace) -> Range<usize> {
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
    let (a, b) = match id.arx.a[0] {
        a if (0.0..1.0).contains(&a) => (a, id.arx.b[0]),
        _ => {
            let deviations = |v: &[f64], mean: f64| -> Vec<f64> {
                v[estimation(first)].iter().map(|x| x - mean).collect()
            };
            stable_output_error(
                &deviations(&first.input, id.input_mean),
                &deviations(&first.output, id.output_mean),
            )
            .unwrap_or((id.arx.a[0], id.arx.b[0]))
        }
    };
    Ok(LinearPrior {
        a,
        b,
        max_abs_input: level_reach(&inputs),
        max_abs_output: level_reach(&outputs),
        output_range: crate::data::range(&outputs),
        est_output_min,
        est_output_max,
        output_mean: first_est.iter().sum::<f64>() / first_est.len() as f64,
    })
}

/// Whether a pole of modulus `pole` is on or outside the unit circle, an
/// integrator's pole of 1 computed to within rounding of it included.
pub fn is_unstable(pole: f64) -> bool {
    pole >= 1.0 - 1e-9
}

/// The warning an ARX model whose poles are not all inside the unit circle
/// owes its user ([`Arx::largest_pole`]).
pub fn unstable_warning(arx: &Arx) -> Option<String> {
    let pole = arx.largest_pole();
    is_unstable(pole).then(|| {
        format!(
            "a pole of modulus {pole:.4} is on or outside the unit circle: the identified model is \
             unstable, and its free run drifts or grows without bound (least squares on one \
             step puts the pole of a record too short, or too little excited, at 1 or past \
             it)"
        )
    })
}

/// Poles [`stable_output_error`] tries: `1 − 10^(−t)` for `t` from 0 to 4
/// by 0.05, from 0 to 0.9999, as fine near 1, where a muscle sampled fast
/// has its pole, as far from it.
fn stable_poles() -> impl Iterator<Item = f64> {
    (0..=80).map(|i| 1.0 - 10f64.powf(-0.05 * i as f64))
}

/// The first-order model `x(k) = a·x(k−1) + b·u(k−1) + c`, `x(0) = y(0)`,
/// whose free run fits `y` best over the stable poles `a` in [0, 1)
/// (`stable_poles`; `b` and `c` by least squares for each): `(a, b)`,
/// or `None` where no pole gives a finite fit. What `fit`'s box is built
/// around where ARX's pole is no stable one: least squares on one step
/// puts the pole of a record too short, or too little excited, at 1 or
/// past it, where `b` can take either sign, and a box around that misses
/// the muscle's gain.
pub fn stable_output_error(u: &[f64], y: &[f64]) -> Option<(f64, f64)> {
    let n = u.len().min(y.len());
    if n < 3 {
        return None;
    }
    let mut best: Option<(f64, f64, f64)> = None;
    for a in stable_poles() {
        // x(k) = a^k·y(0) + b·su(k) + c·s1(k): least squares in b and c.
        let (mut su, mut s1, mut free) = (0.0, 0.0, y[0]);
        let [mut uu, mut u1, mut ones, mut ur, mut onr, mut rr] = [0.0; 6];
        for k in 1..n {
            su = a * su + u[k - 1];
            s1 = a * s1 + 1.0;
            free *= a;
            let r = y[k] - free;
            uu += su * su;
            u1 += su * s1;
            ones += s1 * s1;
            ur += su * r;
            onr += s1 * r;
            rr += r * r;
        }
        let det = uu * ones - u1 * u1;
        if det.is_nan() || det.abs() <= f64::EPSILON * uu * ones {
            continue;
        }
        let b = (ur * ones - onr * u1) / det;
        let c = (uu * onr - u1 * ur) / det;
        let sse = rr - b * ur - c * onr;
        if sse.is_finite() && best.is_none_or(|(_, _, s)| sse < s) {
            best = Some((a, b, sse));
        }
    }
    best.map(|(a, b, _)| (a, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arx(a: &[f64]) -> Arx {
        Arx {
            orders: ArxOrders {
                na: a.len(),
                nb: 1,
                nk: 1,
            },
            a: a.to_vec(),
            b: vec![1.0],
        }
    }

    /// The poles are the roots of `z² − a1·z − a2`: 1.00597 and 0.568 for
    /// a record's second-order ARX that drifts; a complex pair inside.
    #[test]
    fn the_largest_pole_is_the_companion_matrix_s_largest_eigenvalue() {
        let drifting = arx(&[1.574402, -0.571819]);
        let (a1, a2) = (1.574402f64, -0.571819f64);
        let root = (a1 + (a1 * a1 + 4.0 * a2).sqrt()) / 2.0;
        assert!((drifting.largest_pole() - root).abs() < 1e-9);
        assert!(unstable_warning(&drifting).is_some());
        // z² − z + 0.5: |z| = √0.5.
        let ringing = arx(&[1.0, -0.5]);
        assert!((ringing.largest_pole() - 0.5f64.sqrt()).abs() < 1e-12);
        assert!(unstable_warning(&ringing).is_none());
        assert_eq!(arx(&[-1.2]).largest_pole(), 1.2);
        assert_eq!(arx(&[]).largest_pole(), 0.0);
    }

    /// A first-order run is recovered from its free run, noise and all,
    /// to the grid's step in the pole.
    #[test]
    fn the_stable_output_error_fit_finds_a_first_order_system() {
        let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(3);
        let u: Vec<f64> = (0..2000).map(|k| f64::from((k / 150) % 2 == 1)).collect();
        let (a, b) = (0.95, 2.0);
        let mut y = vec![0.0; u.len()];
        for k in 1..u.len() {
            y[k] = a * y[k - 1] + b * u[k - 1];
        }
        let noisy: Vec<f64> = y
            .iter()
            .map(|v| v + 0.1 * rand::RngExt::random_range(&mut rng, -1.0..1.0))
            .collect();
        let (fa, fb) = stable_output_error(&u, &noisy).unwrap();
        // The grid's poles near 0.95: 1 − 10^(−1.3) = 0.9499.
        assert!((fa - a).abs() < 0.01, "{fa}");
        assert!((fb / (1.0 - fa) - b / (1.0 - a)).abs() < 0.5, "{fa} {fb}");
    }

    /// A record whose one-step least squares puts the pole past 1 (the
    /// shipped stair's first 25 s: its estimation half rises and falls
    /// once) gets a box around a stable pole and the gain's sign of the
    /// whole record, not ARX's `b` of the wrong sign.
    #[test]
    fn an_unstable_arx_pole_gives_way_to_the_stable_run_in_the_prior() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv");
        let whole = crate::data::csv::read_traces(
            std::path::Path::new(path),
            &crate::data::csv::ReadOptions::default(),
        )
        .unwrap()
        .remove(0);
        let first = |t: &Trace, n: usize| {
            Trace::uniform(
                "first.csv",
                t.dt(),
                t.input[..n].to_vec(),
                t.output[..n].to_vec(),
            )
        };
        let short = first(&whole, 2500);
        let id = identify(&short, ArxOrders::default()).unwrap();
        assert!(id.arx.a[0] >= 1.0 && id.arx.b[0] < 0.0, "{:?}", id.arx);
        let prior = linear_prior(&[short]).unwrap();
        let sign = linear_prior(&[whole]).unwrap();
        assert!((0.0..1.0).contains(&prior.a), "{prior:?}");
        assert!(prior.b > 0.0 && sign.b > 0.0, "{prior:?} {sign:?}");
    }

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

    /// Values whose squares overflow a double are named by column, not
    /// reported as a fit of NaN % with an infinite RMSE.
    #[test]
    fn values_past_double_precision_name_the_column() {
        let input: Vec<f64> = (0..400).map(|k| (k as f64 * 0.05).sin()).collect();
        let output: Vec<f64> = (0..400).map(|k| 1e160 * (k as f64 * 0.07).cos()).collect();
        let huge = Trace::uniform("huge.csv", 0.01, input, output);
        let err = identify(&huge, ArxOrders::default())
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("huge.csv: the column `displacement` reaches 1")
                && err.contains("e160 from its mean: its squares overflow"),
            "{err}"
        );
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

    /// Output of `y(k) = a·y(k−1) + b·u(k−1)` from `y0`, no means.
    fn first_order(a: f64, b: f64, y0: f64, u: &[f64]) -> Vec<f64> {
        let mut y = vec![y0];
        for k in 1..u.len() {
            y.push(a * y[k - 1] + b * u[k - 1]);
        }
        y
    }

    /// Stretches that do not continue each other (the second starts far
    /// from where the first ended) give the exact model, because no row
    /// regresses one stretch's sample on the other's; the same samples run
    /// together as one record do not.
    #[test]
    fn no_regressor_reaches_from_one_stretch_into_the_next() {
        let u1: Vec<f64> = (0..300).map(|k| (k as f64 * 0.05).sin()).collect();
        let u2: Vec<f64> = (0..300).map(|k| (k as f64 * 0.11).cos()).collect();
        let y1 = first_order(0.9, 2.0, 0.0, &u1);
        let y2 = first_order(0.9, 2.0, 40.0, &u2);
        let arx = Arx::estimate_on("two", &[(&u1, &y1), (&u2, &y2)], ArxOrders::default()).unwrap();
        assert!(
            (arx.a[0] - 0.9).abs() < 1e-9 && (arx.b[0] - 2.0).abs() < 1e-9,
            "{arx:?}"
        );
        let joined = |a: &[f64], b: &[f64]| [a, b].concat();
        let run_together = Arx::estimate(
            "one",
            &joined(&u1, &u2),
            &joined(&y1, &y2),
            ArxOrders::default(),
        )
        .unwrap();
        assert!((run_together.a[0] - 0.9).abs() > 1e-3, "{run_together:?}");
    }

    /// Two records at other levels, one model: the same model whichever
    /// record comes first, each record scored on its own, and the pooled
    /// figure between theirs (a mediant of their error ratios). One record
    /// has no `records`; records at other sample times are refused.
    #[test]
    fn a_joint_identification_pools_the_records_and_keeps_each_ones_score() {
        let u1: Vec<f64> = (0..600)
            .map(|k| 0.2 + 0.1 * (k as f64 * 0.03).sin())
            .collect();
        let u2: Vec<f64> = (0..400)
            .map(|k| 0.3 + 0.1 * (k as f64 * 0.07).cos())
            .collect();
        let noisy = |y: Vec<f64>, phase: f64| -> Vec<f64> {
            y.iter()
                .enumerate()
                .map(|(k, v)| v + 0.3 * (k as f64 * 1.7 + phase).sin())
                .collect()
        };
        let a = Trace::uniform(
            "a.csv",
            0.01,
            u1.clone(),
            noisy(first_order(0.95, 2.0, 8.0, &u1), 0.0),
        );
        let b = Trace::uniform(
            "b.csv",
            0.01,
            u2.clone(),
            noisy(first_order(0.95, 2.0, 12.0, &u2), 1.0),
        );
        let ab = identify_jointly(&[a.clone(), b.clone()], ArxOrders::default()).unwrap();
        let ba = identify_jointly(&[b.clone(), a.clone()], ArxOrders::default()).unwrap();
        assert!((ab.arx.a[0] - ba.arx.a[0]).abs() < 1e-12, "{ab:?} {ba:?}");
        assert!((ab.arx.b[0] - ba.arx.b[0]).abs() < 1e-9, "{ab:?} {ba:?}");
        assert_eq!(ab.source, "a.csv, b.csv");
        assert_eq!(ab.samples, 1000);
        let names: Vec<&str> = ab.records.iter().map(|r| r.data.as_str()).collect();
        assert_eq!(names, ["a.csv", "b.csv"]);
        let own: Vec<f64> = ab
            .records
            .iter()
            .map(|r| r.validation_fit_percent)
            .collect();
        assert!(own[0] != own[1], "{own:?}");
        let (lo, hi) = (own[0].min(own[1]), own[0].max(own[1]));
        assert!(
            lo <= ab.validation_fit_percent && ab.validation_fit_percent <= hi,
            "{} not within {own:?}",
            ab.validation_fit_percent
        );
        assert!(
            identify(&a, ArxOrders::default())
                .unwrap()
                .records
                .is_empty()
        );
        let slower = Trace::uniform("slow.csv", 0.02, u2.clone(), b.output.clone());
        let err = identify_jointly(&[a, slower], ArxOrders::default()).unwrap_err();
        assert!(
            matches!(&err, IdentError::Unlike(why) if why.contains("every 0.02 s")),
            "{err}"
        );
    }

    /// A half's first `lag` samples start its simulation as measured and
    /// are not scored: counted, they made `--nk 1990` on the shipped stair
    /// read 99.98 %.
    #[test]
    fn samples_a_simulation_starts_from_are_not_scored() {
        let input: Vec<f64> = (0..600).map(|k| (k as f64 * 0.05).sin()).collect();
        let output = first_order(0.9, 2.0, 1.0, &input)
            .iter()
            .enumerate()
            .map(|(k, v)| v + 0.2 * (k as f64 * 1.3).sin())
            .collect();
        let trace = Trace::uniform("x.csv", 0.01, input, output);
        let orders = ArxOrders {
            na: 1,
            nb: 1,
            nk: 200,
        };
        let id = identify(&trace, orders).unwrap();
        let u: Vec<f64> = trace.input.iter().map(|v| v - id.input_mean).collect();
        let y: Vec<f64> = trace.output.iter().map(|v| v - id.output_mean).collect();
        let sim = id.arx.simulate(&u[300..], &y[300..]);
        assert_eq!(
            id.validation_fit_percent,
            fit_percent(&y[500..], &sim[200..]),
            "scored from the first simulated sample on"
        );
    }
}
