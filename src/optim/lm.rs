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

use std::cell::RefCell;

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use super::normal::Jacobian;

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
    /// Coordinates held where each start has them (empty: none): no probe,
    /// no step. For a coordinate in which the objective is piecewise
    /// constant, whose difference quotients are noise.
    pub held: Vec<bool>,
}

impl Default for LmSettings {
    fn default() -> Self {
        LmSettings {
            max_iterations: 30,
            rel_step: 1e-6,
            tolerance: 1e-12,
            central: false,
            held: Vec::new(),
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
pub type BatchResiduals<'a, R = DVector<f64>> =
    dyn FnMut(&[Vec<f64>]) -> anyhow::Result<Vec<Option<R>>> + 'a;

/// A point's residuals as its scorer gives them: `f64`, or a batch
/// evaluator's `f32`, read in `f64` (exactly) only inside the step of the
/// start that asked for them. A lock-step round on a GPU holds every
/// start's probes at once (16 000 starts at `--pop 1000000`), and in `f32`
/// until then they take a third of the memory the `f32` read-back and its
/// `f64` copy took together.
pub trait Residuals: Send {
    /// The residuals in `f64`.
    fn widen(self) -> DVector<f64>;

    /// The residuals read in `f64` where they lie, for a probe whose
    /// values only enter a Jacobian's column: no `f64` copy is made.
    fn values(&self) -> impl Iterator<Item = f64> + '_;
}

impl Residuals for DVector<f64> {
    fn widen(self) -> DVector<f64> {
        self
    }

    fn values(&self) -> impl Iterator<Item = f64> + '_ {
        self.iter().copied()
    }
}

impl Residuals for Vec<f32> {
    fn widen(self) -> DVector<f64> {
        DVector::from_vec(self.values().collect())
    }

    fn values(&self) -> impl Iterator<Item = f64> + '_ {
        self.iter().map(|&v| f64::from(v))
    }
}

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
    bounds: (&[f64], &[f64]),
    step_floor: &[f64],
    settings: &LmSettings,
    interrupt: Option<&std::sync::atomic::AtomicBool>,
) -> anyhow::Result<LmOutcome> {
    let starts = [start.to_vec()];
    let mut runs =
        levenberg_marquardt_lockstep(residuals, &starts, bounds, step_floor, settings, interrupt)?;
    Ok(runs.pop().expect("one start, one outcome").outcome?)
}

/// One start's polish in lock-step: where it ended, and how many points it
/// had scored (its own share of the calls).
#[derive(Debug, Clone, PartialEq)]
pub struct Polished {
    pub outcome: Result<LmOutcome, LmError>,
    pub points: usize,
}

/// [`levenberg_marquardt_batched`] from several starts in lock-step: every
/// round, the points all unfinished starts need (one's Jacobian probes,
/// another's trial steps) are scored in one call, so that a batch evaluator
/// scores the polish of `k` starts in the calls of one; a start that is done
/// drops out. Each start takes the very steps it takes alone: its points
/// and its arithmetic do not depend on the others. One result a start, in
/// order; only the scorer's own error ends them all.
pub fn levenberg_marquardt_lockstep<R: Residuals>(
    residuals: &mut BatchResiduals<'_, R>,
    starts: &[Vec<f64>],
    bounds: (&[f64], &[f64]),
    step_floor: &[f64],
    settings: &LmSettings,
    interrupt: Option<&std::sync::atomic::AtomicBool>,
) -> anyhow::Result<Vec<Polished>> {
    let mut runs: Vec<Run> = starts
        .iter()
        .map(|s| Run::new(s, bounds, step_floor, settings))
        .collect();
    let cut = || interrupt.is_some_and(|f| f.load(std::sync::atomic::Ordering::SeqCst));
    loop {
        // Which run asked for how many of the points.
        let mut asked: Vec<(usize, usize)> = Vec::new();
        let mut points: Vec<Vec<f64>> = Vec::new();
        for (k, run) in runs.iter_mut().enumerate() {
            if let Some(p) = run.request(&cut) {
                asked.push((k, p.len()));
                points.extend(p);
            }
        }
        if asked.is_empty() {
            break;
        }
        // Each run's share of the scored points, then every run's step
        // (its Jacobian, normal equations and solves) at once: the runs are
        // independent, so their order of work does not matter.
        let mut scored = residuals(&points)?.into_iter();
        let mut told: Vec<Option<Vec<Option<R>>>> = runs.iter().map(|_| None).collect();
        for (k, count) in asked {
            runs[k].points += count;
            told[k] = Some(scored.by_ref().take(count).collect());
        }
        runs.par_iter_mut().zip(told).for_each(|(run, told)| {
            if let Some(points) = told {
                run.receive(points);
            }
        });
    }
    Ok(runs
        .into_iter()
        .map(|run| Polished {
            points: run.points,
            outcome: run.outcome(),
        })
        .collect())
}

