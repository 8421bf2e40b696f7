//! The twin's settings: one struct per physical part, every parameter named
//! with its unit, value and where the value comes from; and the switches
//! (`Effects`) that scale or remove each non-ideal effect.
//!
//! The thesis gives almost no rig data (tap water, two proportional valves
//! driven 0–10 V, a dSPACE DS1104, loads of 4.5 and 7 kg, displacements of
//! 20–40 mm in the PI runs). Everything else is an engineering assumption,
//! said so in each doc comment and collected in `docs/TWIN.md`.

use serde::{Deserialize, Serialize};

use crate::model::static_force::Braid;

/// Standard gravity (m/s²).
pub const GRAVITY: f64 = 9.80665;

/// The two proportional valves (input: supply → muscle; output: muscle → drain).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ValveParams {
    /// Full-scale command (V). Thesis §4.3.1: 0–10 V.
    pub full_scale_v: f64,
    /// Dead band (V): below this command the spool overlap keeps the valve
    /// shut. Assumption: 0.8 V, i.e. 8 % of the stroke, within the 5–20 %
    /// overlap typical of low-cost proportional valves.
    pub deadband_v: f64,
    /// Time constant of the spool's first-order lag (s). Assumption: 30 ms,
    /// the order of the −90° bandwidth (5–10 Hz) of small direct-acting
    /// proportional valves.
    pub spool_tau_s: f64,
    /// Orifice area at full opening (m²). Assumption: 30 mm², a 6.2 mm bore
    /// (a 3/8" tap-water solenoid-class valve); with it the stair's steps
    /// settle within their 1 s (the thesis' stair, figure 3, shows settled
    /// levels), see docs/TWIN.md.
    pub area_max_m2: f64,
    /// Discharge coefficient of the orifice, 0.61 (sharp-edged orifice;
    /// Merritt, *Hydraulic Control Systems*, 1967, §3.2).
    pub discharge_coefficient: f64,
    /// Pressure drop (Pa) below which the flow is taken as laminar (linear in
    /// the drop) so that the flow law has a finite slope at zero drop.
    /// Assumption: 2 kPa; it only rounds the corner of `√Δp`.
    pub laminar_dp_pa: f64,
}

impl ValveParams {
    /// The output valve's command for the input valve's `valve_in` (V):
    /// full scale less it (appendix A.1.1: the two signals are symmetric).
    pub fn output_command(&self, valve_in: f64) -> f64 {
        self.full_scale_v - valve_in
    }
}

impl Default for ValveParams {
    fn default() -> Self {
        ValveParams {
            full_scale_v: 10.0,
            deadband_v: 0.8,
            spool_tau_s: 0.03,
            area_max_m2: 30e-6,
            discharge_coefficient: 0.61,
            laminar_dp_pa: 2e3,
        }
    }
}

/// The water path: supply, drain, hose volume and compliance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HydraulicParams {
    /// Tap supply, gauge (Pa). Thesis: tap water; municipal mains deliver
    /// 0.3–0.5 MPa gauge. Assumption: 0.4 MPa.
    pub supply_pa: f64,
    /// Drain pressure, gauge (Pa): open to atmosphere, 0.
    pub drain_pa: f64,
    /// Water density (kg/m³) at 20 °C: 998.
    pub density: f64,
    /// Bulk modulus of water (Pa) at 20 °C: 2.2 GPa.
    pub bulk_modulus_water: f64,
    /// Volume of the hose between the valves and the muscle (m³).
    /// Assumption: 1.5 m of 8 mm bore hose, 75 ml.
    pub hose_volume_m3: f64,
    /// Compliance of the hose wall and bladder (m³/Pa), the volume they take
    /// up per pascal. Assumption: hose volume / 50 MPa, the effective bulk
    /// modulus of a water-filled reinforced PVC hose (Merritt §3.5 gives
    /// effective moduli of 10–700 MPa for hoses); it lowers the effective
    /// bulk modulus of the water column from 2.2 GPa to about 50 MPa.
    pub hose_compliance_m3_per_pa: f64,
    /// Bore area of the muscle's inlet fitting (m²). Assumption: 8 mm², a
    /// 3.2 mm bore, the size of the barbed fittings on 10–15 mm muscles; at
    /// 50 ml/s it drops about 50 kPa, so the muscle's pressure lags the
    /// manifold's (where the sensor is): a 1 V stair step reaches 63 % of its
    /// displacement in about 0.3 s, see docs/TWIN.md.
    pub inlet_area_m2: f64,
    /// Discharge coefficient of the inlet fitting, 0.61 (as the valves).
    pub inlet_discharge_coefficient: f64,
    /// Laminar threshold of the inlet's flow law (Pa), as the valves': 2 kPa.
    pub laminar_dp_pa: f64,
}

