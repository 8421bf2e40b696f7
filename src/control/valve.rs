//! The valve → pressure model a model-based controller predicts with:
//!
//! ```text
//! p(k+1) = π·p(k) + g(V(k))
//! ```
//!
//! with `p` the measured pressure (MPa), `V` the input valve voltage held over
//! the sample, `π` a pole and `g` a static map, piecewise linear between knots
//! at every volt of the 0–10 V range and increasing. The map is not a straight
//! line because the rig's two valves set the pressure by the ratio of their
//! openings: dead band at the bottom, the supply pressure at the top, an S in
//! between (docs/TWIN.md). On the twin its slope falls markedly from 5 V to
//! 7 V (docs/CONTROL.md, "The controllers", `mpc`), which a linear model
//! would absorb as a gain error at the top of every sine.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Knots of the static map: 0, 1, …, 10 V.
pub const KNOTS: usize = 11;
/// Smallest slope the map is given (MPa per V per sample), so that it stays
/// invertible and a controller never sees a valve without effect.
const MIN_SLOPE: f64 = 1e-5;

/// `p(k+1) = pole·p(k) + g(V(k))`, `g` piecewise linear on [`KNOTS`] knots.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValveModel {
    /// Pole of the pressure per sample.
    pub pole: f64,
    /// `g` at 0, 1, …, 10 V (MPa per sample), increasing.
    pub map: Vec<f64>,
}

/// Interpolation weights of `v` on the knots: the two knots around it.
fn hat(v: f64) -> (usize, f64) {
    let v = v.clamp(0.0, (KNOTS - 1) as f64);
    let i = (v.floor() as usize).min(KNOTS - 2);
    (i, v - i as f64)
}

impl ValveModel {
    /// The static map `g(v)`.
    pub fn map_at(&self, v: f64) -> f64 {
        let (i, f) = hat(v);
        (1.0 - f) * self.map[i] + f * self.map[i + 1]
    }

    /// `dg/dV` at `v` (the right-hand slope at a knot).
    pub fn slope(&self, v: f64) -> f64 {
        let (i, _) = hat(v);
        self.map[i + 1] - self.map[i]
    }

    /// One step of the model.
    pub fn step(&self, p: f64, v: f64) -> f64 {
        self.pole * p + self.map_at(v)
    }

    /// Steady pressure held by a constant voltage `v`.
    pub fn static_pressure(&self, v: f64) -> f64 {
        self.map_at(v) / (1.0 - self.pole)
    }

    /// The voltage whose map value is `g` (the map is increasing), clamped
    /// to the 0–10 V range.
    pub fn inverse(&self, g: f64) -> f64 {
        if g <= self.map[0] {
            return 0.0;
        }
        for i in 0..KNOTS - 1 {
            if g <= self.map[i + 1] {
                return i as f64 + (g - self.map[i]) / (self.map[i + 1] - self.map[i]);
            }
        }
        (KNOTS - 1) as f64
    }

    /// Least squares for the predictions 1 to `horizon` samples ahead from
    /// the measured pressure, over the windows that start with the valve in
    /// `band` (V): for a fixed pole each prediction is linear in the knot
    /// values, so least squares gives them, and a grid over the pole keeps
    /// the smallest error. Knots the data do not reach are extrapolated with
    /// the neighbouring segment's slope; the map is then made increasing.
    /// Returns the model and its RMS prediction error (MPa).
    pub fn identify(
        source: &str,
        valve: &[f64],
        pressure: &[f64],
        band: (f64, f64),
        horizon: usize,
    ) -> anyhow::Result<(ValveModel, f64)> {
        anyhow::ensure!(
            valve.len() == pressure.len() && valve.len() > horizon + 10,
            "{source}: need equally long valve and pressure records longer than the horizon"
        );
        let starts = window_starts(valve, band, horizon);
        anyhow::ensure!(
            starts.len() > 10,
            "{source}: only {} prediction windows start with the valve in {:?} V",
            starts.len(),
            band
        );
        let mut best: Option<(ValveModel, f64)> = None;
        for &pole in &POLES {
            let mut ata = DMatrix::<f64>::zeros(KNOTS, KNOTS);
            let mut atb = DVector::<f64>::zeros(KNOTS);
            let (mut btb, mut count) = (0.0, 0usize);
            for &k in &starts {
                let mut r = [0.0; KNOTS];
                let mut decay = 1.0;
                for h in 1..=horizon {
                    let (i, f) = hat(valve[k + h - 1]);
                    r.iter_mut().for_each(|v| *v *= pole);
                    r[i] += 1.0 - f;
                    r[i + 1] += f;
                    decay *= pole;
                    let t = pressure[k + h] - decay * pressure[k];
                    for a in 0..KNOTS {
                        if r[a] != 0.0 {
                            for b in 0..KNOTS {
                                ata[(a, b)] += r[a] * r[b];
                            }
                            atb[a] += r[a] * t;
                        }
                    }
                    btb += t * t;
                    count += 1;
                }
            }
            let peak = ata.diagonal().max();
            let supported: Vec<bool> = (0..KNOTS).map(|i| ata[(i, i)] > 1e-3 * peak).collect();
            for i in 0..KNOTS {
                ata[(i, i)] += 1e-9 * peak;
            }
            let Some(chol) = ata.clone().cholesky() else {
                continue;
            };
            let th = chol.solve(&atb);
            let sse = btb - 2.0 * th.dot(&atb) + (&ata * &th).dot(&th);
            let rms = (sse.max(0.0) / count.max(1) as f64).sqrt();
            if best.as_ref().is_none_or(|b| rms < b.1) {
                let map = monotone(th.as_slice(), &supported);
                best = Some((ValveModel { pole, map }, rms));
            }
        }
        best.ok_or_else(|| anyhow::anyhow!("{source}: valve model least squares failed"))
    }
}

