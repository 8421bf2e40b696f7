//! The muscle models: the static force model (eq. 1–9), the identified linear
//! model (eq. 12) and the two Bouc-Wen hysteresis families (eq. 13–25, as
//! corrected in `docs/ARCHITECTURE.md`), with their parameter vectors, names,
//! bounds and the thesis presets.

pub mod bounds;
pub mod coords;
pub mod effects;
pub mod experiment;
pub mod family;
pub mod file;
pub mod fitted;
pub mod presets;
pub mod sim;
pub mod static_force;
pub mod user_bound;

pub use crate::search::Measure;
pub use bounds::{BoundError, Flow, LinearPrior, SearchSpace, Switching};
pub use coords::{Coordinates, Loop};
pub use experiment::Experiment;
pub use family::{Family, ParamInfo};
pub use file::{Model, ModelFile};
pub use fitted::FittedBaseline;
pub use sim::{
    DIVERGENCE_BOUND, Simulation, check_f32_range, measured_sse, residuals, simulate, sse,
};
pub use user_bound::{UserBound, UserBoundError};
