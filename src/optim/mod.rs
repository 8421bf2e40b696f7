//! Population optimizers in ask/tell form, and the fitting [`engine`] that
//! drives them against a batch [`Evaluator`](crate::eval::Evaluator).
//!
//! An optimizer never sees the model: it is handed a box (the free
//! coordinates of a [`SearchSpace`](crate::model::SearchSpace)), *asks* for a population of points in
//! it and is *told* their costs (SSE, lower is better, `+∞` for a diverged
//! candidate). The [`engine`] owns everything around that: stages, seeding,
//! stopping, history, checkpoints, Ctrl-C. Every random draw comes from the
//! `ChaCha8Rng` the engine passes in, so a run is a pure function of its
//! seed, whatever the thread count or backend.
//!
//! The thesis' three methods (chapter 5, appendix A.2) are [`ga`], [`mfa`]
//! and [`pso`]; [`de`] is the modern baseline they are compared against.
//! [`lm`] is not a population method: it polishes one point by
//! Levenberg–Marquardt after a search.

pub mod cases;
pub mod de;
pub mod engine;
pub mod ga;
pub mod history;
pub mod lm;
pub mod mfa;
pub mod pso;

pub mod synthetic;
pub mod task;

use std::cmp::Ordering;
use std::fmt;
use std::str::FromStr;

use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

pub use history::{GenerationRecord, History};

/// The box an optimizer searches: bounds of the free coordinates only
/// (parameters with `lower == upper` in the [`engine::Space`] are held fixed by
/// the engine and never shown to the optimizer).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Bounds {
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    /// Parameter names, for messages and figures.
    pub names: Vec<String>,
}

impl Bounds {
    pub fn dim(&self) -> usize {
        self.lower.len()
    }

    /// Width of the box in coordinate `j`.
    pub fn width(&self, j: usize) -> f64 {
        self.upper[j] - self.lower[j]
    }

    /// Clamps `x` into the box; returns whether any coordinate moved.
    pub fn clamp(&self, x: &mut [f64]) -> bool {
        let mut moved = false;
        for (j, v) in x.iter_mut().enumerate() {
            let c = v.clamp(self.lower[j], self.upper[j]);
            moved |= c != *v;
            *v = c;
        }
        moved
    }

    /// A point drawn uniformly in the box (eq. 26).
    pub fn uniform(&self, rng: &mut ChaCha8Rng) -> Vec<f64> {
        use rand::RngExt;
        (0..self.dim())
            .map(|j| self.lower[j] + rng.random::<f64>() * self.width(j))
            .collect()
    }
}

/// An ask/tell population optimizer.
///
/// The run loop calls `ask`, scores every row, then `tell`s the costs in row
/// order. Costs are sanitised before `tell`: NaN becomes `+∞`, so an
/// optimizer only has to treat `+∞` as "worst".
pub trait Optimizer {
    /// Short name (`ga`, `mfa`, `pso`, `de`).
    fn name(&self) -> &'static str;

    /// The next population to evaluate: row-major, `rows × bounds.dim()`,
    /// every row inside the box.
    fn ask(&mut self, rng: &mut ChaCha8Rng) -> Vec<f64>;

    /// The costs of the rows of the last `ask`, in order.
    fn tell(&mut self, costs: &[f32]);

    /// The members whose costs drive the next move (row-major) and those
    /// costs: what a later stage of a fit starts from. Empty before the first
    /// `tell`.
    fn members(&self) -> (Vec<f64>, Vec<f32>);
}

/// The smallest population every algorithm accepts: differential evolution
/// draws three partners distinct from the individual itself.
pub const MIN_POPULATION: usize = 4;