/// One start's polish, as a sequence of requests for scored points: it
/// says which points it needs next ([`Run::request`]) and goes on when told
/// their residuals ([`Run::receive`]). The steps are those of
/// Levenberg–Marquardt as the module describes it.
struct Run<'a> {
    bounds: (&'a [f64], &'a [f64]),
    step_floor: &'a [f64],
    settings: &'a LmSettings,
    x: Vec<f64>,
    r: DVector<f64>,
    sse: f64,
    lambda: f64,
    /// Iterations begun (Jacobians asked for).
    iterations: usize,
    /// Points scored for it so far.
    points: usize,
    phase: Phase,
}

thread_local! {
    /// Each thread's Jacobian storage, reused from one step to the next. A
    /// step needs its Jacobian only until it has formed its normal
    /// equations. Storage of its own in every start would be held by
    /// thousands of starts at once on a GPU, whose lock-step rounds move
    /// every start together (16 000 at `--pop 1000000`); a fresh Jacobian
    /// a step, allocated and zeroed, shows in the polish's time.
    static JACOBIAN: RefCell<Jacobian> = RefCell::new(Jacobian::zeros(0, 0));
}

/// Where a [`Run`] stands.
enum Phase {
    /// It needs the start's residuals.
    Start,
    /// At the top of an iteration: it needs the Jacobian's probes next.
    Iterate,
    /// It waits for the probes: forward from `x` by `steps`, then back
    /// where `back` holds (central differences).
    Probing {
        steps: Vec<f64>,
        back: Vec<bool>,
    },
    /// It makes trial steps from these normal equations; `tried` so far.
    Trials {
        jtj: DMatrix<f64>,
        jtr: DVector<f64>,
        tried: usize,
    },
    /// It waits for these trial steps, each with its λ.
    Trying {
        jtj: DMatrix<f64>,
        jtr: DVector<f64>,
        tried: usize,
        trials: Vec<(Vec<f64>, f64)>,
    },
    Done(Result<(), LmError>),
}

