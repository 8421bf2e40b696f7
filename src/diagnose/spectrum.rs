//! The residual's spectrum and its peaks: a resonance the model lacks (the
//! Cavatappi muscle's hanging load ringing at about 4 Hz after each pressure
//! step) shows as a narrow peak, which the five broad bands of
//! [`locate`](super::locate) smear out.
//!
//! **Welch's method** (Welch 1967): each series is cut into half-overlapping
//! segments, each segment's linear trend removed (a drift would otherwise
//! leak from the lowest bins into the rest), a Hann window applied, and the
//! periodograms averaged. Averaging `K` segments divides the variance of
//! each bin by about `K`, which is what lets a peak be told from a noisy bin;
//! the segment is the longest power of two, no longer than the shortest
//! series, that still gives at least [`MIN_SEGMENTS`] segments over all the
//! series (the diagnosis' selection part is several blocks of a record).
//!
//! **A peak** is a bin that is the largest within ±2 bins (the Hann window's
//! main lobe) and stands at least [`Settings::min_prominence`] times above
//! the background there: the medians of its two flanks (bins 3 to 8 away on
//! either side, the lower one cut short at bin 1) interpolated in log power,
//! i.e. their geometric mean. A resonance on the falling slope of a step
//! response's spectrum stands above that line; a drift's spectrum (power
//! falling as 1/f² into a flat noise floor) is convex in log power, so the
//! line lies above it and no bin of it counts.

use serde::Serialize;

/// At least this many half-overlapping segments are averaged.
pub const MIN_SEGMENTS: usize = 7;
/// Bins either side of a peak that belong to it (the Hann main lobe).
const LOBE: usize = 2;
/// Bins either side, beyond the lobe, that make a flank.
const FLANK: usize = 6;
/// Bins of the lower flank that suffice near DC.
const MIN_LOWER_FLANK: usize = 2;

/// Settings of the peak detection.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Settings {
    /// A peak stands this many times above its flanks' background.
    /// Each averaged bin is about the true density times `χ²_ν/ν` with
    /// `ν ≈ 2·K ≥ 14` (`K` segments); a bin of white noise four times its
    /// flanks' median has a chance of about 1e-6, so none of the few hundred
    /// bins of a spectrum passes by chance.
    pub min_prominence: f64,
    /// And carries at least this share of the residual's energy above its
    /// flanks: a peak a thousand times below the rest matters to nobody.
    pub min_energy_share: f64,
    /// At most this many peaks are reported, largest share first.
    pub max_peaks: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            min_prominence: 4.0,
            min_energy_share: 0.01,
            max_peaks: 5,
        }
    }
}

/// One spectral peak.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Peak {
    /// Frequency (Hz), refined between bins by a parabola through the log
    /// power of the peak bin and its neighbours.
    pub hz: f64,
    /// Power of the peak bin over the geometric mean of its two flanks' medians.
    pub prominence: f64,
    /// Share of the residual's (detrended) energy in the peak's lobe above the flanks.
    pub energy_share: f64,
}

/// A Welch power spectral density.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Spectrum {
    /// Bin frequencies (Hz), DC to Nyquist.
    pub hz: Vec<f64>,
    /// One-sided density (signal units² per Hz).
    pub power: Vec<f64>,
    /// Segment length (samples) and segments averaged.
    pub segment: usize,
    pub segments: usize,
    pub peaks: Vec<Peak>,
}

/// In-place radix-2 FFT of `re + i·im` (length a power of two).
fn fft(re: &mut [f64], im: &mut [f64]) {
    let n = re.len();
    debug_assert!(n.is_power_of_two() && im.len() == n);
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let step = -2.0 * std::f64::consts::PI / len as f64;
        for start in (0..n).step_by(len) {
            for k in 0..len / 2 {
                let (s, c) = (step * k as f64).sin_cos();
                let (a, b) = (start + k, start + k + len / 2);
                let (xr, xi) = (re[b] * c - im[b] * s, re[b] * s + im[b] * c);
                re[b] = re[a] - xr;
                im[b] = im[a] - xi;
                re[a] += xr;
                im[a] += xi;
            }
        }
        len <<= 1;
    }
}

