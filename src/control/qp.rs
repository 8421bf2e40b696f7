//! The MPC's quadratic program, solved exactly by a dense primal active-set
//! method (Nocedal & Wright, *Numerical Optimization*, 2nd ed., 2006,
//! algorithm 16.3) that is warm-started from the previous sample's plan:
//!
//! ```text
//! minimise ½·vᵀHv + fᵀv   over the valve plan v ∈ ℝⁿ
//! subject to   lo₀ ≤ v₀ ≤ hi₀                  (range and slew from the command in force)
//!              lo ≤ vᵢ ≤ hi,  |vᵢ − vᵢ₋₁| ≤ s   (i ≥ 1)
//! ```
//!
//! Why this and not an interior-point solver: every iterate of a primal
//! active-set method is feasible, so a step cut short by its iteration cap
//! still yields a command within the limits; and the previous plan shifted
//! by one sample is feasible for the new problem and nearly optimal, so most
//! samples need one or two iterations — each a solve with `H⁻¹`, which is
//! formed once per sample. An interior-point method cannot start from the
//! old solution and walks the same central path every sample (the two
//! compared: docs/lab/control.md, "Real time").

/// One of the problem's inequality constraints, by the index it bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Constraint {
    /// `vᵢ ≤ hi` (`hi₀` for `i = 0`).
    Upper(usize),
    /// `vᵢ ≥ lo`.
    Lower(usize),
    /// `vᵢ − vᵢ₋₁ ≤ s` (`i ≥ 1`).
    Rise(usize),
    /// `vᵢ₋₁ − vᵢ ≤ s` (`i ≥ 1`).
    Fall(usize),
}

impl Constraint {
    /// The row `a` of `aᵀv ≤ b` as at most two `(index, coefficient)` terms.
    fn terms(self) -> [(usize, f64); 2] {
        match self {
            Constraint::Upper(i) => [(i, 1.0), (i, 0.0)],
            Constraint::Lower(i) => [(i, -1.0), (i, 0.0)],
            Constraint::Rise(i) => [(i, 1.0), (i - 1, -1.0)],
            Constraint::Fall(i) => [(i, -1.0), (i - 1, 1.0)],
        }
    }

    fn dot(self, v: &[f64]) -> f64 {
        self.terms().iter().map(|&(i, c)| c * v[i]).sum()
    }

    /// The same constraint one sample later in the plan (`None` for those
    /// on the first element, which the new command window replaces).
    fn shifted(self) -> Option<Constraint> {
        match self {
            Constraint::Upper(i) if i > 0 => Some(Constraint::Upper(i - 1)),
            Constraint::Lower(i) if i > 0 => Some(Constraint::Lower(i - 1)),
            Constraint::Rise(i) if i > 1 => Some(Constraint::Rise(i - 1)),
            Constraint::Fall(i) if i > 1 => Some(Constraint::Fall(i - 1)),
            _ => None,
        }
    }

    /// The edge this row adds to the graph whose forests are exactly the
    /// linearly independent sets of rows: a bound ties `vᵢ` to the ground
    /// node `n`, a slew ties `vᵢ₋₁` to `vᵢ`.
    fn edge(self, n: usize) -> (usize, usize) {
        match self {
            Constraint::Upper(i) | Constraint::Lower(i) => (i, n),
            Constraint::Rise(i) | Constraint::Fall(i) => (i - 1, i),
        }
    }
}

/// The limits of the plan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Interval of `v₀`: the valve range intersected with the slew window
    /// around the command in force.
    pub first: (f64, f64),
    /// Interval of every later `vᵢ`.
    pub range: (f64, f64),
    /// Largest change between consecutive elements.
    pub slew: f64,
}

impl Limits {
    fn bound(&self, c: Constraint) -> f64 {
        let window = |i: usize| if i == 0 { self.first } else { self.range };
        match c {
            Constraint::Upper(i) => window(i).1,
            Constraint::Lower(i) => -window(i).0,
            Constraint::Rise(_) | Constraint::Fall(_) => self.slew,
        }
    }

