//! The thesis' genetic algorithm (§5.2.1, Algorithm 1, appendix A.2.1).
//!
//! Each generation: the population is scored, fit = 1/SSE (eq. 29),
//! normalised (eq. 30); pairs of parents are drawn by roulette until the
//! mating pool holds N children; each gene of each child mutates with
//! probability `P_mut` by `±m_m` of its value; children that leave the box
//! are clamped back and their fit is penalised. The children replace the
//! parents (no elitism, as in the thesis, unless `elitism > 0`); the run loop
//! always reports the best individual ever seen.
//!
//! Appendix bugs fixed (see `docs/ARCHITECTURE.md`): the code's fit is
//! `−1/SSE` and is then normalised by its (negative) sum, and the penalty
//! `−1/SSE⁵` *rewards* a clamped individual whose SSE is below 1; here fit is
//! positive and the penalty `min(1/SSE, 1/SSE^q)` never rewards. The second
//! parent's roulette in `getMatingPartners` drops the first parent but then
//! indexes the shortened list as if it were the full one, and can step past
//! its end (`second + 1`); here the second parent is drawn from the others
//! with the right indices.

use rand::RngExt;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{Bounds, Optimizer, RowRng, Streams};
use crate::search::{Coords, Population, ROWS_PER_TASK, Rows};

/// How two parents make two children (§5.2.1.5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Crossover {
    /// Each child takes the first `x` genes of one parent and the rest of the
    /// other, `x` uniform in `1..=d`.
    Random,
    /// Each gene comes from the fitter parent with probability
    /// `fit(p1) / (fit(p1) + fit(p2))`.
    Weighted,
    /// Each gene is, with probability `1 − P_cross` (the appendix code's
    /// `rand > p_crossover`), the fit-weighted mean of the parents' genes;
    /// otherwise the child keeps its own parent's gene. The only strategy
    /// that creates new gene values, and the thesis' best (§5.4.2.1).
    #[default]
    Proportional,
}

/// How large a mutation is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Mutation {
    /// Exactly `±m_m` of the gene's value (§5.2.1.6): steps of fixed
    /// relative size, so the GA cannot refine a gene below `m_m`.
    Fixed,
    /// A relative change drawn uniformly in `[−m_m, m_m]`: the same reach,
    /// but arbitrarily small steps too.
    Uniform,
    /// Michalewicz's non-uniform mutation (Michalewicz, *Genetic
    /// Algorithms + Data Structures = Evolution Programs*, 1996, §6.2;
    /// `m_m` unused):
    /// the gene moves towards the upper or the lower bound (even odds) by
    /// `Δ(k, y) = y·(1 − r^((1 − k/G)^b))`, `y` its distance to that bound,
    /// `r` uniform in [0, 1], `b` = 5 (`NON_UNIFORM_B`). Early it can reach
    /// anywhere in the box — a gene near 0 is not stuck, as it is under a
    /// change relative to its own value — and the reach shrinks to 0 by
    /// generation `G`, so the same operator explores and then refines.
    NonUniform,
}

/// Michalewicz's "degree of dependency on the iteration number" `b` of the
/// non-uniform mutation (his suggested value, 1996 §6.2).
pub const NON_UNIFORM_B: f64 = 5.0;

/// GA settings; defaults are the thesis' (tables 5 and 13: `P_cross = 0.5`,
/// `P_mut = 0.1`, `m_m = 0.05`, proportional crossover as in A.2.1.1).
/// Population size and generations belong to the run (`N = 30` / `20`,
/// `G = 30` in the thesis).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GaSettings {
    pub crossover: Crossover,
    pub p_cross: f64,
    pub p_mut: f64,
    /// Mutation magnitude `m_m`: a mutated gene becomes `g·(1 ± m_m)`.
    pub m_mut: f64,
    pub mutation: Mutation,
    /// Exponent `q` of the bounds penalty: a clamped child's fit is
    /// `min(1/SSE, 1/SSE^q)` (the appendix code's `SSE⁵`).
    pub penalty_exponent: f64,
    /// Best individuals copied unchanged into the next generation (0 in the thesis).
    pub elitism: usize,
}

