//! The CPU evaluator: the reference numbers, computed fast.
//!
//! Candidates are advanced [`LANES`] at a time, side by side, each lane in its
//! own slot of plain `f32` arrays, so that the compiler turns the inner loop
//! into SIMD instructions (a naive one-candidate loop runs about ten times
//! slower, DESIGN.md §4), compiled for AVX-512 or AVX2 where the CPU has them. Every lane calls the very step functions of
//! [`crate::model::sim`] (the single source of truth), in the same order and
//! without fused multiply-adds, so each lane's SSE is bit-identical to
//! [`crate::model::sse`] for that candidate.
//!
//! Divergence: `sse` stops at the first out-of-bounds state and returns `+∞`.
//! A batch cannot stop one lane, so each lane carries a mask that latches at
//! the first out-of-bounds state; a latched lane's SSE is `+∞` whatever it
//! accumulated afterwards. The batch stops early once every lane has latched.
//!
//! Batches are spread over threads with rayon. Each batch is computed by one
//! thread from its own inputs only, so results do not depend on the number of
//! threads.

use rayon::prelude::*;

use super::{Evaluator, Problem, Scores, to_f32};
use crate::model::Family;
use crate::model::sim::{classic_w, generalized_w, in_bounds, linear_part, linear_step};

/// Candidates advanced side by side in one batch. One step of one candidate
/// is a chain of about ten dependent operations (x → Δ → w → next x), so a
/// single vector of 16 lanes waits on latency; 32 lanes (two AVX-512 or four
/// AVX2 registers per quantity) keep independent chains in flight: 1.8× the
/// throughput of 16 lanes here, while 64 lanes gain little more
/// (`docs/PERFORMANCE.md`).
pub const LANES: usize = 32;

/// How often (in samples) a batch checks whether every lane has diverged.
const DIVERGENCE_CHECK: usize = 128;

/// The batched, multi-threaded CPU evaluator.
#[derive(Debug, Default)]
pub struct CpuEvaluator {
    /// Why the CPU was chosen, when `--backend auto` chose it.
    note: Option<String>,
}

impl CpuEvaluator {
    pub fn new() -> Self {
        CpuEvaluator::default()
    }

    /// A CPU evaluator that says why it was chosen (in [`Evaluator::describe`]).
    pub fn with_note(note: impl Into<String>) -> Self {
        CpuEvaluator {
            note: Some(note.into()),
        }
    }
}

impl Evaluator for CpuEvaluator {
    fn describe(&self) -> String {
        let base = format!(
            "cpu ({LANES}-lane batches on {} threads)",
            rayon::current_num_threads()
        );
        match &self.note {
            Some(note) => format!("{base}; {note}"),
            None => base,
        }
    }

    fn evaluate(&mut self, problem: &Problem, population: &[f64]) -> anyhow::Result<Scores> {
        let rows = to_f32(population);
        let d = problem.family.dim();
        anyhow::ensure!(
            rows.len() % d == 0,
            "population length {} is not a multiple of the {} model's {d} parameters",
            rows.len(),
            problem.family
        );
        Ok(score_rows(problem, &rows))
    }
}

/// Scores `f32` rows (row-major `N × d`) on every experiment of `problem`.
pub fn score_rows(problem: &Problem, rows: &[f32]) -> Scores {
    let family = problem.family;
    let d = family.dim();
    let n = rows.len() / d;
    let batches: Vec<Vec<[f32; LANES]>> = rows
        .par_chunks(LANES * d)
        .map(|chunk| {
            let params = transpose(chunk, d);
            problem
                .experiments
                .iter()
                .map(|e| batch_sse(family, &params, &e.u, &e.y))
                .collect()
        })
        .collect();
    let per_experiment = (0..problem.experiments.len())
        .map(|e| {
            batches
                .iter()
                .flat_map(|b| b[e])
                .take(n)
                .collect::<Vec<f32>>()
        })
        .collect();
    Scores::from_per_experiment(per_experiment)
}

