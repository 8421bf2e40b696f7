//! Closed-loop control of the muscle's displacement through the input valve
//! voltage: the thesis' PI (chapter 6.2, Table 22), an MPC that stays convex
//! despite the hysteresis (the future work of §6.3), gain tuning with the
//! project's optimizers, and the closed-loop episodes that measure them.
//!
//! Units everywhere in this module: displacement in mm, pressure in MPa,
//! valve voltage in V (input valve `u`, output valve driven at `10 − u` by the
//! plant), time in s. Controllers see only measurements (pressure and
//! displacement), never a plant's internals.

pub mod closed_loop;
pub mod design;
pub mod limits;
pub mod metrics;
pub mod mpc;
pub mod pi;
pub mod plant;
pub mod reference;
pub mod tuning;

pub use closed_loop::{Controller, Episode, EpisodeResult, run_episode};
pub use design::{ControlModel, ValveModel};
pub use limits::ValveLimits;
pub use metrics::Metrics;
pub use mpc::{Mpc, MpcSettings};
pub use pi::{Pi, PiGains};
pub use plant::{Measurement, Plant, StandIn};
