//! The CPU batch path of a model with effect stages (the diagnosis'
//! augmented models): [`LANES`] candidates (fewer for a short batch)
//! advance side by side through the one augmented step, [`Prepared::step`]
//! (whose stages are loops over the lanes that compile to vector
//! instructions), so that every lane's SSE and residuals are bit-identical
//! to [`ModelDescription::measured_sse`] and
//! [`ModelDescription::residuals`] for that candidate. Divergence latches
//! per lane as in [`super::cpu`].

use super::Problem;
use super::batch::{LANES, block};
use crate::model::effects::{ModelDescription, Prepared};

/// The SSE of every lane of one batch (`chunk`: up to [`LANES`] rows of
/// `model`'s parameters) on each experiment of `problem`; lanes past the
/// chunk's rows hold nothing the caller reads.
pub fn batch_sse(problem: &Problem, model: &ModelDescription, chunk: &[f32]) -> Vec<[f32; LANES]> {
    let used = chunk.len() / model.dim();
    match width(used) {
        NARROW => sse_of::<NARROW>(problem, model, chunk),
        HALF => sse_of::<HALF>(problem, model, chunk),
        _ => sse_of::<LANES>(problem, model, chunk),
    }
}

/// [`batch_sse`] on `N` lanes, widened to [`LANES`].
fn sse_of<const N: usize>(
    problem: &Problem,
    model: &ModelDescription,
    chunk: &[f32],
) -> Vec<[f32; LANES]> {
    let rows = padded(chunk, model.dim(), N);
    let every = problem.measure.restart_every();
    problem
        .experiments
        .iter()
        .zip(&problem.contexts)
        .enumerate()
        .map(|(e, (exp, ctx))| {
            let lanes: Prepared<N> = model.prepare(&rows, e, ctx);
            let sse = lanes_sse(&lanes, &exp.u, &exp.y, every);
            std::array::from_fn(|l| sse.get(l).copied().unwrap_or(f32::INFINITY))
        })
        .collect()
}

/// The residuals `ŷ − y` of each row of one batch (`chunk`: up to
/// [`LANES`] rows), every experiment of `problem` in turn from its second
/// sample on, each row's bit for bit as [`ModelDescription::residuals`]
/// gives them; `None` for a row that leaves the bounds on any experiment.
/// A polish's probes go through here: one batch steps them side by side
/// where the scalar reference would run them one after another.
pub fn batch_residuals(
    problem: &Problem,
    model: &ModelDescription,
    chunk: &[f32],
) -> Vec<Option<Vec<f32>>> {
    let used = chunk.len() / model.dim();
    match width(used) {
        NARROW => residuals_of::<NARROW>(problem, model, chunk),
        HALF => residuals_of::<HALF>(problem, model, chunk),
        _ => residuals_of::<LANES>(problem, model, chunk),
    }
}

/// [`batch_residuals`] on `N` lanes.
fn residuals_of<const N: usize>(
    problem: &Problem,
    model: &ModelDescription,
    chunk: &[f32],
) -> Vec<Option<Vec<f32>>> {
    let used = chunk.len() / model.dim();
    let rows = padded(chunk, model.dim(), N);
    let every = problem.measure.restart_every();
    let mut residuals: Vec<Option<Vec<f32>>> = (0..used)
        .map(|_| Some(Vec::with_capacity(problem.samples())))
        .collect();
    for (e, (exp, ctx)) in problem
        .experiments
        .iter()
        .zip(&problem.contexts)
        .enumerate()
    {
        let lanes: Prepared<N> = model.prepare(&rows, e, ctx);
        let ok = lanes_residuals(&lanes, &exp.u, &exp.y, every, &mut residuals);
        for (r, ok) in residuals.iter_mut().zip(ok) {
            if !ok {
                *r = None;
            }
        }
    }
    residuals
}

/// Narrower batches for a short chunk: a batch's every lane is stepped,
/// so a tail of a few rows (the last of a population of 40, a polish's 15
/// probes) padded to [`LANES`] would step mostly copies. Each lane's
/// arithmetic is its own, so the width moves no bit.
const NARROW: usize = 8;
const HALF: usize = 16;

/// The narrowest of the batch widths that holds `used` rows.
fn width(used: usize) -> usize {
    [NARROW, HALF, LANES]
        .into_iter()
        .find(|&w| used <= w)
        .unwrap_or(LANES)
}

