//! The proportional valves: a command in volts moves the spool through a
//! first-order lag; past the dead band the orifice opens in proportion; the
//! flow follows the orifice law `Q = C_d·A·√(2Δp/ρ)`.

use super::config::{Effects, ValveParams};

/// One proportional valve's spool.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Valve {
    /// Spool position in command volts (what the spool has reached).
    spool_v: f64,
}

impl Valve {
    /// A valve whose spool already sits at `command_v`.
    pub fn at(command_v: f64) -> Self {
        Valve { spool_v: command_v }
    }

    /// The spool position (V).
    pub fn spool_v(&self) -> f64 {
        self.spool_v
    }

    /// Advances the spool by `h` seconds toward `command_v` with the exact
    /// solution of the first-order lag, written as `u + e^{−h/τ}(s − u)` so a
    /// zero time constant lands exactly on the command.
    pub fn advance(&mut self, command_v: f64, h: f64, p: &ValveParams, fx: &Effects) {
        self.spool_v = match fx.spool_lag.active() {
            Some(scale) => {
                let tau = p.spool_tau_s * scale;
                let decay = (-h / tau).exp();
                command_v + decay * (self.spool_v - command_v)
            }
            None => command_v,
        };
    }

    /// Open fraction of the orifice, 0–1: zero inside the dead band, then linear.
    pub fn opening(&self, p: &ValveParams, fx: &Effects) -> f64 {
        let s = self.spool_v.clamp(0.0, p.full_scale_v);
        match fx.deadband.active() {
            Some(scale) => {
                let db = p.deadband_v * scale;
                ((s - db) / (p.full_scale_v - db)).clamp(0.0, 1.0)
            }
            None => s / p.full_scale_v,
        }
    }
}

/// A sharp-edged orifice: turbulent `Q = C_d·A·√(2|Δp|/ρ)·sgn Δp`, linear
/// below `laminar_dp_pa` (matched in value at the junction) so the slope
/// stays finite at zero drop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Orifice {
    pub area_m2: f64,
    pub discharge_coefficient: f64,
    pub laminar_dp_pa: f64,
}

impl Orifice {
    fn k(&self, density: f64) -> f64 {
        self.discharge_coefficient * self.area_m2 * (2.0 / density).sqrt()
    }

    /// Flow (m³/s) from the high to the low side for a drop `dp` (Pa; a
    /// negative drop reverses the flow).
    pub fn flow(&self, dp: f64, density: f64) -> f64 {
        let a = dp.abs();
        let mag = if a < self.laminar_dp_pa {
            self.k(density) * a / self.laminar_dp_pa.sqrt()
        } else {
            self.k(density) * a.sqrt()
        };
        mag.copysign(dp)
    }

    /// Slope `dQ/d(dp)` of [`Orifice::flow`], for the implicit pressure update.
    pub fn conductance(&self, dp: f64, density: f64) -> f64 {
        let a = dp.abs();
        if a < self.laminar_dp_pa {
            self.k(density) / self.laminar_dp_pa.sqrt()
        } else {
            0.5 * self.k(density) / a.sqrt()
        }
    }
}

impl ValveParams {
    /// The valve's orifice at open fraction `opening` (0–1).
    pub fn orifice(&self, opening: f64) -> Orifice {
        Orifice {
            area_m2: self.area_max_m2 * opening,
            discharge_coefficient: self.discharge_coefficient,
            laminar_dp_pa: self.laminar_dp_pa,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flow_is_continuous_and_odd() {
        let p = ValveParams::default();
        let o = p.orifice(1.0);
        let below = o.flow(p.laminar_dp_pa * (1.0 - 1e-12), 998.0);
        let above = o.flow(p.laminar_dp_pa, 998.0);
        assert!((below - above).abs() < 1e-12);
        let half = p.orifice(0.5);
        assert_eq!(half.flow(-3e5, 998.0), -half.flow(3e5, 998.0));
        assert_eq!(half.flow(0.0, 998.0), 0.0);
        let h = 1e-3;
        let slope = (half.flow(3e5 + h, 998.0) - half.flow(3e5 - h, 998.0)) / (2.0 * h);
        assert!((slope - half.conductance(3e5, 998.0)).abs() < 1e-6 * slope);
    }

    #[test]
    fn dead_band_shuts_the_valve() {
        let p = ValveParams::default();
        let fx = Effects::default();
        assert_eq!(Valve::at(0.5).opening(&p, &fx), 0.0);
        assert!(Valve::at(1.0).opening(&p, &fx) > 0.0);
        assert_eq!(Valve::at(10.0).opening(&p, &fx), 1.0);
    }
}
