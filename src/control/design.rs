//! Identification of the controller's model ([`ControlModel`]) from an
//! open-loop record of valve voltage, pressure and displacement — the twin's
//! or a real rig's — and the measures of how well it predicts.
//!
//! The MPC predicts up to a horizon ahead from the measured state, so the
//! model is fitted for exactly that: the error of the predictions 1 to
//! `horizon` samples ahead from every window that starts with the valve in
//! the operating band, with the Bouc-Wen state `w` carried along the
//! *predicted* displacement inside each window (it starts from `w` tracked
//! along the measured displacement, as the controller's own estimate does).
//! A one-step (equation-error) fit returns a near-integrator on this rig, and
//! a fit that fed `w` from the measured displacement inside the window would
//! see the future: with `β = γ = 0`, `w` *is* the displacement, and such a
//! fit turns the multi-step predictor back into a one-step one, so it
//! chooses a linear model (docs/CONTROL.md, "The model, identified from
//! data").

use nalgebra::DVector;
use serde::{Deserialize, Serialize};

use super::model::{ControlModel, DIVERGED_MM, Predictor, State};
use super::valve::{ValveModel, window_starts};
use crate::data::Trace;
use crate::data::signals::Multisine;
use crate::model::{Family, FittedBaseline};
use crate::optim::lm::{LmSettings, levenberg_marquardt};

/// The valve band the sine references of §6.2 need on the twin (20–40 mm lie
/// between about 4.5 and 7.5 V going up and 4 and 7 V coming down), with
/// margin: the windows the fit scores start here.
pub const OPERATING_BAND_V: (f64, f64) = (3.0, 8.0);

/// The open-loop experiment the controller's model is identified from: a
/// multisine over the operating band, 5.5 ± 2.5 V, 8 sines from 0.02 to 2 Hz
/// (past the 0.5 Hz of the 3 rad/s reference and the rig's own corner), 120 s.
pub fn design_multisine() -> Multisine {
    Multisine {
        mean_v: 5.5,
        amplitude_v: 2.5,
        f_min_hz: 0.02,
        f_max_hz: 2.0,
        components: 8,
        duration_s: 120.0,
    }
}

/// How well a model predicts a record, `1..=horizon` samples ahead from the
/// measured state, over the windows that start in the operating band.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PredictionReport {
    pub horizon: usize,
    /// RMS error (mm) `j` samples ahead (`by_step[j − 1]`), the displacement
    /// model driven by the measured pressure.
    pub by_step_mm: Vec<f64>,
    /// RMS over every step of every window (mm).
    pub rmse_mm: f64,
    /// The same with the pressure predicted by the valve model from the valve
    /// voltage: the whole chain the MPC predicts with.
    pub end_to_end_by_step_mm: Vec<f64>,
    pub end_to_end_rmse_mm: f64,
    /// RMS error of the valve model's pressure predictions (MPa).
    pub pressure_rmse_mpa: f64,
}