impl Default for HydraulicParams {
    fn default() -> Self {
        let hose_volume_m3 = 1.5 * std::f64::consts::PI * 0.004 * 0.004;
        HydraulicParams {
            supply_pa: 0.4e6,
            drain_pa: 0.0,
            density: 998.0,
            bulk_modulus_water: 2.2e9,
            hose_volume_m3,
            hose_compliance_m3_per_pa: hose_volume_m3 / 50e6,
            inlet_area_m2: 8e-6,
            inlet_discharge_coefficient: 0.61,
            laminar_dp_pa: 2e3,
        }
    }
}

/// The muscle: braid geometry (eq. 1–9) and rubber elasticity.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MuscleParams {
    /// The braid: `crate::model::static_force::Braid::default()` (b = 0.35 m,
    /// n = 3, t_k = 1.5 mm), the project's one description of the muscle.
    pub braid: Braid,
    /// Braid angle at the rubber's natural length, no load, no pressure (rad).
    /// Assumption: 20°, which puts the natural length at 0.329 m and the
    /// diameter at 12.7 mm, the size of the Kobayashi–Ito tap-water muscles.
    pub natural_angle_rad: f64,
    /// Axial stiffness of the rubber tube (N/m): its elastic force is
    /// `k·(L − L_nat)`, a tension when stretched. Assumption: 9 kN/m, chosen
    /// so the muscle contracts about 43 mm at the full 0.4 MPa under 4.5 kg,
    /// which covers the thesis' 20–40 mm PI reference (§6.2.2).
    pub rubber_stiffness_n_per_m: f64,
    /// Viscous damping of the rubber and the water in the braid (N·s/m).
    /// Assumption: 100 N·s/m (damping ratio ≈ 0.3 of the load on the rubber).
    pub damping_n_s_per_m: f64,
    /// Share of the rubber's stiffness that relaxes (the `creep` effect): a
    /// standard linear solid whose Maxwell arm holds this share of
    /// `rubber_stiffness_n_per_m` and lets it go with `creep_time_s`.
    /// Assumption: 0.1, the 5–15 % stress relaxation of natural-rubber
    /// tubing over a minute; under a pressure step it lets the muscle creep
    /// ≈ 8 % further than its fast response (docs/TWIN.md).
    pub creep_share: f64,
    /// Relaxation time of that arm (s). Assumption: 5 s, so the muscle's
    /// creep (retardation) time is ≈ 5.5 s, the several seconds of the
    /// pulse-to-pulse deepening on real records.
    pub creep_time_s: f64,
    /// Loss factor `η = tan δ` of the rubber at a few hertz (the `ringing`
    /// effect's damping): a hysteretic loss `η·k_rubber` per radian, taken
    /// as the viscous `c = η·k_rubber/ω` at the load's frequency ω.
    /// Assumption: 0.2, within the 0.1–0.3 of natural rubber near 5 Hz;
    /// it gives a damping ratio `ζ = η·k_rubber/(2k)` of 0.07–0.10.
    pub rubber_loss_factor: f64,
}

