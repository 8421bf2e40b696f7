//! Population optimizers in ask/tell form, and the fitting [`engine`] that
//! drives them against an [`engine::Objective`] that scores whole
//! populations (a fit's is a batch evaluator of a model).
//!
//! An optimizer never sees the model: it is handed a box (the free
//! coordinates of an [`engine::Space`]), *asks* for a population of points in
//! it and is *told* their costs (SSE, lower is better, `+∞` for a diverged
//! candidate). The [`engine`] owns everything around that: stages, seeding,
//! stopping, history, checkpoints, Ctrl-C. Every random draw comes from the
//! [`Streams`] the engine passes in, one stream per individual, so the
//! update rules run row by row in parallel and a run is a pure function of
//! its seed, whatever the thread count or backend.
//!
//! The thesis' three methods (chapter 5, appendix A.2) are [`ga`], [`mfa`]
//! and [`pso`]; [`de`] is the modern baseline they are compared against.
//! [`lm`] is not a population method: it polishes one point by
//! Levenberg–Marquardt after a search.

pub mod de;
pub mod engine;
pub mod ga;
pub mod history;
pub mod lm;
pub mod mfa;
pub mod normal;
pub mod pso;
pub mod stage;
pub mod stop;
pub mod streams;

use std::cmp::Ordering;
use std::fmt;
use std::str::FromStr;

use rand::RngExt;
use rayon::prelude::*;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::names::UnknownName;
use crate::search::{Coords, Population, ROWS_PER_TASK, Rows};

pub use history::{GenerationRecord, History};
pub use streams::{RowRng, Streams};

/// Which of the thesis' models a search's thesis settings are for: its
/// tables state other PSO settings for the generalized model (Table 19) than
/// for the classic one (Table 11). A label, so that the optimizers' presets
/// need not know the models.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ThesisModel {
    Classic,
    Generalized,
}

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

    /// Fills `row` with a point drawn uniformly in the box (eq. 26).
    pub fn uniform(&self, row: &mut [f64], rng: &mut RowRng) {
        for (j, v) in row.iter_mut().enumerate() {
            *v = self.lower[j] + rng.random::<f64>() * self.width(j);
        }
    }
}

/// A population algorithm, as its own file implements it, with its
/// settings; its line in this module's `registry!` makes it selectable.
///
/// It is driven through [`AskTell`], which keeps the phases: `init` once,
/// then `tell` and `next` in turn, each `tell` with one cost per row of the
/// population just returned. Costs are sanitised before `tell`: NaN becomes
/// `+∞`, so an optimizer only has to treat `+∞` as "worst".
pub trait Optimizer: Sized + Clone + fmt::Debug + Serialize + DeserializeOwned {
    /// Its settings; `Default` is what its paper states.
    type Settings: Clone + Default + PartialEq + fmt::Debug + Serialize + DeserializeOwned;

    /// One line on it, for `--algo`'s help.
    const HELP: &'static str;

    /// The smallest population it searches with, whatever its settings: the
    /// one rule on population sizes, stated in each algorithm's file. The
    /// engine refuses a smaller island, the commands a smaller `--pop`.
    const MIN_POPULATION: usize;

    /// A fresh search over `bounds` with `n ≥ MIN_POPULATION` individuals a
    /// generation and `generations` planned (the horizon of schedules that
    /// run over the search).
    fn new(settings: Self::Settings, bounds: Bounds, n: usize, generations: usize) -> Self;

    /// The box it searches.
    fn bounds(&self) -> &Bounds;

    /// The settings of the thesis' flow and of Table 21 (chapter 5): the
    /// paper's unless the thesis states others for `model`.
    fn thesis_settings(_model: ThesisModel) -> Self::Settings {
        Self::Settings::default()
    }

    /// The settings of the staged fit's global stage with `n` individuals:
    /// the paper's unless they were measured to miss the basin there
    /// (docs/lab/results.md, "1. Known truth").
    fn staged_settings(_n: usize) -> Self::Settings {
        Self::Settings::default()
    }

    /// The first population: `initial` rows (a warm start) and uniform
    /// draws for the rest, as `first_population` makes it, row `i` drawing
    /// from `streams.row(i)`. `n` rows, every one inside the box; it stays
    /// the optimizer's own (no copy is handed out).
    fn init(&mut self, initial: Population<Coords>, streams: &Streams) -> Rows<'_, Coords>;

    /// The next population, from the costs told of the last one: each
    /// individual's move from its own stream (`streams.row(i)`), so that
    /// the rows can be made in parallel, in any order.
    fn next(&mut self, streams: &Streams) -> Rows<'_, Coords>;

