//! The input signals of the thesis' experiments (appendix A.1): the valve
//! staircase of the identification experiment (A.1.1), the sine reference of
//! the PI experiments (A.1.2), and a seeded multisine for richer excitation.
//!
//! Every generator returns one value per sample on the time base
//! `t(k) = k·dt`, so the caller decides the sample time.

use rand::RngExt;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// Full scale of the proportional valves' command, volts (thesis §4.3.1: 0–10 V).
pub const VALVE_FULL_SCALE_V: f64 = 10.0;

/// The identification staircase of appendix A.1.1 (thesis figure 2).
///
/// The thesis prints neither the step height nor the hold time, so these are
/// choices: 1 V steps from 0 to 10 V and back down, each level held 1 s
/// (about three time constants of the rig, so each step nearly settles), the
/// whole up-and-down cycle repeated `cycles` times. Going up and coming down
/// through the same levels is what exposes the hysteresis (figure 4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stair {
    /// Height of one step (V).
    pub step_v: f64,
    /// Highest level (V), reached at the top of each cycle.
    pub top_v: f64,
    /// Time each level is held (s).
    pub hold_s: f64,
    /// Number of up-and-down cycles.
    pub cycles: usize,
}

impl Default for Stair {
    /// 1 V steps, 0 → 10 → 0 V, 1 s per level, two cycles: 40 levels, 40 s,
    /// 4000 samples at 10 ms, so that the thesis' split in halves (§4.3.1)
    /// gives one full cycle for estimation and one for validation.
    fn default() -> Self {
        Stair {
            step_v: 1.0,
            top_v: VALVE_FULL_SCALE_V,
            hold_s: 1.0,
            cycles: 2,
        }
    }
}

impl Stair {
    /// The levels of one cycle, in order: 0, step, …, top, top − step, …, step.
    pub fn levels(&self) -> Vec<f64> {
        let n = (self.top_v / self.step_v).round() as usize;
        let up = (0..=n).map(|i| i as f64 * self.step_v);
        let down = (1..n).rev().map(|i| i as f64 * self.step_v);
        up.chain(down).collect()
    }

    /// Seconds the staircase lasts.
    pub fn duration_s(&self) -> f64 {
        self.levels().len() as f64 * self.cycles as f64 * self.hold_s
    }

    /// The input-valve command, one value per sample of period `dt`.
    pub fn generate(&self, dt: f64) -> Vec<f64> {
        let per_level = (self.hold_s / dt).round().max(1.0) as usize;
        let levels = self.levels();
        (0..self.cycles)
            .flat_map(|_| levels.iter())
            .flat_map(|&v| std::iter::repeat_n(v, per_level))
            .collect()
    }
}

/// The most samples a generated or resampled record may hold: 10⁷, 28
/// hours at 100 Hz. A step typed a few decades too small (`1e-9` for
/// `1e-2`) would otherwise ask for more memory than the machine has.
pub const MAX_SAMPLES: usize = 10_000_000;

/// The samples of a record `seconds` long, one every `dt` s, or why there
/// cannot be that many ([`MAX_SAMPLES`]).
pub fn samples_in(seconds: f64, dt: f64) -> Result<usize, String> {
    let n = (seconds / dt).round();
    if n > MAX_SAMPLES as f64 {
        return Err(format!(
            "{seconds} s at {dt} s a sample is {n:.3e} samples, more than the {MAX_SAMPLES} \
             a record may hold"
        ));
    }
    Ok(n as usize)
}

/// Whether two samples are the same to the rounding of a file's digits.
fn same(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * (1.0 + b.abs())
}

/// Whether `u` repeats itself `period` samples on, to the rounding of a
/// file's digits.
pub fn repeats_every(u: &[f64], period: usize) -> bool {
    period > 0 && period < u.len() && (period..u.len()).all(|i| same(u[i], u[i - period]))
}

/// The shortest period, of two samples up to half the record, with which
/// `u` repeats itself (a periodic excitation, as a multisine repeated or a
/// commanded staircase logged as the input); `None` where it does not, and
/// for a constant input. In one pass (the prefix function of string
/// matching: the shortest period is the length less the longest prefix
/// that is also a suffix), where trying each period in turn took time
/// proportional to the record times its longest plateau; the period found
/// is checked sample by sample.
pub fn period_of(u: &[f64]) -> Option<usize> {
    let n = u.len();
    if n < 2 {
        return None;
    }
    // border[i]: the longest proper prefix of u[..=i] that is also its suffix.
    let mut border = vec![0usize; n];
    for i in 1..n {
        let mut k = border[i - 1];
        while k > 0 && !same(u[i], u[k]) {
            k = border[k - 1];
        }
        if same(u[i], u[k]) {
            k += 1;
        }
        border[i] = k;
    }
    let period = n - border[n - 1];
    (period > 1 && period <= n / 2 && repeats_every(u, period)).then_some(period)
}

/// Nyquist's angular frequency for samples `dt` s apart, `π/dt` (rad/s): a
/// sine at or above it shows in its samples as a slower sine or a constant,
/// so a signal asked for there says nothing of the frequency asked for.
pub fn nyquist_rad_s(dt: f64) -> f64 {
    std::f64::consts::PI / dt
}

/// The sine reference of appendix A.1.2 with the erratum fixed (the thesis'
/// script omits `t` inside `sin`): `r(t) = bias + amplitude·sin(ω t)`, in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SineReference {
    /// Amplitude (mm), thesis: 10.
    pub amplitude_mm: f64,
    /// Bias (mm), thesis: 30.
    pub bias_mm: f64,
    /// Angular frequency ω (rad/s), thesis: 1, 2 or 3.
    pub omega_rad_s: f64,
    /// Duration (s).
    pub duration_s: f64,
}