/// Pole candidates per sample (time constants from 40 ms to 1 s at 10 ms).
const POLES: [f64; 12] = [
    0.78, 0.82, 0.85, 0.88, 0.9, 0.92, 0.93, 0.94, 0.95, 0.96, 0.97, 0.99,
];

/// Samples that start a prediction window: the valve in `band`, a full
/// window ahead, every third sample (the windows still overlap).
pub(crate) fn window_starts(valve: &[f64], band: (f64, f64), horizon: usize) -> Vec<usize> {
    (1..valve.len().saturating_sub(horizon))
        .filter(|&k| k % 3 == 0 && band.0 <= valve[k] && valve[k] <= band.1)
        .collect()
}

/// The knot values with unsupported knots extrapolated from the nearest
/// supported segment and every step at least [`MIN_SLOPE`].
fn monotone(raw: &[f64], supported: &[bool]) -> Vec<f64> {
    let first = supported.iter().position(|&s| s).unwrap_or(0);
    let last = supported.iter().rposition(|&s| s).unwrap_or(KNOTS - 1);
    let mut g = raw.to_vec();
    for i in first + 1..=last {
        g[i] = g[i].max(g[i - 1] + MIN_SLOPE);
    }
    let low_slope = if last > first {
        (g[first + 1] - g[first]).max(MIN_SLOPE)
    } else {
        MIN_SLOPE
    };
    for i in (0..first).rev() {
        g[i] = g[i + 1] - low_slope;
    }
    let high_slope = if last > first {
        (g[last] - g[last - 1]).max(MIN_SLOPE)
    } else {
        MIN_SLOPE
    };
    for i in last + 1..KNOTS {
        g[i] = g[i - 1] + high_slope;
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s_curve(v: f64) -> f64 {
        0.004 / (1.0 + (-(v - 5.0)).exp())
    }

    #[test]
    fn recovers_pole_and_map_of_its_own_structure() {
        let pole = 0.9;
        let valve: Vec<f64> = (0..3000)
            .map(|k| 5.0 + 2.5 * (k as f64 * 0.013).sin() + 1.0 * (k as f64 * 0.071).sin())
            .collect();
        let mut p = vec![0.2];
        for k in 0..valve.len() - 1 {
            p.push(pole * p[k] + s_curve(valve[k]));
        }
        let (m, rms) = ValveModel::identify("t", &valve, &p, (2.0, 8.0), 20).unwrap();
        assert_eq!(m.pole, pole);
        // The S-curve is not piecewise linear; between knots the chords
        // differ from it by under 2 % of its range.
        assert!(rms < 2e-3, "rms {rms}");
        for v in [3.0, 4.5, 5.0, 6.2, 7.0] {
            assert!((m.map_at(v) - s_curve(v)).abs() < 1e-4, "{v} V");
        }
        assert!(m.map.windows(2).all(|w| w[1] > w[0]));
        for g in [0.001, 0.002, 0.003] {
            assert!((m.map_at(m.inverse(g)) - g).abs() < 1e-12);
        }
    }
}