impl Default for GaSettings {
    fn default() -> Self {
        GaSettings {
            crossover: Crossover::Proportional,
            p_cross: 0.5,
            p_mut: 0.1,
            m_mut: 0.05,
            mutation: Mutation::Fixed,
            penalty_exponent: 5.0,
            elitism: 0,
        }
    }
}

/// GA state between generations.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Ga {
    pub settings: GaSettings,
    bounds: Bounds,
    n: usize,
    /// Planned generations `G` (the non-uniform mutation's horizon).
    #[serde(default)]
    generations: usize,
    /// Offspring generations made so far (`k` of the next is `moves + 1`).
    #[serde(default)]
    moves: usize,
    /// The population last asked for, row-major.
    pop: Vec<f64>,
    /// Which rows were clamped into the box (penalised).
    clamped: Vec<bool>,
    /// Their costs, once told.
    #[serde(with = "super::inf_serde")]
    costs: Vec<f32>,
    /// Where the next population is made, then swapped with `pop` (and its
    /// flags with `clamped`): no population is allocated or copied a
    /// generation. Scratch, not state.
    #[serde(skip)]
    spare: Vec<f64>,
    #[serde(skip)]
    spare_clamped: Vec<bool>,
}

impl Ga {
    /// Fit of every individual: `1/SSE`, penalised when clamped, 0 when diverged.
    fn fitness(&self) -> Vec<f64> {
        let q = self.settings.penalty_exponent;
        self.costs
            .par_iter()
            .zip(self.clamped.par_iter())
            .with_min_len(ROWS_PER_TASK)
            .map(|(&c, &clamped)| {
                if !c.is_finite() {
                    return 0.0;
                }
                let sse = (c as f64).max(f64::MIN_POSITIVE);
                let fit = (1.0 / sse).min(f64::MAX);
                if clamped { fit.min(sse.powf(-q)) } else { fit }
            })
            .collect()
    }

    /// Makes the next population in `spare`: the elites, then children in
    /// pairs, in parallel, pair `p` (children `elite + 2p` and
    /// `elite + 2p + 1`) from the stream of its first child.
    fn offspring(&mut self, streams: &Streams) {
        let (n, d) = (self.n, self.bounds.dim());
        // Remaining share of the run, for the non-uniform mutation's reach.
        let k = (self.moves + 1) as f64;
        let reach = (1.0 - k / self.generations.max(1) as f64)
            .max(0.0)
            .powf(NON_UNIFORM_B);
        self.spare.resize(n * d, 0.0);
        self.spare_clamped.resize(n, false);
        let elite = self.settings.elitism.min(n);
        for (k, i) in super::best_indices(&self.costs, elite)
            .into_iter()
            .enumerate()
        {
            self.spare[k * d..(k + 1) * d].copy_from_slice(&self.pop[i * d..(i + 1) * d]);
            self.spare_clamped[k] = self.clamped[i];
        }
        let mating = Mating {
            settings: &self.settings,
            bounds: &self.bounds,
            pop: &self.pop,
            roulette: Roulette::new(self.fitness()),
            reach,
        };
        self.spare[elite * d..]
            .par_chunks_mut(2 * d)
            .zip(self.spare_clamped[elite..].par_chunks_mut(2))
            .enumerate()
            .with_min_len(ROWS_PER_TASK / 2)
            .for_each(|(p, (children, clamped))| {
                mating.pair(children, clamped, &mut streams.row(elite + 2 * p));
            });
    }
}

/// What two children are made from: the parents, their fit and the settings.
struct Mating<'a> {
    settings: &'a GaSettings,
    bounds: &'a Bounds,
    pop: &'a [f64],
    /// The parents' fit (eq. 30).
    roulette: Roulette,
    /// The non-uniform mutation's reach this generation.
    reach: f64,
}

