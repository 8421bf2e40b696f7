//! Where a candidate fit starts, read off the data: a mode of the hanging
//! load (an effect whose [`Effect::hint`] is [`StartHint::ResidualPeak`],
//! e.g. [`Effect::LoadMode`], [`Effect::Ringing`]) starts at the peak of
//! the residual's spectrum.
//!
//! Why: the free-run cost of a lightly damped mode is a narrow valley along
//! its frequency (a ringing out of phase with the data's costs more than no
//! ringing), which uniform draws over the box rarely hit, while the
//! residual's spectrum says where it is (as on the Cavatappi muscle's
//! ringing: docs/lab/diagnosis.md, "Which: the effects catalogue"). Only
//! the estimation part is read.

use super::effects::{Effect, StartHint};
use super::spectrum::{Peak, Settings, welch};
use crate::fit::problem::FitProblem;

/// Extra starts (row-major, canonical) for the first stage of a warm fit
/// from `start` whose new effect's parameters begin at `new_from`: when the
/// new effect is a mode, for each of the two largest peaks of `start`'s
/// estimation residual spectrum away from the input's lines, `start` with
/// the mode ringing at the peak's frequency, lightly and moderately damped
/// (ζ = 0.05, 0.2), and a ringing's kick the least-squares one for that
/// mode. Empty for any other effect, or when there is no such peak.
pub fn mode_hints(
    problem: &FitProblem,
    start: &[f64],
    new_from: usize,
    (lo, hi): (&[f64], &[f64]),
) -> Vec<f64> {
    let model = &problem.model;
    let Some((kick, at)) = model.effects.iter().find_map(|&e| match e.hint() {
        StartHint::ResidualPeak { kick, .. } => model
            .offset_of(e)
            .filter(|&at| at >= new_from)
            .map(|at| (kick, at)),
        StartHint::None => None,
    }) else {
        return Vec::new();
    };
    let Some((peaks, residuals)) = estimation_peaks(problem, start) else {
        return Vec::new();
    };
    let dt = problem.records.est[0].dt;
    let mut rows = Vec::new();
    for peak in peaks.iter().take(2) {
        let theta = std::f64::consts::TAU * peak.hz * dt;
        if !(theta > 0.0 && theta < std::f64::consts::PI) {
            continue;
        }
        for zeta in [0.05f64, 0.2] {
            let r = (-zeta * theta / (1.0 - zeta * zeta).sqrt()).exp();
            let (a1, a2) = (2.0 * r * theta.cos(), r * r);
            let mut row = start.to_vec();
            row[at] = a1.clamp(lo[at], hi[at]);
            row[at + 1] = a2.clamp(lo[at + 1], hi[at + 1]);
            if let Some(k) = kick.map(|k| at + k) {
                row[k] = ringing_kick(problem, &residuals, a1, a2).clamp(lo[k], hi[k]);
            }
            rows.extend(row);
        }
    }
    rows
}

/// The peaks of the spectrum of `theta`'s estimation residuals `ŷ − y`
/// (every dataset's periodograms averaged) that are not within two bins of
/// a peak of the input's spectrum, with the residuals; `None` when the
/// model diverges or the data are too short for a spectrum.
fn estimation_peaks(problem: &FitProblem, theta: &[f64]) -> Option<(Vec<Peak>, Vec<Vec<f64>>)> {
    let model = &problem.model;
    let dt = problem.records.est.first()?.dt;
    let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
    let mut residuals = Vec::new();
    for (i, (e, c)) in problem
        .records
        .est
        .iter()
        .zip(&problem.records.ctx)
        .enumerate()
    {
        let r: Vec<f64> = model
            .simulate(&t, i, c, e)
            .iter()
            .zip(&e.y)
            .skip(1)
            .map(|(&a, &b)| (a - b) as f64)
            .collect();
        if !r.iter().all(|v| v.is_finite()) {
            return None;
        }
        residuals.push(r);
    }
    let series: Vec<&[f64]> = residuals.iter().map(Vec::as_slice).collect();
    let spectrum = welch(&series, dt, &Settings::default())?;
    // The input's own lines (a multisine's) come out in any misfit's
    // residual: only a peak away from them is the data ringing.
    let inputs: Vec<Vec<f64>> = problem
        .records
        .est
        .iter()
        .map(|e| e.u.iter().map(|&v| f64::from(v)).collect())
        .collect();
    let inputs: Vec<&[f64]> = inputs.iter().map(Vec::as_slice).collect();
    let lines = welch(&inputs, dt, &Settings::default()).map_or(Vec::new(), |s| s.peaks);
    let bin = 1.0 / (spectrum.segment as f64 * dt);
    let free = spectrum
        .peaks
        .into_iter()
        .filter(|p| lines.iter().all(|l| (l.hz - p.hz).abs() > 2.0 * bin))
        .collect();
    Some((free, residuals))
}