/// The first population of an optimizer: the given `initial` rows (clamped
/// into the box; a warm start from known models), then uniform draws (eq. 26).
pub(crate) fn first_population(
    bounds: &Bounds,
    n: usize,
    initial: &[f64],
    rng: &mut ChaCha8Rng,
) -> Vec<f64> {
    let d = bounds.dim().max(1);
    let mut pop: Vec<f64> = initial[..initial.len().min(n * d)].to_vec();
    for row in pop.chunks_mut(d) {
        bounds.clamp(row);
    }
    let given = pop.len() / d;
    pop.extend((given..n).flat_map(|_| bounds.uniform(rng)));
    pop
}

/// Total order on costs for minimisation: `+∞` and NaN last, never
/// panicking (the comparison every sort and selection here uses).
pub fn cost_order(a: f32, b: f32) -> Ordering {
    let key = |v: f32| if v.is_nan() { f32::INFINITY } else { v };
    key(a).total_cmp(&key(b))
}

/// Index of the lowest cost, `None` if every cost is infinite.
pub fn argmin(costs: &[f32]) -> Option<usize> {
    costs
        .iter()
        .enumerate()
        .filter(|(_, c)| c.is_finite())
        .min_by(|a, b| cost_order(*a.1, *b.1).then(a.0.cmp(&b.0)))
        .map(|(i, _)| i)
}

/// Which algorithm; parses from the `--algo` names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Algorithm {
    /// Genetic algorithm (§5.2.1, A.2.1).
    Ga,
    /// Modified firefly algorithm (§5.3.2, A.2.2).
    Mfa,
    /// Particle swarm optimization (§5.3.3, A.2.3).
    Pso,
    /// Differential evolution (jDE-adapted current-to-pbest/1/bin), the baseline.
    De,
}

impl Algorithm {
    pub const ALL: [Algorithm; 4] = [Algorithm::Ga, Algorithm::Mfa, Algorithm::Pso, Algorithm::De];

    pub fn name(self) -> &'static str {
        match self {
            Algorithm::Ga => "ga",
            Algorithm::Mfa => "mfa",
            Algorithm::Pso => "pso",
            Algorithm::De => "de",
        }
    }
}

impl fmt::Display for Algorithm {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Algorithm {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Algorithm::ALL
            .into_iter()
            .find(|a| a.name() == s.to_ascii_lowercase())
            .ok_or_else(|| format!("unknown algorithm `{s}`: expected ga, mfa, pso or de"))
    }
}

/// Any of the optimizers, as one serialisable value (what a checkpoint stores).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "algo", rename_all = "lowercase")]
pub enum AnyOptimizer {
    Ga(ga::Ga),
    Mfa(mfa::Mfa),
    Pso(pso::Pso),
    De(de::De),
}

/// The algorithm settings of every optimizer, for building one by name.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct AlgoSettings {
    pub ga: ga::GaSettings,
    pub mfa: mfa::MfaSettings,
    pub pso: pso::PsoSettings,
    pub de: de::DeSettings,
}

impl AnyOptimizer {
    /// A fresh optimizer of `algo` over `bounds` with `n` individuals and
    /// `g` planned generations (the GA's, MFA's and PSO's schedules run over them).
    pub fn new(algo: Algorithm, s: &AlgoSettings, bounds: Bounds, n: usize, g: usize) -> Self {
        match algo {
            Algorithm::Ga => AnyOptimizer::Ga(ga::Ga::new(s.ga.clone(), bounds, n, g)),
            Algorithm::Mfa => AnyOptimizer::Mfa(mfa::Mfa::new(s.mfa.clone(), bounds, n, g)),
            Algorithm::Pso => AnyOptimizer::Pso(pso::Pso::new(s.pso.clone(), bounds, n, g)),
            Algorithm::De => AnyOptimizer::De(de::De::new(s.de.clone(), bounds, n)),
        }
    }

