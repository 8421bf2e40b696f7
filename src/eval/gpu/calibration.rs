//! The calibration kernel: how many `f32` operations a second the device
//! does, timed by its own clock, so that a model kernel's rate reads as a
//! share of what the device can do (`mckibben bench`).
//!
//! `shaders/calibration.wgsl` runs, in every invocation, a loop whose step
//! has a known number of operations ([`Variant::ops_per_step`]) in three
//! shapes: one chain of dependent mul-adds (bound by an operation's
//! latency), eight independent chains (bound by the throughput: the
//! ceiling) and eight chains of `pow` and an add. It runs on the project's
//! one host (`Host::run_probe`); [`reference()`] is the CPU's evaluation of
//! the same loop, which the mul-add variants match bit for bit (each product
//! is exact, so a fused and an unfused mul-add round alike).
//!
//! The model kernels' own operation counts ([`ops_per_candidate_sample`])
//! turn their candidate-samples a second into operations a second.

use serde::Serialize;

use super::host::Host;
use crate::model::Family;

const SOURCE: &str = include_str!("../../../shaders/calibration.wgsl");

/// Chains of the independent and pow variants, and mul-adds a step of the
/// dependent one: enough independent work to hide an operation's latency
/// on a GPU's core, and on a CPU's vector unit (lavapipe).
pub const CHAINS: u32 = 8;

/// The loop's operands, the shader's uniform block: values only the run
/// knows, so that the compiler cannot fold the loop.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Operands {
    steps: u32,
    count: u32,
    pad: [u32; 2],
    scale: f32,
    exponent: f32,
    base: f32,
    spread: f32,
}

/// The multiplier of every mul-add: a power of two, so that each product is
/// exact (a fused and an unfused mul-add round alike) and each chain tends
/// to twice its addend, bounded for any number of steps.
const SCALE: f32 = 0.5;
/// The pow variant's exponent: the chains tend to a fixed point above 1.
const EXPONENT: f32 = 0.5;
/// Chain j's addend is `BASE + j · SPREAD + (i mod 256) · SPREAD / 256`,
/// exact in `f32` (multiples of 2⁻¹⁰ below 4).
const BASE: f32 = 1.0;
const SPREAD: f32 = 0.25;

/// The loop's shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Variant {
    /// One chain of [`CHAINS`] mul-adds a step, each waiting on the one before.
    Dependent,
    /// [`CHAINS`] chains of one mul-add a step: the throughput ceiling.
    Independent,
    /// [`CHAINS`] chains of one `pow` and one add a step.
    Pow,
}

impl Variant {
    pub const ALL: [Variant; 3] = [Variant::Dependent, Variant::Independent, Variant::Pow];

    pub fn name(self) -> &'static str {
        match self {
            Variant::Dependent => "dependent",
            Variant::Independent => "independent",
            Variant::Pow => "pow",
        }
    }

    /// `f32` operations in one step of one invocation: a mul-add counts
    /// two (a multiply and an add, as a device's data sheet counts an FMA),
    /// a `pow` one.
    pub fn ops_per_step(self) -> u32 {
        2 * CHAINS
    }

    /// The pipeline's WGSL: the variant's switch and the kernel.
    pub fn source(self) -> String {
        let index = match self {
            Variant::Dependent => 0,
            Variant::Independent => 1,
            Variant::Pow => 2,
        };
        format!("const VARIANT: u32 = {index}u;\n{SOURCE}")
    }
}

/// Chain `j`'s addend in invocation `i`, as the shader's `addend` forms it.
fn addend(i: u32, j: u32) -> f32 {
    (BASE + j as f32 * SPREAD) + (i & 255) as f32 * (SPREAD * 0.003_906_25)
}

/// The CPU's evaluation of invocation `i`'s loop over `steps` steps: the
/// shader's operations in its order. The mul-add variants give the
/// device's bits; `pow` is within the device's accuracy only.
pub fn reference(variant: Variant, i: u32, steps: u32) -> f32 {
    let a: [f32; CHAINS as usize] = std::array::from_fn(|j| addend(i, j as u32));
    if variant == Variant::Dependent {
        let mut x = a[0];
        for _ in 0..steps {
            for &aj in &a {
                x = x * SCALE + aj;
            }
        }
        return x;
    }
    let mut x = a;
    for _ in 0..steps {
        for (xj, &aj) in x.iter_mut().zip(&a) {
            *xj = match variant {
                Variant::Pow => xj.powf(EXPONENT) + aj,
                _ => *xj * SCALE + aj,
            };
        }
    }
    ((x[0] + x[1]) + (x[2] + x[3])) + ((x[4] + x[5]) + (x[6] + x[7]))
}