    /// The costs of the rows of the population last returned, in order.
    fn tell(&mut self, costs: &[f32]);

    /// The members whose costs drive the next move and those costs: what a
    /// later stage of a fit starts from. Only asked after a `tell`.
    fn members(&self) -> (Population<Coords>, Vec<f32>);
}

/// Where a search stands between `ask` and `tell`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
enum Phase {
    /// Nothing asked yet; the first population starts with these rows.
    Fresh { initial: Vec<f64> },
    /// A population was asked for and awaits its costs.
    Asked,
    /// The costs of the last population were told.
    Told,
}

/// An `ask` or `tell` out of turn.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PhaseError {
    #[error("{0}: asked for a population while the last one awaits its costs")]
    AskedTwice(Algorithm),
    #[error("{0}: told costs with no population asked for")]
    NothingAsked(Algorithm),
    #[error("{algorithm}: told {got} costs for a population of {want}")]
    WrongLength {
        algorithm: Algorithm,
        got: usize,
        want: usize,
    },
}

/// A search by any registered algorithm in explicit phases: `ask` and `tell`
/// alternate, starting with `ask`. A call out of turn is an error and
/// changes nothing, so that a stray second `ask` cannot restart a search
/// silently (docs/ARCHITECTURE.md, "Adding an optimizer").
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct AskTell {
    /// Individuals a generation: the costs each `tell` brings.
    n: usize,
    phase: Phase,
    optimizer: AnyOptimizer,
}

impl AskTell {
    /// A search by `settings`' algorithm over `bounds` with `n` individuals
    /// a generation (at least [`Algorithm::min_population`]) and
    /// `generations` planned, whose first population starts with the
    /// `initial` rows (clamped into the box; may be empty).
    pub fn new(
        settings: &AlgoSettings,
        bounds: Bounds,
        n: usize,
        generations: usize,
        initial: Population<Coords>,
    ) -> AskTell {
        let min = settings.algorithm().min_population();
        assert!(
            n >= min,
            "{} needs a population of at least {min} (got {n})",
            settings.algorithm()
        );
        assert_eq!(initial.dim(), bounds.dim(), "initial rows of another box");
        AskTell {
            n,
            phase: Phase::Fresh {
                initial: initial.into_flat(),
            },
            optimizer: AnyOptimizer::new(settings, bounds, n, generations),
        }
    }

    pub fn algorithm(&self) -> Algorithm {
        self.optimizer.algorithm()
    }

    /// Individuals a generation: the rows each `ask` gives.
    pub fn population(&self) -> usize {
        self.n
    }

    /// The next population to evaluate: `n` rows, every one inside the box,
    /// individual `i` drawn from `streams.row(i)`.
    pub fn ask(&mut self, streams: &Streams) -> Result<Rows<'_, Coords>, PhaseError> {
        let fresh = match &mut self.phase {
            Phase::Fresh { initial } => Some(std::mem::take(initial)),
            Phase::Told => None,
            Phase::Asked => return Err(PhaseError::AskedTwice(self.algorithm())),
        };
        self.phase = Phase::Asked;
        Ok(match fresh {
            Some(initial) => {
                let initial = Population::new(initial, self.optimizer.bounds().dim());
                self.optimizer.init(initial, streams)
            }
            None => self.optimizer.next(streams),
        })
    }

    /// The costs of the rows last asked for, in order.
    pub fn tell(&mut self, costs: &[f32]) -> Result<(), PhaseError> {
        if !matches!(self.phase, Phase::Asked) {
            return Err(PhaseError::NothingAsked(self.algorithm()));
        }
        if costs.len() != self.n {
            return Err(PhaseError::WrongLength {
                algorithm: self.algorithm(),
                got: costs.len(),
                want: self.n,
            });
        }
        self.optimizer.tell(costs);
        self.phase = Phase::Told;
        Ok(())
    }

    /// [`Optimizer::members`] after a `tell`; none otherwise.
    pub fn members(&self) -> (Population<Coords>, Vec<f32>) {
        match self.phase {
            Phase::Told => self.optimizer.members(),
            _ => (
                Population::zeros(0, self.optimizer.bounds().dim()),
                Vec::new(),
            ),
        }
    }
}

/// The first population of an optimizer: the given `initial` rows (clamped
/// into the box; a warm start from known models), then uniform draws (eq.
/// 26), row `i` from `streams.row(i)`.
pub(crate) fn first_population(
    bounds: &Bounds,
    n: usize,
    initial: Population<Coords>,
    streams: &Streams,
) -> Vec<f64> {
    let d = bounds.dim();
    let (mut pop, given) = first_rows(bounds, n, initial);
    pop.par_chunks_mut(d)
        .enumerate()
        .with_min_len(ROWS_PER_TASK)
        .for_each(|(i, row)| first_row(bounds, row, i < given, &mut streams.row(i)));
    pop
}

