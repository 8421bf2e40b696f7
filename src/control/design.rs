//! The models a model-based controller is designed with, identified from
//! data by the project (never read from a plant's internals):
//!
//! - the displacement model of eq. 13 (pressure → displacement, ARX linear
//!   part plus a Bouc-Wen state), as a [`FittedModel`]: either the one
//!   `mckibben fit` wrote, or the control-oriented fit of [`fit_predictive`];
//! - a first-order valve → pressure model, [`ValveModel`], by least squares.

use serde::{Deserialize, Serialize};

use crate::data::Trace;
use crate::model::sim::{classic_w, generalized_w};
use crate::model::{Family, FittedModel};

/// `p(k+1) = pole·p(k) + gain·v(k) + offset`: pressure (MPa) from the input
/// valve voltage `v` (V), identified by least squares (ARX(1,1,1) on
/// mean-removed data, the offset restored from the means).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ValveModel {
    pub pole: f64,
    /// MPa per V per sample.
    pub gain: f64,
    /// MPa per sample.
    pub offset: f64,
}

impl ValveModel {
    /// Least squares on a record of valve voltages and measured pressures.
    pub fn identify(source: &str, valve: &[f64], pressure: &[f64]) -> anyhow::Result<ValveModel> {
        Self::identify_in_band(
            source,
            valve,
            pressure,
            (f64::NEG_INFINITY, f64::INFINITY),
            1,
        )
    }

    /// As [`ValveModel::identify`], from prediction windows that start
    /// with the valve voltage in `band` only, fitted for predictions up to
    /// `horizon` samples ahead (the MPC's use; see [`fit_predictive`]). The
    /// valves' flow law makes the static map an S-curve (dead band at the
    /// bottom, supply pressure at the top): a straight line fitted over the
    /// whole stair averages the flat ends into a slow, weak model, so a
    /// controller that works in the middle should fit the middle.
    pub fn identify_in_band(
        source: &str,
        valve: &[f64],
        pressure: &[f64],
        band: (f64, f64),
        horizon: usize,
    ) -> anyhow::Result<ValveModel> {
        anyhow::ensure!(
            valve.len() == pressure.len() && valve.len() > 10,
            "{source}: need equally long valve and pressure records of more than 10 samples"
        );
        let starts: Vec<usize> = (0..valve.len() - 1)
            .filter(|&k| band.0 <= valve[k] && valve[k] <= band.1 && k % STRIDE == 0)
            .collect();
        anyhow::ensure!(
            starts.len() > 10,
            "{source}: only {} samples with the valve in {:?} V",
            starts.len() * STRIDE,
            band
        );
        let zeros = vec![0.0; valve.len()];
        let (pole, th, _) = predictive_ls(pressure, valve, &zeros, &starts, horizon)
            .ok_or_else(|| anyhow::anyhow!("{source}: valve model least squares failed"))?;
        Ok(ValveModel {
            pole,
            gain: th[0],
            offset: th[2],
        })
    }

    /// One step of the model.
    pub fn step(&self, p: f64, v: f64) -> f64 {
        self.pole * p + self.gain * v + self.offset
    }
}

/// What a model-based controller knows about the plant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControlModel {
    /// Pressure (MPa) → displacement (mm), eq. 13 in deviation coordinates.
    pub displacement: FittedModel,
    pub valve: ValveModel,
}

/// The linear part and hysteresis of a [`FittedModel`] in `f64`, unpacked
/// for prediction: `x(k+1) = a·α·x + a·(1−α)·w + b·u + c`.
#[derive(Debug, Clone, PartialEq)]
pub struct Unpacked {
    pub a: f64,
    pub alpha: f64,
    pub b: f64,
    pub c: f64,
    family: Family,
    theta32: Vec<f32>,
}