impl Default for MuscleParams {
    fn default() -> Self {
        MuscleParams {
            braid: Braid::default(),
            natural_angle_rad: 20f64.to_radians(),
            rubber_stiffness_n_per_m: 9e3,
            damping_n_s_per_m: 100.0,
            creep_share: 0.1,
            creep_time_s: 5.0,
            rubber_loss_factor: 0.2,
        }
    }
}

/// Braid friction as Maxwell-slip elements (Lazan 1968; Vo-Minh et al. 2011
/// for McKibben muscles): springs in parallel, each in series with a Coulomb
/// slider. The sum gives rate-independent hysteresis with a smooth
/// pre-sliding transition. The threads are pressed together by the bladder,
/// so each slider's break-away force grows with pressure (Tondu & Lopez 2000).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrictionParams {
    /// Total break-away force at zero gauge pressure (N), the rubber and
    /// threads rubbing under the load alone. Assumption: 5 N.
    pub break_force_n: f64,
    /// Increase of the total break-away force per MPa (N/MPa). Assumption:
    /// 100 N/MPa, i.e. 45 N at 0.4 MPa, about 12 % of the pressure force
    /// there, within the 5–15 % force hysteresis Tondu & Lopez (2000) report
    /// for braided muscles. It opens a loop about 5 mm wide at mid pressure
    /// (≈ 12 % of the stroke), see docs/TWIN.md.
    pub break_force_per_mpa: f64,
    /// Pre-sliding deflection of each element (m): element `i` slips after
    /// this travel. Assumption: 0.2, 0.6, 1.5 and 3 mm, spread so the loop
    /// corners are rounded like the thesis' figure 4.
    pub slip_deflection_m: Vec<f64>,
}

impl Default for FrictionParams {
    fn default() -> Self {
        FrictionParams {
            break_force_n: 5.0,
            break_force_per_mpa: 100.0,
            slip_deflection_m: vec![0.2e-3, 0.6e-3, 1.5e-3, 3e-3],
        }
    }
}

/// The hanging load's travel limits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EndStopParams {
    /// Lowest position: contraction (m, negative = extension) at which the
    /// load lands on its support. Assumption: −5 mm.
    pub min_contraction_m: f64,
    /// Highest position: contraction (m) at which the load hits the upper
    /// bracket. Assumption: 50 mm, just above the 43 mm the muscle reaches
    /// at full supply under 4.5 kg, so the nominal runs do not touch it.
    pub max_contraction_m: f64,
    /// Contact stiffness (N/m). Assumption: 2 MN/m (a rubber-padded stop).
    pub stiffness_n_per_m: f64,
    /// Contact damping (N·s/m). Assumption: 2 kN·s/m, near critical for 4.5 kg.
    pub damping_n_s_per_m: f64,
}

impl Default for EndStopParams {
    fn default() -> Self {
        EndStopParams {
            min_contraction_m: -5e-3,
            max_contraction_m: 50e-3,
            stiffness_n_per_m: 2e6,
            damping_n_s_per_m: 2e3,
        }
    }
}

/// Displacement and pressure sensors, read by the DS1104's ADC.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SensorParams {
    /// Displacement noise, standard deviation (mm). Assumption: 0.03 mm, a
    /// linear potentiometer read over a 0.5 m cable.
    pub displacement_noise_mm: f64,
    /// Displacement resolution (ADC counts per mm): a 100 mm sensor on one
    /// of the DS1104's 12-bit ADC channels gives 4096/100 ≈ 41 counts/mm;
    /// 40 is used, so the recorded values are short decimals (0.025 mm steps).
    pub displacement_counts_per_mm: f64,
    /// Pressure noise, standard deviation (MPa). Assumption: 0.002 MPa,
    /// 0.2 % of a 1 MPa transducer's span.
    pub pressure_noise_mpa: f64,
    /// Pressure resolution (counts per MPa): a 0–1 MPa transducer on a
    /// 12-bit channel, 4096 counts/MPa; 4000 is used (0.25 kPa steps).
    pub pressure_counts_per_mpa: f64,
}