/// `initial` cut or grown to `n` rows, and how many of them were given.
pub(crate) fn first_rows(
    bounds: &Bounds,
    n: usize,
    mut initial: Population<Coords>,
) -> (Vec<f64>, usize) {
    assert_eq!(initial.dim(), bounds.dim(), "initial rows of another box");
    let given = initial.len().min(n);
    initial.resize(n);
    (initial.into_flat(), given)
}

/// Row of a first population: a `given` row clamped into the box, or else
/// a uniform draw from `rng`.
pub(crate) fn first_row(bounds: &Bounds, row: &mut [f64], given: bool, rng: &mut RowRng) {
    if given {
        bounds.clamp(row);
    } else {
        bounds.uniform(row, rng);
    }
}

/// Total order on costs for minimisation: `+∞` and NaN last, never
/// panicking (the comparison every sort and selection here uses).
pub fn cost_order(a: f32, b: f32) -> Ordering {
    let key = |v: f32| if v.is_nan() { f32::INFINITY } else { v };
    key(a).total_cmp(&key(b))
}

/// The indices of the `k` lowest costs, best first (ties by index): a
/// partial selection, `O(n + k log k)`, where a full sort would be
/// `O(n log n)`. The order is [`cost_order`] then the index, a total order,
/// so the result is unique. It selects on one integer a row, the cost's
/// place in that order above the index, which compares in one instruction.
pub fn best_indices(costs: &[f32], k: usize) -> Vec<usize> {
    assert!(
        costs.len() <= u32::MAX as usize,
        "more rows than a u32 counts"
    );
    let mut keys: Vec<u64> = costs
        .iter()
        .enumerate()
        .map(|(i, &c)| (u64::from(ordered_bits(c)) << 32) | i as u64)
        .collect();
    let k = k.min(keys.len());
    if k == 0 {
        return Vec::new();
    }
    if k < keys.len() {
        keys.select_nth_unstable(k - 1);
        keys.truncate(k);
    }
    keys.sort_unstable();
    keys.into_iter()
        .map(|key| (key & 0xffff_ffff) as usize)
        .collect()
}

