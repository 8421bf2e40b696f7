//! The rate: a Bouc-Wen stiffness that grows with the input rate.

use super::super::stage::{At, Columns, Frame, Stage, StateLoop};

/// `A_eff = A·(1 + η·|u(k−1) − u(k−2)|/dt)`.
#[derive(Debug)]
pub struct Rate;

impl<const L: usize> Stage<L> for Rate {
    /// The growth `η` (seconds per input unit).
    type Consts = [f32; L];
    type State = ();

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        p.get(0)
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) {}
}

impl<const L: usize> StateLoop<L> for Rate {
    #[inline(always)]
    fn apply(eta: &[f32; L], _: &mut (), _: &mut [f32; L], a_eff: &mut [f32; L], at: &At<'_, L>) {
        let prev = if at.k >= 2 { at.u[at.k - 2] } else { at.u[0] };
        let rate = (at.raw - prev).abs() * at.frame.inv_dt;
        for l in 0..L {
            a_eff[l] *= 1.0 + (eta[l] * rate);
        }
    }
}
