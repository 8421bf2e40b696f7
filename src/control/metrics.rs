//! Tracking and effort measures of an episode, over its steady-state part.

use serde::{Deserialize, Serialize};

/// What an episode scored.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Metrics {
    /// RMS of `r − y` over the steady-state part (mm).
    pub rms_error_mm: f64,
    /// Largest `|r − y|` over the steady-state part (mm).
    pub max_error_mm: f64,
    /// RMS of the valve command about its mean over the steady-state part (V).
    pub effort_rms_v: f64,
    /// Valve travel per second, `Σ|Δu| / T` over the steady-state part (V/s).
    pub effort_travel_v_per_s: f64,
    /// Samples whose command broke the valve range or the slew limit.
    pub constraint_violations: usize,
    /// Samples whose measurement was missing (a rig over a link); the
    /// command in force was held and the sample is left out of the errors.
    pub missing_measurements: usize,
    /// Longest time one controller step took (µs), wall clock.
    pub max_step_time_us: f64,
    /// Longest CPU time of one controller step (µs): the thread's own CPU
    /// time, without the waits for a core that a loaded machine adds to the
    /// wall clock (NaN where the platform has no thread clock).
    pub max_step_cpu_us: f64,
    /// Mean time of one controller step (µs), wall clock.
    pub mean_step_time_us: f64,
    /// Steps whose CPU time (the wall clock's where there is no thread
    /// clock) exceeded the sample time: on a real-time rig each such
    /// command comes late, and the measurements queue behind it, each one
    /// older than the loop takes it to be.
    pub overrun_steps: usize,
    /// RMS of `r − mean(r)` over the steady-state part (mm): the error of a
    /// muscle held still at the reference's mean. A loop that scores above
    /// it tracks worse than doing nothing.
    pub holding_rms_mm: f64,
    /// A measurement became non-finite, or the steady-state error exceeded
    /// [`DIVERGENCE_FACTOR`] times the reference amplitude.
    pub diverged: bool,
}

/// An error larger than this many reference amplitudes counts as divergence:
/// the loop is then worse than a muscle that does not move at all.
pub const DIVERGENCE_FACTOR: f64 = 3.0;

impl Metrics {
    /// Whether the loop tracked worse than a muscle held still at the
    /// reference's mean ([`Metrics::holding_rms_mm`]), short of diverging,
    /// over a scored part where the reference of `amplitude` moves (its
    /// RMS about its mean a tenth of the amplitude at least: on one plateau
    /// of the steps holding is perfect, and any error would read as worse).
    pub fn worse_than_holding(&self, amplitude: f64) -> bool {
        !self.diverged
            && self.holding_rms_mm >= 0.1 * amplitude
            && self.rms_error_mm > self.holding_rms_mm
    }

    /// Measures the samples with `t ≥ steady_from` (no samples: NaN errors).
    pub fn of(
        t: &[f64],
        reference: &[f64],
        y: &[f64],
        u: &[f64],
        steady_from: f64,
        amplitude: f64,
    ) -> Metrics {
        let first = t
            .iter()
            .position(|&t| t >= steady_from - 1e-9)
            .unwrap_or(t.len());
        let err: Vec<f64> = (first..t.len())
            .filter(|&k| !y[k].is_nan())
            .map(|k| reference[k] - y[k])
            .collect();
        let n = err.len() as f64;
        let rms = (err.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
        let steady = &reference[first..];
        let mean_r = steady.iter().sum::<f64>() / steady.len() as f64;
        let holding =
            (steady.iter().map(|r| (r - mean_r).powi(2)).sum::<f64>() / steady.len() as f64).sqrt();
        let max = err.iter().fold(f64::NAN, |m, e| m.max(e.abs()));
        let us = &u[first..];
        let n_u = us.len() as f64;
        let mean_u = us.iter().sum::<f64>() / n_u;
        let effort_rms = (us.iter().map(|v| (v - mean_u).powi(2)).sum::<f64>() / n_u).sqrt();
        let travel: f64 = us.windows(2).map(|w| (w[1] - w[0]).abs()).sum();
        let span = match (t.get(first), t.last()) {
            (Some(a), Some(b)) if b > a => b - a,
            _ => f64::NAN,
        };
        Metrics {
            rms_error_mm: rms,
            max_error_mm: max,
            effort_rms_v: effort_rms,
            effort_travel_v_per_s: travel / span,
            constraint_violations: 0,
            missing_measurements: 0,
            max_step_time_us: 0.0,
            mean_step_time_us: 0.0,
            max_step_cpu_us: 0.0,
            overrun_steps: 0,
            holding_rms_mm: holding,
            // NaN (no steady samples, or a non-finite error) counts as diverged.
            diverged: max.is_nan() || max > DIVERGENCE_FACTOR * amplitude,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scores_only_the_steady_part() {
        let t: Vec<f64> = (0..100).map(|k| k as f64 * 0.1).collect();
        let r = vec![1.0; 100];
        // 5 mm error before t = 5, 1 mm after.
        let y: Vec<f64> = t
            .iter()
            .map(|&t| if t < 5.0 { -4.0 } else { 0.0 })
            .collect();
        let u: Vec<f64> = (0..100).map(|k| (k % 2) as f64).collect();
        let m = Metrics::of(&t, &r, &y, &u, 5.0, 10.0);
        assert!((m.rms_error_mm - 1.0).abs() < 1e-12);
        // A constant reference: holding it scores 0, and no error is
        // called worse than that.
        assert_eq!(m.holding_rms_mm, 0.0);
        assert!(!m.worse_than_holding(10.0));
        assert_eq!(m.max_error_mm, 1.0);
        assert!((m.effort_rms_v - 0.5).abs() < 1e-12);
        assert!(!m.diverged);
        // The 5 mm transient does not count; a steady 1 mm error on a 0.3 mm
        // sine (more than three amplitudes) does.
        assert!(!Metrics::of(&t, &r, &y, &u, 5.0, 1.0).diverged);
        assert!(Metrics::of(&t, &r, &y, &u, 5.0, 0.3).diverged);
    }

    /// Holding still at the mean of a sine scores its amplitude over √2: a
    /// loop at that error is no better than holding, one below it is.
    #[test]
    fn holding_at_the_mean_is_the_yardstick() {
        let t: Vec<f64> = (0..1000).map(|k| k as f64 * 0.01).collect();
        let r: Vec<f64> = t.iter().map(|&t| 30.0 + 10.0 * (2.0 * t).sin()).collect();
        let u = vec![0.0; 1000];
        let mean = r.iter().sum::<f64>() / 1000.0;
        let held = Metrics::of(&t, &r, &vec![mean; 1000], &u, 0.0, 10.0);
        // 3.2 periods: near the amplitude over √2, not on it.
        assert!(
            (held.holding_rms_mm - 10.0 / 2f64.sqrt()).abs() < 0.1,
            "{held:?}"
        );
        assert!((held.rms_error_mm - held.holding_rms_mm).abs() < 1e-12);
        assert!(!held.worse_than_holding(10.0));
        let lagging: Vec<f64> = t
            .iter()
            .map(|&t| 30.0 + 10.0 * (2.0 * t - 1.7).sin())
            .collect();
        assert!(Metrics::of(&t, &r, &lagging, &u, 0.0, 10.0).worse_than_holding(10.0));
        let close: Vec<f64> = r.iter().map(|r| r + 0.1).collect();
        assert!(!Metrics::of(&t, &r, &close, &u, 0.0, 10.0).worse_than_holding(10.0));
    }
}
