//! What every search on a fitting problem shares: the evaluator that
//! scores its populations and the flag that stops them.

use std::sync::{Arc, Mutex};

use crate::eval::Evaluator;

pub use crate::optim::stop::StopFlag;

/// The evaluator a problem scores populations on, shared by its clones: one
/// that forks ([`Evaluator::fork`]: the CPU path), of which every search
/// takes a fork, so searches run side by side; or a device behind the same
/// lock, on which searches take turns.
#[derive(Clone)]
pub struct Scorer(Arc<Mutex<Box<dyn Evaluator + Send>>>);

impl Scorer {
    pub fn of(evaluator: Box<dyn Evaluator + Send>) -> Scorer {
        Scorer(Arc::new(Mutex::new(evaluator)))
    }

    /// Runs `job` on the evaluator: a fork of it where it forks (searches
    /// run side by side), else the evaluator itself in turn.
    pub fn run<T>(
        &self,
        job: impl FnOnce(&mut dyn Evaluator) -> anyhow::Result<T>,
    ) -> anyhow::Result<T> {
        let mut evaluator = self
            .0
            .lock()
            .map_err(|_| anyhow::anyhow!("the evaluator failed in an earlier call"))?;
        match evaluator.fork() {
            Some(mut fork) => {
                drop(evaluator);
                job(fork.as_mut())
            }
            None => job(evaluator.as_mut()),
        }
    }
}

/// What every search on a problem shares, beside the problem itself: the
/// evaluator it scores on and the flag that stops it. A
/// [`crate::fit::problem::FitProblem`] is a plain value (data, parts,
/// model, box, admission); the searches that run on it (the diagnosis'
/// many, side by side) carry this.
#[derive(Debug, Clone)]
pub struct Searches {
    pub scorer: Scorer,
    pub stop: StopFlag,
}

impl Searches {
    pub fn new(evaluator: Box<dyn Evaluator + Send>, stop: StopFlag) -> Searches {
        Searches {
            scorer: Scorer::of(evaluator),
            stop,
        }
    }

    /// The batched CPU evaluator, never stopped: a search's default.
    pub fn cpu() -> Searches {
        Searches::new(
            Box::new(crate::eval::cpu::CpuEvaluator::new()),
            StopFlag::default(),
        )
    }

    /// Runs `job` on the evaluator ([`Scorer::run`]).
    pub fn run<T>(
        &self,
        job: impl FnOnce(&mut dyn Evaluator) -> anyhow::Result<T>,
    ) -> anyhow::Result<T> {
        self.scorer.run(job)
    }
}

impl std::fmt::Debug for Scorer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0.lock() {
            Ok(e) => f.write_str(&e.describe()),
            Err(_) => f.write_str("(evaluator poisoned)"),
        }
    }
}
