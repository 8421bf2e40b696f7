//! Levenberg–Marquardt for box-bounded nonlinear least squares: the local
//! polish after a population search.
//!
//! A population search finds the basin; inside a narrow, curved valley it
//! creeps (differential evolution's differences shrink along the valley's
//! width, not its length). Gauss–Newton steps follow the valley because they
//! use the residuals' Jacobian, so a few dozen iterations from the search's
//! best reach what thousands of generations would not.
//!
//! Jacobian by forward or central differences (`LmSettings::central`;
//! columns in parallel), Marquardt's diagonal scaling (Marquardt 1963, "An
//! algorithm for least-squares estimation of nonlinear parameters", SIAM J.
//! Appl. Math. 11(2)), λ
//! divided by 3 after a successful step and multiplied by 4 after a failed
//! one. Bounds by an active set: a coordinate on its bound whose step points
//! out of the box is held there and the step solved for the others
//! (projecting a coupled step instead would spoil it).

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// How far and how finely to polish.
#[derive(Debug, Clone, PartialEq)]
pub struct LmSettings {
    /// Jacobian evaluations at most.
    pub max_iterations: usize,
    /// Forward-difference step of coordinate `j`: `rel_step · max(|x_j|, step_floor[j])`.
    /// About √ε of the residuals' arithmetic: 1e-6 for `f64`, 1e-3…1e-4 for `f32`.
    pub rel_step: f64,
    /// Stop when an accepted step lowers the SSE by less than this fraction.
    pub tolerance: f64,
    /// Central differences (twice the probes) instead of forward ones.
    pub central: bool,
}

impl Default for LmSettings {
    fn default() -> Self {
        LmSettings {
            max_iterations: 30,
            rel_step: 1e-6,
            tolerance: 1e-12,
            central: false,
        }
    }
}

/// Where the polish ended.
#[derive(Debug, Clone, PartialEq)]
pub struct LmOutcome {
    pub x: Vec<f64>,
    pub sse: f64,
    pub iterations: usize,
}

/// Why the polish could not run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LmError {
    /// The start's residuals are not finite.
    StartDiverges,
    /// A finite-difference probe diverged (the start sits on the edge of
    /// the region where the model stays bounded).
    ProbeDiverges,
}

impl std::fmt::Display for LmError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            LmError::StartDiverges => "the starting point's simulation diverges",
            LmError::ProbeDiverges => "a finite-difference probe diverged during refinement",
        })
    }
}

impl std::error::Error for LmError {}

/// Residual vectors of a batch of points, `None` where the model diverges:
/// what the polish asks for, one batch per Jacobian and one per group of
/// trial steps, so that a batch evaluator (a GPU) scores them in one call.
pub type BatchResiduals<'a> =
    dyn FnMut(&[Vec<f64>]) -> anyhow::Result<Vec<Option<DVector<f64>>>> + 'a;

/// Trial steps (λ, 4λ, 16λ, …) scored per batch: most iterations accept the
/// first, so a larger group wastes simulations on the CPU; a smaller one
/// costs a GPU round trip per failed trial.
const TRIALS_PER_BATCH: usize = 4;

/// Trial steps at most per iteration before the polish gives up.
const MAX_TRIALS: usize = 12;

/// Minimises `Σ r(x)²` from `start` inside `lower ≤ x ≤ upper` (infinite
/// bounds allowed), scoring one point at a time with `residuals` (the
/// Jacobian's columns in parallel). See [`levenberg_marquardt_batched`].
pub fn levenberg_marquardt(
    residuals: impl Fn(&[f64]) -> Option<DVector<f64>> + Sync,
    start: &[f64],
    bounds: (&[f64], &[f64]),
    step_floor: &[f64],
    settings: &LmSettings,
) -> Result<LmOutcome, LmError> {
    let mut batch = |points: &[Vec<f64>]| -> anyhow::Result<Vec<Option<DVector<f64>>>> {
        Ok(points.par_iter().map(|p| residuals(p)).collect())
    };
    levenberg_marquardt_batched(&mut batch, start, bounds, step_floor, settings, None).map_err(
        |e| {
            e.downcast::<LmError>()
                .expect("a point-wise scorer cannot fail")
        },
    )
}