/// Walks every prediction window of `record` and hands each error to `sink`
/// as `(steps ahead, displacement error mm, pressure error MPa)`. With
/// `end_to_end` the displacement model is fed the predicted pressure, else
/// the measured one. Returns `None` if a prediction leaves the model's range.
fn walk_windows(
    pr: &Predictor,
    record: &Record,
    starts: &[usize],
    horizon: usize,
    end_to_end: bool,
    mut sink: impl FnMut(usize, f64, f64),
) -> Option<()> {
    // The state along the measured displacement, as the controller tracks
    // it: `w`, and with an effect chain the effects' states, the baseline's
    // `x` being the measured output less them (`super::chain`).
    let n = record.x.len();
    let mut track = Vec::with_capacity(n);
    match &pr.chain {
        None => {
            let mut w_measured = vec![0.0; n];
            w_measured[0] = pr.at_start(record.p[0], record.x[0]).w;
            for k in 1..n {
                let w = pr
                    .hysteresis
                    .step(w_measured[k - 1], record.x[k] - record.x[k - 1]);
                if !(w.is_finite() && w.abs() < 1e6) {
                    return None;
                }
                w_measured[k] = w;
            }
            for ((&p, &x), &w) in record.p.iter().zip(&record.x).zip(&w_measured) {
                track.push(State::new(p, x, w));
            }
        }
        Some(chain) => {
            track.push(pr.at_start(record.p[0], record.x[0]));
            for k in 1..n {
                let last: State = track[k - 1];
                let (u, _) = chain.effective(last.p, pr.input_mean);
                let (x, e) = chain.restart(&last.e, u, last.p - last.p_prev, record.x[k]);
                let w = pr.hysteresis.step(last.w, x - last.x);
                if !(w.is_finite() && w.abs() < 1e6) {
                    return None;
                }
                track.push(State {
                    p: record.p[k],
                    x,
                    w,
                    e,
                    p_prev: last.p,
                });
            }
        }
    }
    for &k in starts {
        let mut s = track[k];
        for j in 1..=horizon {
            let i = k + j - 1;
            let input = if end_to_end {
                s
            } else {
                State {
                    p: record.p[i],
                    p_prev: if i > 0 { record.p[i - 1] } else { record.p[i] },
                    ..s
                }
            };
            s = pr.step(&input, record.valve[i], 0.0, 0.0);
            if !(s.x.is_finite() && s.x.abs() < DIVERGED_MM) {
                return None;
            }
            sink(j, pr.output(&s) - record.x[k + j], s.p - record.p[k + j]);
        }
    }
    Some(())
}

/// The design record's column of the input valve's voltage (V).
pub const VALVE_IN: &str = "valve_in";

/// A record in the model's coordinates.
struct Record {
    valve: Vec<f64>,
    p: Vec<f64>,
    x: Vec<f64>,
}

impl Record {
    fn new(trace: &Trace, output_mean: f64) -> anyhow::Result<Record> {
        let valve = trace.column(VALVE_IN).ok_or_else(|| {
            anyhow::anyhow!(
                "{}: no `valve_in` column; the valve → pressure model needs the input valve voltage",
                trace.source
            )
        })?;
        Ok(Record {
            valve: valve.to_vec(),
            p: trace.input.clone(),
            x: trace.output.iter().map(|y| y - output_mean).collect(),
        })
    }
}

/// The prediction errors of `model` on `trace` (which needs a `valve_in`
/// column), from the windows that start with the valve in `band`.
pub fn prediction_report(
    model: &ControlModel,
    trace: &Trace,
    band: (f64, f64),
    horizon: usize,
) -> anyhow::Result<PredictionReport> {
    let pr = Predictor::new(model)?;
    let record = Record::new(trace, pr.output_mean)?;
    let starts = window_starts(&record.valve, band, horizon);
    anyhow::ensure!(
        !starts.is_empty(),
        "{}: no prediction window starts with the valve in {band:?} V",
        trace.source
    );
    let rms = |sum: &[f64]| -> Vec<f64> {
        sum.iter()
            .map(|s| (s / starts.len() as f64).sqrt())
            .collect()
    };
    let total = |sum: &[f64]| (sum.iter().sum::<f64>() / (starts.len() * horizon) as f64).sqrt();
    let mut measured = vec![0.0; horizon];
    let mut chained = vec![0.0; horizon];
    let mut pressure = 0.0;
    // Where the record steps further a sample than the model's
    // hysteresis update settles within, that is the likely cause: say so.
    let base = &model.displacement;
    let largest = trace
        .output
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0, f64::max);
    let why = match base.family.stable_step(&base.params) {
        Some(stable) if largest > stable => format!(
            ": its hysteresis update settles only within {} mm a sample (`stable_step`), and \
             this record steps up to {} mm: motion faster than the model holds (it was \
             fitted on slower motion, or on too little motion this fast; docs/GUIDE.md, \
             \"When not to trust it\")",
            crate::report::number::significant(stable, 3),
            crate::report::number::significant(largest, 3)
        ),
        _ => String::new(),
    };
    let diverged = || anyhow::anyhow!("{}: the model's prediction diverges{why}", trace.source);
    walk_windows(&pr, &record, &starts, horizon, false, |j, e, _| {
        measured[j - 1] += e * e
    })
    .ok_or_else(diverged)?;
    walk_windows(&pr, &record, &starts, horizon, true, |j, e, ep| {
        chained[j - 1] += e * e;
        pressure += ep * ep;
    })
    .ok_or_else(diverged)?;
    Ok(PredictionReport {
        horizon,
        by_step_mm: rms(&measured),
        rmse_mm: total(&measured),
        end_to_end_by_step_mm: rms(&chained),
        end_to_end_rmse_mm: total(&chained),
        pressure_rmse_mpa: (pressure / (starts.len() * horizon) as f64).sqrt(),
    })
}

