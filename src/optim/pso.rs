//! The thesis' particle swarm optimization (§5.3.3, Algorithm 3, appendix
//! A.2.3).
//!
//! After each evaluation the particles update their personal best and the
//! swarm's global best, then move: `v ← w·v + c1·r1∘(pbest − x) + c2·r2∘(gbest − x)`
//! (eq. 39), `|v_j| ≤ Vmax_j`, `x ← x + v` (eq. 40), clamped into the box. The
//! inertia falls linearly, `w(k) = a − (a − b)·k/G` (§5.3.3.4). The staged
//! fit replaces `gbest` by the best on a ring of neighbours
//! ([`PsoSettings::constriction`]).
//!
//! Appendix bugs fixed (see `docs/ARCHITECTURE.md`): the code clamps
//! `speed(j)` — the j-th entry of the whole speed *matrix* — instead of
//! `speed(i,j)`, and only from above; here every particle's every velocity
//! component is clamped to `[−Vmax_j, Vmax_j]`. The code draws a vector of
//! randoms for the cognitive term but one scalar for the social term; by
//! default both are per-dimension (eq. 39 as usually read), and
//! `scalar_social` restores the code's choice.

use rand::RngExt;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{Bounds, Optimizer, Streams, ThesisModel};
use crate::search::{Coords, Population, ROWS_PER_TASK, Rows};

/// PSO settings; defaults are Table 11 (classic); [`PsoSettings::thesis`]
/// gives Table 19 for the generalized model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PsoSettings {
    /// Inertia at the start (`a`).
    pub w_start: f64,
    /// Inertia at the end (`b`).
    pub w_end: f64,
    /// Cognitive (personal best) acceleration `c1`.
    pub c1: f64,
    /// Social (global best) acceleration `c2`.
    pub c2: f64,
    /// Velocity limit in the parameters' units (Table 11: 20, Table 19: 0.1).
    #[serde(with = "super::inf_serde::one_f64")]
    pub vmax: f64,
    /// Further limit as a fraction of each coordinate's box width, so that a
    /// coordinate much narrower or wider than the thesis' (about 1) gets a
    /// proportionate limit. 1.0: a particle never jumps more than the box.
    pub vmax_fraction: f64,
    /// The appendix code's single random number for the social term.
    pub scalar_social: bool,
    /// Whose best pulls a particle socially: `None` the whole swarm's (the
    /// thesis' global best), `Some(k)` the best of the `k` particles on each
    /// side of it on a ring (its own included), the "lbest" topology.
    #[serde(default)]
    pub ring: Option<usize>,
}

impl Default for PsoSettings {
    fn default() -> Self {
        PsoSettings {
            w_start: 1.1,
            w_end: 0.3,
            c1: 2.0,
            c2: 2.0,
            vmax: 20.0,
            vmax_fraction: 1.0,
            scalar_social: false,
            ring: None,
        }
    }
}

impl PsoSettings {
    /// Table 11 (classic: inertia 1.1 → 0.3, Vmax 20) or Table 19
    /// (generalized: inertia 2.1 → 0.6, Vmax 0.1); `c1 = c2 = 2` in both.
    pub fn thesis(model: ThesisModel) -> PsoSettings {
        match model {
            ThesisModel::Generalized => PsoSettings {
                w_start: 2.1,
                w_end: 0.6,
                vmax: 0.1,
                ..PsoSettings::default()
            },
            ThesisModel::Classic => PsoSettings::default(),
        }
    }

    /// Clerc and Kennedy's constriction coefficients ("The particle swarm —
    /// explosion, stability, and convergence in a multidimensional complex
    /// space", IEEE TEC 2002): χ = 0.7298 on velocity, χ·φ/2 = 1.49618 on
    /// each pull, with velocity capped at half the box. The thesis' decaying
    /// inertia from 1.1 diverges for most of its schedule; the constriction
    /// keeps the swarm convergent by construction (measured on the generated
    /// cases: docs/ARCHITECTURE.md, "PSO in the staged fit uses Clerc and
    /// Kennedy's constriction").
    ///
    /// On a ring of neighbours one to each side, as Bratton and Kennedy's
    /// standard PSO ("Defining a standard for particle swarm optimization",
    /// IEEE Swarm Intelligence Symposium 2007) advises: a best found
    /// anywhere spreads one neighbour per move, so the swarm keeps searching
    /// other basins while it does. With the global best the staged fit's
    /// islands can all collapse into the linear model (A → 0) on the
    /// shipped stair (docs/lab/results.md, "PSO on a ring").
    pub fn constriction() -> PsoSettings {
        PsoSettings {
            w_start: 0.7298,
            w_end: 0.7298,
            c1: 1.49618,
            c2: 1.49618,
            vmax: f64::INFINITY,
            vmax_fraction: 0.5,
            scalar_social: false,
            ring: Some(1),
        }
    }

