//! Model predictive control that stays a convex QP despite the hysteresis.
//!
//! The thesis' MPC (§6.3) failed because putting the Bouc-Wen model into the
//! prediction made the problem non-convex. Here the hysteresis enters the
//! prediction only through the state `w`, and `w` is *known*: at the current
//! sample it is tracked from the measured displacement (the same update as
//! `model::sim`), and over the horizon it is predicted along the previous
//! plan. With `w` known, eq. 13 reads
//!
//! ```text
//! x(k+1) = a·α·x(k) + v(k) + c,     v(k) = b·u(k) + a·(1−α)·w(k),
//! ```
//!
//! linear in the virtual input `v`; here `u = p − ū` is the pressure, itself
//! driven by the valve voltage through the identified first-order
//! [`ValveModel`](super::design::ValveModel). So the predicted displacement is affine in the valve
//! voltages of the horizon, and tracking the planned reference under the
//! valve range and the slew limit is a small dense QP, solved by `clarabel`
//! at every sample. The valve voltage is the QP's variable, so the inversion
//! "virtual input → pressure → voltage" is done by the QP itself, and the
//! voltage limits are exact constraints rather than clipped after the fact.
//!
//! Offset-free: the one-step prediction errors of displacement and pressure
//! are low-pass filtered into constant disturbances over the horizon, which
//! absorbs what the identified models miss (load, valve nonlinearity).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus};
use serde::{Deserialize, Serialize};

use super::closed_loop::Controller;
use super::design::{ControlModel, Unpacked};
use super::limits::ValveLimits;
use super::plant::Measurement;

/// Tuning of the MPC.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MpcSettings {
    /// Prediction horizon in samples (the thesis planned 8; a 10 ms sample
    /// needs more to see a 2 s period coming).
    pub horizon: usize,
    /// Weight of the squared tracking error (per mm²).
    pub q_error: f64,
    /// Weight of the squared valve move (per V²).
    pub r_move: f64,
    /// Filter pole of the disturbance estimates (0: use the last innovation).
    pub disturbance_pole: f64,
    /// QP solves per sample: the second and later re-predict `w` along the
    /// plan just found.
    pub passes: usize,
}

impl Default for MpcSettings {
    fn default() -> Self {
        MpcSettings {
            horizon: 30,
            q_error: 1.0,
            r_move: 3.0,
            disturbance_pole: 0.9,
            passes: 1,
        }
    }
}

/// The MPC controller.
pub struct Mpc {
    pub settings: MpcSettings,
    pub limits: ValveLimits,
    model: Unpacked,
    valve: super::design::ValveModel,
    mean_u: f64,
    mean_y: f64,
    label: String,
    /// Sensitivities: `gx[j][i]` = ∂x(j)/∂v(i), j = 0..=N+1.
    gx: Vec<Vec<f64>>,
    /// Upper triangle of the QP's Hessian, CSC.
    hessian: CscMatrix<f64>,
    constraints: CscMatrix<f64>,
    solver: Option<DefaultSolver<f64>>,
    // Loop state.
    prev_u: f64,
    prev: Option<(f64, f64, f64)>, // (x, p, w) at the previous sample, deviation x
    w: f64,
    dist_x: f64,
    dist_p: f64,
    plan_x: Vec<f64>,
    /// Samples where the QP did not solve and the previous command was held.
    pub solver_failures: usize,
}

