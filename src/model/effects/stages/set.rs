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

/// Ratchet: the output moves by `a` at the first loading, and at the `n`-th
/// loading by the step before times `1 − q/n`: an offset that walks with
/// every cycle, its steps falling as a power of the count (about `n^−q`).
/// `q = 0` walks at a steady rate, `q = 1` as the log of the count, and
/// `q > 1` settles (shakedown); at `q = 2` the first step is all.
#[derive(Debug)]
pub struct Ratchet;

/// The branch of the measured input, which marks where a loading begins,
/// the offset the loadings add to the output, the step the last one added,
/// and their number. Aligned to a cache line ([`Stage::State`]), the lane
/// arrays right after the branch.
#[derive(Debug, Clone)]
#[repr(C, align(64))]
pub struct Walk<const L: usize> {
    branch: Branch,
    offset: [f32; L],
    step: [f32; L],
    count: f32,
}

impl<const L: usize> Stage<L> for Ratchet {
    /// `a` and `q`.
    type Consts = [[f32; L]; 2];
    type State = Walk<L>;

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        [p.get(0), p.get(1)]
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], u0: f32) -> Self::State {
        Walk {
            branch: Branch::start(u0),
            offset: [0.0; L],
            step: [0.0; L],
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
        [a, q]: &Self::Consts,
        s: &mut Walk<L>,
        y: &mut [f32; L],
        _: &[f32; L],
        _: &[f32; L],
        at: &At<'_, L>,
    ) {
        // The offset moves only where a loading begins, and holds between.
        if s.branch.follow(at) {
            s.count += 1.0;
            if s.count == 1.0 {
                s.step = *a;
            } else {
                let inverse = count_reciprocal(s.count);
                for (step, q) in s.step.iter_mut().zip(q) {
                    *step *= 1.0 - q * inverse;
                }
            }
            for (offset, step) in s.offset.iter_mut().zip(&s.step) {
                *offset += step;
            }
        }
        for (y, offset) in y.iter_mut().zip(&s.offset) {
            *y += offset;
        }
    }
}

/// `1/n` for a count `n ≥ 1` by multiplications and subtractions alone: a
/// first guess from the float's bits and three Newton steps, each of
/// which squares the relative error (0.12, 0.014, 2·10⁻⁴, 4·10⁻⁸). A
/// division would do, but the GPU need not round one as the CPU does;
/// these operations it rounds the same (the shader's twin keeps the
/// products apart, as `rounded` does everywhere).
#[inline(always)]
fn count_reciprocal(n: f32) -> f32 {
    let mut y = f32::from_bits(0x7EF3_11C3u32.wrapping_sub(n.to_bits()));
    for _ in 0..3 {
        y *= 2.0 - n * y;
    }
    y
}

#[cfg(test)]
mod tests {
    use super::count_reciprocal;

    #[test]
    fn a_count_reciprocal_is_within_a_rounding_of_the_division() {
        for n in 1..=100_000u32 {
            let n = n as f32;
            let (got, want) = (count_reciprocal(n), 1.0 / n);
            assert!(
                (got - want).abs() <= 2.0 * f32::EPSILON * want,
                "1/{n}: {got} against {want}"
            );
        }
    }
}
