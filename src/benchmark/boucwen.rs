//! The Bouc-Wen oscillator of the benchmark (Noël & Schoukens 2016, eq. 1–5)
//! and its Newmark integration, in `f64` (the reference) and in `f32` (the
//! twin that `shaders/boucwen_oscillator.wgsl` spells operation for operation).
//!
//! ```text
//! m·ÿ + c·ẏ + k·y + z = u
//! ż = α·ẏ − β·(γ·|ẏ|·|z|^(ν−1)·z + δ·ẏ·|z|^ν)
//! ```
//!
//! **Identifiability.** β enters only through the products β·γ and β·δ, so
//! (β, γ, δ) are not jointly identifiable from input–output data: (β, γ, δ) and
//! (sβ, γ/s, δ/s) give the same trajectory for every s. The parameter vector
//! therefore carries `bg = β·γ` and `bd = β·δ` (true system: 800 and −1100 m⁻¹).
//! The scale of the unmeasured state z is fixed by its unit coefficient in the
//! force balance, so the remaining parameters are identifiable.
//!
//! **Integration (PDF §3–4).** Newmark with a = ½, b = ¼ for (y, ẏ) and the
//! trapezoidal rule c = ½ for z, at h = 1/15000 s (20 × the 750 Hz sampling
//! rate). Each step predicts with ÿ(t+h) = 0 and ż(t+h) = 0, then corrects by
//! Newton–Raphson until the force balance and the Bouc-Wen equation hold at
//! t + h. The force balance is linear in ÿ(t+h), so it is eliminated and the
//! Newton iteration runs on the single unknown ż(t+h). The initial
//! acceleration comes from the force balance at t = 0.

use crate::model::sim::{DIVERGENCE_BOUND, abs_pow};

/// Newmark's velocity weight `a` (PDF eq. 4).
pub const NEWMARK_A: f64 = 0.5;
/// Newmark's displacement weight `b` (PDF eq. 4).
pub const NEWMARK_B: f64 = 0.25;
/// The weight `c` of the z-integration rule (PDF eq. 5).
pub const NEWMARK_C: f64 = 0.5;
/// The benchmark's working sampling rate (Hz, PDF §4).
pub const FS: f64 = 750.0;
/// Upsampling factor during integration (PDF §4: "strongly advised ... 20").
pub const UPSAMPLE: usize = 20;
/// Newton iterations of the `f32` twin and the shader: a fixed count, so that
/// both execute the same operations. From the ż = 0 predictor three
/// iterations reach `f32` round-off at h = 1/15000 s (the `f64` reference
/// iterates to convergence; `tests/benchmark_boucwen.rs` compares them).
pub const NEWTON_ITERS_F32: usize = 4;

/// Parameter names of the canonical vector, in order.
pub const PARAM_NAMES: [&str; DIM] = ["m", "c", "k", "alpha", "beta_gamma", "beta_delta", "nu"];

/// Parameters of the canonical vector.
pub const DIM: usize = 7;

/// Physical parameters, reparametrised: `bg = β·γ`, `bd = β·δ`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Params {
    /// Mass m_L (kg).
    pub m: f64,
    /// Viscous damping c_L (N·s/m).
    pub c: f64,
    /// Linear stiffness k_L (N/m).
    pub k: f64,
    /// Bouc-Wen stiffness α (N/m).
    pub alpha: f64,
    /// β·γ (1/m).
    pub beta_gamma: f64,
    /// β·δ (1/m).
    pub beta_delta: f64,
    /// Exponent ν.
    pub nu: f64,
}

impl Params {
    /// The benchmark's true system (PDF Table 1: m = 2, c = 10, k = 5e4,
    /// α = 5e4, β = 1e3, γ = 0.8, δ = −1.1, ν = 1).
    pub fn benchmark() -> Params {
        Params {
            m: 2.0,
            c: 10.0,
            k: 5.0e4,
            alpha: 5.0e4,
            beta_gamma: 1.0e3 * 0.8,
            beta_delta: 1.0e3 * -1.1,
            nu: 1.0,
        }
    }

