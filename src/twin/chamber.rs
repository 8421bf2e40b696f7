//! The water path, two nodes joined by the muscle's inlet fitting:
//!
//! - the *manifold* between the two valves, where the pressure sensor sits,
//!   with the hose: `C_v·dp_v/dt = Q_in(p_s − p_v) − Q_out(p_v − p_d) − Q_f(p_v − p_m)`;
//! - the *muscle chamber*: `C_m·dp_m/dt = Q_f(p_v − p_m) − A(x)·ẋ`,
//!
//! with capacitances `C = V/β_water (+ C_hose at the manifold)`. The inlet
//! fitting `Q_f` is a restriction of its own: at the 100–200 ml/s the valves
//! pass, a few-millimetre bore drops tens of kPa, so the muscle's pressure
//! (which makes the force) lags the measured one. That lag is the slow pole
//! the thesis' ARX model sees between measured pressure and displacement.
//!
//! The capacitances are tiny next to the orifice conductances (time constants
//! of micro- to milliseconds), so each substep solves both pressures
//! implicitly (backward Euler, a 2×2 monotone system) with Newton's method.

use super::config::{Effects, HydraulicParams};
use super::valve::Orifice;

/// Capacitance `dV/dp` of the manifold node (m³/Pa): the hose's water plus,
/// unless switched off, the hose wall's compliance.
pub fn manifold_capacitance(h: &HydraulicParams, fx: &Effects) -> f64 {
    let water = h.hose_volume_m3 / h.bulk_modulus_water;
    match fx.compliance.active() {
        Some(scale) => water + scale * h.hose_compliance_m3_per_pa,
        None => water,
    }
}

/// Capacitance of the water in the muscle chamber of volume `v` (m³/Pa).
/// The chamber's real compliance, its change of volume with length, is in
/// the mechanics (`A(x)·ẋ`), not here.
pub fn chamber_capacitance(v: f64, h: &HydraulicParams) -> f64 {
    v / h.bulk_modulus_water
}

/// The muscle's inlet fitting as an orifice.
pub fn inlet(h: &HydraulicParams) -> Orifice {
    Orifice {
        area_m2: h.inlet_area_m2,
        discharge_coefficient: h.inlet_discharge_coefficient,
        laminar_dp_pa: h.laminar_dp_pa,
    }
}

/// Inputs of one pressure update.
pub struct PressureStep<'a> {
    /// Manifold and chamber pressures at the start of the step (Pa gauge).
    pub p_manifold: f64,
    pub p_chamber: f64,
    pub dt: f64,
    pub cap_manifold: f64,
    pub cap_chamber: f64,
    pub valve_in: Orifice,
    pub valve_out: Orifice,
    /// Volume rate taken by the moving chamber, `A(x)·ẋ` (m³/s).
    pub volume_rate: f64,
    pub hydraulics: &'a HydraulicParams,
}

impl PressureStep<'_> {
    /// Residuals of the two node equations at `(pv, pm)` and their Jacobian
    /// `[[j11, j12], [j21, j22]]` (an M-matrix: positive diagonal, both
    /// off-diagonals `−G_f`).
    fn residual(&self, pv: f64, pm: f64) -> ([f64; 2], [f64; 3]) {
        let h = self.hydraulics;
        let rho = h.density;
        let fit = inlet(h);
        let (din, dout, df) = (h.supply_pa - pv, pv - h.drain_pa, pv - pm);
        let qf = fit.flow(df, rho);
        let r1 = self.cap_manifold * (pv - self.p_manifold) / self.dt
            - self.valve_in.flow(din, rho)
            + self.valve_out.flow(dout, rho)
            + qf;
        let r2 = self.cap_chamber * (pm - self.p_chamber) / self.dt - qf + self.volume_rate;
        let gf = fit.conductance(df, rho);
        let j11 = self.cap_manifold / self.dt
            + self.valve_in.conductance(din, rho)
            + self.valve_out.conductance(dout, rho)
            + gf;
        let j22 = self.cap_chamber / self.dt + gf;
        ([r1, r2], [j11, gf, j22])
    }

    /// Both pressures at the end of the step, `(manifold, chamber)`: Newton
    /// from the start values, each step limited to 50 kPa so the `√Δp` kinks
    /// cannot throw it far; stops when the update is below 1 mPa.
    pub fn solve(&self) -> (f64, f64) {
        let (mut pv, mut pm) = (self.p_manifold, self.p_chamber);
        for _ in 0..50 {
            let ([r1, r2], [j11, gf, j22]) = self.residual(pv, pm);
            // [j11 −gf; −gf j22]·[dv; dm] = −[r1; r2]
            let det = j11 * j22 - gf * gf;
            let dv = -(r1 * j22 + gf * r2) / det;
            let dm = -(j11 * r2 + gf * r1) / det;
            let big = dv.abs().max(dm.abs());
            let cut = if big > 5e4 { 5e4 / big } else { 1.0 };
            pv += cut * dv;
            pm += cut * dm;
            if big * cut < 1e-3 {
                break;
            }
        }
        (pv, pm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::config::ValveParams;

    #[test]
    fn steady_state_balances_the_valves() {
        // Both valves half open, chamber still: the manifold settles where
        // the two equal orifices split the supply, p_s/2, and the chamber
        // follows it.
        let h = HydraulicParams::default();
        let v = ValveParams::default();
        let fx = Effects::default();
        let (mut pv, mut pm) = (0.0, 0.0);
        for _ in 0..20000 {
            (pv, pm) = PressureStep {
                p_manifold: pv,
                p_chamber: pm,
                dt: 5e-5,
                cap_manifold: manifold_capacitance(&h, &fx),
                cap_chamber: chamber_capacitance(20e-6, &h),
                valve_in: v.orifice(0.5),
                valve_out: v.orifice(0.5),
                volume_rate: 0.0,
                hydraulics: &h,
            }
            .solve();
        }
        assert!((pv - h.supply_pa / 2.0).abs() < 1.0, "{pv}");
        assert!((pm - pv).abs() < 1.0, "{pm}");
    }
}
