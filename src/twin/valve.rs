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

/// Orifice flow (m³/s) from the high to the low side through `opening` (0–1)
/// for a pressure drop `dp` (Pa, may be negative: then the flow reverses).
/// Turbulent `√Δp` law, linear below `laminar_dp_pa` (matched in value at the
/// junction) so the slope stays finite.
pub fn orifice_flow(opening: f64, dp: f64, p: &ValveParams, density: f64) -> f64 {
    let k = p.discharge_coefficient * p.area_max_m2 * opening * (2.0 / density).sqrt();
    let a = dp.abs();
    let mag = if a < p.laminar_dp_pa {
        k * a / p.laminar_dp_pa.sqrt()
    } else {
        k * a.sqrt()
    };
    mag.copysign(dp)
}

/// Slope `dQ/d(dp)` of [`orifice_flow`], for the implicit pressure update.
pub fn orifice_conductance(opening: f64, dp: f64, p: &ValveParams, density: f64) -> f64 {
    let k = p.discharge_coefficient * p.area_max_m2 * opening * (2.0 / density).sqrt();
    let a = dp.abs();
    if a < p.laminar_dp_pa {
        k / p.laminar_dp_pa.sqrt()
    } else {
        0.5 * k / a.sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flow_is_continuous_and_odd() {
        let p = ValveParams::default();
        let below = orifice_flow(1.0, p.laminar_dp_pa * (1.0 - 1e-12), &p, 998.0);
        let above = orifice_flow(1.0, p.laminar_dp_pa, &p, 998.0);
        assert!((below - above).abs() < 1e-12);
        assert_eq!(
            orifice_flow(0.5, -3e5, &p, 998.0),
            -orifice_flow(0.5, 3e5, &p, 998.0)
        );
        assert_eq!(orifice_flow(0.5, 0.0, &p, 998.0), 0.0);
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
