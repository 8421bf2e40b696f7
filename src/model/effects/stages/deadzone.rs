//! The dead zone's realisations: the input dead zone and the hysteretic
//! threshold.

use super::super::stage::{At, Columns, Frame, InputLoop, Lane, Stage, larger};

/// `p_eff = max(p − p0, 0)` on the absolute input.
#[derive(Debug)]
pub struct Deadzone;

impl<const L: usize> Stage<L> for Deadzone {
    /// The threshold `p0` (absolute input units).
    type Consts = [f32; L];
    type State = ();

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        p.get(0)
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) {}
}

impl<const L: usize> Lane<L> for Deadzone {
    #[inline(always)]
    fn lane(p0: &[f32; L], _: &mut (), l: usize, v: f32, at: &At<'_, L>) -> f32 {
        larger(v - p0[l], -at.frame.u_mean)
    }
}

/// On above `p_on`, off below `p_off`, as it was in between; while off the
/// input is the lowest one recorded.
#[derive(Debug)]
pub struct OnOffThreshold;

impl<const L: usize> Stage<L> for OnOffThreshold {
    /// `p_on` and `p_off` in deviation coordinates.
    type Consts = ([f32; L], [f32; L]);
    /// 1 while on, else 0.
    type State = [f32; L];

    fn prepare(p: &Columns<'_, L>, frame: &Frame) -> Self::Consts {
        let on = p.get(0).map(|x| x - frame.u_mean);
        let gap = p.get(1);
        (on, std::array::from_fn(|l| on[l] - gap[l]))
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) -> Self::State {
        [0.0; L]
    }
}

impl<const L: usize> InputLoop<L> for OnOffThreshold {
    #[inline(always)]
    fn apply((on, off): &Self::Consts, s: &mut [f32; L], ui: &mut [f32; L], at: &At<'_, L>) {
        // Copies in locals: a select between a lane's input and a field of
        // the step's constants compiled to a select of addresses, one lane
        // at a time.
        let (mut state, rest) = (*s, at.frame.rest);
        for l in 0..L {
            let kept = if ui[l] < off[l] { 0.0 } else { state[l] };
            state[l] = if ui[l] > on[l] { 1.0 } else { kept };
            ui[l] = if state[l] > 0.0 { ui[l] } else { rest };
        }
        *s = state;
    }
}
