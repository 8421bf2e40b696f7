//! The thesis' modified firefly algorithm (§5.3.1–5.3.2, Algorithm 2,
//! appendix A.2.2), after Zaman & Sikder.
//!
//! Each generation `k` every firefly `i` moves, in index order `j`, towards
//! every *brighter* firefly `j` (lower SSE; a diverged firefly is never
//! brighter): `n_i ← n_i + Λ_ij·(n_j − n_i) + ρ·v`, `v ~ N(0, 1)^d`, then
//! clamped into the box (eq. 35, as the appendix code does it: the walk is
//! part of each attraction, so the brightest firefly stays put). The
//! attractiveness is `Λ_ij = Λ0·e^(−σ·r)` (code) or `Λ0·e^(−σ·r²)` (eq. 32),
//! with the schedules of eq. 36–38: `Λ0` from `a` to `b` (code) or to `a − b`
//! (eq. 36), `σ(k) = 2·7^(−k/G)`, `ρ(k) = 0.1·e^(−4.8k/G)`.
//!
//! Parallel and deterministic: the fireflies move in parallel (rayon), each
//! against a snapshot of the others' positions taken at the start of the
//! generation (the appendix code moves them in place one after another, so a
//! later firefly sees earlier ones already moved), and each with its own
//! random stream ([`Streams`]), so the result does not depend on the thread
//! count. The all-pairs move is `O(N²·d)` per
//! generation; `max_attractors` caps it at `O(N·K·d)` by moving each firefly
//! towards `K` brighter fireflies (drawn at random, or the `K` brightest)
//! instead of all of them.

use rand::RngExt;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{Bounds, Optimizer, RowRng, Streams};
use crate::search::{Coords, Population, ROWS_PER_TASK, Rows};

/// Above this population the all-pairs move, `O(N²·d)` a generation, stops
/// being practical (timed: docs/lab/results.md, "3. Equal budgets over 10
/// seeds"), so the thesis' flow and Table 21 move each firefly towards the
/// [`BRIGHTEST`] brightest instead, unless told otherwise.
pub const ALL_PAIRS_MAX: usize = 2000;

/// The attractors of a capped move: the staged fit's, and the thesis' flow's
/// above [`ALL_PAIRS_MAX`] fireflies.
pub const BRIGHTEST: usize = 10;

/// Where `Λ0` ends (eq. 36 and the appendix code disagree).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Lambda0Schedule {
    /// Appendix A.2.2.1: `Λ0(k) = a − (a − b)·(1 − k)/(1 − G)`, from `a` to `b`.
    Code,
    /// Eq. 36: `Λ0(k) = a − b·(1 − k)/(1 − G)`, from `a` to `a − b`.
    Equation,
}

/// How attractiveness decays with distance (eq. 32 and the code disagree).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Distance {
    /// Appendix A.2.2: `e^(−σ·r)`.
    Linear,
    /// Eq. 32: `e^(−σ·r²)`.
    Squared,
}

/// The units distances and the random walk are measured in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Scale {
    /// The parameters' own units, as the thesis (whose box is about 1 wide
    /// in every coordinate).
    Raw,
    /// Each coordinate in units of its box width: distances are taken on the
    /// normalised box and the walk of coordinate `j` is `ρ·(U_j − L_j)·v_j`.
    /// Needed when widths differ by orders of magnitude (the joint flow's
    /// intercept spans tens of millimetres, `a` a few tenths).
    Box,
}

/// MFA settings; defaults are the thesis' (tables 9 and 17: `a = 1.1`,
/// `b = 0.3`; appendix A.2.2 for the schedule forms).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MfaSettings {
    /// Start of the `Λ0` schedule.
    pub a: f64,
    /// End (code) or drop (eq. 36) of the `Λ0` schedule.
    pub b: f64,
    pub lambda0: Lambda0Schedule,
    pub distance: Distance,
    pub scale: Scale,
    /// Move each firefly towards at most this many brighter ones (`None`:
    /// all of them, as the thesis).
    pub max_attractors: Option<usize>,
    /// Which brighter fireflies when capped.
    pub attractors: Attractors,
    /// Start `ρ0` of the random walk's schedule `ρ(k) = ρ0·e^(−4.8k/G)`
    /// (eq. 38: 0.1).
    #[serde(default = "default_rho0")]
    pub rho0: f64,
}

fn default_rho0() -> f64 {
    0.1
}

/// Which brighter fireflies a capped firefly moves towards.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Attractors {
    /// Drawn uniformly among all brighter ones.
    Random,
    /// The brightest of the swarm, dimmest first so the brightest acts last.
    Brightest,
}

impl Default for MfaSettings {
    fn default() -> Self {
        MfaSettings {
            a: 1.1,
            b: 0.3,
            lambda0: Lambda0Schedule::Code,
            distance: Distance::Linear,
            scale: Scale::Raw,
            max_attractors: None,
            attractors: Attractors::Random,
            rho0: default_rho0(),
        }
    }
}

