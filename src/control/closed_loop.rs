//! One closed-loop episode: a controller drives a plant to follow the sine
//! reference of appendix A.1.2, at the plant's sample time.

use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::limits::ValveLimits;
use super::metrics::Metrics;
use super::plant::{Measurement, Plant};
use super::reference::SineReference;

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
}

/// How an episode runs and which part of it is scored.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Episode {
    pub reference: SineReference,
    /// Seconds of regulation at the bias before the sine starts, so that every
    /// controller starts the sine from a settled loop.
    pub warmup_s: f64,
    /// Length of the sine (s): `total_time = 20` in appendix A.1.2.
    pub duration_s: f64,
    /// Scoring starts this long after the sine starts (s); the part before is
    /// the transient.
    pub steady_from_s: f64,
    /// Valve command before the episode (V): 5 V, where the input and output
    /// valves are open alike.
    pub u0: f64,
    pub limits: ValveLimits,
}

impl Episode {
    /// The thesis' experiment at `omega` rad/s: 10 s settling at 30 mm, 20 s
    /// of sine, scored over its last 10 s (from 1.6 periods at 1 rad/s to
    /// 4.8 at 3 rad/s).
    pub fn thesis(omega: f64) -> Self {
        Episode {
            reference: SineReference::thesis(omega),
            warmup_s: 10.0,
            duration_s: 20.0,
            steady_from_s: 10.0,
            u0: 5.0,
            limits: ValveLimits::default(),
        }
    }

    /// A short episode for tests and tuning.
    pub fn short(omega: f64, warmup_s: f64, duration_s: f64, steady_from_s: f64) -> Self {
        Episode {
            warmup_s,
            duration_s,
            steady_from_s,
            ..Episode::thesis(omega)
        }
    }
}

/// Everything an episode recorded; time 0 is the start of the sine.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeResult {
    pub controller: String,
    pub t: Vec<f64>,
    pub reference: Vec<f64>,
    pub displacement: Vec<f64>,
    pub pressure: Vec<f64>,
    pub valve: Vec<f64>,
    pub metrics: Metrics,
}

/// Runs `controller` on `plant` for one episode.
pub fn run_episode(
    plant: &mut dyn Plant,
    controller: &mut dyn Controller,
    episode: &Episode,
) -> EpisodeResult {
    let dt = plant.dt();
    let n_warm = (episode.warmup_s / dt).round() as usize;
    let n = n_warm + (episode.duration_s / dt).round() as usize;
    let time = |k: usize| (k as f64 - n_warm as f64) * dt;
    let reference: Vec<f64> = (0..n).map(|k| episode.reference.at(time(k))).collect();
    let mut out = EpisodeResult {
        controller: controller.name().to_string(),
        t: Vec::with_capacity(n),
        reference: Vec::with_capacity(n),
        displacement: Vec::with_capacity(n),
        pressure: Vec::with_capacity(n),
        valve: Vec::with_capacity(n),
        metrics: Metrics::default(),
    };
    controller.reset(episode.u0);
    let mut u = episode.u0;
    let mut violations = 0usize;
    let mut max_step_us = 0.0f64;
    let mut total_us = 0.0f64;
    let mut max_cpu_us = 0.0f64;
    for (k, r) in reference.iter().enumerate() {
        let m = plant.step(u);
        if !(m.displacement_mm.is_finite() && m.pressure_mpa.is_finite()) {
            out.metrics.diverged = true;
            break;
        }
        let (start, cpu_start) = (Instant::now(), thread_cpu_s());
        let next = controller.command(m, &reference[k..]);
        let us = start.elapsed().as_secs_f64() * 1e6;
        max_step_us = max_step_us.max(us);
        max_cpu_us = max_cpu_us.max((thread_cpu_s() - cpu_start) * 1e6);
        total_us += us;
        if episode.limits.violated(next, u) {
            violations += 1;
        }
        u = next;
        out.t.push(time(k));
        out.reference.push(*r);
        out.displacement.push(m.displacement_mm);
        out.pressure.push(m.pressure_mpa);
        out.valve.push(u);
    }
    let diverged = out.metrics.diverged;
    out.metrics = Metrics::of(
        &out.t,
        &out.reference,
        &out.displacement,
        &out.valve,
        episode.steady_from_s,
        episode.reference.amplitude_mm,
    );
    out.metrics.diverged |= diverged || out.t.len() < n;
    out.metrics.constraint_violations = violations;
    out.metrics.max_step_time_us = max_step_us;
    out.metrics.mean_step_time_us = total_us / out.t.len().max(1) as f64;
    out.metrics.max_step_cpu_us = max_cpu_us;
    out
}

/// CPU time consumed by the calling thread (s). Unlike wall-clock time it
/// leaves out the time the thread waited for a core, which on a shared
/// machine can dwarf the computation itself.
#[cfg(unix)]
fn thread_cpu_s() -> f64 {
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

#[cfg(not(unix))]
fn thread_cpu_s() -> f64 {
    f64::NAN
}