    /// The nearest feasible plan element by element (each clamped into its
    /// window given the one before): feasible whenever the windows are not
    /// empty, which holds for `first ⊆ range` or any nonempty `first`.
    pub fn repair(&self, v: &mut [f64]) {
        for i in 0..v.len() {
            let (lo, hi) = if i == 0 {
                self.first
            } else {
                let (lo, hi) = self.range;
                (lo.max(v[i - 1] - self.slew), hi.min(v[i - 1] + self.slew))
            };
            v[i] = v[i].clamp(lo, hi.max(lo));
        }
    }

    fn constraints(&self, n: usize) -> impl Iterator<Item = Constraint> {
        (0..n)
            .flat_map(|i| [Constraint::Upper(i), Constraint::Lower(i)])
            .chain((1..n).flat_map(|i| [Constraint::Rise(i), Constraint::Fall(i)]))
    }
}

/// How a solve ended.
#[derive(Debug, Clone, PartialEq)]
pub struct SolveStatus {
    /// Active-set iterations (each one linear solve).
    pub iterations: usize,
    /// Whether the optimality conditions hold; when the iteration cap cut
    /// the solve short the plan is feasible but not optimal.
    pub optimal: bool,
}

/// The solver, with the memory that warm-starts it: the working set of the
/// last solve, and buffers reused from sample to sample.
#[derive(Debug, Clone, Default)]
pub struct ActiveSetQp {
    working: Vec<Constraint>,
    hinv: Vec<f64>,
    parent: Vec<usize>,
}

/// Tolerance on a step's size and on slacks, in the units of `v` (volts).
const TOL: f64 = 1e-10;

impl ActiveSetQp {
    /// Shifts the remembered working set by one sample, for a plan that
    /// will be shifted the same way.
    pub fn shift(&mut self) {
        self.working = self.working.iter().filter_map(|c| c.shifted()).collect();
    }

    /// Forgets the working set (the next solve starts cold).
    pub fn clear(&mut self) {
        self.working.clear();
    }