impl Default for SensorParams {
    fn default() -> Self {
        SensorParams {
            displacement_noise_mm: 0.03,
            displacement_counts_per_mm: 40.0,
            pressure_noise_mpa: 0.002,
            pressure_counts_per_mpa: 4000.0,
        }
    }
}

/// The names accepted by `--effect NAME=VALUE`, in the order `--help` lists
/// them. The last two, `creep` and `ringing`, are off (scale 0) by default.
pub const EFFECT_NAMES: [&str; 10] = [
    "friction",
    "deadband",
    "spool_lag",
    "compliance",
    "endstop",
    "noise",
    "quantization",
    "thickness",
    "creep",
    "ringing",
];

/// One non-ideal effect: a scale on its nominal size (1 = as documented,
/// 0 = size zero but still computed) or removed from the model altogether
/// (the code path skipped). A scale of 0 must give exactly the trace of the
/// removed effect; `tests/twin.rs` checks that for every effect.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EffectScale {
    pub scale: f64,
    pub present: bool,
}

impl Default for EffectScale {
    fn default() -> Self {
        EffectScale {
            scale: 1.0,
            present: true,
        }
    }
}

impl EffectScale {
    /// An effect in the model at scale 0: off until `--effect NAME=1`.
    pub const fn off() -> Self {
        EffectScale {
            scale: 0.0,
            present: true,
        }
    }

    /// The scale if the effect is in the model, `None` if removed.
    pub fn active(&self) -> Option<f64> {
        self.present.then_some(self.scale)
    }
}

/// A setting of the twin that it cannot run: an effect's name or scale,
/// the load or the frequency of an experiment.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TwinError {
    #[error("unknown effect `{0}`; known: {names}", names = EFFECT_NAMES.join(", "))]
    UnknownEffect(String),
    #[error("effect {name}: scale must be a finite number ≥ 0 (got {scale})")]
    BadScale { name: String, scale: f64 },
    #[error("--effect {0} is given twice: give each effect one scale")]
    Repeated(String),
    #[error("--effect {0}: expected NAME=VALUE, e.g. friction=0")]
    NotNameValue(String),
    #[error("--effect {arg}: `{value}` is not a number")]
    NotANumber { arg: String, value: String },
    /// The creep's scale would relax the rubber's whole stiffness.
    #[error(
        "effect creep: a share {share} of the rubber's stiffness would relax, \
         leaving it no relaxed stiffness; the scale must stay below {below}"
    )]
    CreepRelaxesAll { share: f64, below: f64 },
    #[error(
        "--load {}: expected a mass in kg above 0 and at most {max} (thesis: 4.5 or 7)",
        crate::data::readable(*.0),
        max = super::MAX_LOAD_KG
    )]
    BadLoad(f64),
    /// The load stretches the muscle at rest to its braid's thread length:
    /// the braid would be straight before any pressure.
    #[error(
        "a {load_kg} kg load stretches the muscle at rest to {rest_mm:.1} mm, past its braid's \
         thread length of {thread_mm:.1} mm{}",
        if *creep { " (--effect creep leaves the rubber softer: a smaller scale carries more)" } else { "" }
    )]
    TooHeavy {
        load_kg: f64,
        rest_mm: f64,
        thread_mm: f64,
        /// Whether the creep effect softened the rubber.
        creep: bool,
    },
    /// The run left the rig's physics: a sensor read a value that is not
    /// finite.
    #[error(
        "the twin's `{column}` is not finite from {t_s:.3} s on (sample {k}): `{command}` takes \
         the rig outside what it models; try another load (a very light one leaves the \
         muscle slack), or --effect scales nearer 1"
    )]
    NotFinite {
        column: String,
        k: usize,
        t_s: f64,
        command: String,
    },
    /// The load's ringing unloaded the muscle past the tension that holds
    /// the load: the muscle would go slack, which the twin does not model.
    #[error(
        "the load's ringing leaves the muscle slack from {t_s:.3} s on (sample {k}) of \
         `{command}`: its swing lifts the load faster than the muscle can carry it, which the \
         twin's linear swing does not model; use a smaller --effect ringing (1 is as documented)"
    )]
    Slack { k: usize, t_s: f64, command: String },
    #[error("--freq {0}: expected a positive angular frequency in rad/s (thesis: 1, 2, 3)")]
    BadFrequency(f64),
    #[error(
        "--freq {freq}: the twin samples every {dt} s, so a sine must stay below \
         Nyquist's {nyquist:.1} rad/s (π/dt); above, its samples show a slower sine"
    )]
    AboveNyquist { freq: f64, dt: f64, nyquist: f64 },
}