/// The fitted parameters `θ = [a·α, a·(1−α), b, b₂, c, β, γ]` as a model.
fn model_of(theta: &[f64], valve: &ValveModel, trace: &Trace, mu: f64, my: f64) -> ControlModel {
    let [rho, h, b, b2, c, beta, gamma] = [
        theta[0], theta[1], theta[2], theta[3], theta[4], theta[5], theta[6],
    ];
    let a = rho + h;
    ControlModel {
        displacement: FittedBaseline {
            family: Family::Classic,
            // A = 1 and n = 1: for n = 1, A only rescales w, which the
            // weight a·(1−α) absorbs.
            params: vec![1.0, rho / a, beta, gamma, 1.0, a, b, c, 0.0],
            input_mean: mu,
            output_mean: my,
            dt: trace.dt(),
            input_name: trace.input_name.clone(),
            output_name: trace.output_name.clone(),
        },
        curvature: b2,
        valve: valve.clone(),
        chain: None,
        rest_start: false,
    }
}

/// Identifies the [`ControlModel`] from an open-loop record with columns
/// pressure (input), displacement (output) and `valve_in`: the valve model
/// by least squares ([`ValveModel::identify`]), then the displacement model
/// by Levenberg–Marquardt (`optim::lm`) on the errors of its predictions
/// `1..=horizon` samples ahead from the measured state, driven by the
/// measured pressure, over the windows that start with the valve in `band`.
///
/// The loop may come out either way round: `a·(1−α) < 0` (so `α > 1`) is the
/// orientation of friction, which holds the muscle back on the way up and
/// on the way down. Four starts (either orientation, a narrow and a wide
/// loop); the smallest error wins. Deterministic.
pub fn identify(trace: &Trace, band: (f64, f64), horizon: usize) -> anyhow::Result<ControlModel> {
    let n = trace.len();
    anyhow::ensure!(
        n > 4 * horizon,
        "{}: {n} samples is too short to fit {horizon}-step predictions",
        trace.source
    );
    let mu = trace.input.iter().sum::<f64>() / n as f64;
    let my = trace.output.iter().sum::<f64>() / n as f64;
    let record = Record::new(trace, my)?;
    // A column that does not move holds nothing to identify: the least
    // squares would end on a bound and the controllers on nonsense.
    for (name, values) in [
        ("valve_in", &record.valve),
        (trace.input_name.as_str(), &record.p),
        (trace.output_name.as_str(), &trace.output),
    ] {
        anyhow::ensure!(
            crate::data::range(values) > 0.0,
            "{}: the column `{name}` is constant, so there is no response to identify; \
             record the valve driven by a multisine (`mckibben twin --experiment multisine` \
             shows one)",
            trace.source
        );
    }
    let (valve, _) = ValveModel::identify(&trace.source, &record.valve, &record.p, band, horizon)?;
    let starts = window_starts(&record.valve, band, horizon);
    anyhow::ensure!(
        starts.len() > 20,
        "{}: only {} prediction windows start with the valve in {band:?} V",
        trace.source,
        starts.len()
    );
    let residuals = |theta: &[f64]| -> Option<DVector<f64>> {
        let pr = Predictor::new(&model_of(theta, &valve, trace, mu, my)).ok()?;
        let mut r = Vec::with_capacity(starts.len() * horizon);
        walk_windows(&pr, &record, &starts, horizon, false, |_, e, _| r.push(e))?;
        Some(DVector::from_vec(r))
    };
    let lower = [0.0, -2.0, -1e3, -1e4, -1e2, 0.0, -10.0];
    let upper = [0.9999, 2.0, 1e3, 1e4, 1e2, 10.0, 10.0];
    let floor = [0.1, 0.1, 1.0, 1.0, 1.0, 0.1, 0.1];
    let settings = LmSettings {
        max_iterations: 60,
        ..LmSettings::default()
    };
    let mut best: Option<(Vec<f64>, f64)> = None;
    for weight in [-0.1, 0.1] {
        for saturation in [0.2, 1.0] {
            let start = [
                0.9,
                weight,
                5.0,
                0.0,
                0.0,
                saturation / 2.0,
                saturation / 2.0,
            ];
            let Ok(out) =
                levenberg_marquardt(residuals, &start, (&lower, &upper), &floor, &settings)
            else {
                continue;
            };
            if best.as_ref().is_none_or(|b| out.sse < b.1) {
                best = Some((out.x, out.sse));
            }
        }
    }
    let (theta, _) = best.ok_or_else(|| {
        anyhow::anyhow!(
            "{}: every start of the displacement fit diverged",
            trace.source
        )
    })?;
    Ok(model_of(&theta, &valve, trace, mu, my))
}