    /// Minimises `½vᵀHv + fᵀv` (`h` row-major `n×n`, symmetric positive
    /// definite) under `limits`, starting from `v` (repaired into the
    /// feasible set first) and from the remembered working set; leaves the
    /// solution in `v`. `None` when `H` is not positive definite.
    pub fn solve(
        &mut self,
        h: &[f64],
        f: &[f64],
        limits: &Limits,
        v: &mut [f64],
        max_iterations: usize,
    ) -> Option<SolveStatus> {
        let n = v.len();
        inverse_spd(h, n, &mut self.hinv)?;
        limits.repair(v);
        // Keep the remembered constraints that are still active and
        // independent of each other.
        let remembered = std::mem::take(&mut self.working);
        for c in remembered {
            let active = (c.dot(v) - limits.bound(c)).abs() < 1e-9;
            if active && !self.working.contains(&c) && self.independent(n, c) {
                self.working.push(c);
            }
        }
        let mut g = vec![0.0; n];
        let mut p = vec![0.0; n];
        for iteration in 1..=max_iterations {
            for i in 0..n {
                g[i] = f[i] + (0..n).map(|j| h[i * n + j] * v[j]).sum::<f64>();
            }
            let lambda = self.equality_step(n, &g, &mut p)?;
            let step = p.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            if step < TOL {
                // At the minimiser on the working set: optimal unless a
                // multiplier says a constraint should be let go.
                match lambda.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1)) {
                    Some((i, &l)) if l < -1e-9 => {
                        self.working.remove(i);
                    }
                    _ => {
                        return Some(SolveStatus {
                            iterations: iteration,
                            optimal: true,
                        });
                    }
                }
                continue;
            }
            let mut alpha = 1.0;
            let mut blocking = None;
            for c in limits.constraints(n) {
                let ap = c.dot(&p);
                if ap > TOL && !self.working.contains(&c) {
                    let slack = (limits.bound(c) - c.dot(v)).max(0.0);
                    if slack < alpha * ap && self.independent(n, c) {
                        alpha = slack / ap;
                        blocking = Some(c);
                    }
                }
            }
            for (vi, pi) in v.iter_mut().zip(&p) {
                *vi += alpha * pi;
            }
            if let Some(c) = blocking {
                self.working.push(c);
            }
        }
        limits.repair(v);
        Some(SolveStatus {
            iterations: max_iterations,
            optimal: false,
        })
    }

    /// Whether adding `c` keeps the working set's rows independent
    /// (union-find over [`Constraint::edge`]).
    fn independent(&mut self, n: usize, c: Constraint) -> bool {
        self.parent.clear();
        self.parent.extend(0..=n);
        fn root(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        for w in self.working.iter().chain(std::iter::once(&c)) {
            let (a, b) = w.edge(n);
            let (ra, rb) = (root(&mut self.parent, a), root(&mut self.parent, b));
            if ra == rb {
                return false;
            }
            self.parent[ra] = rb;
        }
        true
    }

    /// The step `p` to the minimiser on the working set `W` from a point
    /// with gradient `g`: `H·p + A_Wᵀλ = −g`, `A_W·p = 0`, by the range-space
    /// method (`A_W H⁻¹ A_Wᵀ λ = −A_W H⁻¹ g`). Returns the multipliers λ.
    fn equality_step(&self, n: usize, g: &[f64], p: &mut [f64]) -> Option<Vec<f64>> {
        let hinv = &self.hinv;
        for i in 0..n {
            p[i] = -(0..n).map(|j| hinv[i * n + j] * g[j]).sum::<f64>();
        }
        let m = self.working.len();
        if m == 0 {
            return Some(Vec::new());
        }
        // z_c = H⁻¹ a_c, one column per working constraint.
        let z: Vec<Vec<f64>> = self
            .working
            .iter()
            .map(|c| {
                let t = c.terms();
                (0..n)
                    .map(|i| t[0].1 * hinv[i * n + t[0].0] + t[1].1 * hinv[i * n + t[1].0])
                    .collect()
            })
            .collect();
        let mut s = vec![0.0; m * m];
        let mut rhs = vec![0.0; m];
        for (r, c) in self.working.iter().enumerate() {
            for col in 0..m {
                s[r * m + col] = c.dot(&z[col]);
            }
            // −A_W H⁻¹ g = A_W p (p holds −H⁻¹g here).
            rhs[r] = c.dot(p);
        }
        let mut lambda = rhs;
        let mut factor = Vec::new();
        cholesky(&s, m, &mut factor)?;
        cholesky_solve(&factor, m, &mut lambda);
        for (zc, l) in z.iter().zip(&lambda) {
            for i in 0..n {
                p[i] -= zc[i] * l;
            }
        }
        Some(lambda)
    }
}

/// Lower Cholesky factor of the SPD matrix `a` (`n×n`, row-major) into `l`.
fn cholesky(a: &[f64], n: usize, l: &mut Vec<f64>) -> Option<()> {
    l.clear();
    l.resize(n * n, 0.0);
    for i in 0..n {
        for j in 0..=i {
            let mut sum = a[i * n + j];
            for k in 0..j {
                sum -= l[i * n + k] * l[j * n + k];
            }
            if i == j {
                // Not positive (or NaN): not positive definite.
                if sum.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                    return None;
                }
                l[i * n + i] = sum.sqrt();
            } else {
                l[i * n + j] = sum / l[j * n + j];
            }
        }
    }
    Some(())
}

/// Solves `L Lᵀ x = b` in place.
fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let s: f64 = (0..i).map(|k| l[i * n + k] * b[k]).sum();
        b[i] = (b[i] - s) / l[i * n + i];
    }
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|k| l[k * n + i] * b[k]).sum();
        b[i] = (b[i] - s) / l[i * n + i];
    }
}

