//! The rig twin: a physically based simulator of the thesis' tap-water
//! McKibben rig (chapters 3, 4.2, 6.1), the stand-in for the real rig.
//!
//! Parts, one module each: [`valve`] (two proportional valves, dead band,
//! spool lag, orifice flow), [`chamber`] (water pressure with bulk modulus
//! and hose compliance), [`muscle`] (eq. 1–9 geometry and force, rubber
//! elasticity), [`creep`] (the rubber's slow relaxation), [`friction`]
//! (Maxwell-slip braid friction), [`load`] (the hanging mass, its ringing
//! and its end stops), [`sensors`] (noise and quantization),
//! [`experiment`] (the stair, sine and multisine runs), [`config`] (every
//! parameter and the effect switches).
//!
//! Units at the interface: valve commands in volts (0–10), pressure in MPa
//! gauge, displacement in mm, contraction positive, measured from the rest
//! length at zero gauge pressure with the load hanging.
//!
//! ```
//! use mckibben::twin::{Rig, TwinConfig};
//! let mut rig = Rig::new(&TwinConfig::default(), 4.5, 1);
//! let s = rig.step(10.0);
//! assert!((s.t - rig.dt()).abs() < 1e-12 && s.valve_out == 0.0);
//! ```

pub mod chamber;
pub mod config;
pub mod creep;
pub mod experiment;
pub mod friction;
pub mod load;
pub mod muscle;
pub mod sensors;
pub mod valve;

pub use config::{EFFECT_NAMES, EffectScale, Effects, TwinConfig, TwinError};
pub use experiment::{TwinExperiment, run};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use chamber::PressureStep;
use config::GRAVITY;
use creep::BladderCreep;
use friction::MaxwellSlip;
use load::{Load, Ringing};
use muscle::Muscle;
use valve::Valve;

/// One sample as the controller board sees it: the valve commands held from
/// this instant and the sensors' readings at it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Time (s).
    pub t: f64,
    /// Input-valve command (V, 0–10, after clamping).
    pub valve_in: f64,
    /// Output-valve command, `10 − valve_in` (V).
    pub valve_out: f64,
    /// Measured chamber pressure (MPa gauge), with sensor noise and quantization.
    pub pressure_mpa: f64,
    /// Measured displacement (mm, contraction positive), with noise and quantization.
    pub displacement_mm: f64,
}

/// The true (noise-free) state, for tests and diagnostics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrueState {
    pub t: f64,
    /// Manifold pressure, where the sensor sits (Pa gauge).
    pub pressure_pa: f64,
    /// Pressure inside the muscle (Pa gauge), behind the inlet fitting.
    pub chamber_pressure_pa: f64,
    /// Contraction (m): the load's, its ringing included.
    pub contraction_m: f64,
    /// Contraction rate (m/s), its ringing included.
    pub velocity_m_s: f64,
    /// Muscle length (m).
    pub length_m: f64,
}

/// The simulated rig under one load, advanced one sample at a time.
#[derive(Debug, Clone)]
pub struct Rig {
    config: TwinConfig,
    muscle: Muscle,
    /// The load at the water-set contraction.
    load: Load,
    /// The load's swing about it (`ringing` effect), if in the model.
    ringing: Option<Ringing>,
    /// The rubber's relaxing arm (`creep` effect), if in the model.
    creep: Option<BladderCreep>,
    friction: MaxwellSlip,
    valve_in: Valve,
    valve_out: Valve,
    /// Manifold pressure (Pa gauge), the sensor's.
    manifold_pa: f64,
    /// Muscle chamber pressure (Pa gauge), the force's.
    chamber_pa: f64,
    command_v: f64,
    steps: u64,
    /// The first sample at which the load's ringing unloaded the muscle
    /// past the tension that holds the load: from there on the muscle
    /// would be slack, and the run is outside the twin's physics.
    slack_from: Option<u64>,
    rng: ChaCha8Rng,
}

/// The heaviest load (kg) the commands hang on the twin: the default
/// muscle's rubber stretches the braid straight at about 19 kg
/// ([`Rig::new`]), and the thesis loads it with 4.5 and 7.
pub const MAX_LOAD_KG: f64 = 15.0;