impl Mating<'_> {
    /// Two parents by roulette, crossover, mutation, clamping: the children
    /// written into `children` (two rows, or one where the population ends
    /// with an odd child), their clamp flags into `clamped`.
    fn pair(&self, children: &mut [f64], clamped: &mut [bool], rng: &mut RowRng) {
        let d = self.bounds.dim();
        let (i1, i2) = self.roulette.pair(rng);
        let p1 = &self.pop[i1 * d..(i1 + 1) * d];
        let p2 = &self.pop[i2 * d..(i2 + 1) * d];
        let (f1, f2) = (self.roulette.weights[i1], self.roulette.weights[i2]);
        // Share of the first parent; parents of zero fit count equally.
        let pv1 = if f1 + f2 > 0.0 { f1 / (f1 + f2) } else { 0.5 };
        // The last pair of an odd brood makes its second child and drops it.
        let mut dropped = Vec::new();
        let (c1, c2) = if children.len() == 2 * d {
            children.split_at_mut(d)
        } else {
            dropped.resize(d, 0.0);
            (children, &mut dropped[..])
        };
        c1.copy_from_slice(p1);
        c2.copy_from_slice(p2);
        match self.settings.crossover {
            Crossover::Random => {
                let x = rng.random_range(1..=d);
                c1[x..].copy_from_slice(&p2[x..]);
                let x = rng.random_range(1..=d);
                c2[x..].copy_from_slice(&p1[x..]);
            }
            Crossover::Weighted => {
                let (better, worse, inp) = if f1 >= f2 {
                    (p1, p2, pv1)
                } else {
                    (p2, p1, 1.0 - pv1)
                };
                for child in [&mut *c1, &mut *c2] {
                    for j in 0..d {
                        child[j] = if rng.random::<f64>() < inp {
                            better[j]
                        } else {
                            worse[j]
                        };
                    }
                }
            }
            Crossover::Proportional => {
                for child in [&mut *c1, &mut *c2] {
                    for j in 0..d {
                        if rng.random::<f64>() > self.settings.p_cross {
                            child[j] = pv1 * p1[j] + (1.0 - pv1) * p2[j];
                        }
                    }
                }
            }
        }
        for (child, flag) in [c1, c2].into_iter().zip(clamped) {
            self.mutate(child, rng);
            *flag = self.bounds.clamp(child);
        }
    }

    /// Each gene mutates with probability `P_mut`.
    fn mutate(&self, child: &mut [f64], rng: &mut RowRng) {
        let m = self.settings.m_mut;
        for (j, g) in child.iter_mut().enumerate() {
            if rng.random::<f64>() >= self.settings.p_mut {
                continue;
            }
            match self.settings.mutation {
                Mutation::Fixed => *g *= 1.0 + if rng.random::<f64>() < 0.5 { m } else { -m },
                Mutation::Uniform => *g *= 1.0 + m * (2.0 * rng.random::<f64>() - 1.0),
                Mutation::NonUniform => {
                    let shrink = 1.0 - rng.random::<f64>().powf(self.reach);
                    if rng.random::<f64>() < 0.5 {
                        *g += (self.bounds.upper[j] - *g).max(0.0) * shrink;
                    } else {
                        *g -= (*g - self.bounds.lower[j]).max(0.0) * shrink;
                    }
                }
            }
        }
    }
}

impl Optimizer for Ga {
    type Settings = GaSettings;

    const HELP: &'static str = "Genetic algorithm (§5.2.1, A.2.1)";

    /// Every child has two distinct parents.
    const MIN_POPULATION: usize = 2;

    fn new(settings: GaSettings, bounds: Bounds, n: usize, generations: usize) -> Ga {
        Ga {
            settings,
            bounds,
            n,
            generations,
            moves: 0,
            pop: Vec::new(),
            clamped: Vec::new(),
            costs: Vec::new(),
            spare: Vec::new(),
            spare_clamped: Vec::new(),
        }
    }