/// The model with its hysteresis off by `factor`: the Bouc-Wen parameters
/// `A`, `β`, `γ` and the weight of `w`, `a·(1−α)`, multiplied by `factor`,
/// the linear part (`a·α`, `b`, `b₂`, `c`) held. The saturated loop's height
/// `a·(1−α)·A/(β+γ)` scales by `factor`, its slope after a reversal by
/// `factor²`. (Scaling `α` itself would move the pole `a·α`: that tests the
/// linear part, not the hysteresis; docs/CONTROL.md, "Robustness".)
pub fn scale_hysteresis(model: &ControlModel, factor: f64) -> ControlModel {
    let mut out = model.clone();
    let d = &mut out.displacement;
    if d.family != Family::Classic {
        return out;
    }
    let idx = |name: &str| d.family.index_of(name).expect("classic parameter");
    let (ia, ialpha) = (idx("a"), idx("alpha"));
    let (a, alpha) = (d.params[ia], d.params[ialpha]);
    let (rho, h) = (a * alpha, a * (1.0 - alpha) * factor);
    d.params[ia] = rho + h;
    d.params[ialpha] = rho / (rho + h);
    for name in ["A", "beta", "gamma"] {
        d.params[idx(name)] *= factor;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A record whose pressure (or valve, or displacement) never moves is
    /// refused by name, where it identified a gain on its bound.
    #[test]
    fn a_constant_column_is_refused_by_name() {
        let n = 2000;
        let moving: Vec<f64> = (0..n)
            .map(|k| 5.0 + 3.0 * (k as f64 * 0.05).sin())
            .collect();
        for constant in ["valve_in", "pressure", "displacement"] {
            let column = |name: &str, scale: f64| -> Vec<f64> {
                match name == constant {
                    true => vec![0.2; n],
                    false => moving.iter().map(|v| v * scale).collect(),
                }
            };
            let mut trace = Trace::uniform(
                "record.csv",
                0.01,
                column("pressure", 0.04),
                column("displacement", 6.0),
            );
            trace
                .extra
                .push(("valve_in".into(), column("valve_in", 1.0)));
            let err = identify(&trace, (3.0, 8.0), 10).unwrap_err().to_string();
            assert!(
                err.contains(&format!("`{constant}` is constant")),
                "{constant}: {err}"
            );
        }
    }

    #[test]
    fn scaling_keeps_the_pole_and_scales_the_loop() {
        let model = super::super::model::example_model();
        let base = Predictor::new(&model).unwrap();
        for f in [0.8, 1.2] {
            let s = Predictor::new(&scale_hysteresis(&model, f)).unwrap();
            assert!((s.rho - base.rho).abs() < 1e-12);
            assert!((s.h - f * base.h).abs() < 1e-12);
            assert_eq!((s.b, s.b2, s.c), (base.b, base.b2, base.c));
            let height =
                |p: &Predictor| p.h * p.hysteresis.big_a / (p.hysteresis.beta + p.hysteresis.gamma);
            assert!((height(&s) - f * height(&base)).abs() < 1e-12);
        }
    }
}
