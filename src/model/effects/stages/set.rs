//! The permanent set's realisations: an offset the muscle keeps after it
//! has been driven, growing with the largest displacement so far, or
//! walking with every loading (a ratchet). Both add to the output, as a
//! length the muscle keeps does (an offset on the input would pass through
//! the muscle's own gain, which is small near rest, where a set shows), and
//! neither feeds back into the muscle's state: the set reads the state and
//! the ratchet counts the input's loadings, so neither can run away.

use super::super::stage::{At, Columns, Frame, OutputLoop, Stage};
use super::Branch;
use super::softening::largest_so_far;

/// Permanent set: the output moves by `share·(x̂ − x)` toward the drive,
/// `x̂` the muscle's largest displacement toward its drive so far (as
/// Dorfmann and Ogden's set grows with the largest strain). At `x̂` the
/// muscle is where it was when first driven there; short of it, it keeps
/// that share of the way back, an offset that at rest grows with every new
/// largest displacement and never shrinks. Driven by the muscle's own
/// state, not by the input: the displacement a pressure reaches grows less
/// than the pressure does, and the offset builds as the muscle returns,
/// not when the valve closes.
#[derive(Debug)]
pub struct Set;

impl<const L: usize> Stage<L> for Set {
    /// `toward · share`, and `toward`.
    type Consts = ([f32; L], f32);
    /// The largest displacement toward the drive so far (`toward · x`), and
    /// the offset it adds to the output.
    type State = [[f32; L]; 2];

    fn prepare(p: &Columns<'_, L>, frame: &Frame) -> Self::Consts {
        // Times ±1: exact, so the share keeps its bits.
        (p.get(0).map(|c| frame.toward * c), frame.toward)
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) -> Self::State {
        [[0.0; L]; 2]
    }

    #[inline(always)]
    fn restart([_, offset]: &mut Self::State, l: usize, _: f32, x: f32) -> f32 {
        x - offset[l]
    }
}

impl<const L: usize> OutputLoop<L> for Set {
    #[inline(always)]
    fn apply(
        (share, toward): &Self::Consts,
        [peak, offset]: &mut Self::State,
        y: &mut [f32; L],
        _: &[f32; L],
        xk: &[f32; L],
        at: &At<'_, L>,
    ) {
        for l in 0..L {
            let reach = toward * xk[l];
            let top = largest_so_far(peak, l, reach, at);
            offset[l] = share[l] * (top - reach);
            y[l] += offset[l];
        }
    }
}

/// Ratchet: the output moves by `a + v·n` after `n ≥ 1` loadings, an
/// offset that walks with every cycle: a step at the first loading, then a
/// steady walk (a ratchetting rate that settles to a constant).
#[derive(Debug)]
pub struct Ratchet;

/// The branch of the measured input, which counts the loadings, and the
/// offset they add to the output. Aligned to a cache line
/// ([`Stage::State`]), the lane array right after the branch.
#[derive(Debug, Clone)]
#[repr(C, align(64))]
pub struct Walk<const L: usize> {
    branch: Branch,
    offset: [f32; L],
    /// The loadings so far.
    count: f32,
}

impl<const L: usize> Stage<L> for Ratchet {
    /// `a` and `v`.
    type Consts = [[f32; L]; 2];
    type State = Walk<L>;

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        [p.get(0), p.get(1)]
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], u0: f32) -> Self::State {
        Walk {
            branch: Branch::start(u0),
            offset: [0.0; L],
            count: 0.0,
        }
    }

    #[inline(always)]
    fn restart(s: &mut Walk<L>, l: usize, _: f32, x: f32) -> f32 {
        x - s.offset[l]
    }
}

impl<const L: usize> OutputLoop<L> for Ratchet {
    #[inline(always)]
    fn apply(
        [a, v]: &Self::Consts,
        s: &mut Walk<L>,
        y: &mut [f32; L],
        _: &[f32; L],
        _: &[f32; L],
        at: &At<'_, L>,
    ) {
        // The offset moves only where a loading begins, and holds between.
        if s.branch.follow(at) {
            s.count += 1.0;
            for l in 0..L {
                s.offset[l] = a[l] + v[l] * s.count;
            }
        }
        for (y, offset) in y.iter_mut().zip(&s.offset) {
            *y += offset;
        }
    }
}
