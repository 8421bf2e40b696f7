//! The controller as a rig sees it: one call per sample, measurement in,
//! valve command out. [`ControlLoop`] binds a [`Controller`] to its
//! reference and the valve limits, keeps the command in force, holds it when
//! a measurement is missing, and times each step. The in-process episodes
//! (`closed_loop::run_episode`) and the loop over a line protocol
//! (`crate::rig`) both drive it, so the two give the same numbers.

use std::time::Instant;

use super::controller::Controller;
use super::limits::ValveLimits;
use super::plant::Measurement;

/// The command for one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Command {
    /// The sample the command is held over (its measurement closes it).
    pub k: usize,
    /// Input valve voltage (V).
    pub volts: f64,
    /// The measurement was missing and the command in force is held.
    pub held: bool,
}

/// Time one controller step took.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepTime {
    /// Wall clock (µs).
    pub wall_us: f64,
    /// The thread's own CPU time (µs), without waits for a core (NaN where
    /// the platform has no thread clock).
    pub cpu_us: f64,
}

/// A controller bound to its reference and the valve limits.
pub struct ControlLoop<'c> {
    controller: &'c mut dyn Controller,
    reference: Vec<f64>,
    limits: ValveLimits,
    /// Index of the next sample to command.
    k: usize,
    u: f64,
    /// Samples whose measurement was missing.
    pub missed: usize,
    /// Timing of the last step.
    pub last_time: StepTime,
}

impl<'c> ControlLoop<'c> {
    /// Starts a run: `reference[k]` is the reference at the measurement that
    /// closes sample `k`; `u0` is the command held over sample 0.
    pub fn new(
        controller: &'c mut dyn Controller,
        reference: Vec<f64>,
        limits: ValveLimits,
        u0: f64,
    ) -> Self {
        controller.reset(u0);
        ControlLoop {
            controller,
            reference,
            limits,
            k: 1,
            u: u0,
            missed: 0,
            last_time: StepTime::default(),
        }
    }

    /// The controller's label.
    pub fn name(&self) -> &str {
        self.controller.name()
    }

    /// The command held over sample 0, before any measurement.
    pub fn first(&self) -> Command {
        Command {
            k: 0,
            volts: self.u,
            held: false,
        }
    }

    /// Samples in the run (one command each).
    pub fn len(&self) -> usize {
        self.reference.len()
    }

    /// Whether the run has no samples.
    pub fn is_empty(&self) -> bool {
        self.reference.is_empty()
    }

    /// Whether every sample's measurement has been taken.
    pub fn done(&self) -> bool {
        self.k > self.reference.len()
    }

    /// The sample the next measurement closes (1, 2, …).
    pub fn next_sample(&self) -> usize {
        self.k
    }

    /// The command in force (V).
    pub fn command_in_force(&self) -> f64 {
        self.u
    }

    /// One sample: the measurement that closes sample `k − 1` (`None` when
    /// it is missing) in, the command for sample `k` out. A missing
    /// measurement holds the command in force, which is within the limits
    /// by construction, and tells the controller so.
    pub fn step(&mut self, m: Option<Measurement>) -> Command {
        let k = self.k;
        let (start, cpu_start) = (Instant::now(), thread_cpu_s());
        let command = match m {
            Some(m) => {
                let next = self.controller.command(m, &self.reference[k - 1..]);
                self.u = next;
                Command {
                    k,
                    volts: next,
                    held: false,
                }
            }
            None => {
                self.missed += 1;
                self.controller.missed(self.u);
                Command {
                    k,
                    volts: self.u,
                    held: true,
                }
            }
        };
        // The wall clock's interval holds the CPU clock's, reads and all:
        // an interrupt taken inside a read of the CPU clock is charged to
        // the thread, and outside the wall interval it made a step's CPU
        // time exceed its wall time (65 µs against 7 µs).
        let cpu_us = (thread_cpu_s() - cpu_start) * 1e6;
        self.last_time = StepTime {
            wall_us: start.elapsed().as_secs_f64() * 1e6,
            cpu_us,
        };
        self.k += 1;
        command
    }

    /// The valve limits the loop is held to.
    pub fn limits(&self) -> &ValveLimits {
        &self.limits
    }
}

/// CPU time consumed by the calling thread (s). Unlike wall-clock time it
/// leaves out the time the thread waited for a core, which on a shared
/// machine can dwarf the computation itself.
#[cfg(unix)]
pub fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; the clock id is a constant
    // every Linux and BSD libc defines.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if rc == 0 {
        ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
    } else {
        f64::NAN
    }
}

/// CPU time consumed by the calling thread (s): not available here.
#[cfg(not(unix))]
pub fn thread_cpu_s() -> f64 {
    f64::NAN
}
