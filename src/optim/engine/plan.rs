//! What a fit does, stage by stage, and the defaults that reach the noise
//! floor.
//!
//! **Why three stages.** The free-run error of a slow hysteretic model is a
//! needle along the pole and the static gain (measured: docs/ARCHITECTURE.md,
//! "Decisions of the fitting engine"), because an error in either piles up
//! through the slow pole, and its roughness grows with the
//! simulated length (Ribeiro, Tiels, Umenberger, Schön and Aguirre, "On the
//! smoothness of nonlinear system identification", Automatica 2020), so a
//! population search on it stalls beside the needle at any population size.
//! So the engine searches where the cost is smooth and refines where it is
//! exact:
//!
//! 1. **Global** — a population search (GA, MFA, PSO or DE: `--algo`) on the
//!    `h`-step-ahead prediction error ([`Measure::Ahead`]), whose restarts from
//!    the measurement keep errors from piling up through the slow pole.
//! 2. **Free run** — differential evolution on the free-run error, started
//!    from the global stage's best members, to move from the predictor's
//!    optimum to the simulator's.
//! 3. **Polish** — bounded Levenberg–Marquardt on the free-run residuals
//!    from the best few distinct members: inside the needle's valley
//!    Gauss–Newton steps follow what a population creeps along.
//!
//! 4. **Refine** — rounds of differential evolution on the free run in a
//!    cloud around the best so far, each followed by a polish, while a round
//!    still lowers the SSE: the free run of a model whose state switches
//!    (the generalized family's sign terms) jumps where a sample crosses a
//!    switching level, so the polish can stop on a ledge that a population
//!    steps over.
//!
//! The whole plan runs as independent **tries**, each from its own seed
//! ([`crate::optim::streams::try_seed`]), scored together in the same
//! evaluator calls: a larger budget buys more searches, not one larger
//! population (IPOP and BIPOP CMA-ES restart with growing populations for
//! the same reason: Auger & Hansen, CEC 2005; Hansen, 2009). Each try's
//! draws are its own, so a run of more tries runs those of fewer.
//!
//! The thesis' flow ([`Plan::thesis`]) is the global stage alone, on the free
//! run, as chapter 5 does it.

use serde::{Deserialize, Serialize};

use super::super::{AlgoSettings, Algorithm};
use crate::search::Measure;

/// The stages of a fit; an absent stage is skipped.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    pub global: Option<Global>,
    pub free_run: Option<FreeRun>,
    pub polish: Option<Polish>,
    /// Rounds that refine each try's best after the polish.
    #[serde(default)]
    pub refine: Option<Refine>,
    /// Independent tries of the whole plan (at least 1); every population
    /// size above is a try's, unless `sizes` says otherwise.
    #[serde(default = "one")]
    pub tries: usize,
    /// Each try's populations where the tries differ in size, in try order
    /// (empty: every try runs the populations of the stages above). On
    /// some problems a small population stops short of a wrong basin that
    /// every large one converges into, and on others the reverse; tries of
    /// both sizes hedge (BIPOP: Hansen, 2009).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sizes: Vec<TrySize>,
}

/// One try's populations, stage by stage (an absent stage's is unread).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct TrySize {
    /// The global stage's, all its islands together.
    pub global: usize,
    /// The free-run stage's, all its islands together.
    pub free_run: usize,
    /// A refining round's.
    pub refine: usize,
    /// The starts of its polish after the population stages (a refining
    /// round's polish has the round's own: [`Refine::starts`]).
    pub polish: usize,
}

fn one() -> usize {
    1
}

/// Rounds of differential evolution on the free run in a cloud around a
/// try's best ([`super::Space::cloud`]), each followed by a polish of its
/// best distinct members with the plan's polish settings (on the free run
/// alone: the round starts in the free run's own basin).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Refine {
    pub population: usize,
    /// Generations a round: populations evaluated, the cloud included.
    pub generations: usize,
    /// Rounds at most (`fit --refine-rounds`): a try still gaining when
    /// they run out is reported ([`super::TryEnd::cut_gain`]).
    pub rounds: usize,
    /// A try stops refining after a round that lowers its SSE by less than
    /// this share.
    pub gain: f64,
    /// Members polished after each round.
    pub starts: usize,
}