/// The switches of every non-ideal effect. All are on (scale 1) by default
/// except `creep` and `ringing`: off, they leave the twin's default runs,
/// and every number published from them, as they are.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Effects {
    /// Braid friction: scales the break-away forces of the Maxwell-slip elements.
    pub friction: EffectScale,
    /// Valve dead band: scales its width.
    pub deadband: EffectScale,
    /// Valve spool lag: scales its time constant.
    pub spool_lag: EffectScale,
    /// Hose and bladder compliance: scales it (0 leaves water's own bulk modulus).
    pub compliance: EffectScale,
    /// End stops: scale their contact stiffness and damping.
    pub endstop: EffectScale,
    /// Sensor noise: scales both standard deviations.
    pub noise: EffectScale,
    /// Sensor quantization: scales both steps (divides the counts per unit).
    pub quantization: EffectScale,
    /// Wall thickness t_k of eq. 8–9: scales it (0 gives the ideal eq. 7).
    pub thickness: EffectScale,
    /// Creep of the bladder: scales the relaxing share of the rubber's
    /// stiffness. Off by default.
    pub creep: EffectScale,
    /// The load's ringing on the muscle's stiffness: scales its excitation.
    /// Off by default.
    pub ringing: EffectScale,
}

impl Default for Effects {
    fn default() -> Self {
        Effects {
            friction: EffectScale::default(),
            deadband: EffectScale::default(),
            spool_lag: EffectScale::default(),
            compliance: EffectScale::default(),
            endstop: EffectScale::default(),
            noise: EffectScale::default(),
            quantization: EffectScale::default(),
            thickness: EffectScale::default(),
            creep: EffectScale::off(),
            ringing: EffectScale::off(),
        }
    }
}

impl Effects {
    fn get_mut(&mut self, name: &str) -> Option<&mut EffectScale> {
        Some(match name {
            "friction" => &mut self.friction,
            "deadband" => &mut self.deadband,
            "spool_lag" => &mut self.spool_lag,
            "compliance" => &mut self.compliance,
            "endstop" => &mut self.endstop,
            "noise" => &mut self.noise,
            "quantization" => &mut self.quantization,
            "thickness" => &mut self.thickness,
            "creep" => &mut self.creep,
            "ringing" => &mut self.ringing,
            _ => return None,
        })
    }

    /// Sets the scale of effect `name`; an error names the unknown effect
    /// and lists the known ones, or rejects a negative or non-finite scale.
    pub fn set(&mut self, name: &str, scale: f64) -> Result<(), TwinError> {
        if !scale.is_finite() || scale < 0.0 {
            return Err(TwinError::BadScale {
                name: name.to_string(),
                scale,
            });
        }
        let e = self
            .get_mut(name)
            .ok_or_else(|| TwinError::UnknownEffect(name.to_string()))?;
        e.scale = scale;
        Ok(())
    }