impl Default for SineReference {
    /// Thesis §6.2.2: amplitude 10 mm, bias 30 mm, ω = 1 rad/s; 40 s (the
    /// thesis' script runs 20 s; 40 s gives six periods even at 1 rad/s).
    fn default() -> Self {
        SineReference {
            amplitude_mm: 10.0,
            bias_mm: 30.0,
            omega_rad_s: 1.0,
            duration_s: 40.0,
        }
    }
}

impl SineReference {
    /// The reference at time `t` (s).
    pub fn at(&self, t: f64) -> f64 {
        self.bias_mm + self.amplitude_mm * (self.omega_rad_s * t).sin()
    }

    /// One value per sample of period `dt` over the duration.
    pub fn generate(&self, dt: f64) -> Vec<f64> {
        let n = (self.duration_s / dt).round() as usize;
        (0..n).map(|k| self.at(k as f64 * dt)).collect()
    }
}

/// A multisine valve command: `mean + Σ a_i·sin(2π f_i t + φ_i)` with the
/// frequencies spread log-uniformly over `[f_min, f_max]`, equal amplitudes
/// scaled so the peak stays inside `mean ± amplitude`, and phases drawn from
/// the seed. Clamped to the valves' 0–10 V.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Multisine {
    /// Centre of the command (V).
    pub mean_v: f64,
    /// Largest excursion from the centre (V).
    pub amplitude_v: f64,
    /// Lowest frequency (Hz).
    pub f_min_hz: f64,
    /// Highest frequency (Hz).
    pub f_max_hz: f64,
    /// Number of sines.
    pub components: usize,
    /// Duration (s).
    pub duration_s: f64,
}

impl Default for Multisine {
    /// 5 ± 4 V, 8 sines from 0.02 to 1 Hz (the rig's bandwidth is about
    /// 0.5 Hz, see docs/TWIN.md), 40 s.
    fn default() -> Self {
        Multisine {
            mean_v: 5.0,
            amplitude_v: 4.0,
            f_min_hz: 0.02,
            f_max_hz: 1.0,
            components: 8,
            duration_s: 40.0,
        }
    }
}

impl Multisine {
    /// One value per sample of period `dt`; the phases come from a
    /// `ChaCha8Rng` seeded with `seed`, so the same seed gives the same signal.
    pub fn generate(&self, dt: f64, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let m = self.components.max(1);
        let freqs: Vec<f64> = (0..m)
            .map(|i| {
                let s = if m == 1 {
                    0.0
                } else {
                    i as f64 / (m - 1) as f64
                };
                self.f_min_hz * (self.f_max_hz / self.f_min_hz).powf(s)
            })
            .collect();
        let phases: Vec<f64> = (0..m)
            .map(|_| rng.random_range(0.0..std::f64::consts::TAU))
            .collect();
        let n = (self.duration_s / dt).round() as usize;
        let raw: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 * dt;
                freqs
                    .iter()
                    .zip(&phases)
                    .map(|(f, p)| (std::f64::consts::TAU * f * t + p).sin())
                    .sum()
            })
            .collect();
        let peak = raw.iter().fold(0.0f64, |a, v| a.max(v.abs())).max(1e-12);
        raw.iter()
            .map(|v| (self.mean_v + self.amplitude_v * v / peak).clamp(0.0, VALVE_FULL_SCALE_V))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pattern repeated is found at its length, the shortest; a record
    /// that repeats nothing within its halves, or holds still, has none.
    #[test]
    fn a_repeated_excitation_has_its_period() {
        let pattern = [0.1, 0.4, -0.2, 0.3, 0.0, 0.25, -0.1];
        let repeated: Vec<f64> = pattern.iter().cycle().take(5 * 7).copied().collect();
        assert_eq!(period_of(&repeated), Some(7));
        let mut perturbed = repeated.clone();
        perturbed[30] += 1e-3;
        assert_eq!(period_of(&perturbed), None);
        // Repeated once only past the middle: no period within half.
        let once: Vec<f64> = pattern.iter().chain(&pattern[..3]).copied().collect();
        assert_eq!(period_of(&once), None);
        assert_eq!(period_of(&[0.2; 50]), None);
        assert!(repeats_every(&repeated, 14) && !repeats_every(&repeated, 5));
    }

    #[test]
    fn stair_goes_up_and_down_in_one_volt_steps() {
        let s = Stair::default();
        let levels = s.levels();
        assert_eq!(levels.len(), 20);
        assert_eq!(levels[10], 10.0);
        let u = s.generate(0.01);
        assert_eq!(u.len(), 4000);
        assert_eq!(u[0], 0.0);
        assert_eq!(u[1050], 10.0);
        assert_eq!(u[1950], 1.0);
    }

    #[test]
    fn sine_has_t_inside_sin() {
        let r = SineReference {
            omega_rad_s: 2.0,
            ..SineReference::default()
        };
        assert!((r.at(0.0) - 30.0).abs() < 1e-12);
        assert!((r.at(std::f64::consts::PI / 4.0) - 40.0).abs() < 1e-12);
        assert_eq!(r.generate(0.01).len(), 4000);
    }

    #[test]
    fn multisine_is_seeded_and_in_range() {
        let m = Multisine::default();
        let a = m.generate(0.01, 7);
        assert_eq!(a, m.generate(0.01, 7));
        assert_ne!(a, m.generate(0.01, 8));
        assert!(a.iter().all(|v| (1.0 - 1e-9..=9.0 + 1e-9).contains(v)));
    }
}