impl Refine {
    /// The default cap on the rounds. The level rounds draw their streams
    /// after this many rounds' whatever the cap, so that a larger cap only
    /// adds rounds (population.rs, `stream_generation`).
    pub const DEFAULT_ROUNDS: usize = 4;
}

impl Default for Refine {
    /// A fifth of the default global population around the best, for as
    /// many generations as the global stage; up to four rounds while a
    /// round gains a thousandth; four polish starts. Sized on the
    /// generalized matrix of generated cases (docs/ARCHITECTURE.md,
    /// "Decisions of the fitting engine").
    fn default() -> Self {
        Refine {
            population: 200,
            generations: 300,
            rounds: Refine::DEFAULT_ROUNDS,
            gain: 1e-3,
            starts: 4,
        }
    }
}

/// The population search that finds the basin.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Global {
    /// The algorithm and its settings.
    pub settings: AlgoSettings,
    /// Individuals per generation (`N`).
    pub population: usize,
    /// Generations (`G`): populations evaluated, the initial one included.
    /// Also the horizon of the GA's, MFA's and PSO's schedules.
    pub generations: usize,
    /// What it minimises.
    pub measure: Measure,
    /// Independent sub-populations of `population / islands` each, scored
    /// in one batch: a population that converges into one basin hands the
    /// later stages one basin, islands hand them several, and the polish
    /// judges them on the free run.
    pub islands: usize,
    /// Island `i` measures the horizon `h·4^i` (the free run once that
    /// reaches `longest`), and the last island of several the free run,
    /// instead of all measuring `h`: on data the model cannot fit exactly,
    /// short- and long-horizon optima lie in different basins, and the free
    /// run judges them all (on the shipped stair the short horizon ranks
    /// the linear model, A → 0, first: docs/ARCHITECTURE.md, "Where the
    /// model cannot fit exactly, the free run judges every basin").
    /// The free-run island searches with [`FreeRun::ALGORITHM`] whatever
    /// the stage's algorithm: it is the island that finds the free run's
    /// basin, and the answer should not depend on `--algo` (PSO's and MFA's
    /// own rules there end in the linear model more often:
    /// docs/lab/results.md, "The shipped stair").
    pub ladder: bool,
    /// The longest experiment (samples).
    pub longest: usize,
}

/// Differential evolution on the free run from the global stage's best.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FreeRun {
    pub population: usize,
    /// Generations: populations evaluated, the initial one (the global
    /// stage's best members, re-scored) included.
    pub generations: usize,
}

impl FreeRun {
    /// The free-run stage's algorithm, with its paper's settings.
    pub const ALGORITHM: Algorithm = Algorithm::De;
}

/// Levenberg–Marquardt from the best distinct members.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Polish {
    /// Members polished (the best first, each at least [`DISTINCT`] box
    /// widths from those before it); the best result is kept.
    pub starts: usize,
    /// Jacobian evaluations per start, at most.
    pub iterations: usize,
    /// Forward-difference step, relative to the coordinate's scale.
    pub rel_step: f64,
    /// A coordinate's scale is at least this share of its box width, so that
    /// one near zero still gets a probe step the residuals feel.
    pub step_floor: f64,
    /// Stop a start when an accepted step lowers the SSE by less than this share.
    pub tolerance: f64,
    /// Central differences for the Jacobian.
    pub central: bool,
    /// Polish each start first on the global stage's prediction error, then
    /// on horizons four times longer in turn up to `longest`, then on the free run.
    pub continuation: bool,
    /// The longest experiment (samples): past it a horizon is the free run.
    pub longest: usize,
}

/// Two polish starts closer than this share of every coordinate's box width
/// are the same start.
pub const DISTINCT: f64 = 1e-3;

