//! Braid friction as a Maxwell-slip model: `N` elements in parallel, each a
//! spring of stiffness `k_i` in series with a Coulomb slider of break-away
//! force `f_i`. An element sticks (its spring deflects with the motion) until
//! `|k_i·z_i|` reaches `f_i`, then slides. The output depends on the path of
//! the motion, not its speed: rate-independent hysteresis with rounded
//! corners, the behaviour Chou & Hannaford and Tondu & Lopez measured on
//! braided muscles, and not the Bouc-Wen model the project identifies.

use super::config::{Effects, FrictionParams};

#[derive(Debug, Clone, PartialEq)]
pub struct MaxwellSlip {
    /// Break-away share of each element in the total (sums to 1).
    share: Vec<f64>,
    /// Pre-sliding deflection `δ_i` of each element (m).
    slip: Vec<f64>,
    /// Spring deflections `z_i` (m), `|z_i| ≤ δ_i`.
    deflection: Vec<f64>,
}

impl MaxwellSlip {
    /// Elements of equal break-away share, all springs relaxed.
    pub fn new(p: &FrictionParams) -> Self {
        let n = p.slip_deflection_m.len();
        MaxwellSlip {
            share: vec![1.0 / n as f64; n],
            slip: p.slip_deflection_m.clone(),
            deflection: vec![0.0; n],
        }
    }

    /// Total break-away force at gauge pressure `p_pa` (N), before scaling.
    pub fn break_force(p: &FrictionParams, p_pa: f64) -> f64 {
        p.break_force_n + p.break_force_per_mpa * p_pa.max(0.0) * 1e-6
    }

    /// Friction force on the load now (N): element `i` carries
    /// `f_i·z_i/δ_i` with `f_i` its share of the break-away force at pressure
    /// `p_pa`, so its stiffness `f_i/δ_i` grows with pressure like the force
    /// pressing the threads together. Zero when the effect is removed.
    pub fn current_force(&self, p_pa: f64, p: &FrictionParams, fx: &Effects) -> f64 {
        let Some(scale) = fx.friction.active() else {
            return 0.0;
        };
        let total = scale * Self::break_force(p, p_pa);
        let mut force = 0.0;
        for ((z, share), slip) in self.deflection.iter().zip(&self.share).zip(&self.slip) {
            force -= share * total * (z / slip);
        }
        force
    }

    /// Moves every element by `dx` (m): a stuck spring deflects with the
    /// motion, a spring at `±δ_i` slides. Nothing moves when the effect is removed.
    pub fn slide(&mut self, dx: f64, fx: &Effects) {
        if fx.friction.active().is_none() {
            return;
        }
        for (z, slip) in self.deflection.iter_mut().zip(&self.slip) {
            *z = (*z + dx).clamp(-slip, *slip);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loop_is_rate_independent_and_bounded() {
        let p = FrictionParams::default();
        let fx = Effects::default();
        let run = |steps: usize| {
            let mut m = MaxwellSlip::new(&p);
            // Out 5 mm and back 2.5 mm, in `steps` equal moves each way.
            for _ in 0..steps {
                m.slide(5e-3 / steps as f64, &fx);
            }
            let top = m.current_force(2e5, &p, &fx);
            for _ in 0..steps {
                m.slide(-2.5e-3 / steps as f64, &fx);
            }
            (top, m.current_force(2e5, &p, &fx))
        };
        let (top_a, end_a) = run(50);
        let (top_b, end_b) = run(500);
        let fb = MaxwellSlip::break_force(&p, 2e5);
        assert!(
            (top_a + fb).abs() < 1e-9,
            "fully slipping: {top_a} vs −{fb}"
        );
        assert!((top_a - top_b).abs() < 1e-9 && (end_a - end_b).abs() < 1e-9);
        assert!(end_a > 0.0 && end_a < fb);
    }
}
