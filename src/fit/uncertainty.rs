//! How closely the estimation half determines a fitted model's parameters:
//! each parameter's standard error from the Gauss–Newton approximation at
//! the fit's end, `s²·(JᵀJ)⁻¹` with `s² = SSE/(N − p)`, as MATLAB's
//! `present` and `getcov` give it for an identified model.
//!
//! The Jacobian is taken in the search coordinates, where the box gives
//! every coordinate a scale (central differences with the polish's steps:
//! a thousandth of the coordinate, at least a hundredth of that of its box
//! width), and carried to the canonical parameters through the chart. A
//! coordinate held by the box, the switching level (the free-run error is
//! piecewise constant in it) and a coordinate within its probe step of a
//! bound are held: the errors are those of the others given them.
//!
//! The formula assumes white residuals. A free run's residuals are what
//! the model cannot describe, correlated from sample to sample, so the
//! figures are a lower bound on the real uncertainty: a parameter whose
//! standard error is as large as itself is not determined by the record;
//! a small one does not prove that it is.

use nalgebra::DMatrix;

use super::problem::FitProblem;

/// The polish's probe step, relative to a coordinate's scale
/// ([`crate::optim::engine::Polish`]'s `rel_step`).
const REL_STEP: f64 = 1e-3;
/// A coordinate's scale is at least this share of its box width (the
/// polish's `step_floor`).
const STEP_FLOOR: f64 = 1e-2;

/// Each canonical parameter's standard error at `theta` on `problem`'s
/// estimation halves, in the parameter's own units; `None` where the box
/// or the rules above hold it, and for every parameter where the
/// residuals diverge at `theta` or the free coordinates are not jointly
/// determined (`JᵀJ` singular).
pub fn standard_errors(problem: &FitProblem, theta: &[f64]) -> Vec<Option<f64>> {
    let d = theta.len();
    let none = vec![None; d];
    let space = &problem.space;
    let Some(r0) = problem.est_residuals(theta) else {
        return none;
    };
    let z0 = space.from_native(theta);
    let switch = problem.model.family.switch_index();
    let mut probed: Vec<(usize, f64)> = Vec::new();
    let mut columns: Vec<f64> = Vec::new();
    for j in space.free() {
        if Some(j) == switch {
            continue;
        }
        let (lo, hi) = (space.lower[j], space.upper[j]);
        let h = REL_STEP * z0[j].abs().max(STEP_FLOOR * (hi - lo));
        if z0[j] - h < lo || z0[j] + h > hi {
            continue;
        }
        let at = |step: f64| {
            let mut z = z0.clone();
            z[j] += step;
            problem.est_residuals(&space.to_native(&z))
        };
        let (Some(plus), Some(minus)) = (at(h), at(-h)) else {
            continue;
        };
        columns.extend(
            plus.iter()
                .zip(minus.iter())
                .map(|(p, m)| (p - m) / (2.0 * h)),
        );
        probed.push((j, h));
    }
    let (n, p) = (r0.len(), probed.len());
    if p == 0 || n <= p {
        return none;
    }
    let jac = DMatrix::from_column_slice(n, p, &columns);
    let Some(inverse) = (jac.transpose() * &jac).cholesky().map(|c| c.inverse()) else {
        return none;
    };
    let s2 = r0.norm_squared() / (n - p) as f64;
    let covariance = inverse * s2;
    // The chart's derivatives: how each canonical parameter moves with each
    // probed coordinate (exact arithmetic, no simulation).
    let mut chart = DMatrix::zeros(d, p);
    for (k, &(j, h)) in probed.iter().enumerate() {
        let step = 1e-3 * h;
        let mut up = z0.clone();
        up[j] += step;
        let mut down = z0.clone();
        down[j] -= step;
        let (up, down) = (space.to_native(&up), space.to_native(&down));
        for i in 0..d {
            chart[(i, k)] = (up[i] - down[i]) / (2.0 * step);
        }
    }
    (0..d)
        .map(|i| {
            let g = chart.row(i);
            if g.iter().all(|&v| v == 0.0) {
                return None;
            }
            let var = (g * &covariance * g.transpose())[(0, 0)];
            (var.is_finite() && var >= 0.0).then(|| var.sqrt())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::cpu::CpuEvaluator;
    use crate::fit::cases::{Case, matrix, polished_truth};
    use crate::model::Family;

    /// On a generated record the model describes exactly, with white noise:
    /// the errors scale with the noise, the fit's deviation from the truth
    /// is of the size they say, and what the box holds has none.
    #[test]
    fn standard_errors_are_the_size_of_the_estimates_scatter() {
        let spec = matrix(Family::Classic, 1, 1000)[0];
        let case = Case::generate(spec);
        let problem = case.problem();
        let at_truth = standard_errors(&problem, &case.truth);
        let names = problem.model.param_names();
        for (name, e) in names.iter().zip(&at_truth) {
            let held = name == "A" || name == "n";
            assert_eq!(e.is_none(), held, "{name}: {e:?}");
        }
        // Twice the noise, the same draws: the residuals at the truth
        // double, and so does every error (within a few per cent: the
        // start offset, the first sample less its noise, moves too).
        let louder = Case::generate(crate::fit::cases::CaseSpec {
            noise_mm: 2.0 * spec.noise_mm,
            ..spec
        });
        let twice = standard_errors(&louder.problem(), &louder.truth);
        for ((name, one), two) in names.iter().zip(&at_truth).zip(&twice) {
            if let (Some(one), Some(two)) = (one, two) {
                assert!((1.8..2.3).contains(&(two / one)), "{name}: {one} -> {two}");
            }
        }
        // The least-squares estimate strays from the truth by about its
        // standard error: not by many of them, and not by none.
        let (polished, _) =
            polished_truth(&problem, &case.truth, &mut CpuEvaluator::new()).unwrap();
        let errors = standard_errors(&problem, &polished);
        let z: Vec<f64> = polished
            .iter()
            .zip(&case.truth)
            .zip(&errors)
            .filter_map(|((p, t), e)| e.map(|e| (p - t) / e))
            .collect();
        assert!(z.len() >= 5, "{z:?}");
        let largest = z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(largest < 5.0 && largest > 0.05, "{z:?}");
    }
}