impl Default for Polish {
    /// Several starts with continuation through the horizons, because from
    /// the free run alone a start stops in the flat valleys of slow
    /// multisine cases. Central differences with a probe step of 1e-3: a
    /// forward difference's error grows with the valley's curvature, and
    /// Levenberg–Marquardt stops where the biased gradient vanishes. A step
    /// of 1e-3 stays above the `f32` simulation's rounding in a central
    /// difference, whose own error is second order; a smaller one drowns
    /// the loop-shape parameters' columns in rounding. Sixteen starts (four
    /// per island of the default plan), because the slow multisines have
    /// distinct free-run minima of nearly the same SSE that validate
    /// differently, and fewer starts miss the true one. All measured:
    /// docs/ARCHITECTURE.md, "Decisions of the fitting engine".
    fn default() -> Self {
        Polish {
            starts: 16,
            iterations: 30,
            rel_step: 1e-3,
            step_floor: 1e-2,
            tolerance: 1e-9,
            central: true,
            continuation: true,
            longest: usize::MAX,
        }
    }
}

impl Global {
    pub fn algorithm(&self) -> Algorithm {
        self.settings.algorithm()
    }
}

impl Plan {
    /// The thesis' flow: one population search on the free run (chapter 5).
    pub fn thesis(settings: AlgoSettings, n: usize, g: usize) -> Plan {
        Plan::search(settings, n, g)
    }

    /// `polish` alone, from the engine's initial rows: a known point
    /// refined (the diagnosis' polish, a generated case's polished truth).
    pub fn polish(polish: Polish) -> Plan {
        Plan {
            global: None,
            free_run: None,
            polish: Some(polish),
            refine: None,
            tries: 1,
            sizes: Vec::new(),
        }
    }

    /// A population search alone, on one island, for objectives with one
    /// measure and no residuals (the PID tuning, the benchmark's search).
    pub fn search(settings: AlgoSettings, n: usize, g: usize) -> Plan {
        Plan {
            global: Some(Global {
                settings,
                population: n,
                generations: g,
                measure: Measure::FreeRun,
                islands: 1,
                ladder: false,
                longest: usize::MAX,
            }),
            free_run: None,
            polish: None,
            refine: None,
            tries: 1,
            sizes: Vec::new(),
        }
    }

    /// The same plan from a known point on: no global stage, one try of the
    /// first try's size (a warm start; the edge rule's refit of any try,
    /// the small ones included: a refit refines a point, and its free-run
    /// stage and polish at the larger size cost little beside the tries).
    pub fn from_point(&self) -> Plan {
        Plan {
            global: None,
            tries: 1,
            sizes: self.sizes.first().copied().into_iter().collect(),
            ..self.clone()
        }
    }

    /// Try `t`'s populations: its entry of `sizes`, or the stages' own.
    pub fn try_size(&self, t: usize) -> TrySize {
        self.sizes.get(t).copied().unwrap_or(TrySize {
            global: self.global.as_ref().map_or(0, |g| g.population),
            free_run: self.free_run.as_ref().map_or(0, |f| f.population),
            refine: self.refine.as_ref().map_or(0, |r| r.population),
            polish: self.polish.as_ref().map_or(0, |p| p.starts),
        })
    }

    /// Candidates a generation of the global stage holds, every try's.
    pub fn population(&self) -> usize {
        (0..self.tries).map(|t| self.try_size(t).global).sum()
    }

    /// Islands of the population stages (the free-run stage keeps the
    /// global stage's).
    pub fn islands(&self) -> usize {
        self.global.as_ref().map_or(1, |g| g.islands.max(1))
    }

    /// Generations of all population stages, every refining round run.
    pub fn generations(&self) -> usize {
        self.global.as_ref().map_or(0, |g| g.generations)
            + self.free_run.as_ref().map_or(0, |f| f.generations)
            + self.refine.as_ref().map_or(0, |r| r.rounds * r.generations)
    }
}
