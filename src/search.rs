//! The terms a search and the model it searches share, below both: what a
//! candidate's cost measures, and which bound of a box. The model's
//! simulation runs under a [`Measure`] and its search box has sides; the
//! fitting engine plans its stages on measures and finds the sides a
//! result ends on, without knowing the model.

use serde::{Deserialize, Serialize};

/// What a score sums: the error of the free run (the thesis' fitness, eq. 29)
/// or of the `h`-step-ahead prediction.
///
/// The `h`-step-ahead predictor is the free run with its output state set
/// back to the measurement after every `h`-th sample (a state that is never
/// measured follows that jump as it follows any motion of the output:
/// `model::sim`'s `Stepper::restart`). Its error cannot pile up through a
/// slow pole for longer than `h` samples, so its cost surface has no needle along the pole
/// and the static gain where the free run's has one (Ribeiro, Tiels,
/// Umenberger, Schön and Aguirre, "On the smoothness of nonlinear system
/// identification", Automatica 2020: the Lipschitz constant of a simulation
/// error can grow exponentially with the simulated length; short predictions
/// restore smoothness). `h = 1` is the equation error; `h` past the data is
/// the free run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Measure {
    /// `Σ_{k≥1} (x(k) − y(k))²` of the free run.
    #[default]
    FreeRun,
    /// The same sum with the output state restarted from `y(k)` after every
    /// `horizon`-th sample (`horizon ≥ 1`).
    Ahead { horizon: usize },
}

impl Measure {
    /// Samples between restarts (`usize::MAX`: never).
    pub fn restart_every(self) -> usize {
        match self {
            Measure::FreeRun => usize::MAX,
            Measure::Ahead { horizon } => horizon.max(1),
        }
    }
}

impl std::fmt::Display for Measure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Measure::FreeRun => f.write_str("free run"),
            Measure::Ahead { horizon } => write!(f, "{horizon}-step-ahead prediction"),
        }
    }
}

/// Which bound of a coordinate's box.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    Lower,
    Upper,
}

impl Side {
    pub const BOTH: [Side; 2] = [Side::Lower, Side::Upper];

    /// Its place in a `[lower, upper]` pair (as a model's search box keeps
    /// its bounds' origins).
    pub fn index(self) -> usize {
        match self {
            Side::Lower => 0,
            Side::Upper => 1,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Side::Lower => "lower",
            Side::Upper => "upper",
        }
    }
}

impl std::fmt::Display for Side {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
