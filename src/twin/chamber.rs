//! The water in the muscle chamber and the hose: the pressure rises with the
//! net inflow and falls as the chamber grows,
//! `C·dp/dt = Q_in(p_s − p) − Q_out(p − p_d) − A(x)·ẋ`,
//! with the capacitance `C = V/β_water + C_hose` (water's bulk modulus plus
//! the hose and bladder compliance).
//!
//! Even with the compliance the capacitance is tiny next to the orifice
//! conductances, so the pressure is stiff: each substep solves the update
//! implicitly (backward Euler in `p`, a monotone scalar equation) with a
//! safeguarded Newton iteration.

use super::config::{Effects, HydraulicParams, ValveParams};
use super::valve::{orifice_conductance, orifice_flow};

/// Capacitance `dV/dp` of the water column (m³/Pa) for a chamber volume `v_chamber`.
pub fn capacitance(v_chamber: f64, h: &HydraulicParams, fx: &Effects) -> f64 {
    let water = (v_chamber + h.hose_volume_m3) / h.bulk_modulus_water;
    match fx.compliance.active() {
        Some(scale) => water + scale * h.hose_compliance_m3_per_pa,
        None => water,
    }
}

/// Inputs of one pressure update.
pub struct PressureStep<'a> {
    pub p: f64,
    pub dt: f64,
    pub capacitance: f64,
    /// Open fractions of the input and output valves.
    pub open_in: f64,
    pub open_out: f64,
    /// Volume rate taken by the moving chamber, `A(x)·ẋ` (m³/s).
    pub volume_rate: f64,
    pub valve: &'a ValveParams,
    pub hydraulics: &'a HydraulicParams,
}

impl PressureStep<'_> {
    /// `g(q) = C(q − p)/h − Q_in + Q_out + A·ẋ`, increasing in `q`, and its slope.
    fn residual(&self, q: f64) -> (f64, f64) {
        let h = self.hydraulics;
        let rho = h.density;
        let q_in = orifice_flow(self.open_in, h.supply_pa - q, self.valve, rho);
        let q_out = orifice_flow(self.open_out, q - h.drain_pa, self.valve, rho);
        let g = self.capacitance * (q - self.p) / self.dt - q_in + q_out + self.volume_rate;
        let dg = self.capacitance / self.dt
            + orifice_conductance(self.open_in, h.supply_pa - q, self.valve, rho)
            + orifice_conductance(self.open_out, q - h.drain_pa, self.valve, rho);
        (g, dg)
    }

    /// The pressure at the end of the step: the root of `g`, bracketed by
    /// doubling a window around `p`, then Newton steps that fall back to
    /// bisection when they leave the bracket. Converges to 1e-4 Pa.
    pub fn solve(&self) -> f64 {
        let (g0, _) = self.residual(self.p);
        if g0 == 0.0 {
            return self.p;
        }
        let dir = if g0 > 0.0 { -1.0 } else { 1.0 };
        let mut width = 1e3;
        let (mut lo, mut hi) = (self.p, self.p);
        loop {
            let q = self.p + dir * width;
            let (g, _) = self.residual(q);
            if (g > 0.0) != (g0 > 0.0) || width > 1e9 {
                if dir > 0.0 {
                    hi = q;
                } else {
                    lo = q;
                }
                break;
            }
            if dir > 0.0 {
                lo = q;
            } else {
                hi = q;
            }
            width *= 2.0;
        }
        let mut q = 0.5 * (lo + hi);
        for _ in 0..60 {
            let (g, dg) = self.residual(q);
            if g > 0.0 {
                hi = q;
            } else {
                lo = q;
            }
            let newton = q - g / dg;
            let next = if newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            if (next - q).abs() < 1e-4 {
                return next;
            }
            q = next;
        }
        q
    }
}
