//! The hanging load: a mass on the muscle, moving along the muscle's axis,
//! with a support below and a bracket above (the end stops).
//!
//! `m·ẍ = F_p(p, x) + T_rubber(x) − m·g + F_friction − c·ẋ + F_stop(x, ẋ)`,
//! integrated with symplectic (semi-implicit) Euler: velocity first, then
//! position with the new velocity, which keeps the stiff contact and the
//! water column from gaining energy.

use super::config::{Effects, EndStopParams};

/// Contact force of the end stops on the load (N, positive upward): a
/// spring-damper that acts only while the load presses into a stop.
pub fn stop_force(x: f64, v: f64, p: &EndStopParams, fx: &Effects) -> f64 {
    let Some(scale) = fx.endstop.active() else {
        return 0.0;
    };
    let (k, c) = (scale * p.stiffness_n_per_m, scale * p.damping_n_s_per_m);
    if x > p.max_contraction_m {
        // Pressing up into the bracket: push down; damping only resists entry.
        -(k * (x - p.max_contraction_m) + c * v.max(0.0))
    } else if x < p.min_contraction_m {
        k * (p.min_contraction_m - x) - c * v.min(0.0)
    } else {
        0.0
    }
}

/// Position and velocity of the load.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Load {
    pub mass_kg: f64,
    /// Contraction (m).
    pub x: f64,
    /// Contraction rate (m/s).
    pub v: f64,
}

impl Load {
    /// One symplectic Euler step under the net force `force` (N); returns
    /// the displacement of the step.
    pub fn advance(&mut self, force: f64, h: f64) -> f64 {
        self.v += h * force / self.mass_kg;
        let dx = h * self.v;
        self.x += dx;
        dx
    }
}