/// `chunk`'s rows of `d` parameters, padded to `n` rows with copies of its
/// first.
fn padded(chunk: &[f32], d: usize, n: usize) -> Vec<f32> {
    let mut rows = chunk.to_vec();
    for _ in chunk.len() / d..n {
        rows.extend_from_slice(&chunk[..d]);
    }
    rows
}

/// `fn NAME<const N: usize>(ARGS) -> R` that runs `PORTABLE(ARGS)`
/// compiled for the widest vector unit the CPU has, chosen at run time
/// (AVX-512F, AVX2, else the build's own): the arithmetic is the same IEEE
/// `f32` on each, so the bits do not depend on the choice.
macro_rules! widest {
    ($(#[$doc:meta])* fn $name:ident<const $n:ident: usize>($($arg:ident: $ty:ty),*) -> $ret:ty
        = $portable:ident) => {
        $(#[$doc])*
        fn $name<const $n: usize>($($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f")]
                fn avx512<const $n: usize>($($arg: $ty),*) -> $ret {
                    $portable($($arg),*)
                }
                #[target_feature(enable = "avx2")]
                fn avx2<const $n: usize>($($arg: $ty),*) -> $ret {
                    $portable($($arg),*)
                }
                if std::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the CPU has AVX-512F.
                    return unsafe { avx512($($arg),*) };
                }
                if std::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2.
                    return unsafe { avx2($($arg),*) };
                }
            }
            $portable($($arg),*)
        }
    };
}

widest! {
    /// A batch's SSE per lane ([`lanes_sse_portable`]).
    fn lanes_sse<const N: usize>(p: &Prepared<N>, u: &[f32], y: &[f32], every: usize) -> [f32; N]
        = lanes_sse_portable
}

widest! {
    /// As [`lanes_sse`], each lane's errors appended to its row of
    /// `residuals` (the padding's lanes, past its end, are dropped);
    /// whether each lane stayed in bounds.
    fn lanes_residuals<const N: usize>(
        p: &Prepared<N>,
        u: &[f32],
        y: &[f32],
        every: usize,
        residuals: &mut [Option<Vec<f32>>]
    ) -> [bool; N] = lanes_residuals_portable
}

/// The scoring loop of [`super::cpu`]'s `lanes_sse` over the augmented step,
/// on the same schedule ([`block`]).
#[inline(always)]
fn lanes_sse_portable<const N: usize>(
    p: &Prepared<N>,
    u: &[f32],
    y: &[f32],
    every: usize,
) -> [f32; N] {
    let mut acc = [0.0f32; N];
    let ok = walk(p, u, y, every, |errors| {
        for l in 0..N {
            acc[l] += errors[l] * errors[l];
        }
    });
    std::array::from_fn(|l| if ok[l] { acc[l] } else { f32::INFINITY })
}

#[inline(always)]
fn lanes_residuals_portable<const N: usize>(
    p: &Prepared<N>,
    u: &[f32],
    y: &[f32],
    every: usize,
    residuals: &mut [Option<Vec<f32>>],
) -> [bool; N] {
    walk(p, u, y, every, |errors| {
        for (r, &e) in residuals.iter_mut().zip(errors) {
            if let Some(r) = r {
                r.push(e);
            }
        }
    })
}

/// Steps every lane through `u` from `y[0]` on [`block`]'s schedule (the
/// output state restarts from the measurement after each block where
/// `every` says so), handing `errors` each sample's `ŷ − y` of every lane;
/// whether each lane stayed in bounds. Stops once no lane does.
#[inline(always)]
fn walk<const N: usize>(
    p: &Prepared<N>,
    u: &[f32],
    y: &[f32],
    every: usize,
    mut errors: impl FnMut(&[f32; N]),
) -> [bool; N] {
    assert_eq!(u.len(), y.len(), "input and output lengths differ");
    let mut ok = [true; N];
    if u.is_empty() {
        return ok;
    }
    let mut s = p.start(y[0], u[0]);
    let mut start = 1;
    while start < u.len() {
        let (end, restarts) = block(start, u.len(), every);
        for (k, &yk) in y.iter().enumerate().take(end).skip(start) {
            let predicted = p.step(&mut s, k, u);
            let mut e = [0.0f32; N];
            for l in 0..N {
                ok[l] &= Prepared::in_bounds(&s, l, predicted[l]);
                e[l] = predicted[l] - yk;
            }
            errors(&e);
        }
        if restarts {
            p.restart(&mut s, y[end - 1]);
        }
        if !ok.iter().any(|&o| o) {
            break;
        }
        start = end;
    }
    ok
}
