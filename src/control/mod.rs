//! Closed-loop control of the muscle's displacement through the input valve
//! voltage: the thesis' PI (chapter 6.2, Table 22), an MPC whose model keeps
//! the hysteresis and stays a convex QP (the future work of §6.3), gain
//! tuning with the project's optimizers, and the closed-loop episodes that
//! measure them.
//!
//! Units everywhere in this module: displacement in mm, pressure in MPa,
//! valve voltage in V (input valve `u`, output valve driven at `10 − u` by the
//! plant), time in s. Controllers see only measurements (pressure and
//! displacement), never a plant's internals.

pub mod chain;
pub mod closed_loop;
pub mod controller;
pub mod design;
pub mod feedforward;
pub mod figures;
pub mod interrupt;
pub mod limits;
pub mod metrics;
pub mod model;
pub mod mpc;
pub mod observer;
pub mod pi;
pub mod plant;
pub mod qp;
pub mod reference;
pub mod runtime;
pub mod session;
pub mod sweep;
pub mod table;
pub mod tuning;
pub mod validation;
pub mod valve;

pub use closed_loop::{Episode, EpisodeResult, run_episode};
pub use controller::Controller;
pub use limits::ValveLimits;
pub use metrics::Metrics;
pub use model::ControlModel;
pub use mpc::{Mpc, MpcSettings};
pub use pi::{Pi, PiGains};
pub use plant::{Measurement, Plant, StandIn};
pub use runtime::{Command, ControlLoop};
pub use valve::ValveModel;
