//! Does the identified model have the plant's hysteresis? The check drives
//! the plant with a slow valve triangle across the operating band and runs
//! the displacement model free along the measured pressure, then compares
//! the two pressure–displacement loops: their area and their width at mid
//! pressure (the gap between the rising and falling branches).

use serde::{Deserialize, Serialize};

use super::model::{ControlModel, DIVERGED_MM, Predictor, State};
use super::plant::Plant;
use crate::ident::fit::{loop_area, rmse};

/// The valve triangle of the check: 10 s held at the bottom of `band`, then
/// two slow cycles bottom → top → bottom, each `cycle_s` long.
pub fn triangle(band: (f64, f64), cycle_s: f64, dt: f64) -> Vec<f64> {
    let settle = (10.0 / dt).round() as usize;
    let half = (cycle_s / 2.0 / dt).round() as usize;
    let mut v = vec![band.0; settle];
    for _ in 0..2 {
        v.extend((0..half).map(|k| band.0 + (band.1 - band.0) * k as f64 / half as f64));
        v.extend((0..half).map(|k| band.1 - (band.1 - band.0) * k as f64 / half as f64));
    }
    v
}

/// An open-loop record: `(valve, pressure, displacement)`, the valve held
/// over each sample and the measurement at its end.
pub fn record(plant: &mut dyn Plant, valve: &[f64]) -> (Vec<f64>, Vec<f64>) {
    valve
        .iter()
        .map(|&v| {
            let m = plant.step(v);
            (m.pressure_mpa, m.displacement_mm)
        })
        .unzip()
}

/// One loop, measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LoopShape {
    /// Area enclosed in the pressure–displacement plane (MPa·mm).
    pub area_mpa_mm: f64,
    /// Falling minus rising branch at mid pressure (mm).
    pub width_mm: f64,
}

/// The plant's loop against the model's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LoopCheck {
    pub plant: LoopShape,
    pub model: LoopShape,
    /// RMS difference of the two displacements over the last cycle (mm).
    pub rmse_mm: f64,
    /// The last cycle, for figures: pressure (MPa), the plant's and the
    /// model's displacement (mm).
    pub pressure: Vec<f64>,
    pub plant_mm: Vec<f64>,
    pub model_mm: Vec<f64>,
}

fn shape(p: &[f64], x: &[f64]) -> LoopShape {
    let (lo, hi) = p
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let mid = 0.5 * (lo + hi);
    let top = p
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(i, _)| i);
    // First crossing of the mid pressure on each branch.
    let cross = |range: Vec<usize>| -> f64 {
        for w in range.windows(2) {
            let (i, j) = (w[0], w[1]);
            if (p[i] - mid) * (p[j] - mid) <= 0.0 && p[i] != p[j] {
                let f = (mid - p[i]) / (p[j] - p[i]);
                return x[i] + f * (x[j] - x[i]);
            }
        }
        f64::NAN
    };
    let rising = cross((0..=top).collect());
    let falling = cross((top..p.len()).collect());
    LoopShape {
        area_mpa_mm: loop_area(p, x),
        width_mm: falling - rising,
    }
}

/// Compares the model's loop with the plant's on the triangle record
/// `(pressure, displacement)` of [`triangle`] with `cycle` samples per cycle.
pub fn check_loop(
    model: &ControlModel,
    pressure: &[f64],
    displacement: &[f64],
    cycle: usize,
) -> anyhow::Result<LoopCheck> {
    let pr = Predictor::new(model)?;
    let n = pressure.len();
    anyhow::ensure!(
        n == displacement.len() && n > cycle + 1,
        "the loop check needs a record longer than one cycle"
    );
    // The displacement model free along the measured pressure, from the
    // first measured displacement.
    let mut s = pr.at_start(pressure[0], displacement[0] - pr.output_mean);
    let mut model_mm = vec![displacement[0]];
    for &p in &pressure[..n - 1] {
        let input = State {
            p,
            p_prev: s.p,
            ..s
        };
        let x = pr.next_x(&input);
        s = pr.moved(&input, p, x, pr.hysteresis.step(s.w, x - s.x));
        model_mm.push(pr.output(&s) + pr.output_mean);
    }
    // A model whose free run leaves every displacement a muscle can hold
    // steers the controllers by nonsense (an MPC on it holds the valve and
    // reports nothing amiss).
    if let Some(k) = model_mm.iter().position(|x| {
        let off = (x - pr.output_mean).abs();
        !(off.is_finite() && off < DIVERGED_MM)
    }) {
        anyhow::bail!(
            "the model's displacement, run free along the twin's pressure over the loop \
             check's valve triangle, diverges (it passes ±{DIVERGED_MM} mm at sample {k} of \
             {n}): it cannot steer the controllers"
        );
    }
    let last = n - cycle..n;
    let (p, xp, xm) = (
        pressure[last.clone()].to_vec(),
        displacement[last.clone()].to_vec(),
        model_mm[last].to_vec(),
    );
    Ok(LoopCheck {
        plant: shape(&p, &xp),
        model: shape(&p, &xm),
        rmse_mm: rmse(&xp, &xm),
        pressure: p,
        plant_mm: xp,
        model_mm: xm,
    })
}
