//! A problem with a known answer, for checking optimizers: a trace
//! simulated from a hysteresis model *in absolute units* (so the intercept
//! of the deviation-coordinate model is not zero, as on real data), plus
//! Gaussian measurement noise, split into estimation and validation halves
//! the way `fit` splits real data.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use crate::data::Trace;
use crate::ident::arx::linear_prior;
use crate::model::{Experiment, Family, Flow, LinearPrior, SearchSpace};

/// A known-truth identification problem.
#[derive(Debug, Clone)]
pub struct Synthetic {
    pub family: Family,
    /// The trace in absolute units (pressure MPa, displacement mm).
    pub trace: Trace,
    pub estimation: Experiment,
    pub validation: Experiment,
    /// The true parameters in the estimation data's deviation coordinates
    /// (canonical vector, intercept included).
    pub truth: Vec<f64>,
    /// The ARX prior the default search box is built from.
    pub prior: LinearPrior,
}

/// True parameters in absolute units: canonical layout with `c` the
/// absolute-units intercept. Classic: A = 0.8, α = 0.6, β = 0.05, γ = 0.02;
/// generalized: A = 0.9, α = 0.7, β = [0.05, 0.02, 0.03, −0.02, 0.01, 0.02],
/// switching at the sensor's zero (`x_s = 0`; [`Synthetic::new`] moves it to
/// the estimation mean); a = 0.95, b = 20 mm/MPa, c = 1 mm, n = 1 for both,
/// no start offset.
pub fn truth_absolute(family: Family) -> Vec<f64> {
    match family {
        Family::Linear => vec![0.95, 20.0, 1.0, 0.0],
        Family::Classic => vec![0.8, 0.6, 0.05, 0.02, 1.0, 0.95, 20.0, 1.0, 0.0],
        Family::Generalized => vec![
            0.9, 0.7, 0.05, 0.02, 0.03, -0.02, 0.01, 0.02, 1.0, 0.0, 0.95, 20.0, 1.0, 0.0,
        ],
    }
}

/// A pressure stair (MPa) of `len` samples: levels drawn in [0.05, 0.5],
/// each held 25–60 samples, as the thesis' identification input (A.1.1).
pub fn stair_input(len: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let mut p = Vec::with_capacity(len);
    while p.len() < len {
        let level = 0.05 + 0.45 * rng.random::<f64>();
        let hold = rng.random_range(25..=60);
        p.extend(std::iter::repeat_n(level, hold));
    }
    p.truncate(len);
    p
}

impl Synthetic {
    /// `len` samples at 0.1 s of `family` on a random stair, plus
    /// `noise_mm` Gaussian noise on the displacement.
    ///
    /// Two passes: [`truth_absolute`] is simulated in absolute units to find
    /// the estimation half's means `ū`, `ȳ`; the truth in deviation
    /// coordinates (intercept `c + b·ū − (1 − a·α)·ȳ`) is then simulated
    /// again in those coordinates and shifted back by `ȳ`. The generalized
    /// truth switches at that `ȳ` (`x_s = ȳ`, where the thesis' model
    /// switches), so its second pass is another trace than its first; for
    /// the classic model both passes give the same trace up to rounding.
    pub fn new(family: Family, len: usize, noise_mm: f64, seed: u64) -> Synthetic {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let p = stair_input(len, &mut rng);
        let abs = truth_absolute(family);
        let [ia, ib, ic] = family.linear_indices();
        let alpha = if family == Family::Linear {
            1.0
        } else {
            abs[1]
        };
        // Start at the absolute-units equilibrium of the first input.
        let x0 = (abs[ib] * p[0] + abs[ic]) / (1.0 - abs[ia] * alpha);
        let run = |theta: &[f64], y_mean: f64, u: &[f64], x0: f64| -> Vec<f64> {
            let theta: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
            let u: Vec<f32> = u.iter().map(|&v| v as f32).collect();
            crate::model::simulate(family, &theta, y_mean as f32, &u, x0 as f32)
                .x
                .iter()
                .map(|&x| x as f64)
                .collect()
        };
        let clean = run(&abs, 0.0, &p, x0);
        let (est, _) = crate::model::experiment::halves(len);
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let (u_mean, y_mean) = (mean(&p[est.clone()]), mean(&clean[est]));
        let mut truth = abs.clone();
        truth[ic] = abs[ic] + abs[ib] * u_mean - (1.0 - abs[ia] * alpha) * y_mean;
        if let Some(is) = family.switch_index() {
            truth[is] = y_mean;
        }
        let u: Vec<f64> = p.iter().map(|v| v - u_mean).collect();
        let x = run(&truth, y_mean, &u, x0 - y_mean);
        let l: Vec<f64> = x
            .iter()
            .map(|&x| {
                let noise: f64 = rng.sample(StandardNormal);
                x + y_mean + noise_mm * noise
            })
            .collect();
        let trace = Trace::uniform(format!("synthetic {family}"), 0.1, p, l);
        let (estimation, validation) = Experiment::split_halves(&trace);
        // The noise moves the means a little: keep the truth exact in the
        // coordinates the fit uses (the shift of ȳ moves c, nothing else:
        // `x_s` is absolute).
        truth[ic] -= (1.0 - abs[ia] * alpha) * (estimation.y_mean - y_mean)
            - abs[ib] * (estimation.u_mean - u_mean);
        let prior = linear_prior(std::slice::from_ref(&trace)).expect("synthetic data identify");
        Synthetic {
            family,
            trace,
            estimation,
            validation,
            truth,
            prior,
        }
    }

    /// The default search box (hull of the thesis' bounds, joint flow).
    pub fn space(&self) -> SearchSpace {
        SearchSpace::from_prior(self.family, None, self.prior, Flow::Joint, false)
    }

    /// SSE of the true parameters on the estimation half.
    pub fn true_sse(&self) -> f64 {
        let theta: Vec<f32> = self.truth.iter().map(|&v| v as f32).collect();
        let e = &self.estimation;
        crate::model::sse(self.family, &theta, e.y_mean as f32, &e.u, &e.y) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truth_lies_in_the_default_box_and_reaches_the_noise_floor() {
        for family in [Family::Classic, Family::Generalized] {
            let s = Synthetic::new(family, 600, 0.05, 7);
            assert!(s.space().contains(&s.truth), "{family}: {:?}", s.truth);
            let per_sample = s.true_sse() / s.estimation.len() as f64;
            // Classic: noise 0.05 mm, a mean squared error near 0.0025 mm²
            // (a little more: the noisy start shifts the hysteretic state for
            // good). Generalized: its sgn terms make the free run from the
            // noisy start flip signs, so the truth sits further from the floor.
            let ceiling = if family == Family::Classic {
                0.005
            } else {
                2.0
            };
            assert!(
                (0.0015..ceiling).contains(&per_sample),
                "{family}: {per_sample}"
            );
            // The intercept matters: the deviation-coordinate c is far from 0.
            let ic = family.linear_indices()[2];
            assert!(s.truth[ic].abs() > 0.5, "{family}: c = {}", s.truth[ic]);
        }
    }
}