impl Unpacked {
    pub fn new(model: &FittedModel) -> Self {
        let [ia, ib, ic] = model.family.linear_indices();
        let alpha = model
            .family
            .index_of("alpha")
            .map_or(1.0, |i| model.params[i]);
        Unpacked {
            a: model.params[ia],
            alpha,
            b: model.params[ib],
            c: model.params[ic],
            family: model.family,
            theta32: model.params.iter().map(|&v| v as f32).collect(),
        }
    }

    /// Advances the Bouc-Wen state over one sample in which the displacement
    /// (deviation coordinates) went from `x_prev` to `x` — the same update
    /// `model::sim` uses, fed with measured or predicted displacement.
    pub fn advance_w(&self, w_prev: f64, x_prev: f64, x: f64) -> f64 {
        let th = &self.theta32;
        let delta = (x - x_prev) as f32;
        match self.family {
            Family::Linear => 0.0,
            Family::Classic => classic_w(th[0], th[2], th[3], th[4], w_prev as f32, delta) as f64,
            Family::Generalized => {
                let betas = [th[2], th[3], th[4], th[5], th[6], th[7]];
                generalized_w(th[0], &betas, th[8], w_prev as f32, x as f32, delta) as f64
            }
        }
    }
}

/// Result of the control-oriented fit, with its prediction error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PredictiveFit {
    pub model: FittedModel,
    /// RMS error of the displacement predicted 1 to `horizon` samples ahead
    /// from measured states (mm).
    pub rmse_mm: f64,
    pub horizon: usize,
}

/// Pole candidates of the predictive fits (per 10 ms sample).
const POLES: [f64; 14] = [
    0.7, 0.8, 0.85, 0.9, 0.92, 0.94, 0.95, 0.96, 0.97, 0.975, 0.98, 0.985, 0.99, 0.995,
];

/// Every `STRIDE`-th sample starts a prediction window (keeps the fit fast;
/// the windows still overlap).
const STRIDE: usize = 3;

/// Least squares for `θ` (3 entries) in `target ≈ θ·r` from accumulated
/// normal equations; returns `θ` and the residual sum of squares.
/// A regressor that is identically zero (the valve model has one input)
/// gets a tiny ridge so that its coefficient comes out 0.
fn solve3(ata: &[[f64; 3]; 3], atb: &[f64; 3], btb: f64) -> Option<([f64; 3], f64)> {
    let m = nalgebra::Matrix3::from_fn(|i, j| ata[i][j] + if i == j { 1e-12 } else { 0.0 });
    let v = nalgebra::Vector3::from_fn(|i, _| atb[i]);
    let th = m.lu().solve(&v)?;
    let sse = btb - 2.0 * th.dot(&v) + (m * th).dot(&th);
    Some(([th[0], th[1], th[2]], sse.max(0.0)))
}

/// Fits `y(k+1) = ρ·y(k) + θ0·s(k) + θ1·q(k) + θ2` for the `horizon`-step
/// predictions from measured `y(k)`, for every pole `ρ` of [`POLES`]:
/// with `ρ` fixed, each prediction is linear in `θ`, so least squares over
/// all windows gives `θ`; the pole with the smallest error wins.
/// Returns `(ρ, θ, rms error)`.
fn predictive_ls(
    y: &[f64],
    s: &[f64],
    q: &[f64],
    starts: &[usize],
    horizon: usize,
) -> Option<(f64, [f64; 3], f64)> {
    let mut best: Option<(f64, [f64; 3], f64)> = None;
    for &rho in &POLES {
        let mut ata = [[0.0; 3]; 3];
        let mut atb = [0.0; 3];
        let (mut btb, mut count) = (0.0, 0usize);
        for &k in starts {
            let mut r = [0.0f64; 3];
            let mut decay = 1.0;
            for h in 1..=horizon {
                if k + h >= y.len() {
                    break;
                }
                r = [
                    rho * r[0] + s[k + h - 1],
                    rho * r[1] + q[k + h - 1],
                    rho * r[2] + 1.0,
                ];
                decay *= rho;
                let t = y[k + h] - decay * y[k];
                for i in 0..3 {
                    for j in 0..3 {
                        ata[i][j] += r[i] * r[j];
                    }
                    atb[i] += r[i] * t;
                }
                btb += t * t;
                count += 1;
            }
        }
        if let Some((th, sse)) = solve3(&ata, &atb, btb) {
            let rms = (sse / count.max(1) as f64).sqrt();
            if best.as_ref().is_none_or(|b| rms < b.2) {
                best = Some((rho, th, rms));
            }
        }
    }
    best
}

