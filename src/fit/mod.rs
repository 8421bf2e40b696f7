//! Fitting a muscle model to recorded traces: the records and their split
//! ([`records`]), the problem on one trace ([`problem`]), the objective the
//! engine minimises ([`objective`]), what a fresh fit runs ([`settings`]), one run of `mckibben fit` ([`run`]),
//! the edge rule ([`edge`]), how far its tries agree ([`agreement`]), how closely the record determines
//! each parameter ([`uncertainty`]), synthetic records with known truths
//! ([`synthetic`], [`cases`]), what a larger population buys on those
//! ([`sweep`]) and the thesis' comparison of algorithms ([`compare`]).
//!
//! The optimizers and the engine that drives them ([`crate::optim`]) know
//! nothing of muscles: this module is where a model, its data and its box
//! meet them.

pub mod agreement;
pub mod cases;
pub mod chart;
pub mod compare;
pub mod edge;
pub mod memory;
pub mod objective;
pub mod problem;
pub mod records;
pub mod report;
pub mod request;
pub mod run;
pub mod searches;
pub mod settings;
pub mod sweep;
pub mod synthetic;
pub mod uncertainty;