/// A cost's bits, mapped so that unsigned order is [`cost_order`]: NaN as
/// `+∞`, negative costs flipped below the positive ones.
fn ordered_bits(c: f32) -> u32 {
    let bits = if c.is_nan() { f32::INFINITY } else { c }.to_bits();
    if bits & 0x8000_0000 != 0 {
        !bits
    } else {
        bits | 0x8000_0000
    }
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

/// Generates from the one list of algorithms below everything that names
/// them: [`Algorithm`] (the `--algo` value, with its help), [`AlgoSettings`]
/// and `AnyOptimizer` (the state [`AskTell`] drives). An entry is the variant, the name (`--algo`, the
/// JSON output's `algo`, the checkpoint's tag) and the [`Optimizer`].
macro_rules! registry {
    ($($variant:ident = $name:literal => $optimizer:ty,)+) => {
        /// Which algorithm; parses from the `--algo` names.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
        pub enum Algorithm {
            $(#[serde(rename = $name)] $variant,)+
        }

        impl Algorithm {
            /// Every algorithm, in the registry's order.
            pub const ALL: [Algorithm; [$($name),+].len()] = [$(Algorithm::$variant),+];

            pub fn name(self) -> &'static str {
                match self {
                    $(Algorithm::$variant => $name,)+
                }
            }

            /// One line on it ([`Optimizer::HELP`]).
            pub fn help(self) -> &'static str {
                match self {
                    $(Algorithm::$variant => <$optimizer as Optimizer>::HELP,)+
                }
            }

            /// Its smallest population ([`Optimizer::MIN_POPULATION`]).
            pub fn min_population(self) -> usize {
                match self {
                    $(Algorithm::$variant => <$optimizer as Optimizer>::MIN_POPULATION,)+
                }
            }

            /// Its paper's settings.
            pub fn default_settings(self) -> AlgoSettings {
                match self {
                    $(Algorithm::$variant => AlgoSettings::$variant(Default::default()),)+
                }
            }

            /// Its settings in the thesis' flow ([`Optimizer::thesis_settings`]).
            pub fn thesis_settings(self, model: ThesisModel) -> AlgoSettings {
                match self {
                    $(Algorithm::$variant => {
                        AlgoSettings::$variant(<$optimizer as Optimizer>::thesis_settings(model))
                    })+
                }
            }

            /// Its settings in the staged fit ([`Optimizer::staged_settings`]).
            pub fn staged_settings(self, n: usize) -> AlgoSettings {
                match self {
                    $(Algorithm::$variant => {
                        AlgoSettings::$variant(<$optimizer as Optimizer>::staged_settings(n))
                    })+
                }
            }
        }

        /// One algorithm and its settings (tagged by its name when serialised).
        #[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
        #[serde(tag = "algo")]
        pub enum AlgoSettings {
            $(#[serde(rename = $name)] $variant(<$optimizer as Optimizer>::Settings),)+
        }

        impl AlgoSettings {
            pub fn algorithm(&self) -> Algorithm {
                match self {
                    $(AlgoSettings::$variant(_) => Algorithm::$variant,)+
                }
            }
        }

        /// Any of the optimizers, as one serialisable value (what a checkpoint stores).
        #[derive(Debug, Clone, Serialize, Deserialize)]
        #[serde(tag = "algo")]
        enum AnyOptimizer {
            $(#[serde(rename = $name)] $variant($optimizer),)+
        }

        impl AnyOptimizer {
            /// A fresh optimizer of `settings`' algorithm over `bounds` with
            /// `n` individuals and `g` planned generations.
            fn new(settings: &AlgoSettings, bounds: Bounds, n: usize, g: usize) -> Self {
                match settings {
                    $(AlgoSettings::$variant(s) => {
                        AnyOptimizer::$variant(<$optimizer as Optimizer>::new(s.clone(), bounds, n, g))
                    })+
                }
            }

            fn algorithm(&self) -> Algorithm {
                match self {
                    $(AnyOptimizer::$variant(_) => Algorithm::$variant,)+
                }
            }

            fn bounds(&self) -> &Bounds {
                match self {
                    $(AnyOptimizer::$variant(o) => o.bounds(),)+
                }
            }

            fn init(&mut self, initial: Population<Coords>, streams: &Streams) -> Rows<'_, Coords> {
                match self {
                    $(AnyOptimizer::$variant(o) => o.init(initial, streams),)+
                }
            }

            fn next(&mut self, streams: &Streams) -> Rows<'_, Coords> {
                match self {
                    $(AnyOptimizer::$variant(o) => o.next(streams),)+
                }
            }

            fn tell(&mut self, costs: &[f32]) {
                match self {
                    $(AnyOptimizer::$variant(o) => o.tell(costs),)+
                }
            }

            fn members(&self) -> (Population<Coords>, Vec<f32>) {
                match self {
                    $(AnyOptimizer::$variant(o) => o.members(),)+
                }
            }
        }
    };
}

// The registry: adding an algorithm is its file (an `Optimizer`, declared by
// `pub mod` above) and a line here.
registry! {
    Ga = "ga" => ga::Ga,
    Mfa = "mfa" => mfa::Mfa,
    Pso = "pso" => pso::Pso,
    De = "de" => de::De,
}

impl fmt::Display for Algorithm {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Algorithm {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        crate::names::one_of("algorithm", s, &Algorithm::ALL, |a| a.name())
    }
}

/// `--algo`'s values and their help, from the registry.
impl clap::ValueEnum for Algorithm {
    fn value_variants<'a>() -> &'a [Self] {
        &Algorithm::ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.name()).help(self.help()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use stage::Stage;

    /// Generation `g`'s streams of a run seeded by `seed`.
    fn at(seed: u64, g: usize) -> Streams {
        Streams::new(seed, Stage::Global, g)
    }

    #[test]
    fn infinite_and_nan_costs_sort_last() {
        let mut v = [3.0f32, f32::INFINITY, f32::NAN, 1.0, 2.0];
        v.sort_by(|a, b| cost_order(*a, *b));
        assert_eq!(&v[..3], &[1.0, 2.0, 3.0]);
        assert!(v[3..].iter().all(|c| !c.is_finite()));
        assert_eq!(argmin(&[f32::INFINITY, 2.0, f32::NAN, 1.0]), Some(3));
        assert_eq!(argmin(&[f32::INFINITY, f32::NAN]), None);
    }

    /// The partial selection is the full sort's head, on costs with ties,
    /// signs, zeros of both signs, infinities and NaN.
    #[test]
    fn best_indices_are_the_head_of_the_full_order() {
        let costs = [
            3.0f32,
            f32::NAN,
            -1.0,
            0.0,
            -0.0,
            f32::INFINITY,
            3.0,
            f32::NEG_INFINITY,
            1e-30,
            -2.5,
            3.0,
            f32::NAN,
        ];
        let mut order: Vec<usize> = (0..costs.len()).collect();
        order.sort_by(|&a, &b| cost_order(costs[a], costs[b]).then(a.cmp(&b)));
        for k in 0..=costs.len() + 1 {
            assert_eq!(
                best_indices(&costs, k),
                order[..k.min(costs.len())],
                "k = {k}"
            );
        }
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
                .to_string()
                .contains("ga, mfa")
        );
    }