/// Control-oriented identification of the classic model (n = 1) from a
/// record of pressure and displacement.
///
/// The MPC predicts the displacement up to `horizon` samples ahead from the
/// measured state, with the Bouc-Wen state tracked from the *measured*
/// displacement. So the model is fitted for exactly that: with `w` computed
/// from the measured displacement and the pole `a·α` fixed, every
/// prediction of eq. 13 is linear in `(a·(1−α), b, c)`; least squares over
/// all prediction windows gives them, for each pole on a grid and each
/// `(β, γ)` on a grid, and the smallest prediction error wins. `A` is fixed
/// at 1: for n = 1 it only rescales `w`, which `a·(1−α)` absorbs. Shapes
/// whose hysteretic weight `a·(1−α)` comes out negative (a reversed loop)
/// are discarded. A one-step fit is not enough: with noisy pressure and a
/// load with inertia it returns a near-integrator that predicts one sample
/// well and thirty badly.
pub fn fit_predictive(
    trace: &Trace,
    use_row: &[bool],
    horizon: usize,
) -> anyhow::Result<PredictiveFit> {
    let n = trace.len();
    let starts: Vec<usize> = (0..n.saturating_sub(1))
        .filter(|&k| use_row[k] && k % STRIDE == 0)
        .collect();
    anyhow::ensure!(
        starts.len() > 20,
        "{}: too few samples ({}) in the operating band for a fit",
        trace.source,
        starts.len() * STRIDE
    );
    let mu = trace.input.iter().sum::<f64>() / n as f64;
    let my = trace.output.iter().sum::<f64>() / n as f64;
    let u: Vec<f64> = trace.input.iter().map(|p| p - mu).collect();
    let x: Vec<f64> = trace.output.iter().map(|l| l - my).collect();
    let levels = [0.0, 0.001, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0];
    let mut best: Option<(f64, Vec<f64>)> = None;
    for &sum in &levels {
        for &diff in &levels {
            // sum = β + γ (loop saturation), diff = β − γ (loop fatness).
            let (beta, gamma) = ((sum + diff) / 2.0, (sum - diff) / 2.0);
            let probe = FittedModel {
                family: Family::Classic,
                params: vec![1.0, 0.5, beta, gamma, 1.0, 0.9, 1.0, 0.0],
                input_mean: mu,
                output_mean: my,
                dt: trace.dt(),
                input_name: trace.input_name.clone(),
                output_name: trace.output_name.clone(),
            };
            let un = Unpacked::new(&probe);
            let mut w = vec![0.0; n];
            for k in 1..n {
                w[k] = un.advance_w(w[k - 1], x[k - 1], x[k]);
            }
            let Some((rho, th, rms)) = predictive_ls(&x, &w, &u, &starts, horizon) else {
                continue;
            };
            let a = rho + th[0];
            if !(th[0] >= 0.0 && a > 0.0) {
                continue;
            }
            if best.as_ref().is_none_or(|(r, _)| rms < *r) {
                best = Some((rms, vec![1.0, rho / a, beta, gamma, 1.0, a, th[1], th[2]]));
            }
        }
    }
    let (rmse, params) = best.ok_or_else(|| {
        anyhow::anyhow!(
            "{}: no Bouc-Wen shape gave a hysteresis loop of the right orientation",
            trace.source
        )
    })?;
    Ok(PredictiveFit {
        model: FittedModel {
            family: Family::Classic,
            params,
            input_mean: mu,
            output_mean: my,
            dt: trace.dt(),
            input_name: trace.input_name.clone(),
            output_name: trace.output_name.clone(),
        },
        rmse_mm: rmse,
        horizon,
    })
}

