//! The muscle's geometry and forces: the braid of eq. 1 sets length, angle
//! and chamber volume; the pressure force is eq. 9 (eq. 7 when the wall
//! thickness is switched off); the rubber tube adds a linear elastic force,
//! part of which relaxes slowly when the `creep` effect is on
//! ([`super::creep`]).
//!
//! Position is the contraction `x` (m), positive when the muscle shortens,
//! measured from the rest length `L_rest` at zero gauge pressure with the
//! load hanging: `L = L_rest − x`.

use super::config::{Effects, GRAVITY, MuscleParams};
use crate::model::static_force::Braid;

/// The muscle under one load.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Muscle {
    /// The braid with the wall thickness the effects switches leave.
    braid: Braid,
    /// Eq. 9 (thickness present) or eq. 7 (thickness removed).
    thick: bool,
    /// Length of the unloaded, unpressurised rubber (m).
    natural_length: f64,
    /// Length at zero gauge pressure with the load hanging long enough for
    /// the rubber to relax (m).
    rest_length: f64,
    /// The rubber's instantaneous axial stiffness (N/m).
    stiffness: f64,
    /// Its relaxed stiffness (N/m): all of it unless the `creep` effect
    /// hands a share to the Maxwell arm of [`super::creep::BladderCreep`].
    relaxed_stiffness: f64,
}

impl Muscle {
    pub fn new(p: &MuscleParams, load_kg: f64, fx: &Effects) -> Self {
        let mut braid = p.braid;
        let thick = match fx.thickness.active() {
            Some(scale) => {
                braid.thickness *= scale;
                true
            }
            None => {
                braid.thickness = 0.0;
                false
            }
        };
        let natural_length = braid.length(p.natural_angle_rad);
        let relaxed_stiffness = p.rubber_stiffness_n_per_m * (1.0 - p.relaxing_share(fx));
        let rest_length = natural_length + load_kg * GRAVITY / relaxed_stiffness;
        Muscle {
            braid,
            thick,
            natural_length,
            rest_length,
            stiffness: p.rubber_stiffness_n_per_m,
            relaxed_stiffness,
        }
    }

    /// Length at rest under the load (m).
    pub fn rest_length(&self) -> f64 {
        self.rest_length
    }

    /// Muscle length at contraction `x` (m).
    pub fn length(&self, x: f64) -> f64 {
        self.rest_length - x
    }

    /// Braid angle at contraction `x` (eq. 1 inverted). Lengths beyond the
    /// thread length (impossible: the braid is straight) are held at ψ = 0+.
    pub fn angle(&self, x: f64) -> f64 {
        let c = (self.length(x) / self.braid.thread_length).clamp(-1.0, 1.0 - 1e-9);
        c.acos()
    }

    /// The contraction at which the braid reaches its geometric limit
    /// `cos²ψ = 1/3`, where the ideal force vanishes (m).
    pub fn geometric_limit(&self) -> f64 {
        self.rest_length - self.braid.length(crate::model::static_force::max_angle())
    }

    /// Axial force of the pressure `p` (Pa gauge) at contraction `x` (N):
    /// eq. 9, or eq. 7 without thickness. By virtual work this is also
    /// `p·dV/dx`, so [`Muscle::effective_area`] is the same formula at 1 Pa.
    pub fn pressure_force(&self, p: f64, x: f64) -> f64 {
        let psi = self.angle(x);
        if self.thick {
            self.braid.force_thick(p, psi)
        } else {
            self.braid.force_ideal(p, psi)
        }
    }

    /// `dV/dx` (m²): the chamber volume gained per metre of contraction.
    pub fn effective_area(&self, x: f64) -> f64 {
        self.pressure_force(1.0, x)
    }

    /// Chamber volume inside the wall (m³), eq. 8: `π/4·L·(D − 2t_k)²`.
    pub fn volume(&self, x: f64) -> f64 {
        let psi = self.angle(x);
        let d = self.braid.diameter(psi) - 2.0 * self.braid.thickness;
        std::f64::consts::PI / 4.0 * self.braid.length(psi) * d * d
    }

    /// Tension of the rubber tube's relaxed spring (N): `k_∞·(L − L_nat)`,
    /// which with the load's weight `k_∞·(L_rest − L_nat)` leaves `−k_∞·x`
    /// as the net spring force. Without creep `k_∞` is the whole `k`; with
    /// it, the creep arm adds the rest of the rubber's tension.
    pub fn rubber_tension(&self, x: f64) -> f64 {
        self.relaxed_stiffness * (self.length(x) - self.natural_length)
    }

    /// The muscle's axial stiffness at gauge pressure `p` and contraction
    /// `x` (N/m), the force lost per metre of contraction at constant
    /// pressure: `k = k_rubber − ∂F_p/∂x`. The pressure force falls as the
    /// braid angle opens, so `k` grows with pressure. The rubber counts
    /// whole (its creep arm has no time to relax within a period); the slope
    /// of the pressure force is a central difference over ±1 µm.
    pub fn axial_stiffness(&self, p: f64, x: f64) -> f64 {
        let h = 1e-6;
        let slope = (self.pressure_force(p, x + h) - self.pressure_force(p, x - h)) / (2.0 * h);
        self.stiffness - slope
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn effective_area_is_the_volume_slope() {
        let m = Muscle::new(&MuscleParams::default(), 4.5, &Effects::default());
        for x in [0.0, 0.01, 0.03, 0.05] {
            let h = 1e-7;
            let slope = (m.volume(x + h) - m.volume(x - h)) / (2.0 * h);
            let a = m.effective_area(x);
            assert!((slope - a).abs() < 1e-6 * a.abs(), "x={x}: {slope} vs {a}");
        }
    }

    #[test]
    fn load_stretches_the_rest_length() {
        let fx = Effects::default();
        let p = MuscleParams::default();
        let light = Muscle::new(&p, 4.5, &fx);
        let heavy = Muscle::new(&p, 7.0, &fx);
        assert!(heavy.rest_length() > light.rest_length());
        assert!((light.rubber_tension(0.0) - 4.5 * GRAVITY).abs() < 1e-9);
    }

    #[test]
    fn creep_relaxes_the_rest_length_but_not_the_instant_stiffness() {
        let p = MuscleParams::default();
        let mut fx = Effects::default();
        let plain = Muscle::new(&p, 4.5, &fx);
        fx.set("creep", 1.0).unwrap();
        let creeping = Muscle::new(&p, 4.5, &fx);
        let relaxed = p.rubber_stiffness_n_per_m * (1.0 - p.creep_share);
        let stretch = 4.5 * GRAVITY * (1.0 / relaxed - 1.0 / p.rubber_stiffness_n_per_m);
        assert!((creeping.rest_length() - plain.rest_length() - stretch).abs() < 1e-12);
        assert!((creeping.rubber_tension(0.0) - 4.5 * GRAVITY).abs() < 1e-9);
        // At zero pressure only the rubber resists.
        assert!((creeping.axial_stiffness(0.0, 0.01) - p.rubber_stiffness_n_per_m).abs() < 1e-6);
        assert!(plain.axial_stiffness(2e5, 0.02) > p.rubber_stiffness_n_per_m + 1e3);
    }
}
