//! What a controller drives: anything that takes an input valve voltage per
//! sample and returns measured pressure and displacement. The rig twin
//! (`crate::twin::Rig`) is the plant of record; [`StandIn`] is a small plant
//! made from the project's own model for fast tests.

use crate::model::FittedBaseline;
use crate::model::sim::Stepper;

/// Measured values at one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement {
    /// Muscle pressure (MPa).
    pub pressure_mpa: f64,
    /// Muscle displacement (mm).
    pub displacement_mm: f64,
}

/// A sampled plant driven by the input valve voltage (the output valve is
/// driven at `10 − u` by the plant itself).
pub trait Plant {
    /// Sample time (s).
    fn dt(&self) -> f64;
    /// Holds `valve_in_volts` for one sample and returns the measurement at
    /// the end of it.
    fn step(&mut self, valve_in_volts: f64) -> Measurement;
}

/// A plant built from a fitted displacement model (pressure → displacement,
/// `model::sim`) fed by a first-order valve → pressure map:
/// `p(k+1) = pole·p(k) + (1 − pole)·(p_lo + (p_hi − p_lo)·u/10)`.
/// Noise-free and deterministic; for tests and examples, not a rig.
#[derive(Debug, Clone)]
pub struct StandIn {
    model: FittedBaseline,
    stepper: Stepper,
    dt: f64,
    /// Pole of the valve → pressure lag.
    pub pressure_pole: f64,
    /// Static pressure at 0 V and at 10 V (MPa).
    pub pressure_range: (f64, f64),
    p: f64,
    x: f32,
    w: f32,
}

impl StandIn {
    /// Starts at rest with the valve at `u0` volts: pressure at its static
    /// value, the displacement model's state at `x = 0`, `w = 0`.
    pub fn new(
        model: FittedBaseline,
        pressure_pole: f64,
        pressure_range: (f64, f64),
        u0: f64,
    ) -> Self {
        let theta: Vec<f32> = model.params.iter().map(|&v| v as f32).collect();
        let stepper = Stepper::new(model.family, &theta, model.output_mean as f32);
        let dt = model.dt;
        let mut plant = StandIn {
            model,
            stepper,
            dt,
            pressure_pole,
            pressure_range,
            p: 0.0,
            x: 0.0,
            w: 0.0,
        };
        plant.p = plant.static_pressure(u0);
        plant
    }

    /// A rig-like stand-in: the thesis' classic parameters (Table 1 with the
    /// linear part of eq. 12) around 0.25 MPa and 30 mm, a 50 ms valve →
    /// pressure lag and 0.15–0.35 MPa over the valve range, sampled at 10 ms.
    pub fn thesis_like(u0: f64) -> Self {
        let family = crate::model::Family::Classic;
        let model = FittedBaseline {
            family,
            params: crate::model::presets::thesis_params(family),
            input_mean: 0.25,
            output_mean: 30.0,
            dt: 0.01,
            input_name: "pressure".into(),
            output_name: "displacement".into(),
        };
        StandIn::new(model, (-0.01f64 / 0.05).exp(), (0.15, 0.35), u0)
    }

    fn static_pressure(&self, u: f64) -> f64 {
        let (lo, hi) = self.pressure_range;
        lo + (hi - lo) * u.clamp(0.0, 10.0) / 10.0
    }
}

impl Plant for StandIn {
    fn dt(&self) -> f64 {
        self.dt
    }

    fn step(&mut self, valve_in_volts: f64) -> Measurement {
        // Displacement responds to the pressure of the previous sample (eq. 13).
        let u_dev = (self.p - self.model.input_mean) as f32;
        (self.x, self.w) = self.stepper.step(self.x, self.w, u_dev);
        let target = self.static_pressure(valve_in_volts);
        self.p = self.pressure_pole * self.p + (1.0 - self.pressure_pole) * target;
        Measurement {
            pressure_mpa: self.p,
            displacement_mm: self.x as f64 + self.model.output_mean,
        }
    }
}

/// The rig twin is the plant of record.
impl Plant for crate::twin::Rig {
    fn dt(&self) -> f64 {
        crate::twin::Rig::dt(self)
    }

    fn step(&mut self, valve_in_volts: f64) -> Measurement {
        let s = crate::twin::Rig::step(self, valve_in_volts);
        Measurement {
            pressure_mpa: s.pressure_mpa,
            displacement_mm: s.displacement_mm,
        }
    }
}