impl<'a> Run<'a> {
    fn new(
        start: &[f64],
        bounds: (&'a [f64], &'a [f64]),
        step_floor: &'a [f64],
        settings: &'a LmSettings,
    ) -> Run<'a> {
        let mut x = start.to_vec();
        clamp(&mut x, bounds);
        Run {
            bounds,
            step_floor,
            settings,
            x,
            r: DVector::zeros(0),
            sse: f64::INFINITY,
            lambda: 1e-3,
            iterations: 0,
            points: 0,
            phase: Phase::Start,
        }
    }

    /// The points to score next, `None` once done; `cut` stops it at the
    /// top of its next iteration.
    fn request(&mut self, cut: &dyn Fn() -> bool) -> Option<Vec<Vec<f64>>> {
        let (lower, upper) = self.bounds;
        let d = self.x.len();
        loop {
            match &mut self.phase {
                Phase::Start => return Some(vec![self.x.clone()]),
                Phase::Iterate => {
                    if self.iterations >= self.settings.max_iterations || cut() {
                        self.phase = Phase::Done(Ok(()));
                        continue;
                    }
                    self.iterations += 1;
                    let x = &self.x;
                    let steps: Vec<f64> = (0..d)
                        .map(|j| {
                            let h = self.settings.rel_step * x[j].abs().max(self.step_floor[j]);
                            // Probe inward from an upper bound.
                            if x[j] + h > upper[j] { -h } else { h }
                        })
                        .collect();
                    // Central differences where both probes stay in the box:
                    // the truncation error of a forward difference is first
                    // order in the step, and in a flat valley it bends the
                    // Gauss–Newton step.
                    let back: Vec<bool> = (0..d)
                        .map(|j| {
                            self.settings.central
                                && !self.held(j)
                                && x[j] - steps[j] >= lower[j]
                                && x[j] + steps[j] <= upper[j]
                        })
                        .collect();
                    let mut probes: Vec<Vec<f64>> = (0..d)
                        .filter(|&j| !self.held(j))
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
                    self.phase = Phase::Probing { steps, back };
                    return Some(probes);
                }
                // The trial steps in the order a sequential search tries
                // them: λ times 10 after a singular solve, times 4 after a
                // step that does not lower the SSE; the first that lowers it
                // is taken. An iteration whose trials all fail ends the polish.
                Phase::Trials { jtj, jtr, tried } => {
                    if *tried >= MAX_TRIALS {
                        self.phase = Phase::Done(Ok(()));
                        continue;
                    }
                    let mut trials: Vec<(Vec<f64>, f64)> = Vec::new();
                    while trials.len() < TRIALS_PER_BATCH && *tried < MAX_TRIALS {
                        *tried += 1;
                        let held = &self.settings.held;
                        match bounded_step(jtj, jtr, self.lambda, &self.x, self.bounds, held) {
                            None => self.lambda *= 10.0,
                            Some(delta) => {
                                let mut xn: Vec<f64> = self
                                    .x
                                    .iter()
                                    .zip(delta.iter())
                                    .map(|(a, b)| a + b)
                                    .collect();
                                clamp(&mut xn, self.bounds);
                                trials.push((xn, self.lambda));
                                self.lambda *= 4.0;
                            }
                        }
                    }
                    if trials.is_empty() {
                        continue;
                    }
                    let points = trials.iter().map(|(p, _)| p.clone()).collect();
                    let Phase::Trials { jtj, jtr, tried } =
                        std::mem::replace(&mut self.phase, Phase::Iterate)
                    else {
                        unreachable!("in the trials phase")
                    };
                    self.phase = Phase::Trying {
                        jtj,
                        jtr,
                        tried,
                        trials,
                    };
                    return Some(points);
                }
                Phase::Done(_) => return None,
                Phase::Probing { .. } | Phase::Trying { .. } => {
                    unreachable!("a run is asked again before it was told its points")
                }
            }
        }
    }

    /// The residuals of the points last requested, in order.
    fn receive<R: Residuals>(&mut self, scored: Vec<Option<R>>) {
        self.phase = match std::mem::replace(&mut self.phase, Phase::Iterate) {
            Phase::Start => match scored.into_iter().next().flatten().map(R::widen) {
                Some(r) => {
                    self.sse = r.norm_squared();
                    self.r = r;
                    Phase::Iterate
                }
                None => Phase::Done(Err(LmError::StartDiverges)),
            },
            Phase::Probing { steps, back } => {
                JACOBIAN.with_borrow_mut(|jac| match self.jacobian(scored, &steps, &back, jac) {
                    Some(()) => {
                        let (jtj, jtr) = jac.normal_equations(self.r.as_slice());
                        Phase::Trials { jtj, jtr, tried: 0 }
                    }
                    None => Phase::Done(Err(LmError::ProbeDiverges)),
                })
            }
            Phase::Trying {
                jtj,
                jtr,
                tried,
                trials,
            } => {
                let mut next = Phase::Trials { jtj, jtr, tried };
                for ((xn, lam), rn) in trials.into_iter().zip(scored) {
                    let Some(rn) = rn.map(R::widen) else { continue };
                    let sn = rn.norm_squared();
                    if sn < self.sse {
                        let rel = (self.sse - sn) / self.sse;
                        (self.x, self.r, self.sse) = (xn, rn, sn);
                        self.lambda = (lam / 3.0).max(1e-12);
                        next = if rel < self.settings.tolerance {
                            Phase::Done(Ok(()))
                        } else {
                            Phase::Iterate
                        };
                        break;
                    }
                }
                next
            }
            other => other,
        };
    }

    /// Whether coordinate `j` is held ([`LmSettings::held`]).
    fn held(&self, j: usize) -> bool {
        self.settings.held.get(j).copied().unwrap_or(false)
    }

    /// The Jacobian from the probes' residuals, into `jac` (a held
    /// coordinate's column zero); `None` if a probe diverged.
    fn jacobian<R: Residuals>(
        &self,
        scored: Vec<Option<R>>,
        steps: &[f64],
        back: &[bool],
        jac: &mut Jacobian,
    ) -> Option<()> {
        let d = self.x.len();
        let probed: Vec<usize> = (0..d).filter(|&j| !self.held(j)).collect();
        let mut cols = scored.into_iter();
        let forward: Vec<Option<R>> = cols.by_ref().take(probed.len()).collect();
        jac.reshape(self.r.len(), d);
        for j in (0..d).filter(|&j| self.held(j)) {
            jac.set_column(j, std::iter::repeat(0.0));
        }
        for (&j, plus) in probed.iter().zip(forward) {
            let plus = plus?;
            if back[j] {
                let minus = cols.next().flatten()?;
                let h = 2.0 * steps[j];
                jac.set_column(
                    j,
                    plus.values().zip(minus.values()).map(|(p, m)| (p - m) / h),
                );
            } else {
                let h = steps[j];
                jac.set_column(
                    j,
                    plus.values().zip(self.r.iter()).map(|(p, m)| (p - m) / h),
                );
            }
        }
        Some(())
    }

    fn outcome(self) -> Result<LmOutcome, LmError> {
        match self.phase {
            Phase::Done(Err(e)) => Err(e),
            _ => Ok(LmOutcome {
                x: self.x,
                sse: self.sse,
                iterations: self.iterations,
            }),
        }
    }
}

