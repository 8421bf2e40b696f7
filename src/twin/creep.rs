//! Creep of the bladder: the rubber as a standard linear solid. Its tension
//! is a relaxed spring `k_∞·(L − L_nat)` (in [`super::muscle`]) plus one
//! Maxwell arm, a spring `k_1` in series with a dashpot of relaxation time
//! `τ`, with `k_∞ + k_1 = k_rubber`. A sudden stretch meets the whole
//! `k_rubber`; held, the arm's spring relaxes through its dashpot and only
//! `k_∞` remains. Under a held pressure the muscle therefore contracts fast
//! on the whole stiffness, then creeps further as the arm lets go, and on
//! release comes back the same way.
//!
//! The arm's spring extension `w` follows the rubber's stretch
//! `s = L − L_nat` (`ṡ = −ẋ`) and drains through the dashpot:
//! `ẇ = −ẋ − w/τ`. Each substep moves it with the load's displacement and
//! then decays it exactly over the step, `w ← (w − dx)·e^{−h/τ}`, stable for
//! any step.

use super::config::{Effects, MuscleParams};

/// The Maxwell arm of the rubber; built only while the `creep` effect is in
/// the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BladderCreep {
    /// Stiffness of the arm's spring, `k_1` (N/m).
    stiffness: f64,
    /// `e^{−h/τ}`, the share of the arm's extension left after one substep.
    decay: f64,
    /// Extension of the arm's spring, `w` (m); 0 at rest, the load having
    /// hung long enough for the arm to relax.
    extension: f64,
}

impl BladderCreep {
    /// The arm for substeps of `h` seconds, relaxed; `None` when the effect
    /// is removed (its code path skipped).
    pub fn new(p: &MuscleParams, fx: &Effects, h: f64) -> Option<Self> {
        fx.creep.active()?;
        Some(BladderCreep {
            stiffness: p.relaxing_share(fx) * p.rubber_stiffness_n_per_m,
            decay: (-h / p.creep_time_s).exp(),
            extension: 0.0,
        })
    }

    /// The arm's share of the rubber's tension (N, upward on the load while
    /// the arm is stretched).
    pub fn tension(&self) -> f64 {
        self.stiffness * self.extension
    }

    /// Moves the arm with a contraction `dx` (m) of the load, then lets its
    /// dashpot relax it over the substep.
    pub fn advance(&mut self, dx: f64) {
        self.extension = (self.extension - dx) * self.decay;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_held_stretch_relaxes_with_the_documented_time() {
        let p = MuscleParams::default();
        let mut fx = Effects::default();
        fx.set("creep", 1.0).unwrap();
        let h = 1e-3;
        let mut arm = BladderCreep::new(&p, &fx, h).unwrap();
        // Contract 1 mm at once, then hold for one relaxation time.
        arm.advance(1e-3);
        let start = arm.tension();
        let steps = (p.creep_time_s / h).round() as usize;
        for _ in 0..steps {
            arm.advance(0.0);
        }
        let k1 = p.creep_share * p.rubber_stiffness_n_per_m;
        assert!(start < 0.0 && (start + k1 * 1e-3).abs() < 1e-3 * k1 * 1e-3);
        let left = arm.tension() / start;
        assert!((left - (-1f64).exp()).abs() < 1e-9, "{left}");
    }
}
