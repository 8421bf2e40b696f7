//! The backlash: play on the input.

use super::super::stage::{At, Columns, Frame, Lane, Stage, larger, smaller};

/// Play of width `r` (input units) on the input.
#[derive(Debug)]
pub struct Backlash;

impl<const L: usize> Stage<L> for Backlash {
    /// The width `r ≥ 0`.
    type Consts = [f32; L];
    /// The play's output, from the first step on.
    type State = [f32; L];

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        p.get(0).map(|r| larger(r, 0.0))
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) -> Self::State {
        [0.0; L]
    }
}

impl<const L: usize> Lane<L> for Backlash {
    #[inline(always)]
    fn lane(r: &[f32; L], s: &mut [f32; L], l: usize, v: f32, at: &At<'_, L>) -> f32 {
        let half = 0.5 * r[l];
        let prev = if at.started { s[l] } else { v };
        let v = smaller(v + half, larger(v - half, prev));
        s[l] = v;
        v
    }
}