/// `H⁻¹` of an SPD matrix into `out` (row-major), by Cholesky.
fn inverse_spd(h: &[f64], n: usize, out: &mut Vec<f64>) -> Option<()> {
    let mut l = Vec::new();
    cholesky(h, n, &mut l)?;
    out.clear();
    out.resize(n * n, 0.0);
    let mut col = vec![0.0; n];
    for j in 0..n {
        col.iter_mut().for_each(|v| *v = 0.0);
        col[j] = 1.0;
        cholesky_solve(&l, n, &mut col);
        for i in 0..n {
            out[i * n + j] = col[i];
        }
    }
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// Brute force for tiny problems: the best of all feasible points on a
    /// fine grid is never better than the solver's optimum.
    #[test]
    fn optimum_beats_every_grid_point_and_is_feasible() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..50 {
            let n = 3;
            // H = MᵀM + 0.1·I, f random.
            let m: Vec<f64> = (0..n * n).map(|_| rng.random_range(-1.0..1.0)).collect();
            let mut h = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    h[i * n + j] = (0..n).map(|k| m[k * n + i] * m[k * n + j]).sum::<f64>()
                        + if i == j { 0.1 } else { 0.0 };
                }
            }
            let f: Vec<f64> = (0..n).map(|_| rng.random_range(-3.0..3.0)).collect();
            let prev: f64 = rng.random_range(0.0..1.0);
            let limits = Limits {
                first: ((prev - 0.3).max(0.0), (prev + 0.3).min(1.0)),
                range: (0.0, 1.0),
                slew: 0.3,
            };
            let cost = |v: &[f64]| -> f64 {
                let mut c = 0.0;
                for i in 0..n {
                    c += f[i] * v[i];
                    for j in 0..n {
                        c += 0.5 * v[i] * h[i * n + j] * v[j];
                    }
                }
                c
            };
            let feasible = |v: &[f64]| {
                v[0] >= limits.first.0 - 1e-9
                    && v[0] <= limits.first.1 + 1e-9
                    && v.iter().all(|&x| (-1e-9..=1.0 + 1e-9).contains(&x))
                    && v.windows(2).all(|w| (w[1] - w[0]).abs() <= 0.3 + 1e-9)
            };
            let mut qp = ActiveSetQp::default();
            let mut v = vec![prev; n];
            let out = qp.solve(&h, &f, &limits, &mut v, 50).unwrap();
            assert!(out.optimal);
            assert!(feasible(&v), "{v:?}");
            let best = cost(&v);
            let steps = 25;
            for a in 0..=steps {
                for b in 0..=steps {
                    for c in 0..=steps {
                        let g = [a, b, c].map(|i| i as f64 / steps as f64);
                        if feasible(&g) {
                            assert!(cost(&g) >= best - 1e-9, "{g:?} beats {v:?}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn warm_start_from_the_solution_takes_one_iteration() {
        let n = 6;
        let mut h = vec![0.0; n * n];
        for i in 0..n {
            h[i * n + i] = 2.0;
            if i + 1 < n {
                h[i * n + i + 1] = -0.5;
                h[(i + 1) * n + i] = -0.5;
            }
        }
        let f = vec![-30.0; n];
        let limits = Limits {
            first: (4.75, 5.25),
            range: (0.0, 10.0),
            slew: 0.25,
        };
        let mut qp = ActiveSetQp::default();
        let mut v = vec![5.0; n];
        let cold = qp.solve(&h, &f, &limits, &mut v, 100).unwrap();
        assert!(cold.optimal && cold.iterations > 1);
        assert!((v[0] - 5.25).abs() < 1e-12, "{v:?}");
        let again = qp.solve(&h, &f, &limits, &mut v, 100).unwrap();
        assert_eq!(again.iterations, 1);
    }
}
