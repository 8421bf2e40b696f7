//! The inertia's realisations: an extra pole, a load mode on the output
//! and a load that rings after input steps.

use super::super::stage::{At, Columns, Frame, Lane, OutputLoop, Stage};

/// `x(k) += a2·(x(k−1) − x(k−2))`.
#[derive(Debug)]
pub struct Inertia;

impl<const L: usize> Stage<L> for Inertia {
    /// `a2`.
    type Consts = [f32; L];
    /// `x(k−2)`, the output state of the step before the last.
    type State = [f32; L];

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        p.get(0)
    }

    fn start(_: Option<&Self::Consts>, x: &[f32; L], _: f32) -> Self::State {
        *x
    }
}

impl<const L: usize> Lane<L> for Inertia {
    #[inline(always)]
    fn lane(a2: &[f32; L], prev2: &mut [f32; L], l: usize, v: f32, at: &At<'_, L>) -> f32 {
        v + a2[l] * (at.x[l] - prev2[l])
    }

    /// The next step's `x(k−2)` is this one's `x(k−1)` (a restart moves
    /// `x(k−1)`, not it).
    #[inline(always)]
    fn after(_: &[f32; L], prev2: &mut [f32; L], at: &At<'_, L>) {
        *prev2 = *at.x;
    }
}

/// A second-order mode of the hanging load on the output,
/// `q = a1·q(k−1) − a2·q(k−2) + (1 − a1 + a2)·ŷ`.
#[derive(Debug)]
pub struct LoadMode;

impl<const L: usize> Stage<L> for LoadMode {
    /// `a1`, `a2` and the input weight `(1 − a1) + a2`.
    type Consts = ([f32; L], [f32; L], [f32; L]);
    /// The mode's output at the sample before and the one before that.
    type State = [[f32; L]; 2];

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        let (a1, a2) = (p.get(0), p.get(1));
        (a1, a2, std::array::from_fn(|l| (1.0 - a1[l]) + a2[l]))
    }

    fn start(_: Option<&Self::Consts>, x: &[f32; L], _: f32) -> Self::State {
        [*x, *x]
    }

    /// The mode restarts at rest at the measurement.
    #[inline(always)]
    fn restart([mode1, mode2]: &mut Self::State, l: usize, y: f32, x: f32) -> f32 {
        mode1[l] = y;
        mode2[l] = y;
        x
    }
}

impl<const L: usize> OutputLoop<L> for LoadMode {
    #[inline(always)]
    fn apply(
        (a1, a2, gain): &Self::Consts,
        s: &mut Self::State,
        y: &mut [f32; L],
        _: &[f32; L],
        _: &[f32; L],
        _: &At<'_, L>,
    ) {
        let [mode1, mode2] = s;
        for l in 0..L {
            let q = ((a1[l] * mode1[l]) - (a2[l] * mode2[l])) + (gain[l] * y[l]);
            mode2[l] = mode1[l];
            mode1[l] = q;
            y[l] = q;
        }
    }
}

/// A mode excited by the input's change, added to the output:
/// `r = a1·r(k−1) − a2·r(k−2) + g·(u(k−1) − u(k−2))`.
#[derive(Debug)]
pub struct Ringing;

impl<const L: usize> Stage<L> for Ringing {
    /// `a1`, `a2` and the kick `g`.
    type Consts = ([f32; L], [f32; L], [f32; L]);
    /// The ringing at the sample before and the one before that.
    type State = [[f32; L]; 2];

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        (p.get(0), p.get(1), p.get(2))
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) -> Self::State {
        [[0.0; L]; 2]
    }

    /// The output state is the measurement less the ringing, which rings on.
    #[inline(always)]
    fn restart([ring1, _]: &mut Self::State, l: usize, _: f32, x: f32) -> f32 {
        x - ring1[l]
    }
}

impl<const L: usize> OutputLoop<L> for Ringing {
    #[inline(always)]
    fn apply(
        (a1, a2, kick): &Self::Consts,
        s: &mut Self::State,
        y: &mut [f32; L],
        _: &[f32; L],
        _: &[f32; L],
        at: &At<'_, L>,
    ) {
        let prev = if at.k >= 2 { at.u[at.k - 2] } else { at.u[0] };
        let change = at.raw - prev;
        let [ring1, ring2] = s;
        for l in 0..L {
            let r = ((a1[l] * ring1[l]) - (a2[l] * ring2[l])) + (kick[l] * change);
            ring2[l] = ring1[l];
            ring1[l] = r;
            y[l] += r;
        }
    }
}
