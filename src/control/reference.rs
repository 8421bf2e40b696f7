//! The reference of appendix A.1.2: `r(t) = bias + amplitude·sin(ω·t)`
//! (the appendix's code omits `t` inside `sin`, an erratum of the thesis).

use serde::{Deserialize, Serialize};

/// A sine reference for the displacement.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SineReference {
    /// Mean displacement (mm): 30 in §6.2.2.
    pub bias_mm: f64,
    /// Amplitude (mm): 10 in §6.2.2.
    pub amplitude_mm: f64,
    /// Angular frequency (rad/s): 1, 2 or 3 in §6.2.2.
    pub omega_rad_s: f64,
}

impl SineReference {
    /// The thesis' reference at `omega` rad/s (10 mm amplitude, 30 mm bias).
    pub fn thesis(omega_rad_s: f64) -> Self {
        SineReference {
            bias_mm: 30.0,
            amplitude_mm: 10.0,
            omega_rad_s,
        }
    }

    /// The reference at time `t` (s); before `t = 0` it rests at the bias.
    pub fn at(&self, t: f64) -> f64 {
        if t < 0.0 {
            self.bias_mm
        } else {
            self.bias_mm + self.amplitude_mm * (self.omega_rad_s * t).sin()
        }
    }
}
