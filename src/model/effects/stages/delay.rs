//! The delay's realisations: the pure delay, the lag on the input and the
//! lag on the output.

use super::super::stage::{At, Columns, Frame, InputLoop, OutputLoop, Stage, larger};

/// `u(k−1−d)` for `u(k−1)`, `d ≥ 0` samples, interpolated.
#[derive(Debug)]
pub struct Delay;

impl<const L: usize> Stage<L> for Delay {
    /// The delay split into whole samples and the fraction of the sample
    /// before them, once per candidate rather than once per sample.
    type Consts = ([i32; L], [f32; L]);
    /// The delayed input of the sample before, `u(j−1)` for the
    /// interpolation.
    type State = [f32; L];

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        let split = p.get(0).map(|d| split_delay(larger(d, 0.0)));
        (split.map(|s| s.0), split.map(|s| s.1))
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], u0: f32) -> Self::State {
        [u0; L]
    }
}

impl<const L: usize> InputLoop<L> for Delay {
    #[inline(always)]
    fn apply((whole, frac): &Self::Consts, s: &mut [f32; L], ui: &mut [f32; L], at: &At<'_, L>) {
        let before = *s;
        let last = i32::try_from(at.k - 1).expect("an input of under 2³¹ samples");
        for l in 0..L {
            (ui[l], s[l]) = delayed(at.u, last, whole[l], frac[l], before[l]);
        }
    }
}

/// A delay of `d ≥ 0` samples as whole samples and the fraction of a sample
/// beyond them (`d − ⌊d⌋`, exact in `f32`).
#[inline(always)]
fn split_delay(d: f32) -> (i32, f32) {
    let whole = d.floor();
    (whole as i32, d - whole)
}

/// The input `whole + frac` samples before `u(last)`, `last = k − 1`
/// (`u(0)` before the start): `u(j)` moved by `frac` of the way to
/// `before = u(j−1)`, `j = last − whole`, and `u(j)`, which is the next
/// sample's `before` (the delay is fixed). The move is computed in every
/// lane and the result selected, so that the lanes become one vector gather
/// without a branch on `frac` (which differs from lane to lane).
#[inline(always)]
fn delayed(past: &[f32], last: i32, whole: i32, frac: f32, before: f32) -> (f32, f32) {
    assert!(
        last >= 0 && (last as usize) < past.len(),
        "sample {last} is past the input"
    );
    // SAFETY: the index is in 0..=last, which is in `past` (asserted
    // above). Unchecked, because a bounds check per lane keeps the loads
    // scalar and branchy; 32-bit indices, because then one vector gathers 16
    // lanes and is stored whole (two half-vector stores read back as one
    // vector stall the next loop's load).
    let now = unsafe { *past.get_unchecked((last - whole).max(0) as usize) };
    let moved = now + (frac * (before - now));
    (if frac == 0.0 { now } else { moved }, now)
}

/// A first-order lag on the input, `v = ρ·v + (1−ρ)·p`.
#[derive(Debug)]
pub struct InputLag;

impl<const L: usize> Stage<L> for InputLag {
    /// The pole `ρ`.
    type Consts = [f32; L];
    /// The lag's output of the sample before.
    type State = [f32; L];

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        p.get(0)
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) -> Self::State {
        [0.0; L]
    }
}

impl<const L: usize> InputLoop<L> for InputLag {
    #[inline(always)]
    fn apply(rho: &[f32; L], s: &mut [f32; L], ui: &mut [f32; L], at: &At<'_, L>) {
        let prev = if at.started { *s } else { *ui };
        for l in 0..L {
            ui[l] = (rho[l] * prev[l]) + ((1.0 - rho[l]) * ui[l]);
        }
        *s = *ui;
    }
}

/// A first-order lag on the predicted output, `ŷ ← ρ·ŷ(k−1) + (1−ρ)·ŷ`.
#[derive(Debug)]
pub struct OutputLag;

impl<const L: usize> Stage<L> for OutputLag {
    /// The pole `ρ`.
    type Consts = [f32; L];
    /// The lag's output of the sample before.
    type State = [f32; L];

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        p.get(0)
    }

    fn start(_: Option<&Self::Consts>, x: &[f32; L], _: f32) -> Self::State {
        *x
    }

    /// The lag restarts at the measurement.
    #[inline(always)]
    fn restart(s: &mut [f32; L], l: usize, y: f32, x: f32) -> f32 {
        s[l] = y;
        x
    }
}

impl<const L: usize> OutputLoop<L> for OutputLag {
    #[inline(always)]
    fn apply(
        rho: &[f32; L],
        s: &mut [f32; L],
        y: &mut [f32; L],
        _: &[f32; L],
        _: &[f32; L],
        _: &At<'_, L>,
    ) {
        for l in 0..L {
            y[l] = (rho[l] * s[l]) + ((1.0 - rho[l]) * y[l]);
            s[l] = y[l];
        }
    }
}