    const N: usize = 8;

    fn cube() -> Bounds {
        Bounds {
            lower: vec![-1.0; 3],
            upper: vec![1.0; 3],
            names: vec!["x".into(), "y".into(), "z".into()],
        }
    }

    /// A search of 8 over a 3-d box by every registered algorithm.
    fn every_algorithm() -> impl Iterator<Item = AskTell> {
        Algorithm::ALL
            .into_iter()
            .map(|a| AskTell::new(&a.default_settings(), cube(), N, 10, none()))
    }

    /// No warm start in the 3-d box.
    fn none() -> Population<Coords> {
        Population::zeros(0, 3)
    }

    fn sphere(rows: &[f64]) -> Vec<f32> {
        rows.chunks(3)
            .map(|r| r.iter().map(|v| v * v).sum::<f64>() as f32)
            .collect()
    }

    /// The minimum each algorithm states is enough for each of its presets.
    #[test]
    fn every_algorithm_runs_at_its_minimum_population() {
        for algo in Algorithm::ALL {
            let n = algo.min_population();
            for settings in [
                algo.default_settings(),
                algo.thesis_settings(ThesisModel::Generalized),
                algo.staged_settings(n),
            ] {
                let mut search = AskTell::new(&settings, cube(), n, 5, none());
                for g in 0..5 {
                    let rows = search.ask(&at(2, g)).unwrap().as_flat().to_vec();
                    assert_eq!(rows.len(), n * 3, "{algo}");
                    for row in rows.chunks(3) {
                        assert!(!cube().clamp(&mut row.to_vec()), "{algo}: {row:?}");
                    }
                    search.tell(&sphere(&rows)).unwrap();
                }
            }
        }
    }

    #[test]
    fn asking_twice_is_an_error_for_every_algorithm_and_changes_nothing() {
        for (mut refused, mut plain) in every_algorithm().zip(every_algorithm()) {
            let algo = refused.algorithm();
            for g in 0..3 {
                let rows = refused.ask(&at(3, g)).unwrap().as_flat().to_vec();
                assert_eq!(
                    refused.ask(&at(3, g)).map(|r| r.as_flat().to_vec()),
                    Err(PhaseError::AskedTwice(algo))
                );
                // The refused ask did not restart the search: the two
                // searches stay the same.
                assert_eq!(rows, plain.ask(&at(3, g)).unwrap().as_flat(), "{algo}");
                refused.tell(&sphere(&rows)).unwrap();
                plain.tell(&sphere(&rows)).unwrap();
            }
            assert_eq!(refused.members(), plain.members(), "{algo}");
        }
    }

    #[test]
    fn telling_out_of_turn_or_the_wrong_number_of_costs_is_an_error() {
        for mut search in every_algorithm() {
            let algo = search.algorithm();
            assert_eq!(search.tell(&[1.0; N]), Err(PhaseError::NothingAsked(algo)));
            let rows = search.ask(&at(4, 0)).unwrap().as_flat().to_vec();
            for wrong in [N - 1, N + 1] {
                assert_eq!(
                    search.tell(&vec![1.0; wrong]),
                    Err(PhaseError::WrongLength {
                        algorithm: algo,
                        got: wrong,
                        want: N
                    })
                );
            }
            assert!(search.members().0.is_empty(), "{algo}: nothing told yet");
            search.tell(&sphere(&rows)).unwrap();
            assert_eq!(
                search.tell(&sphere(&rows)),
                Err(PhaseError::NothingAsked(algo))
            );
            assert_eq!(search.members().1.len(), N, "{algo}");
        }
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

    /// The same for `f64` costs.
    pub mod f64s {
        use serde::{Deserialize, Deserializer, Serialize, Serializer};

        pub fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
            v.iter()
                .map(|&c| c.is_finite().then_some(c))
                .collect::<Vec<_>>()
                .serialize(s)
        }

        pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
            let v = Vec::<Option<f64>>::deserialize(d)?;
            Ok(v.into_iter().map(|c| c.unwrap_or(f64::INFINITY)).collect())
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