impl MfaSettings {
    /// Moves each firefly towards the [`BRIGHTEST`] brightest only:
    /// `O(N·K·d)` a generation with `K` = [`BRIGHTEST`] instead of `O(N²·d)`.
    pub fn towards_brightest(&mut self) {
        self.max_attractors = Some(BRIGHTEST);
        self.attractors = Attractors::Brightest;
    }

    /// `(Λ0, σ, ρ)` at generation `k` of `g` (eq. 36–38 / A.2.2.1).
    pub fn schedule(&self, k: usize, g: usize) -> (f64, f64, f64) {
        let (k, g) = (k as f64, g.max(2) as f64);
        let frac = (1.0 - k) / (1.0 - g);
        let lambda0 = match self.lambda0 {
            Lambda0Schedule::Code => self.a - (self.a - self.b) * frac,
            Lambda0Schedule::Equation => self.a - self.b * frac,
        };
        let sigma = 2.0 * 7f64.powf(-k / g);
        let rho = self.rho0 * (-4.8 * k / g).exp();
        (lambda0, sigma, rho)
    }
}

/// MFA state between generations.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Mfa {
    pub settings: MfaSettings,
    bounds: Bounds,
    n: usize,
    /// Planned generations `G` (the schedules run from 1 to `G`).
    generations: usize,
    /// Moves made so far (`k` of the next move is `moves + 1`).
    moves: usize,
    pos: Vec<f64>,
    #[serde(with = "super::inf_serde")]
    costs: Vec<f32>,
    /// Where the next positions are made, then swapped with `pos`: the
    /// snapshot every firefly moves against is `pos` itself, never a copy.
    /// Scratch, not state.
    #[serde(skip)]
    spare: Vec<f64>,
}

/// The brightness ranking a capped move needs.
enum Ranking {
    /// Every firefly, brightest first, and each firefly's place in it: to
    /// draw attractors among all brighter ones.
    Full { order: Vec<usize>, rank: Vec<usize> },
    /// The `k` brightest, brightest first: the brightest attractors.
    Top(Vec<usize>),
}

impl Ranking {
    /// The fireflies brighter than `i`, brightest first, as far as the
    /// ranking holds them (with [`Ranking::Top`], all `k` for a firefly
    /// outside them).
    fn brighter(&self, i: usize) -> &[usize] {
        match self {
            Ranking::Full { order, rank } => &order[..rank[i]],
            Ranking::Top(top) => match top.iter().position(|&t| t == i) {
                Some(r) => &top[..r],
                None => top,
            },
        }
    }
}

impl Mfa {
    fn step(&mut self, streams: &Streams) {
        let d = self.bounds.dim();
        self.moves += 1;
        let (lambda0, sigma, rho) = self.settings.schedule(self.moves, self.generations);
        let inv_w: Vec<f64> = (0..d)
            .map(|j| match self.settings.scale {
                Scale::Raw => 1.0,
                Scale::Box => 1.0 / self.bounds.width(j).max(f64::MIN_POSITIVE),
            })
            .collect();
        let walk: Vec<f64> = (0..d)
            .map(|j| match self.settings.scale {
                Scale::Raw => rho,
                Scale::Box => rho * self.bounds.width(j),
            })
            .collect();
        // Brightness ranking, for choosing brighter attractors when capped:
        // the brightest attractors need only the `k` brightest (a partial
        // selection), random ones the whole order.
        let ranking = match (self.settings.max_attractors, self.settings.attractors) {
            (None, _) => None,
            (Some(k), Attractors::Brightest) => {
                Some(Ranking::Top(super::best_indices(&self.costs, k)))
            }
            (Some(_), Attractors::Random) => {
                let order = super::best_indices(&self.costs, self.n);
                let mut rank = vec![0usize; self.n];
                for (r, &i) in order.iter().enumerate() {
                    rank[i] = r;
                }
                Some(Ranking::Full { order, rank })
            }
        };
        let snapshot = &self.pos;
        let costs = &self.costs;
        let settings = &self.settings;
        let bounds = &self.bounds;
        self.spare.resize(snapshot.len(), 0.0);
        // A firefly's move costs one attraction a brighter firefly it
        // heeds (all N, or the cap): a task takes about the work of
        // ROWS_PER_TASK rows of the other optimizers' steps.
        let attractions = settings.max_attractors.unwrap_or(self.n).max(1);
        self.spare
            .par_chunks_mut(d)
            .enumerate()
            .with_min_len((ROWS_PER_TASK / attractions).max(1))
            .for_each(|(i, x)| {
                x.copy_from_slice(&snapshot[i * d..(i + 1) * d]);
                let mut frng = streams.row(i);
                let attract = |x: &mut [f64], j: usize, frng: &mut RowRng| {
                    let nj = &snapshot[j * d..(j + 1) * d];
                    let r2: f64 = (0..d).map(|t| ((nj[t] - x[t]) * inv_w[t]).powi(2)).sum();
                    let decay = match settings.distance {
                        Distance::Linear => r2.sqrt(),
                        Distance::Squared => r2,
                    };
                    let lambda = lambda0 * (-sigma * decay).exp();
                    for t in 0..d {
                        let v: f64 = frng.sample(StandardNormal);
                        x[t] += lambda * (nj[t] - x[t]) + walk[t] * v;
                    }
                    bounds.clamp(x);
                };
                let ci = costs[i];
                let brighter_than_i =
                    |j: usize| costs[j].is_finite() && super::cost_order(costs[j], ci).is_lt();
                match (settings.max_attractors, &ranking) {
                    (Some(k), Some(ranking)) => {
                        let brighter = ranking.brighter(i);
                        let m = k.min(brighter.len());
                        for step in 0..m {
                            let j = match settings.attractors {
                                Attractors::Random => {
                                    brighter[frng.random_range(0..brighter.len())]
                                }
                                // Dimmest first, so that the brightest acts last.
                                Attractors::Brightest => brighter[m - 1 - step],
                            };
                            if brighter_than_i(j) {
                                attract(x, j, &mut frng);
                            }
                        }
                    }
                    _ => {
                        for j in 0..costs.len() {
                            if brighter_than_i(j) {
                                attract(x, j, &mut frng);
                            }
                        }
                    }
                }
            });
        std::mem::swap(&mut self.pos, &mut self.spare);
    }
}

