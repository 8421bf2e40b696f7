//! The CPU batch path of a model with effect stages (the diagnosis'
//! augmented models): [`LANES`] candidates advance side by side through the
//! one augmented step, [`Prepared::step`] (whose stages are loops over the
//! lanes that compile to vector instructions), so that every lane's SSE is
//! bit-identical to [`ModelDescription::measured_sse`] for that candidate.
//! Divergence latches per lane as in [`super::cpu`].

use super::Problem;
use super::batch::{LANES, block};
use crate::model::effects::{ModelDescription, Prepared};

/// The SSE of every lane of one batch (`chunk`: up to [`LANES`] rows of
/// `model`'s parameters; a short batch is padded with its first row, whose
/// copies' scores the caller drops) on each experiment of `problem`.
pub fn batch_sse(problem: &Problem, model: &ModelDescription, chunk: &[f32]) -> Vec<[f32; LANES]> {
    let d = model.dim();
    let used = chunk.len() / d;
    let mut rows = chunk.to_vec();
    for _ in used..LANES {
        rows.extend_from_slice(&chunk[..d]);
    }
    let every = problem.measure.restart_every();
    problem
        .experiments
        .iter()
        .zip(&problem.contexts)
        .enumerate()
        .map(|(e, (exp, ctx))| {
            let lanes: Prepared<LANES> = model.prepare(&rows, e, ctx);
            lanes_sse(&lanes, &exp.u, &exp.y, every)
        })
        .collect()
}

/// Compiled for the widest vector unit the CPU has (chosen at run time; the
/// arithmetic is the same IEEE `f32` on each, so the bits do not depend on
/// the choice).
fn lanes_sse(p: &Prepared<LANES>, u: &[f32], y: &[f32], every: usize) -> [f32; LANES] {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has AVX-512F.
            return unsafe { lanes_sse_avx512(p, u, y, every) };
        }
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2.
            return unsafe { lanes_sse_avx2(p, u, y, every) };
        }
    }
    lanes_sse_portable(p, u, y, every)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn lanes_sse_avx512(p: &Prepared<LANES>, u: &[f32], y: &[f32], every: usize) -> [f32; LANES] {
    lanes_sse_portable(p, u, y, every)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn lanes_sse_avx2(p: &Prepared<LANES>, u: &[f32], y: &[f32], every: usize) -> [f32; LANES] {
    lanes_sse_portable(p, u, y, every)
}

/// The scoring loop of [`super::cpu`]'s `lanes_sse` over the augmented step,
/// on the same schedule ([`block`]).
#[inline(always)]
fn lanes_sse_portable(p: &Prepared<LANES>, u: &[f32], y: &[f32], every: usize) -> [f32; LANES] {
    assert_eq!(u.len(), y.len(), "input and output lengths differ");
    if u.is_empty() {
        return [0.0; LANES];
    }
    let mut s = p.start(y[0], u[0]);
    let mut acc = [0.0f32; LANES];
    let mut ok = [true; LANES];
    let mut start = 1;
    while start < u.len() {
        let (end, restarts) = block(start, u.len(), every);
        for (k, &yk) in y.iter().enumerate().take(end).skip(start) {
            let predicted = p.step(&mut s, k, u);
            for l in 0..LANES {
                ok[l] &= Prepared::in_bounds(&s, l, predicted[l]);
                let e = predicted[l] - yk;
                acc[l] += e * e;
            }
        }
        if restarts {
            p.restart(&mut s, y[end - 1]);
        }
        if !ok.iter().any(|&o| o) {
            break;
        }
        start = end;
    }
    std::array::from_fn(|l| if ok[l] { acc[l] } else { f32::INFINITY })
}
