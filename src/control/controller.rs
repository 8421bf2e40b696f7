//! The controller as the closed loop sees it: the feedback law's trait and
//! the solver counters it may report. Every controller (`pi`,
//! `feedforward`, `mpc`) implements it and every loop that drives one
//! (`closed_loop`'s episodes, `runtime`'s control loop) calls it, so it sits
//! below both.

use serde::{Deserialize, Serialize};

use super::plant::Measurement;

/// A feedback law on the input valve voltage.
pub trait Controller {
    /// Label for tables and figures (`pi`, `pi-tuned`, `mpc`).
    fn name(&self) -> &str;
    /// Prepares an episode; `u0` is the valve command in force before it.
    fn reset(&mut self, u0: f64);
    /// The valve command (V) for the coming sample, from the measurement at
    /// this sample and the reference: `reference[0]` is r at this sample,
    /// `reference[j]` r `j` samples ahead (known in advance: the sine is
    /// planned). A controller may read as far ahead as it likes.
    fn command(&mut self, m: Measurement, reference: &[f64]) -> f64;
    /// A sample passed without a measurement and `held` (the command in
    /// force) was held over it; a controller with a model moves its
    /// estimate on. The default does nothing.
    fn missed(&mut self, _held: f64) {}
    /// The solver's or the feedforward's counters over the episode, for
    /// controllers with one.
    fn stats(&self) -> Option<ControllerStats> {
        None
    }
}

/// Counters of a controller's solver (the MPC's QP) or its feedforward
/// (`ff-pid`'s inverse model) over an episode.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct ControllerStats {
    /// Samples whose QP could not be set up (non-finite prediction); the
    /// command in force was held.
    pub solver_failures: usize,
    /// QPs cut short by the iteration cap (feasible, not optimal).
    pub capped_solves: usize,
    /// Largest number of active-set iterations of one QP.
    pub max_qp_iterations: usize,
    /// Samples whose feedforward (`ff-pid`) was at the valve's range or
    /// not finite: there the inverse model gives nothing, and the PID
    /// alone tracks.
    pub feedforward_at_limit: usize,
}
