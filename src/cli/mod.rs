//! Argument parsing and the dispatch to each command.

mod bench;
mod benchmark;
mod common;
mod compare;
mod diagnose;
mod fit;
mod identify;
mod simulate;
mod static_force;
mod twin;

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
    Fit(fit::Args),
    Compare(compare::Args),
    Identify(identify::Args),
    Simulate(simulate::Args),
    Diagnose(diagnose::Args),
    Twin(twin::Args),
    Bench(bench::Args),
    Benchmark(benchmark::Args),
    Static(static_force::Args),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Fit(args) => fit::run(args),
        Command::Compare(args) => compare::run(args),
        Command::Identify(args) => identify::run(args),
        Command::Simulate(args) => simulate::run(args),
        Command::Diagnose(args) => diagnose::run(args),
        Command::Twin(args) => twin::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Benchmark(args) => benchmark::run(args),
        Command::Static(args) => static_force::run(args),
    }
}