/// The segment `v` less its least-squares line.
fn detrended(v: &[f64]) -> Vec<f64> {
    let n = v.len() as f64;
    let tm = (n - 1.0) / 2.0;
    let vm = v.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (k, x) in v.iter().enumerate() {
        sxy += (k as f64 - tm) * (x - vm);
        sxx += (k as f64 - tm).powi(2);
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    v.iter()
        .enumerate()
        .map(|(k, x)| x - vm - slope * (k as f64 - tm))
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len().is_multiple_of(2) {
        0.5 * (v[m - 1] + v[m])
    } else {
        v[m]
    }
}

/// Welch spectrum of `series` (sampled every `dt` s; the periodograms of
/// all series are averaged together) and its peaks; `None` when the series
/// are too short for [`MIN_SEGMENTS`] segments of 32 samples.
pub fn welch(series: &[&[f64]], dt: f64, settings: &Settings) -> Option<Spectrum> {
    let shortest = series.iter().map(|s| s.len()).min()?;
    if dt.is_nan() || dt <= 0.0 || shortest < 32 {
        return None;
    }
    // A series of n samples holds ⌊(n − L)/(L/2)⌋ + 1 half-overlapping
    // segments of length L.
    let count =
        |seg: usize| -> usize { series.iter().map(|s| (s.len() - seg) / (seg / 2) + 1).sum() };
    let seg = (5..=shortest.ilog2())
        .rev()
        .map(|p| 1usize << p)
        .find(|&seg| count(seg) >= MIN_SEGMENTS)?;
    let hann: Vec<f64> = (0..seg)
        .map(|k| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * k as f64 / seg as f64).cos())
        .collect();
    let w2: f64 = hann.iter().map(|w| w * w).sum();
    let bins = seg / 2 + 1;
    let mut power = vec![0.0; bins];
    let mut segments = 0;
    for s in series {
        for start in (0..=s.len() - seg).step_by(seg / 2) {
            let mut re: Vec<f64> = detrended(&s[start..start + seg])
                .iter()
                .zip(&hann)
                .map(|(x, w)| x * w)
                .collect();
            let mut im = vec![0.0; seg];
            fft(&mut re, &mut im);
            for (j, p) in power.iter_mut().enumerate() {
                // One-sided: the negative frequencies folded onto the positive.
                let fold = if j == 0 || j == seg / 2 { 1.0 } else { 2.0 };
                *p += fold * (re[j] * re[j] + im[j] * im[j]) * dt / w2;
            }
            segments += 1;
        }
    }
    power.iter_mut().for_each(|p| *p /= segments as f64);
    let bin_hz = 1.0 / (seg as f64 * dt);
    let hz: Vec<f64> = (0..bins).map(|j| j as f64 * bin_hz).collect();
    let peaks = peaks(&power, bin_hz, settings);
    Some(Spectrum {
        hz,
        power,
        segment: seg,
        segments,
        peaks,
    })
}

