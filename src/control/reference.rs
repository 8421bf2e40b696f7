//! The reference of appendix A.1.2: `r(t) = bias + amplitude·sin(ω·t)`
//! (the appendix's code omits `t` inside `sin`, an erratum of the thesis).

use serde::{Deserialize, Serialize};

/// The reference's waveform.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Waveform {
    /// `bias + amplitude·sin(ω·t)` (the thesis').
    #[default]
    Sine,
    /// Steps between `bias + amplitude` and `bias − amplitude`, switching
    /// where the sine of the same `ω` crosses zero (a square wave: held
    /// π/ω s, 1.05 s at 3 rad/s), so the hanging load rings after each.
    Steps,
}

impl Waveform {
    pub const ALL: [Waveform; 2] = [Waveform::Sine, Waveform::Steps];

    pub fn name(self) -> &'static str {
        match self {
            Waveform::Sine => "sine",
            Waveform::Steps => "steps",
        }
    }
}

/// A waveform's name in any case (`sine`, `Steps`), as `--reference`
/// reads it.
impl std::str::FromStr for Waveform {
    type Err = crate::names::UnknownName;

    fn from_str(s: &str) -> Result<Waveform, Self::Err> {
        crate::names::one_of("reference", s, &Waveform::ALL, Waveform::name)
    }
}

/// A sine reference for the displacement (or steps of the same period and
/// amplitude, [`Waveform::Steps`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SineReference {
    /// Mean displacement (mm): 30 in §6.2.2.
    pub bias_mm: f64,
    /// Amplitude (mm): 10 in §6.2.2.
    pub amplitude_mm: f64,
    /// Angular frequency (rad/s): 1, 2 or 3 in §6.2.2.
    pub omega_rad_s: f64,
    #[serde(default)]
    pub waveform: Waveform,
}

impl SineReference {
    /// The thesis' reference at `omega` rad/s (10 mm amplitude, 30 mm bias).
    pub fn thesis(omega_rad_s: f64) -> Self {
        SineReference {
            bias_mm: 30.0,
            amplitude_mm: 10.0,
            omega_rad_s,
            waveform: Waveform::Sine,
        }
    }

    /// The reference at time `t` (s); before `t = 0` it rests at the bias.
    pub fn at(&self, t: f64) -> f64 {
        if t < 0.0 {
            self.bias_mm
        } else {
            let s = (self.omega_rad_s * t).sin();
            match self.waveform {
                Waveform::Sine => self.bias_mm + self.amplitude_mm * s,
                Waveform::Steps if s >= 0.0 => self.bias_mm + self.amplitude_mm,
                Waveform::Steps => self.bias_mm - self.amplitude_mm,
            }
        }
    }
}
