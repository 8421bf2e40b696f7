//! The load: an input gain per dataset.

use super::super::stage::{At, Columns, Frame, Lane, Stage};

/// The input gain of dataset `e ≥ 1` is `b·(1 + g_e)` on the absolute
/// input; dataset 0 is the reference.
#[derive(Debug)]
pub struct Load;

impl<const L: usize> Stage<L> for Load {
    /// This dataset's `g`; `None` on the reference dataset (which has no
    /// parameter: a single dataset's load has none at all).
    type Consts = Option<[f32; L]>;
    type State = ();

    fn prepare(p: &Columns<'_, L>, frame: &Frame) -> Self::Consts {
        (frame.dataset >= 1).then(|| p.get(frame.dataset - 1))
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) {}
}

impl<const L: usize> Lane<L> for Load {
    #[inline(always)]
    fn lane(g: &Self::Consts, _: &mut (), l: usize, v: f32, at: &At<'_, L>) -> f32 {
        match g {
            // The gain acts on the absolute input, as the asymmetry's does.
            Some(g) => v + g[l] * (v + at.frame.u_mean),
            None => v,
        }
    }
}