    /// The canonical vector `[m, c, k, α, β·γ, β·δ, ν]`.
    pub fn to_vec(&self) -> [f64; 7] {
        [
            self.m,
            self.c,
            self.k,
            self.alpha,
            self.beta_gamma,
            self.beta_delta,
            self.nu,
        ]
    }

    /// From the canonical vector (see [`PARAM_NAMES`]).
    pub fn from_slice(v: &[f64]) -> Params {
        assert_eq!(v.len(), 7, "the Bouc-Wen oscillator takes 7 parameters");
        Params {
            m: v[0],
            c: v[1],
            k: v[2],
            alpha: v[3],
            beta_gamma: v[4],
            beta_delta: v[5],
            nu: v[6],
        }
    }
}

/// ż and its partial derivatives ∂ż/∂ẏ, ∂ż/∂z, in `f64`.
#[inline]
fn zdot(p: &Params, v: f64, z: f64) -> (f64, f64, f64) {
    let az = z.abs();
    let pz = if p.nu == 1.0 {
        1.0
    } else {
        az.powf(p.nu - 1.0)
    };
    let f = p.alpha * v - p.beta_gamma * v.abs() * pz * z - p.beta_delta * v * pz * az;
    let f_v = p.alpha - p.beta_gamma * v.signum() * pz * z - p.beta_delta * pz * az;
    let f_z = -p.nu * pz * (p.beta_gamma * v.abs() + p.beta_delta * v * sign0(z));
    (f, f_v, f_z)
}

fn sign0(v: f64) -> f64 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Integrates the oscillator from rest (y = ẏ = z = 0, as PDF §4 advises) on
/// the input `u` given at the integration rate (step `h`), and returns the
/// displacement at every integration instant. `None` if the state becomes
/// non-finite or leaves [`DIVERGENCE_BOUND`].
pub fn simulate_f64(p: &Params, u: &[f64], h: f64) -> Option<Vec<f64>> {
    let mut out = Vec::with_capacity(u.len());
    if u.is_empty() {
        return Some(out);
    }
    let (ga, gb, gc) = (NEWMARK_A, NEWMARK_B, NEWMARK_C);
    let (mut y, mut v, mut z, mut zd) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut acc = (u[0] - p.c * v - p.k * y - z) / p.m;
    out.push(y);
    let meff = p.m + p.c * ga * h + p.k * gb * h * h;
    // dẏ(t+h)/dż(t+h) through the eliminated acceleration.
    let dv_ds = -ga * h * gc * h / meff;
    for &u1 in &u[1..] {
        let vp = v + (1.0 - ga) * h * acc;
        let yp = y + h * v + (0.5 - gb) * h * h * acc;
        let zp = z + (1.0 - gc) * h * zd;
        // The force balance m·ÿ1 + c·ẏ1 + k·y1 + z1 = u1 is linear in ÿ1:
        // ÿ1 = (rhs − c_z·h·ż1) / m_eff.
        let rhs = u1 - p.c * vp - p.k * yp - zp;
        let mut s = 0.0; // PDF predictor: ż(t+h) = 0.
        for _ in 0..50 {
            let a1 = (rhs - gc * h * s) / meff;
            let v1 = vp + ga * h * a1;
            let z1 = zp + gc * h * s;
            let (f, f_v, f_z) = zdot(p, v1, z1);
            let g = s - f;
            let dg = 1.0 - f_v * dv_ds - f_z * gc * h;
            let step = g / dg;
            s -= step;
            // A NaN step ends the iteration too.
            let moving = step.abs() > 1e-13 * (1.0 + s.abs());
            if !moving {
                break;
            }
        }
        acc = (rhs - gc * h * s) / meff;
        v = vp + ga * h * acc;
        y = yp + gb * h * h * acc;
        z = zp + gc * h * s;
        zd = s;
        if !(y.abs() <= DIVERGENCE_BOUND as f64 && z.abs() <= 1e12 && v.is_finite()) {
            return None;
        }
        out.push(y);
    }
    Some(out)
}

