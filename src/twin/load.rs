//! The hanging load: a mass on the muscle, moving along the muscle's axis,
//! with a support below and a bracket above (the end stops).
//!
//! `m·ẍ = F_p(p, x) + T_rubber(x) − m·g + F_friction − c·ẋ + F_stop(x, ẋ)`,
//! integrated with symplectic (semi-implicit) Euler: velocity first, then
//! position with the new velocity, which keeps the stiff contact and the
//! water column from gaining energy.
//!
//! The water in the muscle is all but incompressible, so `x` follows the
//! water that the inlet lets in or out: pushing water through the inlet
//! damps the load far past critical. The `ringing` effect adds what real
//! records show nonetheless, the load swinging on the muscle's own
//! stiffness about that water-set position ([`Ringing`]).

use super::config::{Effects, EndStopParams, MuscleParams};

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

/// The load's ringing: its offset `e` from the water-set contraction `x`,
/// a mass on the muscle's axial stiffness `k` (at the current pressure and
/// contraction) whose base, the water-set end of the muscle, moves with
/// `x`: `m·ë = −k·e − c·ė − s·m·ẍ` with `s` the effect's scale and
/// `c = η·k_rubber/ω`, `ω = √(k/m)`, the rubber's hysteretic loss as the
/// equivalent viscous damping at resonance. The offset does not feed back
/// into the chamber: the flow it would move, `A·ė`, is left out.
///
/// Symplectic Euler as the load: `ω ≈ 40–60 rad/s` against substeps of
/// 50 µs gives `ω·h ≈ 0.003`, far inside its stability limit of 2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ringing {
    /// The effect's scale on the excitation.
    scale: f64,
    /// `η·k_rubber` (N/m), the rubber's loss stiffness.
    loss_stiffness: f64,
    /// Offset `e` of the load from the water-set contraction (m).
    pub offset: f64,
    /// Its rate `ė` (m/s).
    pub rate: f64,
}

impl Ringing {
    /// The load at rest on the muscle; `None` when the effect is removed.
    pub fn new(p: &MuscleParams, fx: &Effects) -> Option<Self> {
        Some(Ringing {
            scale: fx.ringing.active()?,
            loss_stiffness: p.rubber_loss_factor * p.rubber_stiffness_n_per_m,
            offset: 0.0,
            rate: 0.0,
        })
    }

    /// The damping coefficient (N·s/m) for a load of `mass` kg on the
    /// stiffness `k` (N/m): `c = η·k_rubber/ω`, a damping ratio
    /// `ζ = c/(2mω) = η·k_rubber/(2k)`.
    pub fn damping(&self, k: f64, mass: f64) -> f64 {
        self.loss_stiffness / (k / mass).sqrt()
    }

    /// How far the swing unloads the muscle (N) on the stiffness `k`
    /// (N/m): the load above its water-set place shortens the muscle by `e`
    /// and relaxes it by `k·e + c·ė`. Where this passes the tension that
    /// holds the load, the muscle would go slack, which this linear swing
    /// does not model.
    pub fn unloading(&self, k: f64, mass: f64) -> f64 {
        k * self.offset + self.damping(k, mass) * self.rate
    }

    /// Whether the load swings at all: at scale 0 it never leaves its
    /// water-set place.
    pub fn swings(&self) -> bool {
        self.scale != 0.0
    }

    /// One substep of `h` seconds on the stiffness `k` (N/m) while the base
    /// (the water-set contraction) changes its velocity by `base_dv` (m/s).
    pub fn advance(&mut self, k: f64, mass: f64, base_dv: f64, h: f64) {
        let force = -k * self.offset - self.damping(k, mass) * self.rate;
        self.rate += h * force / mass - self.scale * base_dv;
        self.offset += h * self.rate;
    }
}