impl Rig {
    /// Checks that the rig can hang `load_kg` (a mass above 0 and at most
    /// [`MAX_LOAD_KG`]) with these settings: the rubber, softened
    /// by the creep effect, must leave the braid short of straight at rest.
    /// Also [`TwinConfig::validate`]. Every command checks it before it
    /// builds a rig, to say so as an error.
    pub fn check_load(config: &TwinConfig, load_kg: f64) -> Result<(), TwinError> {
        config.validate()?;
        if !(load_kg.is_finite() && load_kg > 0.0 && load_kg <= MAX_LOAD_KG) {
            return Err(TwinError::BadLoad(load_kg));
        }
        let rest = Muscle::new(&config.muscle, load_kg, &config.effects).rest_length();
        let thread = config.muscle.braid.thread_length;
        if rest >= thread {
            return Err(TwinError::TooHeavy {
                load_kg,
                rest_mm: rest * 1e3,
                thread_mm: thread * 1e3,
                creep: config.muscle.relaxing_share(&config.effects) > 0.0,
            });
        }
        Ok(())
    }

    /// [`Rig::check_load`], then whether the twin's physics holds `load_kg`
    /// over the valve's whole range: shut for a second, then fully open for
    /// another, every sample finite and the muscle never slack
    /// ([`Rig::slack_from`]). A load a few grams light leaves the
    /// integration at once; this says so before a run records rows of NaN.
    pub fn check_holds(config: &TwinConfig, load_kg: f64, seed: u64) -> Result<(), TwinError> {
        Rig::check_load(config, load_kg)?;
        let mut rig = Rig::new(config, load_kg, seed);
        let second = (1.0 / config.sample_time_s).ceil() as usize;
        let full = config.valve.full_scale_v;
        for k in 1..=2 * second {
            let s = rig.step(if k <= second { 0.0 } else { full });
            if let Some(from) = rig.slack_from() {
                return Err(TwinError::Slack {
                    k: from as usize,
                    t_s: from as f64 * rig.dt(),
                    command: format!("{load_kg} kg, the valve shut for a second, then open"),
                });
            }
            for (column, v) in [
                ("displacement", s.displacement_mm),
                ("pressure", s.pressure_mpa),
            ] {
                if !v.is_finite() {
                    return Err(TwinError::NotFinite {
                        column: column.into(),
                        k,
                        t_s: s.t,
                        command: format!("{load_kg} kg"),
                    });
                }
            }
        }
        Ok(())
    }

