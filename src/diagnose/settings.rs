//! What a diagnosis may spend and the rule it accepts by: the one settings
//! struct every stage of it reads (the fits, the acceptance rule, the
//! selection, the self-tests), so that it sits below all of them.

use std::sync::Arc;

use serde::Serialize;

use crate::eval::Backend;
use crate::fit::searches::Searches;
use crate::fit::searches::StopFlag;
#[cfg(doc)]
use crate::model::experiment::Parts;
use crate::optim::engine::generations_refused;

/// The most seeds of one kind a salt's fits use: its warm fits' seeds run
/// from its first seed on, its from-scratch fits' from this many on, and
/// the next salt's start `2 ·` this many on. More would give two seeds of
/// one fit, or a fit's seed and its from-scratch seed, the same numbers.
pub const SEEDS_A_SALT: usize = 500;

/// The error of a diagnosis stopped by its [`StopFlag`].
#[derive(Debug, thiserror::Error)]
#[error("the diagnosis was interrupted before its verdict; nothing was written")]
pub struct Interrupted;

/// Budget and rule settings of a diagnosis.
#[derive(Debug, Clone, Serialize)]
pub struct Settings {
    /// Seeds per fit (the spread over them is the acceptance rule's yardstick).
    pub seeds: usize,
    /// Seeds, population and generations of the baseline fit (from scratch:
    /// more seeds, since a from-scratch fit can end in a poor basin and the
    /// best of the seeds on the estimation part is kept).
    pub baseline_seeds: usize,
    pub baseline_population: usize,
    pub baseline_generations: usize,
    /// Population and generations of each candidate fit (warm-started from
    /// the current model, effect parameters drawn over their whole box).
    pub population: usize,
    pub generations: usize,
    /// From-scratch seeds of each first-round candidate, on top of its warm
    /// seeds (baseline population and generations, through the
    /// multi-step-ahead predictor first; see
    /// [`Start::Ahead`](super::fitting::Start::Ahead)).
    pub scratch_seeds: usize,
    /// At most this many effects are named.
    pub max_effects: usize,
    /// Rule 1: improvement must exceed this many seed standard deviations.
    pub spread_factor: f64,
    /// Rule 2: ΔBIC must be below this.
    pub bic_threshold: f64,
    /// Rule 3: minimum relative improvement of the validation RMSE.
    pub min_relative: f64,
    /// Rule 4: the current model must miss by more than this multiple of the
    /// noise-floor estimate (which is good to about 10 %), else there is no
    /// gap left to explain.
    pub floor_margin: f64,
    /// Blocks the second half of each record is cut into, alternating
    /// selection and test, selection first ([`Parts::of`]); `None`: as many
    /// as each record's input asks for ([`Parts::chosen`]).
    pub blocks: Option<usize>,
    /// Base seed; seed `i` of the fits of a stage uses
    /// [`seed_of`](Settings::seed_of)`(salt, i)`.
    pub seed: u64,
    /// Where the searches score their populations (the same numbers on
    /// every backend that is bit-exact, lavapipe included).
    pub backend: Backend,
    /// Stops the diagnosis when raised (never, unless a caller raises it).
    #[serde(skip)]
    pub stop: StopFlag,
    /// Hears of each stage as it starts (silent unless a caller listens:
    /// `mckibben diagnose` prints them).
    #[serde(skip)]
    pub progress: Progress,
}

/// What hears of a stage: its name.
type Listener = Arc<dyn Fn(&str) + Send + Sync>;

/// A listener for the stages of a diagnosis, as each starts: a diagnosis
/// runs for minutes, and a person waiting should see where it stands.
#[derive(Clone, Default)]
pub struct Progress(Option<Listener>);

impl Progress {
    pub fn to(listener: impl Fn(&str) + Send + Sync + 'static) -> Progress {
        Progress(Some(Arc::new(listener)))
    }

    /// Tells the listener, if there is one, that `stage` starts.
    pub fn say(&self, stage: &str) {
        if let Some(listener) = &self.0 {
            listener(stage);
        }
    }
}

impl std::fmt::Debug for Progress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() {
            "Progress(listened)"
        } else {
            "Progress(silent)"
        })
    }
}

impl Settings {
    /// The searches of a diagnosis: the evaluator `backend` opens, stopped
    /// by `stop`.
    pub fn searches(&self) -> anyhow::Result<Searches> {
        // Checked before any search: the fits add the initial population
        // to the count, which would wrap past a word.
        if let Some(why) = generations_refused(self.generations) {
            anyhow::bail!("--generations {}: {why}", self.generations);
        }
        for (flag, count) in [
            ("--seeds", self.seeds),
            ("--scratch-seeds", self.scratch_seeds),
            ("baseline seeds", self.baseline_seeds),
        ] {
            anyhow::ensure!(
                count <= SEEDS_A_SALT,
                "{flag} {count}: at most {SEEDS_A_SALT}, or two of a diagnosis' fits would \
                 draw the same numbers"
            );
        }
        Ok(Searches::new(
            crate::eval::open(self.backend)?,
            self.stop.clone(),
        ))
    }
}

impl Settings {
    /// The seed of fit `i` under `salt`: each salt has `2 ·`
    /// [`SEEDS_A_SALT`] seeds of its own.
    pub fn seed_of(&self, salt: u64, i: u64) -> u64 {
        self.seed + 2 * SEEDS_A_SALT as u64 * salt + i
    }
}

impl Default for Settings {
    /// Sized so that `mckibben diagnose` on the default data (a few thousand
    /// samples) finishes in seconds on two cores. The baseline gets 12 seeds
    /// because a from-scratch fit of the classic model to the twin's stair
    /// is multimodal: most seeds stay on the linear model's plateau
    /// (`A = 0`), and the best of many reaches a better basin
    /// (docs/lab/diagnosis.md, "How the diagnosis was built, and what it
    /// measured").
    fn default() -> Self {
        Settings {
            seeds: 3,
            baseline_seeds: 12,
            baseline_population: 40,
            baseline_generations: 600,
            population: 30,
            generations: 300,
            scratch_seeds: 4,
            max_effects: 3,
            spread_factor: 3.0,
            bic_threshold: -10.0,
            min_relative: 0.02,
            floor_margin: 1.1,
            blocks: None,
            seed: 1,
            backend: Backend::Cpu,
            stop: StopFlag::default(),
            progress: Progress::default(),
        }
    }
}
