//! The displacement and pressure sensors: the true value plus Gaussian noise,
//! rounded to the ADC's step.

use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::config::{Effects, SensorParams};

/// Adds noise of standard deviation `sigma` (one draw from `rng`, unless the
/// noise is removed from the model) and rounds to `counts` per unit. The
/// division by the count rate (not multiplication by a step) keeps recorded
/// values short decimals; `+ 0.0` turns a rounded −0 into 0.
fn read(value: f64, sigma: f64, counts: f64, rng: &mut ChaCha8Rng, fx: &Effects) -> f64 {
    let noisy = match fx.noise.active() {
        Some(scale) => {
            let z: f64 = StandardNormal.sample(rng);
            value + scale * sigma * z
        }
        None => value,
    };
    match fx.quantization.active() {
        Some(scale) if scale > 0.0 => {
            let c = counts / scale;
            (noisy * c).round() / c + 0.0
        }
        _ => noisy,
    }
}

/// Measured displacement (mm) for a contraction `x_m` (m).
pub fn displacement_mm(x_m: f64, p: &SensorParams, rng: &mut ChaCha8Rng, fx: &Effects) -> f64 {
    read(
        x_m * 1e3,
        p.displacement_noise_mm,
        p.displacement_counts_per_mm,
        rng,
        fx,
    )
}

/// Measured gauge pressure (MPa) for a pressure `p_pa` (Pa).
pub fn pressure_mpa(p_pa: f64, p: &SensorParams, rng: &mut ChaCha8Rng, fx: &Effects) -> f64 {
    read(
        p_pa * 1e-6,
        p.pressure_noise_mpa,
        p.pressure_counts_per_mpa,
        rng,
        fx,
    )
}
