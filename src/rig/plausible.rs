//! Whether a measurement can be one: the check every line from a rig passes
//! before a controller sees it. A well-formed line may still carry a value
//! no sensor of the rig can read (`1e308` mm, a glitch, a loose cable) or a
//! displacement the load cannot have travelled in the time since the last
//! plausible sample. Such a sample is refused like a missing one: fed to a
//! controller it would drive the valve anywhere (a PI's integral to ±∞,
//! then NaN).
//!
//! Pressure has a range but no speed limit: on the twin one sample can
//! move it by a good share of its span, and with a faster valve it could
//! cross the whole span, so a limit would either never bind or refuse real
//! samples.

use super::protocol::Ranges;
use crate::control::Measurement;
use crate::data::readable;
use crate::twin::TwinConfig;

/// What the physics allows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    pub ranges: Ranges,
    /// Fastest the displacement can change (mm/s).
    pub max_speed_mm_s: f64,
}

impl Limits {
    /// The default limit: several times the fastest the twin's load moves,
    /// full valve either way, under any load it takes (docs/RIG_PROTOCOL.md,
    /// "Implausible measurements"), so that only a jump no load can make is
    /// refused.
    pub const DEFAULT_MAX_SPEED_MM_S: f64 = 500.0;

    /// Noise and quantization may move a reading this far (mm) on top of the
    /// travel: many standard deviations of the twin's 0.03 mm noise plus a
    /// few ADC steps, small against any jump worth refusing.
    const SLACK_MM: f64 = 0.5;

    /// The twin's own limits: pressure between the drain and the supply,
    /// displacement between the end stops, each widened by a tenth of its
    /// span for noise, the valves' overshoot and the stops' give.
    pub fn of_twin(config: &TwinConfig) -> Limits {
        let widen = |lo: f64, hi: f64| {
            let m = 0.1 * (hi - lo);
            (lo - m, hi + m)
        };
        let h = &config.hydraulics;
        let e = &config.endstop;
        Limits {
            ranges: Ranges {
                // Widened in Pa, then divided: READY then shows 0.44, not
                // 0.43999999999999995.
                pressure_mpa: {
                    let (lo, hi) = widen(h.drain_pa, h.supply_pa);
                    (lo / 1e6, hi / 1e6)
                },
                displacement_mm: widen(e.min_contraction_m * 1e3, e.max_contraction_m * 1e3),
            },
            max_speed_mm_s: Self::DEFAULT_MAX_SPEED_MM_S,
        }
    }
}

/// The check, with the last plausible sample to measure jumps from.
#[derive(Debug, Clone)]
pub struct Plausibility {
    limits: Limits,
    dt: f64,
    /// The last plausible sample and its displacement (mm).
    last: Option<(usize, f64)>,
}

impl Plausibility {
    /// A check for a rig with sample time `dt` (s).
    pub fn new(limits: Limits, dt: f64) -> Plausibility {
        Plausibility {
            limits,
            dt,
            last: None,
        }
    }

    /// Checks the measurement that closes sample `k − 1`; says why it cannot
    /// be one. A plausible one becomes the sample the next jump is measured
    /// from; an implausible one leaves it.
    pub fn check(&mut self, k: usize, m: &Measurement) -> Result<(), Implausible> {
        let r = &self.limits.ranges;
        let outside = |v: f64, (lo, hi): (f64, f64)| !(lo..=hi).contains(&v);
        if outside(m.pressure_mpa, r.pressure_mpa) {
            return Err(Implausible::Pressure {
                mpa: m.pressure_mpa,
                range: r.pressure_mpa,
            });
        }
        if outside(m.displacement_mm, r.displacement_mm) {
            return Err(Implausible::Displacement {
                mm: m.displacement_mm,
                range: r.displacement_mm,
            });
        }
        if let Some((j, x)) = self.last {
            let seconds = k.saturating_sub(j) as f64 * self.dt;
            let allowed = self.limits.max_speed_mm_s * seconds + Limits::SLACK_MM;
            let jump = (m.displacement_mm - x).abs();
            if jump > allowed {
                return Err(Implausible::Jump {
                    mm: jump,
                    since: j,
                    from_mm: x,
                    allowed_mm: allowed,
                    seconds,
                    max_speed_mm_s: self.limits.max_speed_mm_s,
                });
            }
        }
        self.last = Some((k, m.displacement_mm));
        Ok(())
    }
}

/// Why a measurement cannot be one the rig read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Implausible {
    #[error("pressure {} MPa is outside the rig's range {}…{} MPa", readable(*mpa), range.0, range.1)]
    Pressure { mpa: f64, range: (f64, f64) },
    #[error(
        "displacement {} mm is outside the rig's range {}…{} mm",
        readable(*mm),
        range.0,
        range.1
    )]
    Displacement { mm: f64, range: (f64, f64) },
    /// A displacement farther from sample `since`'s than the load can
    /// travel in the time between.
    #[error(
        "displacement moved {} mm since sample {since} ({from_mm} mm), more than the \
         {allowed_mm} mm the load can travel in {seconds} s at {max_speed_mm_s} mm/s",
        readable(*mm)
    )]
    Jump {
        mm: f64,
        since: usize,
        from_mm: f64,
        allowed_mm: f64,
        seconds: f64,
        max_speed_mm_s: f64,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(pressure_mpa: f64, displacement_mm: f64) -> Measurement {
        Measurement {
            pressure_mpa,
            displacement_mm,
        }
    }

    #[test]
    fn the_twins_ranges_hold_its_end_stops_and_supply() {
        let l = Limits::of_twin(&TwinConfig::default());
        let close =
            |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9;
        assert!(close(l.ranges.pressure_mpa, (-0.04, 0.44)), "{l:?}");
        assert!(close(l.ranges.displacement_mm, (-10.5, 55.5)), "{l:?}");
    }

    #[test]
    fn values_outside_the_ranges_and_impossible_jumps_are_refused() {
        let mut p = Plausibility::new(Limits::of_twin(&TwinConfig::default()), 0.01);
        assert!(p.check(1, &m(0.2, 25.0)).is_ok());
        for bad in [m(0.2, 1e308), m(0.2, -1e308), m(1e308, 25.0), m(-0.5, 25.0)] {
            let err = p.check(2, &bad).unwrap_err();
            assert!(
                matches!(
                    err,
                    Implausible::Pressure { .. } | Implausible::Displacement { .. }
                ),
                "{bad:?}"
            );
            assert!(err.to_string().contains("outside"), "{err}");
        }
        // 5 mm a sample at 500 mm/s, plus the slack; refused samples leave
        // the reference where it was, so two samples on allow twice as much.
        let err = p.check(2, &m(0.2, 30.6)).unwrap_err();
        assert!(matches!(err, Implausible::Jump { since: 1, .. }), "{err:?}");
        assert!(err.to_string().contains("since sample 1 (25 mm)"), "{err}");
        assert!(p.check(3, &m(0.2, 1e-300)).is_err());
        assert!(p.check(3, &m(0.2, 35.0)).is_ok());
        assert!(p.check(4, &m(0.2, 39.5)).is_ok());
    }
}
