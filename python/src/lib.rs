//! Python bindings of the `mckibben` library (the module `mckibben`).
//!
//! The bindings only convert types: every computation is a call into the
//! library, the same call the command makes (`mckibben fit` and
//! [`mckibben::fit::run::FitRun`], `mckibben diagnose` and
//! [`mckibben::diagnose::diagnose`], `mckibben identify` and
//! [`mckibben::ident::arx::identify`], `mckibben twin` and
//! [`mckibben::twin::experiment::RunSpec`], `mckibben control` and
//! [`mckibben::control::session::ControlPlan`], the batch evaluator behind
//! fit and diagnosis). What is here is checking and converting Python's
//! inputs (any float dtype, layout, lists), releasing the interpreter while
//! Rust computes, turning Ctrl-C into the engine's stop flag, and mapping
//! errors to Python's exceptions. docs/PYTHON.md describes the API.

mod args;
mod control;
mod convert;
mod data;
mod diagnose;
mod evaluator;
mod fit;
mod history;
mod identify;
mod interrupt;
mod model;
mod named;
mod state;
mod twin;

use pyo3::prelude::*;

/// Identify, diagnose and simulate hysteretic McKibben muscles: the Rust
/// library `mckibben`'s staged fit, diagnosis, models and batch evaluator.
#[pymodule]
#[pyo3(name = "mckibben")]
fn mckibben_py(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<data::Trace>()?;
    m.add_class::<model::Model>()?;
    m.add_class::<fit::FitResult>()?;
    m.add_class::<evaluator::Evaluator>()?;
    m.add_class::<evaluator::ScipyObjective>()?;
    m.add_class::<diagnose::Diagnosis>()?;
    m.add_class::<control::ControlResult>()?;
    m.add_class::<identify::Identification>()?;
    m.add_function(wrap_pyfunction!(data::read_csv, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose::diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(twin::twin, m)?)?;
    m.add_function(wrap_pyfunction!(control::control, m)?)?;
    m.add_function(wrap_pyfunction!(identify::identify, m)?)?;
    Ok(())
}