/// `params[j][l]`: parameter `j` of lane `l`. A short last batch is padded
/// with copies of its first row; the padding lanes' scores are dropped.
fn transpose(chunk: &[f32], d: usize) -> Vec<[f32; LANES]> {
    let mut params = vec![[0.0f32; LANES]; d];
    let used = chunk.len() / d;
    for l in 0..LANES {
        let row = if l < used { l } else { 0 };
        for (j, p) in params.iter_mut().enumerate() {
            p[l] = chunk[row * d + j];
        }
    }
    params
}

/// The SSE of every lane of one batch on one experiment, as [`crate::model::sse`],
/// compiled for the widest vector unit the CPU has (chosen at run time; the
/// arithmetic is the same IEEE `f32` on each, and Rust never fuses a·b + c,
/// so the bits do not depend on the choice).
fn batch_sse(family: Family, params: &[[f32; LANES]], u: &[f32], y: &[f32]) -> [f32; LANES] {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has AVX-512F.
            return unsafe { batch_sse_avx512(family, params, u, y) };
        }
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2.
            return unsafe { batch_sse_avx2(family, params, u, y) };
        }
    }
    batch_sse_portable(family, params, u, y)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn batch_sse_avx512(family: Family, params: &[[f32; LANES]], u: &[f32], y: &[f32]) -> [f32; LANES] {
    batch_sse_portable(family, params, u, y)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn batch_sse_avx2(family: Family, params: &[[f32; LANES]], u: &[f32], y: &[f32]) -> [f32; LANES] {
    batch_sse_portable(family, params, u, y)
}

#[inline(always)]
fn batch_sse_portable(
    family: Family,
    params: &[[f32; LANES]],
    u: &[f32],
    y: &[f32],
) -> [f32; LANES] {
    assert_eq!(u.len(), y.len(), "input and output lengths differ");
    if u.is_empty() {
        return [0.0; LANES];
    }
    let n_is_one = |j: usize| params[j].iter().all(|&n| n == 1.0);
    match family {
        Family::Linear => linear_batch(params.try_into().expect("3 parameters"), u, y),
        Family::Classic => {
            let p = params.try_into().expect("8 parameters");
            if n_is_one(4) {
                classic_batch::<true>(p, u, y)
            } else {
                classic_batch::<false>(p, u, y)
            }
        }
        Family::Generalized => {
            let p = params.try_into().expect("12 parameters");
            if n_is_one(8) {
                generalized_batch::<true>(p, u, y)
            } else {
                generalized_batch::<false>(p, u, y)
            }
        }
    }
}

/// Lanes whose mask latched score `+∞`.
#[inline(always)]
fn finish(acc: [f32; LANES], ok: [bool; LANES]) -> [f32; LANES] {
    std::array::from_fn(|l| if ok[l] { acc[l] } else { f32::INFINITY })
}

/// True while some lane is in bounds.
#[inline(always)]
fn any_ok(ok: &[bool; LANES]) -> bool {
    let mut any = false;
    for &o in ok {
        any |= o;
    }
    any
}

#[inline(always)]
fn linear_batch(p: &[[f32; LANES]; 3], u: &[f32], y: &[f32]) -> [f32; LANES] {
    let [a, b, c] = p;
    let mut x = [y[0]; LANES];
    let mut acc = [0.0f32; LANES];
    let mut ok = [true; LANES];
    // Blocks of DIVERGENCE_CHECK samples; stop once every lane has diverged.
    let mut start = 1;
    while start < u.len() {
        let end = (start + DIVERGENCE_CHECK).min(u.len());
        for k in start..end {
            let (up, yk) = (u[k - 1], y[k]);
            for l in 0..LANES {
                let xn = linear_step(a[l], b[l], c[l], x[l], up);
                // w ≡ 0 is always in bounds.
                ok[l] &= in_bounds(xn);
                let e = xn - yk;
                acc[l] += e * e;
                x[l] = xn;
            }
        }
        if !any_ok(&ok) {
            break;
        }
        start = end;
    }
    finish(acc, ok)
}

#[inline(always)]
fn classic_batch<const N_ONE: bool>(p: &[[f32; LANES]; 8], u: &[f32], y: &[f32]) -> [f32; LANES] {
    let [big_a, alpha, beta, gamma, n, a, b, c] = p;
    let mut x = [y[0]; LANES];
    let mut w = [0.0f32; LANES];
    let mut acc = [0.0f32; LANES];
    let mut ok = [true; LANES];
    // Blocks of DIVERGENCE_CHECK samples; stop once every lane has diverged.
    let mut start = 1;
    while start < u.len() {
        let end = (start + DIVERGENCE_CHECK).min(u.len());
        for k in start..end {
            let (up, yk) = (u[k - 1], y[k]);
            for l in 0..LANES {
                let nl = if N_ONE { 1.0 } else { n[l] };
                let xn = linear_part(a[l], alpha[l], b[l], c[l], x[l], w[l], up);
                let wn = classic_w(big_a[l], beta[l], gamma[l], nl, w[l], xn - x[l]);
                ok[l] &= in_bounds(xn) & in_bounds(wn);
                let e = xn - yk;
                acc[l] += e * e;
                x[l] = xn;
                w[l] = wn;
            }
        }
        if !any_ok(&ok) {
            break;
        }
        start = end;
    }
    finish(acc, ok)
}

#[inline(always)]
fn generalized_batch<const N_ONE: bool>(
    p: &[[f32; LANES]; 12],
    u: &[f32],
    y: &[f32],
) -> [f32; LANES] {
    let [big_a, alpha, b1, b2, b3, b4, b5, b6, n, a, b, c] = p;
    let mut x = [y[0]; LANES];
    let mut w = [0.0f32; LANES];
    let mut acc = [0.0f32; LANES];
    let mut ok = [true; LANES];
    // Blocks of DIVERGENCE_CHECK samples; stop once every lane has diverged.
    let mut start = 1;
    while start < u.len() {
        let end = (start + DIVERGENCE_CHECK).min(u.len());
        for k in start..end {
            let (up, yk) = (u[k - 1], y[k]);
            for l in 0..LANES {
                let nl = if N_ONE { 1.0 } else { n[l] };
                let betas = [b1[l], b2[l], b3[l], b4[l], b5[l], b6[l]];
                let xn = linear_part(a[l], alpha[l], b[l], c[l], x[l], w[l], up);
                let wn = generalized_w(big_a[l], &betas, nl, w[l], xn, xn - x[l]);
                ok[l] &= in_bounds(xn) & in_bounds(wn);
                let e = xn - yk;
                acc[l] += e * e;
                x[l] = xn;
                w[l] = wn;
            }
        }
        if !any_ok(&ok) {
            break;
        }
        start = end;
    }
    finish(acc, ok)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::workload::{mixed_population, search_space, stair_experiment};
    use crate::model::sse;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// Every compiled variant the CPU can run gives `model::sse`'s bits
    /// (the evaluator tests only see the one this CPU picks).
    #[test]
    fn every_instruction_set_variant_is_bit_identical() {
        let exp = stair_experiment(700, 21);
        for (family, free_n) in [
            (Family::Linear, false),
            (Family::Classic, false),
            (Family::Classic, true),
            (Family::Generalized, false),
            (Family::Generalized, true),
        ] {
            let d = family.dim();
            let space = search_space(family, &exp, free_n);
            let pop = mixed_population(&space, LANES, &mut ChaCha8Rng::seed_from_u64(2));
            let rows = to_f32(&pop);
            let params = transpose(&rows, d);
            let want: Vec<u32> = rows
                .chunks_exact(d)
                .map(|t| sse(family, t, &exp.u, &exp.y).to_bits())
                .collect();
            let bits = |s: [f32; LANES]| s.map(f32::to_bits).to_vec();
            assert_eq!(
                bits(batch_sse_portable(family, &params, &exp.u, &exp.y)),
                want
            );
            #[cfg(target_arch = "x86_64")]
            {
                if std::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2.
                    let got = unsafe { batch_sse_avx2(family, &params, &exp.u, &exp.y) };
                    assert_eq!(bits(got), want, "{family} avx2");
                }
                if std::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the CPU has AVX-512F.
                    let got = unsafe { batch_sse_avx512(family, &params, &exp.u, &exp.y) };
                    assert_eq!(bits(got), want, "{family} avx512");
                }
            }
        }
    }
}
