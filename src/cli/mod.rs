//! Argument parsing and the dispatch to each command.

// First: its macros are then in scope in every module below.
#[macro_use]
mod output;

mod bench;
mod common;
mod compare;
mod control;
mod diagnose;
mod fit;
mod identify;
mod simulate;
mod static_force;
mod sweep;
mod twin;
mod validate;

use clap::{Parser, Subcommand};

/// Identify, diagnose and control hysteretic tap-water McKibben muscles.
///
/// Every command works on CSV data (columns `t`, `pressure`, `displacement`
/// by default; see `data/README.md`) and, given no data file, on the shipped
/// default experiment. Add `--json` for machine-readable output on stdout.
#[derive(Debug, Parser)]
#[command(
    name = "mckibben",
    version,
    propagate_version = true,
    max_term_width = 100
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    #[command(about = "Fit a Bouc-Wen hysteresis model with GA, MFA, PSO or DE (the main job)")]
    Fit(fit::Args),
    #[command(
        about = "Compare the optimizers: the thesis' Table 21 redone, large populations, cross-load"
    )]
    Compare(compare::Args),
    #[command(about = "Identify a linear ARX model (thesis §4.3): a, b and validation fit %")]
    Identify(identify::Args),
    #[command(about = "Simulate a model on a stair, a sine or a recorded input")]
    Simulate(simulate::Args),
    #[command(
        about = "Diagnose the sim-to-real gap: where the model misses, which effect, how far it shrinks"
    )]
    Diagnose(diagnose::Args),
    #[command(
        about = "Close the loop: thesis PI, tuned PID, feedforward PID and MPC at 1, 2, 3 rad/s, on the rig twin or a rig (--plant)"
    )]
    Control(control::Args),
    #[command(about = "Run an experiment on the rig twin and write the recording as CSV")]
    Twin(twin::Args),
    #[command(about = "Time the batch evaluator on the CPU and GPU and check that they agree")]
    Bench(bench::Args),
    #[command(
        about = "Fit generated cases with a known truth at several populations: what more compute buys"
    )]
    Sweep(sweep::Args),
    #[command(about = "Validate on a public benchmark with published results (Bouc-Wen)")]
    Validate(validate::Args),
    /// Deprecated alias of `validate` (its name reads too close to `bench`),
    /// kept so that existing scripts still run; prints a deprecation note
    /// (CHANGELOG.md).
    #[command(hide = true)]
    Benchmark(validate::Args),
    #[command(about = "The static force model (eq. 7 and 9) against braid angle or muscle length")]
    Static(static_force::Args),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Fit(args) => fit::run(args),
        Command::Compare(args) => compare::run(args),
        Command::Identify(args) => identify::run(args),
        Command::Simulate(args) => simulate::run(args),
        Command::Diagnose(args) => diagnose::run(args),
        Command::Control(args) => control::run(args),
        Command::Twin(args) => twin::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Sweep(args) => sweep::run(args),
        Command::Validate(args) => validate::run(args),
        Command::Benchmark(args) => {
            errln!(
                "mckibben: note: `mckibben benchmark` is deprecated and will be removed; \
                 it is now `mckibben validate` (same arguments)"
            );
            validate::run(args)
        }
        Command::Static(args) => static_force::run(args),
    }
}

/// Whether `err` is a run stopped by Ctrl-C (a fit, a diagnosis, control
/// runs on the twin or a rig): the command then exits with status 130, as
/// a program that SIGINT ended does, so that a shell script running it
/// stops too.
pub fn interrupted(err: &anyhow::Error) -> bool {
    use mckibben::rig::RigError;
    err.chain().any(|cause| {
        cause.is::<fit::Interrupted>()
            || cause.is::<mckibben::diagnose::Interrupted>()
            || cause.is::<mckibben::control::session::Interrupted>()
            || matches!(
                cause.downcast_ref::<RigError>(),
                Some(RigError::Interrupted { .. })
            )
    })
}
