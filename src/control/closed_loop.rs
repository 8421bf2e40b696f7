//! One closed-loop episode: a controller drives a plant to follow the sine
//! reference of appendix A.1.2, at the plant's sample time.

use serde::{Deserialize, Serialize};

use super::controller::Controller;
use super::limits::ValveLimits;
use super::metrics::Metrics;
use super::plant::{Measurement, Plant};
use super::reference::SineReference;
use super::runtime::{ControlLoop, StepTime};
use crate::data::signals::{nyquist_rad_s, samples_in};

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

    /// Why the episode cannot run on a plant sampled every `dt` seconds, if
    /// it cannot: a reference at or above Nyquist's frequency (its samples
    /// would trace another, slower wave), more samples than a record may
    /// hold, or none in the scored part (its metrics would be NaN).
    pub fn check(&self, dt: f64) -> Result<(), String> {
        let nyquist = nyquist_rad_s(dt);
        if self.reference.omega_rad_s >= nyquist {
            return Err(format!(
                "a reference at {} rad/s must stay below Nyquist's {nyquist:.1} rad/s (π/dt)",
                self.reference.omega_rad_s
            ));
        }
        samples_in(self.warmup_s + self.duration_s, dt)
            .map_err(|e| format!("the warm-up and the sine together: {e}"))?;
        // Sample k of the sine is at k·dt; the scored ones at or after
        // `steady_from_s` (Metrics::of). One alone has no valve travel
        // (its rate over no time is NaN).
        let sine = (self.duration_s / dt).round();
        let first = (self.steady_from_s / dt - 1e-9).ceil().max(0.0);
        if sine - first < 2.0 {
            return Err(format!(
                "the sine's {} s, sampled every {dt} s, hold fewer than two samples from {} s \
                 on: a score needs two (lengthen the sine or start scoring earlier)",
                self.duration_s, self.steady_from_s
            ));
        }
        Ok(())
    }

    /// The reference at each sample and the time of each sample (time 0 is
    /// the start of the sine) for a plant sampled every `dt` seconds.
    pub fn schedule(&self, dt: f64) -> (Vec<f64>, Vec<f64>) {
        let n_warm = (self.warmup_s / dt).round() as usize;
        let n = n_warm + (self.duration_s / dt).round() as usize;
        let times: Vec<f64> = (0..n).map(|k| (k as f64 - n_warm as f64) * dt).collect();
        (times.iter().map(|&t| self.reference.at(t)).collect(), times)
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

/// Everything an episode recorded; time 0 is the start of the sine. A
/// missing measurement is recorded as NaN.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeResult {
    pub controller: String,
    pub t: Vec<f64>,
    pub reference: Vec<f64>,
    pub displacement: Vec<f64>,
    pub pressure: Vec<f64>,
    pub valve: Vec<f64>,
    /// Wall-clock and CPU time of each controller step (µs).
    pub step_wall_us: Vec<f64>,
    pub step_cpu_us: Vec<f64>,
    /// The reference's amplitude (mm), which the metrics are read against.
    #[serde(default)]
    pub reference_amplitude_mm: f64,
    pub metrics: Metrics,
}

/// Runs `controller` on `plant` for one episode, through the same
/// [`ControlLoop`] a rig drives over a link.
pub fn run_episode(
    plant: &mut dyn Plant,
    controller: &mut dyn Controller,
    episode: &Episode,
) -> EpisodeResult {
    let dt = plant.dt();
    let (reference, times) = episode.schedule(dt);
    let n = reference.len();
    let mut lp = ControlLoop::new(controller, reference.clone(), episode.limits, episode.u0);
    let mut record = Recorder::new(lp.name(), n);
    let mut u = lp.first().volts;
    for k in 0..n {
        let m = plant.step(u);
        if !(m.displacement_mm.is_finite() && m.pressure_mpa.is_finite()) {
            record.diverged = true;
            break;
        }
        let next = lp.step(Some(m)).volts;
        record.push(
            times[k],
            reference[k],
            Some(m),
            u,
            next,
            lp.last_time,
            &episode.limits,
        );
        u = next;
    }
    record.finish(episode)
}