impl Optimizer for Mfa {
    type Settings = MfaSettings;

    const HELP: &'static str = "Modified firefly algorithm (§5.3.2, A.2.2)";

    /// A firefly moves only towards a brighter one (the walk is part of
    /// each attraction): alone, it would never move.
    const MIN_POPULATION: usize = 2;

    fn new(settings: MfaSettings, bounds: Bounds, n: usize, generations: usize) -> Mfa {
        Mfa {
            settings,
            bounds,
            n,
            generations,
            moves: 0,
            pos: Vec::new(),
            costs: Vec::new(),
            spare: Vec::new(),
        }
    }

    /// The staged fit moves each firefly towards the 10 brightest with
    /// `e^(−σr²)` (eq. 32) in box units: with the thesis' settings the MFA
    /// misses the basin of the generated cases (docs/lab/results.md, "1. Known
    /// truth"), and its all-pairs move is `O(N²·d)` at the staged fit's
    /// populations.
    fn staged_settings(_n: usize) -> MfaSettings {
        MfaSettings {
            max_attractors: Some(BRIGHTEST),
            attractors: Attractors::Brightest,
            distance: Distance::Squared,
            scale: Scale::Box,
            ..MfaSettings::default()
        }
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    fn init(&mut self, initial: Population<Coords>, streams: &Streams) -> Rows<'_, Coords> {
        self.pos = super::first_population(&self.bounds, self.n, initial, streams);
        Rows::new(&self.pos, self.bounds.dim())
    }

    fn next(&mut self, streams: &Streams) -> Rows<'_, Coords> {
        self.step(streams);
        Rows::new(&self.pos, self.bounds.dim())
    }

    fn tell(&mut self, costs: &[f32]) {
        self.costs.clear();
        self.costs.extend_from_slice(costs);
    }

    fn members(&self) -> (Population<Coords>, Vec<f32>) {
        (
            Population::new(self.pos.clone(), self.bounds.dim()),
            self.costs.clone(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schedules_match_the_code_and_eq_36() {
        let code = MfaSettings::default();
        let (l1, s1, r1) = code.schedule(1, 30);
        assert!((l1 - 1.1).abs() < 1e-12);
        assert!((s1 - 2.0 * 7f64.powf(-1.0 / 30.0)).abs() < 1e-12);
        assert!((r1 - 0.1 * (-4.8f64 / 30.0).exp()).abs() < 1e-12);
        assert!((code.schedule(30, 30).0 - 0.3).abs() < 1e-12);
        let eq = MfaSettings {
            lambda0: Lambda0Schedule::Equation,
            ..code
        };
        assert!((eq.schedule(30, 30).0 - 0.8).abs() < 1e-12);
        let wide = MfaSettings {
            rho0: 0.2,
            ..MfaSettings::default()
        };
        assert!((wide.schedule(7, 30).2 - 2.0 * code.schedule(7, 30).2).abs() < 1e-15);
    }

    #[test]
    fn the_brightest_firefly_stays_and_others_move_towards_it() {
        let bounds = Bounds {
            lower: vec![-10.0, -10.0],
            upper: vec![10.0, 10.0],
            names: vec!["x".into(), "y".into()],
        };
        let mut mfa = Mfa::new(MfaSettings::default(), bounds, 3, 30);
        mfa.pos = vec![0.0, 0.0, 0.5, 0.5, -0.5, 0.5];
        mfa.costs = vec![1.0, 2.0, f32::INFINITY];
        let next = mfa.next(&Streams::new(3, crate::optim::stage::Stage::Global, 1));
        assert_eq!(next.row(0), &[0.0, 0.0]);
        let dist = |p: &[f64]| (p[0] * p[0] + p[1] * p[1]).sqrt();
        assert!(dist(next.row(1)) < dist(&[0.5, 0.5]));
        // A diverged firefly is pulled by both brighter ones.
        assert!(dist(next.row(2)) < dist(&[-0.5, 0.5]));
    }
}
