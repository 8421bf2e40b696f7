//! The models a model-based controller is designed with, identified from
//! data by the project (never read from a plant's internals):
//!
//! - the displacement model of eq. 13 (pressure → displacement, ARX linear
//!   part plus a Bouc-Wen state), as a [`FittedModel`]: either the one
//!   `mckibben fit` wrote, or the control-oriented fit of [`fit_one_step`];
//! - a first-order valve → pressure model, [`ValveModel`], by least squares.

use serde::{Deserialize, Serialize};

use crate::data::Trace;
use crate::ident::{Arx, ArxOrders};
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
        anyhow::ensure!(
            valve.len() == pressure.len() && valve.len() > 10,
            "{source}: need equally long valve and pressure records of more than 10 samples"
        );
        let mv = valve.iter().sum::<f64>() / valve.len() as f64;
        let mp = pressure.iter().sum::<f64>() / pressure.len() as f64;
        let u: Vec<f64> = valve.iter().map(|v| v - mv).collect();
        let y: Vec<f64> = pressure.iter().map(|p| p - mp).collect();
        let arx = Arx::estimate(source, &u, &y, ArxOrders::default())?;
        let (pole, gain) = (arx.a[0], arx.b[0]);
        Ok(ValveModel {
            pole,
            gain,
            offset: mp * (1.0 - pole) - gain * mv,
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

/// Result of the control-oriented fit, with its one-step error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OneStepFit {
    pub model: FittedModel,
    /// RMS one-step prediction error of the displacement (mm).
    pub one_step_rmse_mm: f64,
}

/// Control-oriented identification of the classic model (n = 1) from a
/// record of pressure and displacement.
///
/// The MPC tracks the Bouc-Wen state from the *measured* displacement, so
/// what it needs is a good one-step predictor. With `w` computed from the
/// measured displacement, eq. 13 is linear in `(a·α, a·(1−α), b, c)`; least
/// squares gives them for each `(β, γ)` on a grid, and the grid point with
/// the smallest one-step error wins. `A` is fixed at 1: for n = 1 it only
/// rescales `w`, which `a·(1−α)` absorbs. Grid points whose hysteretic weight
/// `a·(1−α)` comes out negative (a reversed loop) are discarded.
pub fn fit_one_step(trace: &Trace) -> anyhow::Result<OneStepFit> {
    let n = trace.len();
    anyhow::ensure!(n > 50, "{}: too few samples ({n}) for a fit", trace.source);
    let mu = trace.input.iter().sum::<f64>() / n as f64;
    let my = trace.output.iter().sum::<f64>() / n as f64;
    let u: Vec<f64> = trace.input.iter().map(|p| p - mu).collect();
    let x: Vec<f64> = trace.output.iter().map(|l| l - my).collect();
    let levels = [0.0, 0.001, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0];
    let mut best: Option<(f64, Vec<f64>)> = None;
    for &s in &levels {
        for &d in &levels {
            // s = β + γ (loop saturation), d = β − γ (loop fatness).
            let (beta, gamma) = ((s + d) / 2.0, (s - d) / 2.0);
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
            let rows = n - 1;
            let phi = nalgebra::DMatrix::from_fn(rows, 4, |r, c| match c {
                0 => x[r],
                1 => w[r],
                2 => u[r],
                _ => 1.0,
            });
            let target = nalgebra::DVector::from_fn(rows, |r, _| x[r + 1]);
            let Ok(th) = phi.clone().svd(true, true).solve(&target, 1e-10) else {
                continue;
            };
            let a = th[0] + th[1];
            if !(th[1] >= 0.0 && a > 0.0) {
                continue;
            }
            let resid = &phi * &th - &target;
            let rmse = (resid.norm_squared() / rows as f64).sqrt();
            if best.as_ref().is_none_or(|(r, _)| rmse < *r) {
                best = Some((
                    rmse,
                    vec![1.0, th[0] / a, beta, gamma, 1.0, a, th[2], th[3]],
                ));
            }
        }
    }
    let (rmse, params) = best.ok_or_else(|| {
        anyhow::anyhow!(
            "{}: no Bouc-Wen shape gave a hysteresis loop of the right orientation",
            trace.source
        )
    })?;
    Ok(OneStepFit {
        model: FittedModel {
            family: Family::Classic,
            params,
            input_mean: mu,
            output_mean: my,
            dt: trace.dt(),
            input_name: trace.input_name.clone(),
            output_name: trace.output_name.clone(),
        },
        one_step_rmse_mm: rmse,
    })
}

/// Identifies a [`ControlModel`] from an open-loop record that carries the
/// input valve voltage (`valve_in` column) besides pressure and displacement
/// (e.g. the twin's stair): the one-step displacement fit and the valve model.
pub fn identify(trace: &Trace) -> anyhow::Result<(ControlModel, OneStepFit)> {
    let valve = trace.column("valve_in").ok_or_else(|| {
        anyhow::anyhow!(
            "{}: no `valve_in` column; the valve → pressure model needs the input valve voltage",
            trace.source
        )
    })?;
    let fit = fit_one_step(trace)?;
    let valve = ValveModel::identify(&trace.source, valve, &trace.input)?;
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
    let hyst = out.family.dim().saturating_sub(4); // before n, a, b, c
    for (i, v) in out.params.iter_mut().enumerate().take(hyst) {
        *v *= factor;
        if out.family.params()[i].name == "alpha" {
            *v = v.clamp(0.0, 1.0);
        }
    }
    out
}
