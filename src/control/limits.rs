//! The actuator's limits: the valve voltage range and a slew limit.

use serde::{Deserialize, Serialize};

/// Limits every controller must respect on the input valve voltage.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ValveLimits {
    /// Lowest valve voltage (V): the proportional valves take 0–10 V (§3, A.1.1).
    pub min_v: f64,
    /// Highest valve voltage (V).
    pub max_v: f64,
    /// Largest change of the command from one sample to the next (V per
    /// sample). The thesis' CVXGEN template (figure 33) has a slew limit `S`
    /// but gives no value; 0.25 V per 10 ms sample (25 V/s, a full stroke in
    /// 0.4 s) is our choice: faster than any command a 3 rad/s sine needs,
    /// slow enough to spare the valves and hoses water hammer.
    pub slew_v_per_step: f64,
}

impl Default for ValveLimits {
    fn default() -> Self {
        ValveLimits {
            min_v: 0.0,
            max_v: 10.0,
            slew_v_per_step: 0.25,
        }
    }
}

/// Tolerance below which an excursion past a limit counts as rounding, not as
/// a violation (V).
pub const TOLERANCE_V: f64 = 1e-6;

impl ValveLimits {
    /// The interval the next command may take, given the previous one.
    pub fn window(&self, prev: f64) -> (f64, f64) {
        let lo = self.min_v.max(prev - self.slew_v_per_step);
        let hi = self.max_v.min(prev + self.slew_v_per_step);
        (lo, hi.max(lo))
    }

    /// Clamps `u` into [`ValveLimits::window`] of `prev`.
    pub fn clamp(&self, u: f64, prev: f64) -> f64 {
        let (lo, hi) = self.window(prev);
        u.clamp(lo, hi)
    }

    /// Whether the step `prev → u` breaks a limit by more than [`TOLERANCE_V`].
    pub fn violated(&self, u: f64, prev: f64) -> bool {
        !u.is_finite()
            || u < self.min_v - TOLERANCE_V
            || u > self.max_v + TOLERANCE_V
            || (u - prev).abs() > self.slew_v_per_step + TOLERANCE_V
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_honours_range_and_slew() {
        let l = ValveLimits::default();
        assert_eq!(l.window(5.0), (4.75, 5.25));
        assert_eq!(l.window(9.9), (9.65, 10.0));
        assert_eq!(l.clamp(-3.0, 0.1), 0.0);
        assert!(l.violated(5.3, 5.0));
        assert!(!l.violated(5.25, 5.0));
        assert!(l.violated(10.1, 10.0));
        assert!(l.violated(f64::NAN, 5.0));
    }
}