impl Mpc {
    pub fn new(
        model: &ControlModel,
        settings: MpcSettings,
        limits: ValveLimits,
        label: impl Into<String>,
    ) -> Self {
        let un = Unpacked::new(&model.displacement);
        let n = settings.horizon.max(1);
        // p(j) = ... + Σ_i gp[j][i] v(i); x(j+1) = aα x(j) + b p(j) + ...
        let mut gp = vec![vec![0.0; n]; n + 1];
        let mut gx = vec![vec![0.0; n]; n + 2];
        for j in 0..n {
            let (done, rest) = gp.split_at_mut(j + 1);
            for (i, (next, prev)) in rest[0].iter_mut().zip(&done[j]).enumerate() {
                *next = model.valve.pole * prev + if i == j { model.valve.gain } else { 0.0 };
            }
        }
        for j in 0..=n {
            for i in 0..n {
                gx[j + 1][i] = un.a * un.alpha * gx[j][i] + un.b * gp[j][i];
            }
        }
        // Hessian of ½ vᵀHv: H = 2·(q·Σ_j gx_jᵀ gx_j + r·DᵀD), j = 2..=N+1.
        let mut h = vec![vec![0.0; n]; n];
        for row in gx.iter().skip(2) {
            for i in 0..n {
                for l in i..n {
                    h[i][l] += 2.0 * settings.q_error * row[i] * row[l];
                }
            }
        }
        for i in 0..n {
            h[i][i] += 2.0 * settings.r_move * if i + 1 < n { 2.0 } else { 1.0 } + 1e-9;
            if i + 1 < n {
                h[i][i + 1] -= 2.0 * settings.r_move;
            }
        }
        let hessian = upper_csc(&h);
        let constraints = constraint_matrix(n);
        Mpc {
            settings,
            limits,
            model: un,
            valve: model.valve,
            mean_u: model.displacement.input_mean,
            mean_y: model.displacement.output_mean,
            label: label.into(),
            gx,
            hessian,
            constraints,
            solver: None,
            prev_u: 0.0,
            prev: None,
            w: 0.0,
            dist_x: 0.0,
            dist_p: 0.0,
            plan_x: Vec::new(),
            solver_failures: 0,
        }
    }

    /// Free response (all valve voltages zero) of displacement over j = 0..=N+1,
    /// with `w` predicted along `path` (deviation displacement, j = 0..=N+1).
    fn free_response(&self, x0: f64, p0: f64, w0: f64, path: &[f64]) -> Vec<f64> {
        let n = self.settings.horizon.max(1);
        let m = &self.model;
        let mut xf = vec![0.0; n + 2];
        xf[0] = x0;
        let (mut p, mut w) = (p0, w0);
        for j in 0..=n {
            let u = p - self.mean_u;
            xf[j + 1] =
                m.a * m.alpha * xf[j] + m.b * u + m.a * (1.0 - m.alpha) * w + m.c + self.dist_x;
            w = m.advance_w(w, path[j], path[j + 1]);
            p = self.valve.pole * p + self.valve.offset + self.dist_p;
        }
        xf
    }

    /// Right-hand side of `[I; −I; D; −D]·v ≤ b`: range and slew from the
    /// command in force.
    fn constraint_rhs(&self) -> Vec<f64> {
        let n = self.settings.horizon.max(1);
        let l = &self.limits;
        let first = |i: usize| if i == 0 { self.prev_u } else { 0.0 };
        let mut b = Vec::with_capacity(4 * n);
        b.extend(std::iter::repeat_n(l.max_v, n));
        b.extend(std::iter::repeat_n(-l.min_v, n));
        b.extend((0..n).map(|i| l.slew_v_per_step + first(i)));
        b.extend((0..n).map(|i| l.slew_v_per_step - first(i)));
        b
    }

    /// Sets the solver up once: the Hessian and the constraint matrix never
    /// change, so the KKT system is analysed here and later samples only
    /// update `q` and `b` (presolve off, which data updates require).
    fn build_solver(&mut self) {
        let n = self.settings.horizon.max(1);
        let settings = DefaultSettings {
            verbose: false,
            presolve_enable: false,
            max_threads: 1,
            direct_solve_method: "qdldl".to_string(),
            ..DefaultSettings::default()
        };
        let cones = [NonnegativeConeT(4 * n)];
        let q = vec![0.0; n];
        let b = self.constraint_rhs();
        self.solver =
            DefaultSolver::new(&self.hessian, &q, &self.constraints, &b, &cones, settings).ok();
    }

    fn solve(&mut self, xf: &[f64], reference: &[f64]) -> Option<Vec<f64>> {
        let n = self.settings.horizon.max(1);
        let rdev = |j: usize| reference[j.min(reference.len() - 1)] - self.mean_y;
        let mut q = vec![0.0; n];
        for (j, row) in self.gx.iter().enumerate().skip(2) {
            let e = xf[j] - rdev(j);
            for i in 0..n {
                q[i] += 2.0 * self.settings.q_error * row[i] * e;
            }
        }
        q[0] -= 2.0 * self.settings.r_move * self.prev_u;
        let b = self.constraint_rhs();
        if self.solver.is_none() {
            self.build_solver();
        }
        let solver = self.solver.as_mut()?;
        solver.update_q(&q).ok()?;
        solver.update_b(&b).ok()?;
        solver.solve();
        match solver.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => Some(solver.solution.x.clone()),
            _ => None,
        }
    }
}