    /// Starts the search from `rows` (free coordinates, row-major): the first
    /// members of the initial population, the rest drawn uniformly.
    pub fn with_initial(self, rows: &[f64]) -> Self {
        match self {
            AnyOptimizer::Ga(o) => AnyOptimizer::Ga(o.with_initial(rows)),
            AnyOptimizer::Mfa(o) => AnyOptimizer::Mfa(o.with_initial(rows)),
            AnyOptimizer::Pso(o) => AnyOptimizer::Pso(o.with_initial(rows)),
            AnyOptimizer::De(o) => AnyOptimizer::De(o.with_initial(rows)),
        }
    }

    pub fn algorithm(&self) -> Algorithm {
        match self {
            AnyOptimizer::Ga(_) => Algorithm::Ga,
            AnyOptimizer::Mfa(_) => Algorithm::Mfa,
            AnyOptimizer::Pso(_) => Algorithm::Pso,
            AnyOptimizer::De(_) => Algorithm::De,
        }
    }

    fn inner(&mut self) -> &mut dyn Optimizer {
        match self {
            AnyOptimizer::Ga(o) => o,
            AnyOptimizer::Mfa(o) => o,
            AnyOptimizer::Pso(o) => o,
            AnyOptimizer::De(o) => o,
        }
    }
}

impl Optimizer for AnyOptimizer {
    fn name(&self) -> &'static str {
        self.algorithm().name()
    }
    fn ask(&mut self, rng: &mut ChaCha8Rng) -> Vec<f64> {
        self.inner().ask(rng)
    }
    fn tell(&mut self, costs: &[f32]) {
        self.inner().tell(costs)
    }
    fn members(&self) -> (Vec<f64>, Vec<f32>) {
        match self {
            AnyOptimizer::Ga(o) => o.members(),
            AnyOptimizer::Mfa(o) => o.members(),
            AnyOptimizer::Pso(o) => o.members(),
            AnyOptimizer::De(o) => o.members(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn infinite_and_nan_costs_sort_last() {
        let mut v = [3.0f32, f32::INFINITY, f32::NAN, 1.0, 2.0];
        v.sort_by(|a, b| cost_order(*a, *b));
        assert_eq!(&v[..3], &[1.0, 2.0, 3.0]);
        assert!(v[3..].iter().all(|c| !c.is_finite()));
        assert_eq!(argmin(&[f32::INFINITY, 2.0, f32::NAN, 1.0]), Some(3));
        assert_eq!(argmin(&[f32::INFINITY, f32::NAN]), None);
    }

    #[test]
    fn algorithm_names_round_trip() {
        for a in Algorithm::ALL {
            assert_eq!(a.name().parse::<Algorithm>().unwrap(), a);
        }
        assert!(
            "cmaes"
                .parse::<Algorithm>()
                .unwrap_err()
                .contains("ga, mfa")
        );
    }
}

/// Serde for costs: JSON has no infinity, so a diverged (`+∞`) cost is
/// written as `null` and read back as `+∞` (checkpoints must round-trip).
pub(crate) mod inf_serde {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    fn to_opt(v: f32) -> Option<f32> {
        v.is_finite().then_some(v)
    }

    pub fn serialize<S: Serializer>(v: &[f32], s: S) -> Result<S::Ok, S::Error> {
        v.iter()
            .map(|&c| to_opt(c))
            .collect::<Vec<_>>()
            .serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f32>, D::Error> {
        let v = Vec::<Option<f32>>::deserialize(d)?;
        Ok(v.into_iter().map(|c| c.unwrap_or(f32::INFINITY)).collect())
    }

    /// The same for a single `f64` cost.
    pub mod one_f64 {
        use serde::{Deserialize, Deserializer, Serialize, Serializer};

        pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
            v.is_finite().then_some(*v).serialize(s)
        }

        pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
            Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
        }
    }

    /// The same for a single cost.
    pub mod one {
        use super::*;

        pub fn serialize<S: Serializer>(v: &f32, s: S) -> Result<S::Ok, S::Error> {
            to_opt(*v).serialize(s)
        }

        pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
            Ok(Option::<f32>::deserialize(d)?.unwrap_or(f32::INFINITY))
        }
    }
}