/// Runs `variant` for `steps` steps in `invocations` invocations: what each
/// invocation wrote, and the pass's device time (`None` where the adapter
/// offers no timestamp queries).
pub fn run(
    host: &mut Host,
    variant: Variant,
    invocations: u32,
    steps: u32,
) -> anyhow::Result<(Vec<f32>, Option<f64>)> {
    let operands = Operands {
        steps,
        count: invocations,
        pad: [0; 2],
        scale: SCALE,
        exponent: EXPONENT,
        base: BASE,
        spread: SPREAD,
    };
    host.run_probe(
        &variant.source(),
        "calibration",
        bytemuck::bytes_of(&operands),
        invocations,
    )
}

/// How large a calibration runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sizing {
    /// Invocations of each pass (a multiple of 64 fills whole workgroups).
    pub invocations: u32,
    /// Each variant's steps grow until the loop's own time (the difference
    /// of two passes, [`ceiling`]) is at least this long on the device's
    /// clock, or the longer pass reaches `max_steps`.
    pub min_seconds: f64,
    pub max_steps: u32,
}

impl Default for Sizing {
    /// 2²⁰ invocations: several per core of the largest GPUs, so that the
    /// dependent chains of many invocations can hide each other's latency;
    /// at least 20 ms of loop, far above the clock's resolution.
    fn default() -> Self {
        Sizing {
            invocations: 1 << 20,
            min_seconds: 0.02,
            max_steps: 1 << 24,
        }
    }
}

/// One variant timed: passes of `s` and of `4s` steps, `steps = 3s` apart.
#[derive(Debug, Clone, Serialize)]
pub struct Timed {
    pub variant: Variant,
    pub ops_per_step: u32,
    /// The steps the longer pass adds.
    pub steps: u32,
    /// The longer pass's device time less the shorter one's: the time of
    /// `steps` steps alone, without what a pass costs whatever its length
    /// (its start, each invocation's set-up and write).
    pub device_s: f64,
    /// `invocations · steps · ops_per_step / device_s`.
    pub ops_per_s: f64,
}

/// Every variant timed on one device.
#[derive(Debug, Clone, Serialize)]
pub struct Ceiling {
    pub invocations: u32,
    pub variants: Vec<Timed>,
}

impl Ceiling {
    /// The rate of `variant`.
    pub fn ops_per_s(&self, variant: Variant) -> Option<f64> {
        self.variants
            .iter()
            .find(|t| t.variant == variant)
            .map(|t| t.ops_per_s)
    }

    /// The throughput ceiling: the independent chains' rate.
    pub fn ceiling_ops_per_s(&self) -> f64 {
        self.ops_per_s(Variant::Independent).unwrap_or(f64::NAN)
    }
}

/// Times every variant on `host`: a pass of `s` steps and one of `4s`,
/// each the fastest of `REPEATS` (what else runs on the device only ever
/// slows a pass), whose difference is the time of `3s` steps alone (a
/// pass's fixed costs, large on a CPU adapter, cancel), from `s = 1` up
/// until that difference is as long as `sizing` asks. `None` where the
/// adapter offers no timestamp queries; an error if an invocation's result
/// is not finite, or if the longer pass is never the longer.
pub fn ceiling(host: &mut Host, sizing: Sizing) -> anyhow::Result<Option<Ceiling>> {
    let mut variants = Vec::with_capacity(Variant::ALL.len());
    for variant in Variant::ALL {
        let mut steps = 1u32;
        loop {
            let (Some(short), Some(long)) = (
                fastest_pass(host, variant, sizing.invocations, steps)?,
                fastest_pass(host, variant, sizing.invocations, 4 * steps)?,
            ) else {
                return Ok(None);
            };
            let loop_s = long - short;
            let last = 4 * steps >= sizing.max_steps;
            if loop_s >= sizing.min_seconds || (last && loop_s > 0.0) {
                let ops = f64::from(sizing.invocations)
                    * f64::from(3 * steps)
                    * f64::from(variant.ops_per_step());
                variants.push(Timed {
                    variant,
                    ops_per_step: variant.ops_per_step(),
                    steps: 3 * steps,
                    device_s: loop_s,
                    ops_per_s: ops / loop_s,
                });
                break;
            }
            anyhow::ensure!(
                !last,
                "the calibration kernel ({}): a pass of {} steps took no longer than one of {steps} \
                 on the device's clock ({long:.3e} s against {short:.3e} s)",
                variant.name(),
                4 * steps
            );
            // Aim a quarter past the target, at most 64 times further; four
            // times where the difference was lost in the passes' noise.
            let factor = if loop_s > 0.0 {
                (sizing.min_seconds / loop_s * 1.25).clamp(2.0, 64.0)
            } else {
                4.0
            };
            steps = (f64::from(steps) * factor)
                .ceil()
                .min(f64::from(sizing.max_steps / 4).max(1.0)) as u32;
        }
    }
    Ok(Some(Ceiling {
        invocations: sizing.invocations,
        variants,
    }))
}

/// Passes of each length [`ceiling`] times, the fastest kept.
const REPEATS: usize = 2;