/// `[I; −I; D; −D]` with `D` the first difference (row 0 is `v0`).
fn constraint_matrix(n: usize) -> CscMatrix<f64> {
    let mut dense = vec![vec![0.0; n]; 4 * n];
    for i in 0..n {
        dense[i][i] = 1.0;
        dense[n + i][i] = -1.0;
        dense[2 * n + i][i] = 1.0;
        dense[3 * n + i][i] = -1.0;
        if i > 0 {
            dense[2 * n + i][i - 1] = -1.0;
            dense[3 * n + i][i - 1] = 1.0;
        }
    }
    csc(&dense, false)
}

fn upper_csc(h: &[Vec<f64>]) -> CscMatrix<f64> {
    csc(h, true)
}

/// Dense rows → CSC, keeping structural entries (only the upper triangle when
/// `upper`), so the sparsity pattern never depends on values.
fn csc(rows: &[Vec<f64>], upper: bool) -> CscMatrix<f64> {
    let m = rows.len();
    let n = rows.first().map_or(0, |r| r.len());
    let mut colptr = vec![0];
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    for c in 0..n {
        for (r, row) in rows.iter().enumerate() {
            if (upper && r <= c) || (!upper && row[c] != 0.0) {
                rowval.push(r);
                nzval.push(row[c]);
            }
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(m, n, colptr, rowval, nzval)
}

impl Controller for Mpc {
    fn name(&self) -> &str {
        &self.label
    }

    fn reset(&mut self, u0: f64) {
        self.prev_u = u0;
        self.prev = None;
        self.w = 0.0;
        self.dist_x = 0.0;
        self.dist_p = 0.0;
        self.plan_x.clear();
        self.solver_failures = 0;
        if self.solver.is_none() {
            self.build_solver();
        }
    }

    fn command(&mut self, m: Measurement, reference: &[f64]) -> f64 {
        let n = self.settings.horizon.max(1);
        let x = m.displacement_mm - self.mean_y;
        let p = m.pressure_mpa;
        let un = &self.model;
        if let Some((xp, pp, wp)) = self.prev {
            // Innovations of the one-step predictions made at the last sample.
            let x_pred = un.a * un.alpha * xp
                + un.b * (pp - self.mean_u)
                + un.a * (1.0 - un.alpha) * wp
                + un.c;
            let p_pred = self.valve.step(pp, self.prev_u);
            let lam = self.settings.disturbance_pole;
            self.dist_x = lam * self.dist_x + (1.0 - lam) * (x - x_pred);
            self.dist_p = lam * self.dist_p + (1.0 - lam) * (p - p_pred);
            self.w = un.advance_w(wp, xp, x);
        }
        self.prev = Some((x, p, self.w));
        // Path along which w is predicted: the last plan shifted by one sample.
        let mut path: Vec<f64> = (0..n + 2)
            .map(|j| {
                if j == 0 {
                    x
                } else {
                    self.plan_x
                        .get(j + 1)
                        .or(self.plan_x.last())
                        .copied()
                        .unwrap_or(x)
                }
            })
            .collect();
        let mut chosen = None;
        for _ in 0..self.settings.passes.max(1) {
            let xf = self.free_response(x, p, self.w, &path);
            let Some(v) = self.solve(&xf, reference) else {
                break;
            };
            path = (0..n + 2)
                .map(|j| xf[j] + self.gx[j].iter().zip(&v).map(|(g, vi)| g * vi).sum::<f64>())
                .collect();
            chosen = Some(v[0]);
        }
        let u = match chosen {
            Some(v0) => {
                self.plan_x = path;
                // Interior-point solutions sit within solver tolerance of a
                // bound; snap those onto it (a real excursion stays visible
                // to the episode's constraint check).
                let (lo, hi) = self.limits.window(self.prev_u);
                if v0 < lo && v0 > lo - super::limits::TOLERANCE_V {
                    lo
                } else if v0 > hi && v0 < hi + super::limits::TOLERANCE_V {
                    hi
                } else {
                    v0
                }
            }
            None => {
                self.solver_failures += 1;
                self.plan_x.clear();
                self.prev_u
            }
        };
        self.prev_u = u;
        u
    }
}