    /// Removes effect `name` from the model (its code path is skipped).
    pub fn remove(&mut self, name: &str) -> Result<(), TwinError> {
        let e = self
            .get_mut(name)
            .ok_or_else(|| TwinError::UnknownEffect(name.to_string()))?;
        e.present = false;
        Ok(())
    }

    /// Applies every `--effect NAME=VALUE` in turn; a name given twice is
    /// an error, where the last would silently win.
    pub fn apply_args(&mut self, args: &[String]) -> Result<(), TwinError> {
        let mut seen: Vec<&str> = Vec::new();
        for arg in args {
            let name = arg.split_once('=').map_or(arg.as_str(), |(n, _)| n.trim());
            if seen.contains(&name) {
                return Err(TwinError::Repeated(name.to_string()));
            }
            seen.push(name);
            self.apply_arg(arg)?;
        }
        Ok(())
    }

    /// Parses `NAME=VALUE` as given to `--effect`.
    fn apply_arg(&mut self, arg: &str) -> Result<(), TwinError> {
        let (name, value) = arg
            .split_once('=')
            .ok_or_else(|| TwinError::NotNameValue(arg.to_string()))?;
        let scale: f64 = value.trim().parse().map_err(|_| TwinError::NotANumber {
            arg: arg.to_string(),
            value: value.to_string(),
        })?;
        self.set(name.trim(), scale)
    }
}

/// Everything the twin needs besides the load and the seed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TwinConfig {
    /// Sample time of the controller board (s). The thesis runs its Simulink
    /// model on a DS1104 and prints no sample time; 10 ms is assumed (the
    /// thesis' pole 0.9618 then means a 0.26 s time constant, plausible for
    /// the rig). The issue fixes 10 ms.
    pub sample_time_s: f64,
    /// Integration substeps per sample. 200 (50 µs): the stiffest mode is the
    /// load on the water in the muscle, `ω = A/√(m·V/β)` ≈ 7.3e3 rad/s under
    /// 4.5 kg (docs/TWIN.md), and symplectic Euler needs ω·h < 2; 50 µs gives
    /// ω·h ≈ 0.37. The pressures are solved implicitly, so the orifices'
    /// microsecond time constants do not limit the step.
    pub substeps: usize,
    pub valve: ValveParams,
    pub hydraulics: HydraulicParams,
    pub muscle: MuscleParams,
    pub friction: FrictionParams,
    pub endstop: EndStopParams,
    pub sensors: SensorParams,
    pub effects: Effects,
}

impl TwinConfig {
    /// The integration substep (s): the sample time over the substeps.
    pub fn substep_s(&self) -> f64 {
        self.sample_time_s / self.substeps.max(1) as f64
    }

    /// Checks the settings the effects can make unphysical: the creep must
    /// leave the rubber a positive relaxed stiffness.
    pub fn validate(&self) -> Result<(), TwinError> {
        let share = self.muscle.relaxing_share(&self.effects);
        if share >= 1.0 {
            return Err(TwinError::CreepRelaxesAll {
                share,
                below: 1.0 / self.muscle.creep_share,
            });
        }
        Ok(())
    }
}

impl MuscleParams {
    /// The share of the rubber's stiffness that relaxes under the `creep`
    /// effect's scale (0 when it is off or removed).
    pub fn relaxing_share(&self, fx: &Effects) -> f64 {
        fx.creep
            .active()
            .map_or(0.0, |scale| scale * self.creep_share)
    }
}

impl Default for TwinConfig {
    fn default() -> Self {
        TwinConfig {
            sample_time_s: 0.01,
            substeps: 200,
            valve: ValveParams::default(),
            hydraulics: HydraulicParams::default(),
            muscle: MuscleParams::default(),
            friction: FrictionParams::default(),
            endstop: EndStopParams::default(),
            sensors: SensorParams::default(),
            effects: Effects::default(),
        }
    }
}