/// The shortest device time of [`REPEATS`] passes (`None` without
/// timestamp queries), every result checked to be finite.
fn fastest_pass(
    host: &mut Host,
    variant: Variant,
    invocations: u32,
    steps: u32,
) -> anyhow::Result<Option<f64>> {
    let mut fastest: Option<f64> = None;
    for _ in 0..REPEATS {
        let (values, seconds) = run(host, variant, invocations, steps)?;
        if let Some((i, v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            anyhow::bail!(
                "the calibration kernel ({}) wrote {v} in invocation {i}: the device's f32 arithmetic is off",
                variant.name()
            );
        }
        let Some(seconds) = seconds else {
            return Ok(None);
        };
        fastest = Some(fastest.map_or(seconds, |f| f.min(seconds)));
    }
    Ok(fastest)
}

/// `f32` operations a model kernel spends on one candidate-sample of the
/// free run, where that is a fixed count: the plain families at `n = 1`
/// (`None` with effect stages, whose count depends on the chain, and with
/// a free exponent, whose `pow` is no fixed number of operations).
///
/// Counted from the shaders as written: every add, subtract and multiply
/// in the per-sample loop (a mul-add two, as [`Variant::ops_per_step`]
/// counts), leaving out what a compiler removes: operations on the
/// candidate's constants alone (hoisted out of the loop) and the products
/// by the literal 1 that `abs_pow` gives at `n = 1`. Not counted: `abs`,
/// `sgn` and the bounds checks (comparisons and selects), the integer
/// work (`rounded()`'s XOR, indices) and the loads. A change to a family's
/// step in `shaders/` must change its count here.
pub fn ops_per_candidate_sample(family: Family, effects: bool, n_one: bool) -> Option<u32> {
    if effects || !n_one {
        return None;
    }
    Some(match family {
        Family::Linear => LINEAR_OPS,
        Family::Classic => CLASSIC_OPS,
        Family::Generalized => GENERALIZED_OPS,
    })
}

/// The score's share of every family's sample (`driver.wgsl`'s `score`):
/// `err = x − y`, `err · err`, `acc + …`.
const SCORE_OPS: u32 = 3;

/// `linear_part` (`prologue.wgsl`): `α·x`, `·w` (its `1 − α` is hoisted),
/// their sum, `a·(…)`, `b·u`, two adds; then `driver.wgsl`'s
/// `Δ = x_new − x`: 7 + 1.
const LINEAR_PART_OPS: u32 = 8;

/// `linear.wgsl`'s `linear_step`: `a·x`, `b·u`, two adds (its `Δ` feeds a
/// hysteresis that returns 0, so it is dead code); and the score.
const LINEAR_OPS: u32 = 4 + SCORE_OPS;

/// `linear_part` and `Δ`; `classic_w` at `n = 1` (`|w|^(n−1)` is the literal
/// 1): `A·Δ`, `w + …`, `β·|Δ|`, its product with `w`, the subtraction,
/// `γ·Δ`, its product with `|w|`, the subtraction (8); and the score.
const CLASSIC_OPS: u32 = LINEAR_PART_OPS + 8 + SCORE_OPS;

/// `linear_part` and `Δ`; `generalized_w` at `n = 1`: `x − x_s`, the three
/// sign products, the six products by `β1..β6`, the five adds of `ψ`,
/// `|w|·ψ`, `A − …`, `Δ·(…)`, `w + …` (19); and the score.
const GENERALIZED_OPS: u32 = LINEAR_PART_OPS + 19 + SCORE_OPS;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reference_stays_bounded_and_the_mul_add_chains_tend_to_twice_their_addends() {
        for variant in Variant::ALL {
            for i in [0, 1, 255, 256, 70_000] {
                let v = reference(variant, i, 1000);
                assert!(v.is_finite() && v > 0.0, "{variant:?} {i}: {v}");
            }
        }
        // One chain: x ← x/2 + a at its fixed point 2a.
        let twice: f32 = (0..CHAINS).map(|j| 2.0 * addend(3, j)).sum();
        assert_eq!(reference(Variant::Independent, 3, 200), twice);
        // The addends are exact: chain 7 of invocation 255 is 1 + 7/4 + 255/1024.
        assert_eq!(addend(255, 7), 1.0 + 1.75 + 255.0 / 1024.0);
    }

    #[test]
    fn only_the_plain_families_at_n_one_have_a_count() {
        assert_eq!(
            ops_per_candidate_sample(Family::Classic, false, true),
            Some(19)
        );
        assert_eq!(
            ops_per_candidate_sample(Family::Generalized, false, true),
            Some(30)
        );
        assert_eq!(
            ops_per_candidate_sample(Family::Linear, false, true),
            Some(7)
        );
        assert_eq!(ops_per_candidate_sample(Family::Classic, true, true), None);
        assert_eq!(
            ops_per_candidate_sample(Family::Classic, false, false),
            None
        );
    }
}
