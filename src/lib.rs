//! `mckibben`: identification, diagnosis and control of hysteretic tap-water
//! McKibben artificial muscles.
//!
//! Data flows one way (see `docs/ARCHITECTURE.md`):
//!
//! ```text
//! CSV / twin -> data::Trace -> ident (ARX) -> model (family, bounds)
//!     -> optim (GA, MFA, PSO, DE) <-> eval::Evaluator (CPU | GPU)
//!     -> fitted model -> report / diagnose / control
//! ```

pub mod benchmark;
pub mod control;
pub mod data;
pub mod diagnose;
pub mod eval;
pub mod fit;
pub mod ident;
pub mod model;
pub mod names;
pub mod optim;
pub mod report;
pub mod rig;
pub mod search;
pub mod twin;