/// The valve band the sine references of §6.2 need on the twin (20–40 mm sit
/// between about 4 and 7 V on its stair), with a volt of margin each side.
pub const OPERATING_BAND_V: (f64, f64) = (3.0, 8.0);

/// Identifies a [`ControlModel`] from an open-loop record that carries the
/// input valve voltage (`valve_in` column) besides pressure and displacement
/// (e.g. the twin's stair): the one-step displacement fit and the valve model.
///
/// Both are fitted on the samples with the valve in `band` (V): the
/// operating range of the controller (see [`ValveModel::identify_in_band`]).
pub fn identify(
    trace: &Trace,
    band: (f64, f64),
    horizon: usize,
) -> anyhow::Result<(ControlModel, PredictiveFit)> {
    let valve = trace.column("valve_in").ok_or_else(|| {
        anyhow::anyhow!(
            "{}: no `valve_in` column; the valve → pressure model needs the input valve voltage",
            trace.source
        )
    })?;
    let use_row: Vec<bool> = valve.iter().map(|&v| band.0 <= v && v <= band.1).collect();
    let fit = fit_predictive(trace, &use_row, horizon)?;
    let valve = ValveModel::identify_in_band(&trace.source, valve, &trace.input, band, horizon)?;
    Ok((
        ControlModel {
            displacement: fit.model.clone(),
            valve,
        },
        fit,
    ))
}

/// The model with every hysteresis parameter (`A`, `α`, the `β`s, `γ`; not
/// `n` nor the linear part) multiplied by `factor`, `α` kept within [0, 1]:
/// the robustness runs' "±20 % error in the hysteresis parameters".
pub fn scale_hysteresis(model: &FittedModel, factor: f64) -> FittedModel {
    let mut out = model.clone();
    let hyst = out.family.dim().saturating_sub(5); // before n, a, b, c, x0
    for (i, v) in out.params.iter_mut().enumerate().take(hyst) {
        *v *= factor;
        if out.family.params()[i].name == "alpha" {
            *v = v.clamp(0.0, 1.0);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaling_touches_only_the_hysteresis_and_keeps_alpha_a_share() {
        let family = Family::Classic;
        let model = FittedModel {
            family,
            params: vec![1.0, 0.9, 0.1, -0.05, 1.0, 0.95, 2.0, 0.3],
            input_mean: 0.2,
            output_mean: 30.0,
            dt: 0.01,
            input_name: "pressure".into(),
            output_name: "displacement".into(),
        };
        let up = scale_hysteresis(&model, 1.2);
        assert_eq!(up.params[..4], [1.2, 1.0, 0.1 * 1.2, -0.05 * 1.2]);
        assert_eq!(up.params[4..], model.params[4..]);
        let down = scale_hysteresis(&model, 0.8);
        assert!((down.params[1] - 0.72).abs() < 1e-12);
    }

    #[test]
    fn valve_model_is_exact_on_its_own_data() {
        let truth = ValveModel {
            pole: 0.9,
            gain: 0.004,
            offset: 0.002,
        };
        let valve: Vec<f64> = (0..400)
            .map(|k| 5.0 + 3.0 * ((k / 37) % 3) as f64 - 3.0)
            .collect();
        let mut p = vec![0.1];
        for k in 0..399 {
            p.push(truth.step(p[k], valve[k]));
        }
        let fit = ValveModel::identify_in_band("t", &valve, &p, (0.0, 10.0), 10).unwrap();
        assert_eq!(fit.pole, 0.9);
        assert!((fit.gain - 0.004).abs() < 1e-9 && (fit.offset - 0.002).abs() < 1e-9);
    }
}