/// Whether an effect is looked for only where the residual rings
/// ([`residual_rings`]), by its start hint.
pub fn only_on_a_peak(effect: Effect) -> bool {
    matches!(
        effect.hint(),
        StartHint::ResidualPeak {
            only_on_a_peak: true,
            ..
        }
    )
}

/// Whether `theta`'s estimation residual rings: its spectrum has a peak
/// where the input's has none. [`Effect::Ringing`] is looked for only then
/// (`select`): a mode kicked by the input and damped near 1/√2 is a
/// high-pass of the input, and without a peak to explain it fits the
/// independent self-test's sensor cross-talk, a high-pass added to the
/// output (docs/lab/diagnosis.md, "Which: the effects catalogue").
pub fn residual_rings(problem: &FitProblem, theta: &[f64]) -> bool {
    estimation_peaks(problem, theta).is_some_and(|(peaks, _)| !peaks.is_empty())
}

/// The kick `g` that best cancels the estimation residuals `ŷ − y` with a
/// ringing of mode `a1`, `a2` (the step of [`Effect::Ringing`]), in `f64`.
fn ringing_kick(problem: &FitProblem, residuals: &[Vec<f64>], a1: f64, a2: f64) -> f64 {
    let (mut qq, mut qr) = (0.0, 0.0);
    for (e, r) in problem.records.est.iter().zip(residuals) {
        let u = &e.u;
        let (mut q1, mut q2) = (0.0f64, 0.0f64);
        for k in 1..u.len() {
            let prev = if k >= 2 { u[k - 2] } else { u[0] };
            let q = a1 * q1 - a2 * q2 + f64::from(u[k - 1] - prev);
            (q2, q1) = (q1, q);
            qq += q * q;
            qr += q * r[k - 1];
        }
    }
    if qq > 0.0 { -qr / qq } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Trace;
    use crate::model::Family;
    use crate::model::effects::ModelDescription;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// A first-order muscle on a random stair whose load rings at `hz`
    /// (damping 0.05, kick `kick`) after every step, sampled at 100 Hz with
    /// 0.01 mm of noise.
    fn ringing_data(hz: f64, kick: f64) -> FitProblem {
        let dt = 0.01;
        let theta = std::f64::consts::TAU * hz * dt;
        let r = (-0.05 * theta / (1.0f64 - 0.0025).sqrt()).exp();
        let (a1, a2) = (2.0 * r * theta.cos(), r * r);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut u = vec![0.0; 4000];
        for k in 1..u.len() {
            u[k] = if k % 150 == 0 {
                0.5 * (1.0 + Normal::new(0.0, 1.0).unwrap().sample(&mut rng))
            } else {
                u[k - 1]
            };
        }
        let noise = Normal::new(0.0, 0.01).unwrap();
        let (mut x, mut q1, mut q2) = (0.0, 0.0, 0.0);
        let mut y = vec![0.0; u.len()];
        for k in 1..u.len() {
            x = 0.9 * x + 1.0 * u[k - 1];
            let prev = if k >= 2 { u[k - 2] } else { u[0] };
            let q = a1 * q1 - a2 * q2 + kick * (u[k - 1] - prev);
            (q2, q1) = (q1, q);
            y[k] = x + q + noise.sample(&mut rng);
        }
        FitProblem::diagnosis(
            &[Trace::uniform("ringing", dt, u, y)],
            Family::Linear,
            None,
            crate::diagnose::Settings::default().blocks,
        )
        .unwrap()
    }

    #[test]
    fn a_ringing_starts_at_the_residual_spectrum_peak_with_its_kick() {
        let (hz, kick) = (4.0, 2.0);
        let data = ringing_data(hz, kick);
        let model = ModelDescription::new(Family::Linear, vec![Effect::Ringing], 1);
        let p = data.with_model(&model);
        let (neutral, lo, hi) = (p.centre(), p.space.lower.clone(), p.space.upper.clone());
        // The first-order muscle itself, in the data's deviation coordinates.
        let e = &data.records.est[0];
        let c = e.u_mean - (1.0 - 0.9) * e.y_mean;
        let mut start = neutral.clone();
        start[..4].copy_from_slice(&[0.9, 1.0, c, 0.0]);
        let rows = mode_hints(&p, &start, 4, (&lo, &hi));
        assert!(!rows.is_empty(), "no peak found");
        let first = &rows[..model.dim()];
        let found = (first[4] / (2.0 * first[5].sqrt())).acos() / (std::f64::consts::TAU * 0.01);
        assert!(
            (found - hz).abs() < 0.05 * hz,
            "starts at {found} Hz, rings at {hz}"
        );
        assert!(
            (first[6] - kick).abs() < 0.3 * kick,
            "kick {} for {kick}",
            first[6]
        );
        assert!(p.est_sse(first) < 0.5 * p.est_sse(&start));
    }

    #[test]
    fn a_ringing_without_a_resonance_is_not_admitted() {
        let data = ringing_data(4.0, 2.0);
        let model = ModelDescription::new(Family::Linear, vec![Effect::Ringing], 1);
        let p = data.with_model(&model);
        let mut theta = p.centre();
        theta[..2].copy_from_slice(&[0.9, 1.0]);
        assert!(p.est_sse(&theta).is_finite(), "the neutral mode rings");
        // Poles 0.99 and 0.5: a kick that decays as a drift, not a ringing.
        theta[4..6].copy_from_slice(&[1.49, 0.495]);
        assert_eq!(p.est_sse(&theta), f64::INFINITY);
        // Complex poles, but damped past 1/√2 (ζ ≈ 0.999): a high-pass.
        theta[4..6].copy_from_slice(&[1.11, 0.309]);
        assert_eq!(p.est_sse(&theta), f64::INFINITY);
        // Damped at ζ ≈ 0.54: it still has a resonance.
        let (r, angle) = (0.6f64, 0.8f64);
        theta[4..6].copy_from_slice(&[2.0 * r * angle.cos(), r * r]);
        assert!(p.est_sse(&theta).is_finite());
    }

    #[test]
    fn only_modes_get_hints() {
        let data = ringing_data(4.0, 2.0);
        let model = ModelDescription::new(Family::Linear, vec![Effect::Creep], 1);
        let p = data.with_model(&model);
        let (neutral, lo, hi) = (p.centre(), p.space.lower.clone(), p.space.upper.clone());
        assert!(mode_hints(&p, &neutral, 4, (&lo, &hi)).is_empty());
        // A mode already in the model (before `new_from`) is not moved.
        let model = ModelDescription::new(Family::Linear, vec![Effect::Ringing, Effect::Creep], 1);
        let p = data.with_model(&model);
        let (neutral, lo, hi) = (p.centre(), p.space.lower.clone(), p.space.upper.clone());
        assert!(mode_hints(&p, &neutral, 7, (&lo, &hi)).is_empty());
    }
}