    /// Inertia at move `k` of `g`.
    pub fn inertia(&self, k: usize, g: usize) -> f64 {
        self.w_start - (self.w_start - self.w_end) * k as f64 / g.max(1) as f64
    }
}

/// PSO state between iterations.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Pso {
    pub settings: PsoSettings,
    bounds: Bounds,
    n: usize,
    generations: usize,
    moves: usize,
    vmax: Vec<f64>,
    pos: Vec<f64>,
    vel: Vec<f64>,
    pbest: Vec<f64>,
    #[serde(with = "super::inf_serde")]
    pbest_cost: Vec<f32>,
    gbest: Vec<f64>,
    #[serde(with = "super::inf_serde::one")]
    gbest_cost: f32,
}

impl Optimizer for Pso {
    type Settings = PsoSettings;

    const HELP: &'static str = "Particle swarm optimization (§5.3.3, A.2.3)";

    /// A lone particle's own best is the swarm's, so both pulls vanish and
    /// its drawn velocity decays by χ a step: it stops near its draw, and a
    /// draw that diverges stays diverged (`fit --algo pso --pop 1` on the
    /// shipped stair ended with no model for five seeds of seven). A second
    /// particle gives each a place to move to.
    const MIN_POPULATION: usize = 2;

    fn new(settings: PsoSettings, bounds: Bounds, n: usize, generations: usize) -> Pso {
        let vmax = (0..bounds.dim())
            .map(|j| settings.vmax.min(settings.vmax_fraction * bounds.width(j)))
            .collect();
        Pso {
            settings,
            n,
            generations,
            moves: 0,
            vmax,
            pos: Vec::new(),
            vel: Vec::new(),
            pbest: Vec::new(),
            pbest_cost: vec![f32::INFINITY; n],
            gbest: bounds.lower.clone(),
            gbest_cost: f32::INFINITY,
            bounds,
        }
    }

    /// Table 19 for the generalized model, Table 11 otherwise.
    fn thesis_settings(model: ThesisModel) -> PsoSettings {
        PsoSettings::thesis(model)
    }

    /// The staged fit uses Clerc and Kennedy's constriction
    /// ([`PsoSettings::constriction`]).
    fn staged_settings(_n: usize) -> PsoSettings {
        PsoSettings::constriction()
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    /// The first swarm, with velocities uniform in `[−Vmax_j, Vmax_j]`,
    /// each particle's drawn after its position from the same stream.
    fn init(&mut self, initial: Population<Coords>, streams: &Streams) -> Rows<'_, Coords> {
        let d = self.bounds.dim();
        let (mut pos, given) = super::first_rows(&self.bounds, self.n, initial);
        let mut vel = vec![0.0; self.n * d];
        let (bounds, vmax) = (&self.bounds, &self.vmax);
        pos.par_chunks_mut(d)
            .zip(vel.par_chunks_mut(d))
            .enumerate()
            .with_min_len(ROWS_PER_TASK)
            .for_each(|(i, (x, v))| {
                let mut rng = streams.row(i);
                super::first_row(bounds, x, i < given, &mut rng);
                for (vj, limit) in v.iter_mut().zip(vmax) {
                    *vj = limit * (2.0 * rng.random::<f64>() - 1.0);
                }
            });
        self.pbest = pos.clone();
        self.pos = pos;
        self.vel = vel;
        Rows::new(&self.pos, self.bounds.dim())
    }

    fn next(&mut self, streams: &Streams) -> Rows<'_, Coords> {
        self.step(streams);
        Rows::new(&self.pos, self.bounds.dim())
    }

    /// Each particle's personal best in parallel, then the swarm's best:
    /// the lowest cost (the first on ties), if it beats the best so far.
    fn tell(&mut self, costs: &[f32]) {
        let d = self.bounds.dim();
        self.pbest
            .par_chunks_mut(d)
            .zip(self.pbest_cost.par_iter_mut())
            .zip(self.pos.par_chunks(d))
            .zip(costs.par_iter())
            .with_min_len(ROWS_PER_TASK)
            .for_each(|(((pbest, pbest_cost), x), &c)| {
                if super::cost_order(c, *pbest_cost).is_lt() {
                    *pbest_cost = c;
                    pbest.copy_from_slice(x);
                }
            });
        if let Some(i) = super::argmin(costs)
            && super::cost_order(costs[i], self.gbest_cost).is_lt()
        {
            self.gbest_cost = costs[i];
            self.gbest.copy_from_slice(&self.pos[i * d..(i + 1) * d]);
        }
    }

    /// The particles' personal bests: the best each has found.
    fn members(&self) -> (Population<Coords>, Vec<f32>) {
        (
            Population::new(self.pbest.clone(), self.bounds.dim()),
            self.pbest_cost.clone(),
        )
    }
}

