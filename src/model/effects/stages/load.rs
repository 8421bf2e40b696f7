//! The load: an input gain per dataset.

use super::super::stage::{At, Columns, Frame, Lane, Stage};

/// The input gain of dataset `e ≥ 1` is `b·(1 + g_e)` on the absolute
/// input; dataset 0 is the reference.
#[derive(Debug)]
pub struct Load;

impl<const L: usize> Stage<L> for Load {
    /// This dataset's `g`; zeros on the reference dataset, which has no
    /// parameter (a single dataset's load has none at all) and is passed
    /// through (not an `Option`: see [`super::super::stage::Slot`]).
    type Consts = [f32; L];
    type State = ();

    fn prepare(p: &Columns<'_, L>, frame: &Frame) -> Self::Consts {
        if frame.dataset >= 1 {
            p.get(frame.dataset - 1)
        } else {
            [0.0; L]
        }
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) {}
}

impl<const L: usize> Lane<L> for Load {
    #[inline(always)]
    fn lane(g: &Self::Consts, _: &mut (), l: usize, v: f32, at: &At<'_, L>) -> f32 {
        // The gain acts on the absolute input, as the asymmetry's does.
        if at.frame.dataset >= 1 {
            v + g[l] * (v + at.frame.u_mean)
        } else {
            v
        }
    }
}