    /// The rig at rest: load hanging, chamber at atmospheric pressure, input
    /// valve commanded shut (0 V) and output valve open (10 V). `seed` seeds
    /// the sensor noise (`ChaCha8Rng`); nothing else is random.
    ///
    /// Panics where [`Rig::check_load`] fails (a load that is not a
    /// positive mass up to [`MAX_LOAD_KG`], or that stretches the braid
    /// straight at rest, or settings [`TwinConfig::validate`] refuses).
    pub fn new(config: &TwinConfig, load_kg: f64, seed: u64) -> Rig {
        if let Err(e) = Rig::check_load(config, load_kg) {
            panic!("twin: {e}");
        }
        let full = config.valve.full_scale_v;
        let muscle = Muscle::new(&config.muscle, load_kg, &config.effects);
        Rig {
            config: config.clone(),
            muscle,
            load: Load {
                mass_kg: load_kg,
                x: 0.0,
                v: 0.0,
            },
            ringing: Ringing::new(&config.muscle, &config.effects),
            creep: BladderCreep::new(&config.muscle, &config.effects, config.substep_s()),
            friction: MaxwellSlip::new(&config.friction),
            valve_in: Valve::at(0.0),
            valve_out: Valve::at(full),
            manifold_pa: config.hydraulics.drain_pa,
            chamber_pa: config.hydraulics.drain_pa,
            command_v: 0.0,
            steps: 0,
            slack_from: None,
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// The first sample from which the load's ringing left the muscle
    /// slack (its swing unloaded the muscle past the tension that holds
    /// the load), which the twin does not model; `None` while it never has.
    pub fn slack_from(&self) -> Option<u64> {
        self.slack_from
    }

    /// The sample time (s).
    pub fn dt(&self) -> f64 {
        self.config.sample_time_s
    }

    /// The configuration the rig runs with.
    pub fn config(&self) -> &TwinConfig {
        &self.config
    }

    /// The hanging load (kg).
    pub fn load_kg(&self) -> f64 {
        self.load.mass_kg
    }

    /// The muscle model under this load.
    pub fn muscle(&self) -> &Muscle {
        &self.muscle
    }

    /// Time now (s).
    pub fn time(&self) -> f64 {
        self.steps as f64 * self.config.sample_time_s
    }

    /// The load's contraction and its rate: the water-set ones plus the
    /// ringing's swing when that is in the model.
    fn load_motion(&self) -> (f64, f64) {
        match &self.ringing {
            Some(r) => (self.load.x + r.offset, self.load.v + r.rate),
            None => (self.load.x, self.load.v),
        }
    }

    /// The true state now.
    pub fn true_state(&self) -> TrueState {
        let (x, v) = self.load_motion();
        TrueState {
            t: self.time(),
            pressure_pa: self.manifold_pa,
            chamber_pressure_pa: self.chamber_pa,
            contraction_m: x,
            velocity_m_s: v,
            length_m: self.muscle.length(x),
        }
    }

    /// Reads the sensors now (one noise draw per sensor: pressure, then displacement).
    pub fn measure(&mut self) -> Sample {
        let cfg = &self.config;
        let pressure_mpa =
            sensors::pressure_mpa(self.manifold_pa, &cfg.sensors, &mut self.rng, &cfg.effects);
        let displacement_mm = sensors::displacement_mm(
            self.load_motion().0,
            &cfg.sensors,
            &mut self.rng,
            &cfg.effects,
        );
        Sample {
            t: self.time(),
            valve_in: self.command_v,
            valve_out: cfg.valve.output_command(self.command_v),
            pressure_mpa,
            displacement_mm,
        }
    }

    /// Holds the input-valve command `valve_in_volts` (clamped to 0–10 V; the
    /// output valve gets `10 − u`) for one sample period, then reads the
    /// sensors: the returned sample is at the end of the period.
    pub fn step(&mut self, valve_in_volts: f64) -> Sample {
        self.advance(valve_in_volts);
        self.measure()
    }

    /// Holds the command for one sample period without reading the sensors.
    pub fn advance(&mut self, valve_in_volts: f64) {
        let full = self.config.valve.full_scale_v;
        let u = if valve_in_volts.is_nan() {
            0.0
        } else {
            valve_in_volts.clamp(0.0, full)
        };
        self.command_v = u;
        let n = self.config.substeps.max(1);
        let h = self.config.substep_s();
        for _ in 0..n {
            self.substep(u, self.config.valve.output_command(u), h);
        }
        self.steps += 1;
    }

    /// One integration substep of length `h`: spools, then the load
    /// (forces at the current chamber pressure) with the rubber's creep arm
    /// and the load's ringing, then both pressures implicitly with the
    /// load's new velocity.
    fn substep(&mut self, u_in: f64, u_out: f64, h: f64) {
        let cfg = &self.config;
        let fx = &cfg.effects;
        self.valve_in.advance(u_in, h, &cfg.valve, fx);
        self.valve_out.advance(u_out, h, &cfg.valve, fx);

        let x = self.load.x;
        let p = self.chamber_pa;
        let weight = self.load.mass_kg * GRAVITY;
        let creep = self.creep.as_ref().map_or(0.0, BladderCreep::tension);
        let spring =
            self.muscle.pressure_force(p, x) + self.muscle.rubber_tension(x) + creep - weight;
        let friction = self.friction.current_force(p, &cfg.friction, fx);
        let stop = load::stop_force(x, self.load.v, &cfg.endstop, fx);
        let damping = -cfg.muscle.damping_n_s_per_m * self.load.v;
        let v_before = self.load.v;
        let dx = self.load.advance(spring + friction + stop + damping, h);
        self.friction.slide(dx, fx);
        if let Some(arm) = &mut self.creep {
            arm.advance(dx);
        }
        if let Some(ringing) = &mut self.ringing {
            let k = self.muscle.axial_stiffness(p, x);
            let mass = self.load.mass_kg;
            let base_dv = self.load.v - v_before;
            ringing.advance(k, mass, base_dv, h);
            // The tension that holds the load as its water-set place
            // accelerates: m·(g + ẍ).
            let holding = mass * (GRAVITY + base_dv / h);
            if ringing.swings() && self.slack_from.is_none() && ringing.unloading(k, mass) > holding
            {
                self.slack_from = Some(self.steps + 1);
            }
        }

        let x = self.load.x;
        let vfx = &cfg.valve;
        (self.manifold_pa, self.chamber_pa) = PressureStep {
            p_manifold: self.manifold_pa,
            p_chamber: p,
            dt: h,
            cap_manifold: chamber::manifold_capacitance(&cfg.hydraulics, fx),
            cap_chamber: chamber::chamber_capacitance(self.muscle.volume(x), &cfg.hydraulics),
            valve_in: vfx.orifice(self.valve_in.opening(vfx, fx)),
            valve_out: vfx.orifice(self.valve_out.opening(vfx, fx)),
            volume_rate: self.muscle.effective_area(x) * self.load.v,
            hydraulics: &cfg.hydraulics,
        }
        .solve();
    }
}