/// The steps whose time exceeded the sample time of the clock `t`: their
/// CPU time, or their wall time where the platform has no thread clock
/// (NaN), so that a loaded machine's waits for a core do not count.
fn overruns(t: &[f64], cpu_us: &[f64], wall_us: &[f64]) -> usize {
    let (Some(first), Some(last)) = (t.first(), t.last()) else {
        return 0;
    };
    if t.len() < 2 {
        return 0;
    }
    let dt_us = (last - first) / (t.len() - 1) as f64 * 1e6;
    cpu_us
        .iter()
        .zip(wall_us)
        .filter(|(cpu, wall)| if cpu.is_nan() { **wall } else { **cpu } > dt_us)
        .count()
}

/// Collects an episode sample by sample (in-process or over a link).
#[derive(Debug, Clone)]
pub struct Recorder {
    out: EpisodeResult,
    violations: usize,
    missing: usize,
    /// The plant's measurement became non-finite.
    pub diverged: bool,
    expected: usize,
}

impl Recorder {
    pub fn new(controller: &str, samples: usize) -> Self {
        let v = || Vec::with_capacity(samples);
        Recorder {
            out: EpisodeResult {
                controller: controller.to_string(),
                t: v(),
                reference: v(),
                displacement: v(),
                pressure: v(),
                valve: v(),
                step_wall_us: v(),
                step_cpu_us: v(),
                reference_amplitude_mm: 0.0,
                metrics: Metrics::default(),
            },
            violations: 0,
            missing: 0,
            diverged: false,
            expected: samples,
        }
    }

    /// One sample: its time and reference, its measurement (`None` if
    /// missing), the command in force before it and the one computed from
    /// it, and the step's time.
    #[allow(clippy::too_many_arguments)]
    pub fn push(
        &mut self,
        t: f64,
        reference: f64,
        m: Option<Measurement>,
        prev: f64,
        next: f64,
        time: StepTime,
        limits: &ValveLimits,
    ) {
        if limits.violated(next, prev) {
            self.violations += 1;
        }
        if m.is_none() {
            self.missing += 1;
        }
        let o = &mut self.out;
        o.t.push(t);
        o.reference.push(reference);
        o.displacement
            .push(m.map_or(f64::NAN, |m| m.displacement_mm));
        o.pressure.push(m.map_or(f64::NAN, |m| m.pressure_mpa));
        o.valve.push(next);
        o.step_wall_us.push(time.wall_us);
        o.step_cpu_us.push(time.cpu_us);
    }

    /// The episode with its metrics.
    pub fn finish(mut self, episode: &Episode) -> EpisodeResult {
        let o = &mut self.out;
        let mut m = Metrics::of(
            &o.t,
            &o.reference,
            &o.displacement,
            &o.valve,
            episode.steady_from_s,
            episode.reference.amplitude_mm,
        );
        m.diverged |= self.diverged || o.t.len() < self.expected;
        m.constraint_violations = self.violations;
        m.missing_measurements = self.missing;
        let steps = o.step_wall_us.len().max(1) as f64;
        m.max_step_time_us = o.step_wall_us.iter().fold(0.0, |a, &b| a.max(b));
        m.mean_step_time_us = o.step_wall_us.iter().sum::<f64>() / steps;
        m.max_step_cpu_us = o.step_cpu_us.iter().fold(0.0, |a, &b| a.max(b));
        m.overrun_steps = overruns(&o.t, &o.step_cpu_us, &o.step_wall_us);
        o.reference_amplitude_mm = episode.reference.amplitude_mm;
        o.metrics = m;
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A step counts as late by its CPU time where there is one (a wait
    /// for a core on a loaded machine is not the controller's), by its
    /// wall time where the thread clock is missing.
    #[test]
    fn a_step_past_the_sample_time_is_an_overrun() {
        let t = [0.0, 0.01, 0.02, 0.03];
        let cpu = [2e3, 12e3, f64::NAN, 9e3];
        let wall = [30e3, 12e3, 11e3, 9e3];
        assert_eq!(overruns(&t, &cpu, &wall), 2);
        assert_eq!(overruns(&t[..1], &cpu[..1], &wall[..1]), 0);
    }
}