    /// The staged fit keeps its best tenth and mutates by uniform relative
    /// steps with `P_mut = 0.3`: with the thesis' settings the GA misses the
    /// basin of the generated cases (docs/lab/results.md, "1. Known truth").
    fn staged_settings(n: usize) -> GaSettings {
        GaSettings {
            elitism: (n / 10).max(1),
            mutation: Mutation::Uniform,
            p_mut: 0.3,
            ..GaSettings::default()
        }
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    fn init(&mut self, initial: Population<Coords>, streams: &Streams) -> Rows<'_, Coords> {
        self.pop = super::first_population(&self.bounds, self.n, initial, streams);
        self.clamped = vec![false; self.n];
        Rows::new(&self.pop, self.bounds.dim())
    }

    fn next(&mut self, streams: &Streams) -> Rows<'_, Coords> {
        self.offspring(streams);
        self.moves += 1;
        std::mem::swap(&mut self.pop, &mut self.spare);
        std::mem::swap(&mut self.clamped, &mut self.spare_clamped);
        Rows::new(&self.pop, self.bounds.dim())
    }

    fn tell(&mut self, costs: &[f32]) {
        self.costs.clear();
        self.costs.extend_from_slice(costs);
    }

    fn members(&self) -> (Population<Coords>, Vec<f32>) {
        (
            Population::new(self.pop.clone(), self.bounds.dim()),
            self.costs.clone(),
        )
    }
}

/// Roulette-wheel selection on non-negative weights (eq. 30), by binary
/// search on the cumulative sums; all-zero weights select uniformly.
struct Roulette {
    cumulative: Vec<f64>,
    weights: Vec<f64>,
}

impl Roulette {
    fn new(weights: Vec<f64>) -> Roulette {
        let mut acc = 0.0;
        let cumulative = weights
            .iter()
            .map(|&w| {
                acc += w;
                acc
            })
            .collect();
        Roulette {
            cumulative,
            weights,
        }
    }

    fn total(&self) -> f64 {
        self.cumulative.last().copied().unwrap_or(0.0)
    }

    /// First index whose cumulative sum exceeds `t`, skipping zero weights.
    fn find(&self, t: f64) -> usize {
        let i = self.cumulative.partition_point(|&c| c <= t);
        let i = i.min(self.cumulative.len() - 1);
        // Rounding can land on a zero-weight entry at the end: step back.
        (0..=i).rev().find(|&k| self.weights[k] > 0.0).unwrap_or(i)
    }