/// The peaks of `power` (bin 0 is DC, bins `bin_hz` apart).
fn peaks(power: &[f64], bin_hz: f64, settings: &Settings) -> Vec<Peak> {
    let total: f64 = power.iter().skip(1).sum();
    if total.is_nan() || total <= 0.0 {
        return Vec::new();
    }
    let n = power.len();
    let mut found = Vec::new();
    // Bin 0 (DC, zero after detrending) never belongs to a flank. A peak
    // needs a whole upper flank but only `MIN_LOWER_FLANK` bins of the lower
    // one, so that a resonance a few bins above DC (4 Hz is bin 5 of a
    // Cavatappi validation half) can be found; where the spectrum falls,
    // the lower flank is the higher one anyway.
    for j in (1 + LOBE + MIN_LOWER_FLANK)..n.saturating_sub(LOBE + FLANK) {
        let lobe = &power[j - LOBE..=j + LOBE];
        if lobe.iter().any(|&p| p > power[j]) {
            continue;
        }
        let left = median(power[(j - LOBE).saturating_sub(FLANK).max(1)..j - LOBE].to_vec());
        let right = median(power[j + LOBE + 1..=j + LOBE + FLANK].to_vec());
        // The background under the peak: the flanks' medians interpolated
        // in log power, i.e. their geometric mean.
        let floor = (left * right).sqrt();
        let prominence = if floor > 0.0 {
            power[j] / floor
        } else {
            f64::INFINITY
        };
        let excess: f64 = lobe.iter().map(|&p| (p - floor).max(0.0)).sum();
        let energy_share = excess / total;
        if prominence < settings.min_prominence || energy_share < settings.min_energy_share {
            continue;
        }
        // Parabola through the log power of the peak bin and its neighbours.
        let (a, b, c) = (
            power[j - 1].max(f64::MIN_POSITIVE).ln(),
            power[j].max(f64::MIN_POSITIVE).ln(),
            power[j + 1].max(f64::MIN_POSITIVE).ln(),
        );
        let denom = a - 2.0 * b + c;
        let offset = if denom < 0.0 {
            (0.5 * (a - c) / denom).clamp(-0.5, 0.5)
        } else {
            0.0
        };
        found.push(Peak {
            hz: (j as f64 + offset) * bin_hz,
            prominence,
            energy_share,
        });
    }
    found.sort_by(|a, b| b.energy_share.total_cmp(&a.energy_share));
    found.truncate(settings.max_peaks);
    found
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    fn noise(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let d = Normal::new(0.0, sigma).unwrap();
        (0..n).map(|_| d.sample(&mut rng)).collect()
    }

    const DT: f64 = 0.01;

    #[test]
    fn fft_matches_the_plain_dft() {
        let x = noise(16, 1.0, 9);
        let (mut re, mut im) = (x.clone(), vec![0.0; 16]);
        fft(&mut re, &mut im);
        for j in 0..16 {
            let (mut r, mut i) = (0.0, 0.0);
            for (k, v) in x.iter().enumerate() {
                let ang = -2.0 * std::f64::consts::PI * (j * k) as f64 / 16.0;
                r += v * ang.cos();
                i += v * ang.sin();
            }
            assert!(
                (re[j] - r).abs() < 1e-9 && (im[j] - i).abs() < 1e-9,
                "bin {j}"
            );
        }
    }

    #[test]
    fn white_noise_has_the_right_level_and_no_peak() {
        for seed in 1..=40 {
            // As long as a Cavatappi validation half, and as the default data's.
            let r = noise(if seed % 2 == 0 { 673 } else { 2000 }, 0.5, seed);
            let s = welch(&[&r], DT, &Settings::default()).unwrap();
            assert!(s.peaks.is_empty(), "seed {seed}: {:?}", s.peaks);
            // Density of white noise: σ²·2·dt one-sided.
            let mid = median(s.power[5..s.power.len() - 5].to_vec());
            let want = 0.25 * 2.0 * DT;
            assert!((mid / want - 1.0).abs() < 0.25, "{mid} vs {want}");
        }
    }

    /// A damped 4 Hz ringing after every step of a stair (a hanging load
    /// on a stiff spring), plus white noise.
    fn ringing(n: usize, seed: u64) -> Vec<f64> {
        let e = noise(n, 0.1, seed);
        (0..n)
            .map(|k| {
                let since = (k % 150) as f64 * DT;
                let sign = if (k / 150) % 2 == 0 { 1.0 } else { -1.0 };
                sign * (-since / 0.3).exp() * (2.0 * std::f64::consts::PI * 4.0 * since).sin()
                    + e[k]
            })
            .collect()
    }

    #[test]
    fn ringing_after_steps_shows_a_peak_at_its_frequency() {
        // Short as a Cavatappi validation half (673 samples at 100 Hz).
        for (n, seed) in [(673, 1), (2000, 2)] {
            let r = ringing(n, seed);
            let s = welch(&[&r], DT, &Settings::default()).unwrap();
            let bin = s.hz[1];
            let top = s.peaks.first().unwrap_or_else(|| panic!("no peak: {s:?}"));
            assert!((top.hz - 4.0).abs() <= bin, "{top:?}, bin {bin}");
            assert!(top.energy_share > 0.3, "{top:?}");
        }
    }

    #[test]
    fn a_slow_drift_is_no_peak() {
        // An exponential creep over the whole record plus a random walk
        // (power falling as 1/f²) and a little white noise.
        let n = 2000;
        let (steps, e) = (noise(n, 0.02, 3), noise(n, 0.01, 4));
        let mut walk = 0.0;
        let r: Vec<f64> = (0..n)
            .map(|k| {
                walk += steps[k];
                2.0 * (1.0 - (-(k as f64) * DT / 8.0).exp()) + walk + e[k]
            })
            .collect();
        let s = welch(&[&r], DT, &Settings::default()).unwrap();
        assert!(s.peaks.is_empty(), "{:?}", s.peaks);
    }

    #[test]
    fn too_short_a_series_gives_no_spectrum() {
        assert!(welch(&[&noise(100, 1.0, 1)], DT, &Settings::default()).is_none());
        assert!(welch(&[], DT, &Settings::default()).is_none());
    }
}
