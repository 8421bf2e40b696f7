//! The static force model of §4.2: the geometry of eq. 1, the lossless
//! virtual-work force of eq. 7, and the form with sleeve thickness of eq. 9.
//!
//! Units are SI: lengths in metres, pressures in pascals, forces in newtons.

use serde::{Deserialize, Serialize};

/// The braid of a McKibben muscle (eq. 1): `L = b·cos ψ`, `D = b·sin ψ / (n·π)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Braid {
    /// Thread length `b` (m).
    pub thread_length: f64,
    /// Turns of one thread around the muscle, `n`.
    pub turns: f64,
    /// Combined thickness `t_k` of the sleeve and the inner tube (m), eq. 8–9.
    pub thickness: f64,
}

impl Default for Braid {
    /// A muscle of about 0.33 m rest length and 12–16 mm diameter, the size of
    /// the tap-water muscles of Kobayashi & Ito (thesis refs. 19–21). The
    /// thesis gives no dimensions; these are assumptions, stated so.
    /// `b = 0.35 m`, `n = 3`, `t_k = 1.5 mm`.
    fn default() -> Self {
        Braid {
            thread_length: 0.35,
            turns: 3.0,
            thickness: 1.5e-3,
        }
    }
}

/// The braid angle at which the ideal force vanishes, `cos²ψ = 1/3` (≈ 54.7°):
/// the geometric limit of contraction.
pub fn max_angle() -> f64 {
    (1.0f64 / 3.0).sqrt().acos()
}

impl Braid {
    /// Muscle length at braid angle `psi` (rad), eq. 1.
    pub fn length(&self, psi: f64) -> f64 {
        self.thread_length * psi.cos()
    }

    /// Outer diameter at braid angle `psi` (rad), eq. 1.
    pub fn diameter(&self, psi: f64) -> f64 {
        self.thread_length * psi.sin() / (self.turns * std::f64::consts::PI)
    }

    /// Braid angle for a muscle length (inverse of eq. 1), `None` if the
    /// length exceeds the thread length.
    pub fn angle_at_length(&self, length: f64) -> Option<f64> {
        let c = length / self.thread_length;
        (0.0..=1.0).contains(&c).then(|| c.acos())
    }

    /// Eq. 7: `F = (π P'/4)·(b/(π n))²·(3 cos²ψ − 1)`, gauge pressure `p` (Pa).
    pub fn force_ideal(&self, p: f64, psi: f64) -> f64 {
        let d0 = self.thread_length / (std::f64::consts::PI * self.turns);
        std::f64::consts::PI * p / 4.0 * d0 * d0 * (3.0 * psi.cos().powi(2) - 1.0)
    }

    /// Eq. 9, the force with wall thickness `t_k`:
    /// `F = (b² P'/(4π n²))·(3 cos²ψ − 1) + π t_k P'·[(b/(π n))·(2 sin ψ − 1/sin ψ) − t_k]`.
    ///
    /// The thesis prints the first bracket as `3 cos²ψ` alone; it must reduce
    /// to eq. 7 at `t_k = 0`, so the `− 1` is restored (Chou & Hannaford 1996).
    pub fn force_thick(&self, p: f64, psi: f64) -> f64 {
        let tk = self.thickness;
        let d0 = self.thread_length / (std::f64::consts::PI * self.turns);
        self.force_ideal(p, psi)
            + std::f64::consts::PI * tk * p * (d0 * (2.0 * psi.sin() - 1.0 / psi.sin()) - tk)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thick_form_reduces_to_ideal_at_zero_thickness() {
        let b = Braid {
            thickness: 0.0,
            ..Braid::default()
        };
        for deg in [10.0f64, 25.0, 40.0, 50.0] {
            let psi = deg.to_radians();
            assert!((b.force_thick(3e5, psi) - b.force_ideal(3e5, psi)).abs() < 1e-9);
        }
    }

    #[test]
    fn force_is_linear_in_pressure_and_falls_with_angle() {
        let b = Braid::default();
        let psi = 0.4;
        assert!((b.force_ideal(4e5, psi) - 2.0 * b.force_ideal(2e5, psi)).abs() < 1e-9);
        let mut last = f64::INFINITY;
        for deg in (5..54).step_by(5) {
            let f = b.force_ideal(3e5, (deg as f64).to_radians());
            assert!(f < last);
            last = f;
        }
        assert!(b.force_ideal(3e5, max_angle()).abs() < 1e-6);
        // Thickness costs force.
        assert!(b.force_thick(3e5, 0.4) < b.force_ideal(3e5, 0.4));
    }

    #[test]
    fn geometry_inverts() {
        let b = Braid::default();
        let psi = 0.5;
        assert!((b.angle_at_length(b.length(psi)).unwrap() - psi).abs() < 1e-12);
        assert!(b.angle_at_length(1.0).is_none());
    }
}
