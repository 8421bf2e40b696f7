//! The stages of a fit, which the engine runs and its history records: here,
//! below both, so that `history` need not import the engine that imports it.

use serde::{Deserialize, Serialize};

/// A stage of a fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stage {
    Global,
    FreeRun,
    Polish,
    /// Differential evolution on the free run in a cloud around a try's
    /// best so far, each round followed by a polish.
    Refine,
}

impl Stage {
    pub fn name(self) -> &'static str {
        match self {
            Stage::Global => "global",
            Stage::FreeRun => "free-run",
            Stage::Polish => "polish",
            Stage::Refine => "refine",
        }
    }
}
