//! The saturation's realisations: the state clip, the output clip and the
//! soft limit. Each bound is stored in deviation coordinates times
//! [`Frame::toward`], and applied as `toward · min(toward · x, bound)`.

use super::super::stage::{At, Columns, Frame, Lane, OutputLoop, Stage, StateLoop, smaller};

/// The bound in deviation coordinates, times [`Frame::toward`].
fn bound<const L: usize>(p: &Columns<'_, L>, frame: &Frame) -> [f32; L] {
    p.get(0).map(|l| frame.toward * (l - frame.y_mean))
}

/// The output state cannot pass the end stop.
#[derive(Debug)]
pub struct Saturation;

impl<const L: usize> Stage<L> for Saturation {
    type Consts = [f32; L];
    type State = ();

    fn prepare(p: &Columns<'_, L>, frame: &Frame) -> Self::Consts {
        bound(p, frame)
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) {}
}

impl<const L: usize> Lane<L> for Saturation {
    #[inline(always)]
    fn lane(bound: &[f32; L], _: &mut (), l: usize, x: f32, at: &At<'_, L>) -> f32 {
        let toward = at.frame.toward;
        toward * smaller(toward * x, bound[l])
    }
}

/// The end stop on the predicted output only (the state runs on).
#[derive(Debug)]
pub struct OutputClip;

impl<const L: usize> Stage<L> for OutputClip {
    type Consts = [f32; L];
    type State = ();

    fn prepare(p: &Columns<'_, L>, frame: &Frame) -> Self::Consts {
        bound(p, frame)
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) {}
}

impl<const L: usize> OutputLoop<L> for OutputClip {
    #[inline(always)]
    fn apply(
        bound: &[f32; L],
        _: &mut (),
        y: &mut [f32; L],
        _: &[f32; L],
        _: &[f32; L],
        at: &At<'_, L>,
    ) {
        let toward = at.frame.toward;
        for l in 0..L {
            y[l] = toward * smaller(toward * y[l], bound[l]);
        }
    }
}

/// The end stop as a smooth knee on the output state.
#[derive(Debug)]
pub struct SoftStop;

impl<const L: usize> Stage<L> for SoftStop {
    type Consts = [f32; L];
    type State = ();

    fn prepare(p: &Columns<'_, L>, frame: &Frame) -> Self::Consts {
        bound(p, frame)
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) {}
}

impl<const L: usize> StateLoop<L> for SoftStop {
    #[inline(always)]
    fn apply(bound: &[f32; L], _: &mut (), xk: &mut [f32; L], _: &mut [f32; L], at: &At<'_, L>) {
        let (knee, toward) = (at.frame.knee, at.frame.toward);
        for l in 0..L {
            xk[l] = toward * soft_stop(toward * xk[l], bound[l], knee);
        }
    }
}

/// The soft end stop on an output that the input drives up: `x` blended
/// into `bound` over `bound − h` by a quadratic whose slope runs from 1 to 0
/// (`knee` = [`super::super::Context::knee`]), `bound` beyond; `x` itself
/// short of the knee. A stop below is this one on `−x` and `−bound`,
/// negated: the same bits as writing it out (negation is exact, and `(b +
/// h) − x` is `−x − (−b − h)`).
#[inline(always)]
fn soft_stop(x: f32, bound: f32, knee: [f32; 3]) -> f32 {
    let [h, two_h, inv_4h] = knee;
    // How far into the knee x is.
    let into = x - (bound - h);
    let bend = (into * into) * inv_4h;
    let bent = x - bend;
    if into <= 0.0 {
        x
    } else if into >= two_h {
        bound
    } else {
        bent
    }
}