/// Minimises `Σ r(x)²` from `start` inside `lower ≤ x ≤ upper` (infinite
/// bounds allowed). `residuals` scores a batch of points, `None` where the
/// model diverges; `step_floor[j]` is coordinate `j`'s typical scale, so that
/// a coordinate near zero still gets a probe step the residuals feel. The
/// SSE never rises: the outcome is the start when no step improves it.
/// `interrupt` stops after the current iteration with the best so far.
///
/// Errors: [`LmError`] (inside the `anyhow::Error`) when the start or a
/// probe diverges, or the scorer's own error.
pub fn levenberg_marquardt_batched(
    residuals: &mut BatchResiduals<'_>,
    start: &[f64],
    (lower, upper): (&[f64], &[f64]),
    step_floor: &[f64],
    settings: &LmSettings,
    interrupt: Option<&std::sync::atomic::AtomicBool>,
) -> anyhow::Result<LmOutcome> {
    let d = start.len();
    let clamp = |v: &mut [f64]| {
        for j in 0..d {
            v[j] = v[j].clamp(lower[j], upper[j]);
        }
    };
    let mut x = start.to_vec();
    clamp(&mut x);
    let mut r = residuals(std::slice::from_ref(&x))?
        .pop()
        .flatten()
        .ok_or(LmError::StartDiverges)?;
    let mut sse = r.norm_squared();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    for _ in 0..settings.max_iterations {
        if interrupt.is_some_and(|f| f.load(std::sync::atomic::Ordering::SeqCst)) {
            break;
        }
        iterations += 1;
        let steps: Vec<f64> = (0..d)
            .map(|j| {
                let h = settings.rel_step * x[j].abs().max(step_floor[j]);
                // Probe inward from an upper bound.
                if x[j] + h > upper[j] { -h } else { h }
            })
            .collect();
        // Central differences where both probes stay in the box: the
        // truncation error of a forward difference is first order in the
        // step, and in a flat valley it bends the Gauss–Newton step.
        let back: Vec<bool> = (0..d)
            .map(|j| settings.central && x[j] - steps[j] >= lower[j] && x[j] + steps[j] <= upper[j])
            .collect();
        let mut probes: Vec<Vec<f64>> = (0..d)
            .map(|j| {
                let mut xp = x.clone();
                xp[j] += steps[j];
                xp
            })
            .collect();
        probes.extend((0..d).filter(|&j| back[j]).map(|j| {
            let mut xp = x.clone();
            xp[j] -= steps[j];
            xp
        }));
        let mut cols = residuals(&probes)?.into_iter();
        let forward: Vec<Option<DVector<f64>>> = cols.by_ref().take(d).collect();
        let mut jac = DMatrix::<f64>::zeros(r.len(), d);
        for (j, col) in forward.into_iter().enumerate() {
            let col = col.ok_or(LmError::ProbeDiverges)?;
            if back[j] {
                let minus = cols.next().flatten().ok_or(LmError::ProbeDiverges)?;
                jac.set_column(j, &((col - minus) / (2.0 * steps[j])));
            } else {
                jac.set_column(j, &((col - &r) / steps[j]));
            }
        }
        let jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * &r;
        // The trial steps in the order a sequential search tries them: λ
        // times 10 after a singular solve, times 4 after a step that does not
        // lower the SSE; the first that lowers it is taken.
        let mut improved = false;
        let mut tried = 0;
        while tried < MAX_TRIALS && !improved {
            let mut trials: Vec<(Vec<f64>, f64)> = Vec::new();
            while trials.len() < TRIALS_PER_BATCH && tried < MAX_TRIALS {
                tried += 1;
                match bounded_step(&jtj, &jtr, lambda, &x, (lower, upper)) {
                    None => lambda *= 10.0,
                    Some(delta) => {
                        let mut xn: Vec<f64> =
                            x.iter().zip(delta.iter()).map(|(a, b)| a + b).collect();
                        clamp(&mut xn);
                        trials.push((xn, lambda));
                        lambda *= 4.0;
                    }
                }
            }
            let points: Vec<Vec<f64>> = trials.iter().map(|(p, _)| p.clone()).collect();
            let scored = if points.is_empty() {
                Vec::new()
            } else {
                residuals(&points)?
            };
            for ((xn, lam), rn) in trials.into_iter().zip(scored) {
                let Some(rn) = rn else { continue };
                let sn = rn.norm_squared();
                if sn < sse {
                    let rel = (sse - sn) / sse;
                    (x, r, sse) = (xn, rn, sn);
                    lambda = (lam / 3.0).max(1e-12);
                    improved = true;
                    if rel < settings.tolerance {
                        return Ok(LmOutcome { x, sse, iterations });
                    }
                    break;
                }
            }
        }
        if !improved {
            break;
        }
    }
    Ok(LmOutcome { x, sse, iterations })
}