/// `v` clamped into the box, coordinate by coordinate.
fn clamp(v: &mut [f64], (lower, upper): (&[f64], &[f64])) {
    for (j, vj) in v.iter_mut().enumerate() {
        *vj = vj.clamp(lower[j], upper[j]);
    }
}

/// The damped Gauss–Newton step `(JᵀJ + λ·diag JᵀJ) δ = −Jᵀr` with the
/// coordinates on a bound whose step points out of the box, and those
/// `always` holds, held at zero.
fn bounded_step(
    jtj: &DMatrix<f64>,
    jtr: &DVector<f64>,
    lambda: f64,
    x: &[f64],
    (lower, upper): (&[f64], &[f64]),
    always: &[bool],
) -> Option<DVector<f64>> {
    let d = x.len();
    let mut held: Vec<bool> = (0..d)
        .map(|j| always.get(j).copied().unwrap_or(false))
        .collect();
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
    fn a_held_coordinate_stays_where_each_start_has_it() {
        let settings = LmSettings {
            max_iterations: 200,
            held: vec![true, false],
            ..LmSettings::default()
        };
        let inf = f64::INFINITY;
        let starts = [vec![0.5, 1.0], vec![-0.3, -2.0]];
        let mut batch = |points: &[Vec<f64>]| -> anyhow::Result<Vec<Option<DVector<f64>>>> {
            Ok(points.iter().map(|p| rosenbrock(p)).collect())
        };
        let runs = levenberg_marquardt_lockstep(
            &mut batch,
            &starts,
            (&[-inf, -inf], &[inf, inf]),
            &[1.0, 1.0],
            &settings,
            None,
        )
        .unwrap();
        for (start, run) in starts.iter().zip(runs) {
            let out = run.outcome.unwrap();
            // x held: the valley's floor at that x, y = x².
            assert_eq!(out.x[0], start[0]);
            assert!((out.x[1] - start[0] * start[0]).abs() < 1e-8, "{out:?}");
            // One probe an iteration: the free coordinate's alone.
            assert!(run.points <= 1 + 2 * out.iterations + 12 * out.iterations);
        }
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

    /// Rosenbrock, diverging right of x = 2, as a batch scorer that counts
    /// its calls and the points it scored.
    fn counted<'a>(calls: &'a mut usize, points: &'a mut usize) -> Box<BatchResiduals<'a>> {
        Box::new(move |batch: &[Vec<f64>]| {
            *calls += 1;
            *points += batch.len();
            Ok(batch
                .iter()
                .map(|p| (p[0] <= 2.0).then(|| rosenbrock(p)).flatten())
                .collect())
        })
    }

    /// Starts polished in lock-step take the very steps each takes alone
    /// (same points, same outcome, a diverging start's error included), in
    /// as many scorer calls as the longest of them needs.
    #[test]
    fn starts_in_lock_step_end_where_each_ends_alone_in_fewer_calls() {
        // The third start begins where the scorer diverges.
        let starts = vec![
            vec![-1.2, 1.0],
            vec![0.5, -0.5],
            vec![2.5, 0.0],
            vec![1.5, 2.5],
        ];
        let inf = f64::INFINITY;
        let bounds: (&[f64], &[f64]) = (&[-inf, -inf], &[inf, inf]);
        let settings = LmSettings {
            max_iterations: 50,
            central: true,
            ..LmSettings::default()
        };
        let (mut alone_calls, mut alone_points) = (Vec::new(), Vec::new());
        let alone: Vec<Result<LmOutcome, LmError>> = starts
            .iter()
            .map(|start| {
                let (mut calls, mut points) = (0, 0);
                let out = levenberg_marquardt_batched(
                    &mut *counted(&mut calls, &mut points),
                    start,
                    bounds,
                    &[1.0, 1.0],
                    &settings,
                    None,
                )
                .map_err(|e| e.downcast::<LmError>().unwrap());
                alone_calls.push(calls);
                alone_points.push(points);
                out
            })
            .collect();
        let (mut calls, mut points) = (0, 0);
        let together = levenberg_marquardt_lockstep(
            &mut *counted(&mut calls, &mut points),
            &starts,
            bounds,
            &[1.0, 1.0],
            &settings,
            None,
        )
        .unwrap();
        let outcomes: Vec<_> = together.iter().map(|p| p.outcome.clone()).collect();
        assert_eq!(outcomes, alone);
        assert_eq!(outcomes[2], Err(LmError::StartDiverges));
        assert!(outcomes[0].as_ref().unwrap().sse < 1e-10);
        // Each start's own share of the points, and all of them together.
        let shares: Vec<usize> = together.iter().map(|p| p.points).collect();
        assert_eq!(shares, alone_points);
        assert_eq!(points, alone_points.iter().sum::<usize>());
        assert_eq!(calls, *alone_calls.iter().max().unwrap());
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
