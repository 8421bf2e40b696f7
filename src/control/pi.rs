//! The PI(D) controller of §6.2 (eq. 41), discretised at the sample time,
//! with anti-windup at the valve limits.
//!
//! Units: the gains map millimetres of error to volts of input valve command,
//! as in the thesis' loop (Table 22): `Kp` in V/mm, `Ki` in V/(mm·s), `Kd` in
//! V·s/mm.
//!
//! Table 22's `Ki = 0.05` is read per sample, `u = Kp·e + Ki·Σe` (5 V/(mm·s)
//! at 10 ms), as the twin's own sine experiment does
//! (`twin::experiment::ThesisPi`): read per second, the integral action would
//! be a hundred times too slow for the precise 1 rad/s tracking of figure 27.

use serde::{Deserialize, Serialize};

use super::controller::Controller;
use super::limits::ValveLimits;
use super::plant::Measurement;

/// The sample time of the thesis' loop (s), which Table 22's `Ki` is per.
pub const THESIS_SAMPLE_TIME_S: f64 = 0.01;

/// PID gains.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PiGains {
    /// Proportional gain (V/mm).
    pub kp: f64,
    /// Integral gain (V/(mm·s)).
    pub ki: f64,
    /// Derivative gain (V·s/mm).
    pub kd: f64,
}

impl Default for PiGains {
    /// Table 22 (the thesis' gains, 4.5 kg): Kp 0.06875 V/mm, Ki 0.05 V/mm
    /// per 10 ms sample (5 V/(mm·s)), Kd 0.
    fn default() -> Self {
        PiGains {
            kp: 0.06875,
            ki: 0.05 / THESIS_SAMPLE_TIME_S,
            kd: 0.0,
        }
    }
}

/// A discrete PI(D): `u = I + Kp·e + Kd·(e − e_prev)/dt`, `I ← I + Ki·e·dt`,
/// with the command clamped to the valve range and slew limit.
///
/// Anti-windup by conditional integration: the integrator does not move
/// while the command sits at a limit and the error pushes further into it,
/// and it is itself kept inside the valve range. So a long saturation (an
/// unreachable reference) cannot wind it up, and the loop recovers as soon as
/// the reference comes back within reach.
#[derive(Debug, Clone)]
pub struct Pi {
    pub gains: PiGains,
    pub limits: ValveLimits,
    dt: f64,
    integral: f64,
    prev_error: Option<f64>,
    prev_u: f64,
    label: String,
}

impl Pi {
    pub fn new(gains: PiGains, limits: ValveLimits, dt: f64, label: impl Into<String>) -> Self {
        Pi {
            gains,
            limits,
            dt,
            integral: 0.0,
            prev_error: None,
            prev_u: 0.0,
            label: label.into(),
        }
    }

    /// The integrator's state (V).
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// Moves the integrator by `dv` volts (a feedforward taking over part of
    /// the command, without a bump).
    pub fn shift_integral(&mut self, dv: f64) {
        self.integral += dv;
    }

    /// The law with a feedforward `ff` (V) added to the command: `u = ff +
    /// I + Kp·e + Kd·ė`, clamped to the limits, with the anti-windup of the
    /// plain PI and the integrator kept where `ff + I` is a valve voltage.
    pub fn command_with(&mut self, m: Measurement, reference: f64, ff: f64) -> f64 {
        let e = reference - m.displacement_mm;
        let de = self.prev_error.map_or(0.0, |p| (e - p) / self.dt);
        self.prev_error = Some(e);
        let raw = ff + self.integral + self.gains.kp * e + self.gains.kd * de;
        let u = self.limits.clamp(raw, self.prev_u);
        let pushing_up = raw > u && e * self.gains.ki > 0.0;
        let pushing_down = raw < u && e * self.gains.ki < 0.0;
        if !(pushing_up || pushing_down) {
            self.integral += self.gains.ki * e * self.dt;
            self.integral = self
                .integral
                .clamp(self.limits.min_v - ff, self.limits.max_v - ff);
        }
        self.prev_u = u;
        u
    }
}

impl Controller for Pi {
    fn name(&self) -> &str {
        &self.label
    }

    /// Bumpless start: the integrator holds the command in force.
    fn reset(&mut self, u0: f64) {
        self.integral = u0.clamp(self.limits.min_v, self.limits.max_v);
        self.prev_u = u0;
        self.prev_error = None;
    }

    fn command(&mut self, m: Measurement, reference: &[f64]) -> f64 {
        self.command_with(m, reference[0], 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meas(y: f64) -> Measurement {
        Measurement {
            pressure_mpa: 0.0,
            displacement_mm: y,
        }
    }

    #[test]
    fn anti_windup_keeps_command_and_integrator_bounded() {
        let limits = ValveLimits::default();
        let mut pi = Pi::new(PiGains::default(), limits, 0.01, "pi");
        pi.reset(5.0);
        let mut prev = 5.0;
        // An unreachable reference for 100 s: the command rides the limit.
        for _ in 0..10_000 {
            let u = pi.command(meas(0.0), &[100.0]);
            assert!(!limits.violated(u, prev), "{prev} -> {u}");
            prev = u;
        }
        assert_eq!(prev, 10.0);
        // Saturated from the first sample on (the slew limit holds the
        // command back): the integrator never moved. Without anti-windup it
        // would hold 5 + 0.05·100·10 000 V.
        assert_eq!(pi.integral(), 5.0);
        // The reference comes back below the output: the command leaves the
        // limit within a few samples instead of unwinding for seconds.
        let mut left_at = None;
        for k in 0..200 {
            let u = pi.command(meas(40.0), &[30.0]);
            assert!(!limits.violated(u, prev));
            prev = u;
            if u < 9.0 && left_at.is_none() {
                left_at = Some(k);
            }
        }
        assert!(left_at.unwrap() < 10, "left the limit at {left_at:?}");
    }

    #[test]
    fn integrates_error_with_table_22_gains() {
        let mut pi = Pi::new(PiGains::default(), ValveLimits::default(), 0.01, "pi");
        pi.reset(5.0);
        // A constant 1 mm error: P gives Kp, the integrator adds 0.05 V per sample.
        let u1 = pi.command(meas(29.0), &[30.0]);
        assert!((u1 - (5.0 + 0.06875)).abs() < 1e-12);
        let u2 = pi.command(meas(29.0), &[30.0]);
        assert!((u2 - (5.0 + 0.05 + 0.06875)).abs() < 1e-12);
    }
}