/// The integrator's step sizes in `f32`, derived from the step `h`: the
/// `f32` twin computes them here and the shader's pipeline header carries
/// these very values (`benchmark::evaluator::source`), so both start from
/// the same bits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepSizes {
    pub h: f32,
    /// `a·h = c·h` (Newmark a = c = 1/2).
    pub half_h: f32,
    /// `b·h²` (Newmark b = 1/4).
    pub quarter_hh: f32,
}

impl StepSizes {
    pub fn new(h: f32) -> StepSizes {
        StepSizes {
            h,
            half_h: 0.5 * h,
            quarter_hh: 0.25 * (h * h),
        }
    }
}

/// The `f32` twin of [`simulate_f64`], scored: integrates from rest on `u`
/// (integration rate) and returns `Σ_j (y(j·stride) − y_meas[j])²` over the
/// measured samples, or `+∞` if a scored displacement is non-finite or leaves
/// [`DIVERGENCE_BOUND`]. Newton runs [`NEWTON_ITERS_F32`] times per step.
///
/// `theta` is the canonical vector in `f32`. Every expression is parenthesised
/// in the order `shaders/boucwen_oscillator.wgsl` evaluates it, and nothing is
/// fused (no `mul_add`): on lavapipe both give the same bits.
pub fn sse_f32(theta: &[f32], u: &[f32], y_meas: &[f32], stride: usize, h: f32) -> f32 {
    let (m, c, k, alpha, bg, bd, nu) = (
        theta[0], theta[1], theta[2], theta[3], theta[4], theta[5], theta[6],
    );
    let n_out = y_meas.len();
    if n_out == 0 {
        return 0.0;
    }
    assert!(
        u.len() > (n_out - 1) * stride,
        "input too short for the scored samples"
    );
    let StepSizes {
        h,
        half_h,
        quarter_hh,
    } = StepSizes::new(h);
    let meff = (m + (c * half_h)) + (k * quarter_hh);
    let dv_ds = -((half_h * half_h) / meff);
    let num1 = nu - 1.0;
    let (mut y, mut v, mut z, mut zd) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
    let mut acc = (((u[0] - (c * v)) - (k * y)) - z) / m;
    let d0 = y - y_meas[0];
    let mut sse = d0 * d0;
    let last = (n_out - 1) * stride;
    for i in 1..=last {
        let u1 = u[i];
        let vp = v + (half_h * acc);
        let yp = (y + (h * v)) + (quarter_hh * acc);
        let zp = z + (half_h * zd);
        let rhs = ((u1 - (c * vp)) - (k * yp)) - zp;
        let mut s = 0.0f32;
        for _ in 0..NEWTON_ITERS_F32 {
            let a1 = (rhs - (half_h * s)) / meff;
            let v1 = vp + (half_h * a1);
            let z1 = zp + (half_h * s);
            let az = z1.abs();
            let pz = abs_pow(az, num1);
            let f = ((alpha * v1) - ((bg * v1.abs()) * (pz * z1))) - ((bd * v1) * (pz * az));
            let f_v = (alpha - ((bg * sgn32(v1)) * (pz * z1))) - (bd * (pz * az));
            let f_z = (-(nu * pz)) * ((bg * v1.abs()) + ((bd * v1) * sgn32(z1)));
            let g = s - f;
            let dg = (1.0 - (f_v * dv_ds)) - (f_z * half_h);
            s -= g / dg;
        }
        acc = (rhs - (half_h * s)) / meff;
        v = vp + (half_h * acc);
        y = yp + (quarter_hh * acc);
        z = zp + (half_h * s);
        zd = s;
        if i % stride == 0 {
            // NaN counts as diverged.
            let bounded = y.abs() <= DIVERGENCE_BOUND;
            if !bounded {
                return f32::INFINITY;
            }
            let d = y - y_meas[i / stride];
            sse += d * d;
        }
    }
    if sse.is_finite() { sse } else { f32::INFINITY }
}

/// `sgn` with `sgn(0) = 0`, as WGSL's `sign`.
#[inline(always)]
fn sgn32(v: f32) -> f32 {
    crate::model::sim::sgn(v)
}