/// The damped Gauss–Newton step `(JᵀJ + λ·diag JᵀJ) δ = −Jᵀr` with the
/// coordinates on a bound whose step points out of the box held at zero.
fn bounded_step(
    jtj: &DMatrix<f64>,
    jtr: &DVector<f64>,
    lambda: f64,
    x: &[f64],
    (lower, upper): (&[f64], &[f64]),
) -> Option<DVector<f64>> {
    let d = x.len();
    let mut held = vec![false; d];
    // Each pass holds at least one more coordinate or stops.
    for _ in 0..=d {
        let mut a = jtj.clone();
        let mut b = -jtr;
        for j in 0..d {
            a[(j, j)] += lambda * jtj[(j, j)].max(1e-30);
        }
        for j in (0..d).filter(|&j| held[j]) {
            a.row_mut(j).fill(0.0);
            a.column_mut(j).fill(0.0);
            a[(j, j)] = 1.0;
            b[j] = 0.0;
        }
        let delta = a.lu().solve(&b)?;
        let outward: Vec<usize> = (0..d)
            .filter(|&j| {
                !held[j]
                    && ((x[j] <= lower[j] && delta[j] < 0.0)
                        || (x[j] >= upper[j] && delta[j] > 0.0))
            })
            .collect();
        if outward.is_empty() {
            return Some(delta);
        }
        for j in outward {
            held[j] = true;
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rosenbrock's valley as residuals: (1 − x, 10 (y − x²)).
    fn rosenbrock(p: &[f64]) -> Option<DVector<f64>> {
        Some(DVector::from_vec(vec![
            1.0 - p[0],
            10.0 * (p[1] - p[0] * p[0]),
        ]))
    }

    /// Rosenbrock from (−1.2, 1) with `x ≤ x_max`, 200 iterations at most.
    fn descend(x_max: f64) -> LmOutcome {
        let inf = f64::INFINITY;
        let settings = LmSettings {
            max_iterations: 200,
            ..LmSettings::default()
        };
        let bounds: (&[f64], &[f64]) = (&[-inf, -inf], &[x_max, inf]);
        levenberg_marquardt(rosenbrock, &[-1.2, 1.0], bounds, &[1.0, 1.0], &settings).unwrap()
    }

    #[test]
    fn follows_a_curved_valley_to_its_minimum() {
        let out = descend(f64::INFINITY);
        assert!((out.x[0] - 1.0).abs() < 1e-5, "{:?}", out);
        assert!((out.x[1] - 1.0).abs() < 1e-5, "{:?}", out);
        assert!(out.sse < 1e-10);
    }

    #[test]
    fn a_bound_that_cuts_the_valley_holds_and_the_rest_moves_on() {
        // The unconstrained minimum (1, 1) lies outside x ≤ 0.5: the best in
        // the box is x = 0.5 on its bound with y = x² = 0.25.
        let out = descend(0.5);
        assert_eq!(out.x[0], 0.5);
        assert!((out.x[1] - 0.25).abs() < 1e-6, "{:?}", out);
    }

    #[test]
    fn never_ends_worse_than_it_started_and_reports_a_diverging_start() {
        let start = [1.0, 1.0];
        let inf = f64::INFINITY;
        let bounds: (&[f64], &[f64]) = (&[-inf, -inf], &[inf, inf]);
        let out = levenberg_marquardt(
            rosenbrock,
            &start,
            bounds,
            &[1.0, 1.0],
            &LmSettings::default(),
        )
        .unwrap();
        assert_eq!(out.x, start.to_vec());
        assert_eq!(out.sse, 0.0);
        let diverges = |_: &[f64]| None;
        assert_eq!(
            levenberg_marquardt(
                diverges,
                &start,
                bounds,
                &[1.0, 1.0],
                &LmSettings::default()
            ),
            Err(LmError::StartDiverges)
        );
    }
}