    /// Two distinct parents: the first by roulette over all, the second by
    /// roulette over the others (the appendix' `getMatingPartners`, fixed).
    fn pair(&self, rng: &mut RowRng) -> (usize, usize) {
        let n = self.weights.len();
        let total = self.total();
        if !(total > 0.0 && total.is_finite()) {
            let a = rng.random_range(0..n);
            let b = (a + rng.random_range(1..n)) % n;
            return (a, b);
        }
        let first = self.find(rng.random::<f64>() * total);
        let rest = total - self.weights[first];
        let second = if rest > 0.0 {
            let t = rng.random::<f64>() * rest;
            let before = self.cumulative[first] - self.weights[first];
            let s = if t < before {
                self.find(t)
            } else {
                self.find(t + self.weights[first])
            };
            if s == first {
                // Only reachable through rounding at the boundary.
                (first + 1..n)
                    .chain(0..first)
                    .find(|&k| self.weights[k] > 0.0)
                    .unwrap_or((first + 1) % n)
            } else {
                s
            }
        } else {
            (first + rng.random_range(1..n)) % n
        };
        (first, second)
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
    fn roulette_picks_distinct_parents_in_proportion() {
        let r = Roulette::new(vec![0.0, 1.0, 3.0, 0.0]);
        let mut rng = at(1, 1).row(0);
        let mut count = [0usize; 4];
        for _ in 0..4000 {
            let (a, b) = r.pair(&mut rng);
            assert_ne!(a, b);
            assert!(r.weights[a] > 0.0 && r.weights[b] > 0.0);
            count[a] += 1;
        }
        // First parent: index 2 three times as often as index 1.
        let ratio = count[2] as f64 / count[1] as f64;
        assert!((2.6..3.4).contains(&ratio), "{count:?}");
    }

    #[test]
    fn a_single_positive_weight_still_gives_two_parents() {
        let r = Roulette::new(vec![0.0, 0.0, 5.0]);
        let mut rng = at(2, 1).row(0);
        for _ in 0..100 {
            let (a, b) = r.pair(&mut rng);
            assert_eq!(a, 2);
            assert_ne!(b, 2);
        }
    }

    #[test]
    fn penalty_never_rewards_a_clamped_child() {
        let bounds = Bounds {
            lower: vec![0.0],
            upper: vec![1.0],
            names: vec!["x".into()],
        };
        let mut ga = Ga::new(GaSettings::default(), bounds, 4, 30);
        ga.pop = vec![0.5; 4];
        ga.clamped = vec![false, true, false, true];
        ga.costs = vec![0.5, 0.5, 4.0, 4.0];
        let fit = ga.fitness();
        assert_eq!(fit[0], 2.0);
        assert_eq!(fit[1], 2.0, "SSE < 1: the thesis' SSE⁵ would reward");
        assert!(fit[3] < fit[2]);
        ga.costs[2] = f32::INFINITY;
        assert_eq!(ga.fitness()[2], 0.0);
    }

    #[test]
    fn random_and_weighted_crossover_only_swap_genes() {
        // §5.4.2.1: without mutation these strategies never leave the
        // initial population's gene values; proportional does.
        let bounds = Bounds {
            lower: vec![0.0; 3],
            upper: vec![1.0; 3],
            names: vec!["x".into(), "y".into(), "z".into()],
        };
        for (crossover, closed) in [
            (Crossover::Random, true),
            (Crossover::Weighted, true),
            (Crossover::Proportional, false),
        ] {
            let settings = GaSettings {
                crossover,
                p_mut: 0.0,
                ..GaSettings::default()
            };
            let mut ga = Ga::new(settings, bounds.clone(), 8, 30);
            let first = ga
                .init(Population::zeros(0, 3), &at(6, 0))
                .as_flat()
                .to_vec();
            ga.tell(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, f32::INFINITY]);
            let next = ga.next(&at(6, 1));
            let inherited = next
                .iter()
                .all(|child| (0..3).all(|j| first.chunks(3).any(|parent| parent[j] == child[j])));
            assert_eq!(inherited, closed, "{crossover:?}");
        }
    }

    #[test]
    fn non_uniform_mutation_stays_in_the_box_and_narrows_over_the_run() {
        let bounds = Bounds {
            lower: vec![0.0],
            upper: vec![10.0],
            names: vec!["x".into()],
        };
        let settings = GaSettings {
            p_mut: 1.0,
            mutation: Mutation::NonUniform,
            ..GaSettings::default()
        };
        let spread = |moves: usize| {
            let mut ga = Ga::new(settings.clone(), bounds.clone(), 200, 10);
            ga.pop = vec![5.0; 200];
            ga.clamped = vec![false; 200];
            ga.costs = vec![1.0; 200];
            ga.moves = moves;
            let pop = ga.next(&at(9, moves + 1)).as_flat().to_vec();
            assert!(pop.iter().all(|x| (0.0..=10.0).contains(x)));
            assert!(ga.clamped.iter().all(|&c| !c), "never leaves the box");
            pop.iter().fold(0.0f64, |m, x| m.max((x - 5.0).abs()))
        };
        // Generation 1 of 10 reaches most of the box; generation 9 hardly moves.
        assert!(spread(0) > 3.0);
        assert!(spread(8) < 0.01);
    }
}