impl Pso {
    /// Every particle moves in parallel, from its own stream.
    fn step(&mut self, streams: &Streams) {
        let d = self.bounds.dim();
        self.moves += 1;
        let w = self.settings.inertia(self.moves, self.generations);
        let (c1, c2) = (self.settings.c1, self.settings.c2);
        let social = self.social_bests();
        let (settings, bounds, vmax) = (&self.settings, &self.bounds, &self.vmax);
        let (pbest, gbest) = (&self.pbest, &self.gbest);
        self.pos
            .par_chunks_mut(d)
            .zip(self.vel.par_chunks_mut(d))
            .zip(social.par_iter())
            .enumerate()
            .with_min_len(ROWS_PER_TASK)
            .for_each(|(i, ((x, v), neighbour))| {
                let mut rng = streams.row(i);
                let r2_scalar: f64 = if settings.scalar_social {
                    rng.random()
                } else {
                    0.0
                };
                let pb = &pbest[i * d..(i + 1) * d];
                let best = match neighbour {
                    Some(k) => &pbest[k * d..(k + 1) * d],
                    None => &gbest[..],
                };
                for j in 0..d {
                    let r1: f64 = rng.random();
                    let r2: f64 = if settings.scalar_social {
                        r2_scalar
                    } else {
                        rng.random()
                    };
                    let vj = w * v[j] + c1 * r1 * (pb[j] - x[j]) + c2 * r2 * (best[j] - x[j]);
                    v[j] = vj.clamp(-vmax[j], vmax[j]);
                    x[j] += v[j];
                }
                bounds.clamp(x);
            });
    }

    /// For each particle, the particle whose personal best pulls it
    /// socially (the lowest cost on its ring neighbourhood, the lower index
    /// on ties), or `None` for the swarm's global best.
    fn social_bests(&self) -> Vec<Option<usize>> {
        let Some(k) = self.settings.ring else {
            return vec![None; self.n];
        };
        let n = self.n;
        let k = k.min(n / 2);
        (0..n)
            .into_par_iter()
            .with_min_len(ROWS_PER_TASK)
            .map(|i| {
                (0..=2 * k).map(|o| (i + n - k + o) % n).min_by(|&a, &b| {
                    super::cost_order(self.pbest_cost[a], self.pbest_cost[b]).then(a.cmp(&b))
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optim::stage::Stage;

    /// Generation `g`'s streams of a run seeded by `seed`.
    fn at(seed: u64, g: usize) -> Streams {
        Streams::new(seed, Stage::Global, g)
    }

    #[test]
    fn thesis_presets_and_inertia() {
        let g = PsoSettings::thesis(ThesisModel::Generalized);
        assert_eq!((g.w_start, g.w_end, g.vmax), (2.1, 0.6, 0.1));
        let c = PsoSettings::thesis(ThesisModel::Classic);
        assert!((c.inertia(30, 30) - 0.3).abs() < 1e-12);
        assert!((c.inertia(15, 30) - 0.7).abs() < 1e-12);
    }

    #[test]
    fn a_ring_pulls_each_particle_towards_its_neighbourhood_best() {
        let bounds = Bounds {
            lower: vec![0.0],
            upper: vec![1.0],
            names: vec!["x".into()],
        };
        let mut pso = Pso::new(PsoSettings::constriction(), bounds.clone(), 5, 10);
        pso.init(Population::zeros(0, 1), &at(1, 0));
        pso.tell(&[5.0, 1.0, 4.0, 3.0, f32::NAN]);
        // Particle 4's NaN ranks last; the ring wraps from 4 to 0.
        let want = [1, 1, 1, 3, 3].map(Some);
        assert_eq!(pso.social_bests(), want.to_vec());
        let mut global = Pso::new(PsoSettings::default(), bounds, 5, 10);
        global.init(Population::zeros(0, 1), &at(1, 0));
        global.tell(&[5.0, 1.0, 4.0, 3.0, 2.0]);
        assert_eq!(global.social_bests(), vec![None; 5]);
    }

    #[test]
    fn every_velocity_component_is_clamped_both_ways() {
        let bounds = Bounds {
            lower: vec![-100.0; 3],
            upper: vec![100.0; 3],
            names: vec!["x".into(), "y".into(), "z".into()],
        };
        let settings = PsoSettings {
            vmax: 0.5,
            ..PsoSettings::default()
        };
        let mut pso = Pso::new(settings, bounds, 4, 10);
        let x0 = pso
            .init(Population::zeros(0, 3), &at(4, 0))
            .as_flat()
            .to_vec();
        // The first particle is far better: everyone is pulled hard towards it.
        pso.tell(&[0.0, 9.0, 9.0, f32::INFINITY]);
        let x1 = pso.next(&at(4, 1));
        for (a, b) in x0.iter().zip(x1.as_flat()) {
            assert!((a - b).abs() <= 0.5 + 1e-12, "{a} -> {b}");
        }
    }
}
