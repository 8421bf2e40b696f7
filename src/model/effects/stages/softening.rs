//! The softening's realisations: the input gain grows with the largest
//! input so far (Mullins-type) or with the number of loadings (cyclic).
//! Both act on the input above the record's lowest one, so the muscle at
//! rest is unchanged and a softer muscle goes deeper at the same input;
//! both are driven by the input, which the model cannot feed back into.

use super::super::stage::{At, Columns, Frame, InputLoop, Stage, larger};
use super::Branch;

/// The largest `v` so far, per lane, from the first step on: the input
/// the muscle has seen (after the stages before it) for the Mullins-type
/// softening, the displacement toward the drive for the permanent set.
#[inline(always)]
pub(super) fn largest_so_far<const L: usize>(
    peak: &mut [f32; L],
    l: usize,
    v: f32,
    at: &At<'_, L>,
) -> f32 {
    let prev = if at.started { peak[l] } else { v };
    peak[l] = larger(v, prev);
    peak[l]
}

/// Mullins-type softening: the input above the lowest one gains
/// `s·(p̂ − p_rest)`, `p̂` the largest input so far, so a muscle that has
/// once been driven harder responds more at every input; equal pulses
/// change only the first rise.
#[derive(Debug)]
pub struct Softening;

impl<const L: usize> Stage<L> for Softening {
    /// `s` (per input unit).
    type Consts = [f32; L];
    /// The largest input so far.
    type State = [f32; L];

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        p.get(0)
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) -> Self::State {
        [0.0; L]
    }
}

impl<const L: usize> InputLoop<L> for Softening {
    #[inline(always)]
    fn apply(s: &[f32; L], peak: &mut [f32; L], ui: &mut [f32; L], at: &At<'_, L>) {
        let rest = at.frame.rest;
        for l in 0..L {
            let v = ui[l];
            let top = largest_so_far(peak, l, v, at);
            ui[l] = v + (s[l] * (top - rest)) * (v - rest);
        }
    }
}

/// Cyclic softening: the input above the lowest one gains `s·(1 − r^n)`
/// after `n` loadings, so equal pulses go deeper one after the other, by
/// less each time, and a rest does not undo it (a creep recovers).
#[derive(Debug)]
pub struct CyclicSoftening;

/// The branch of the measured input, which counts the loadings, and
/// `r^n` per lane. Aligned to a cache line ([`Stage::State`]).
#[derive(Debug, Clone)]
#[repr(C, align(64))]
pub struct Loadings<const L: usize> {
    branch: Branch,
    /// `r^n`: the share of the growth still to come.
    to_come: [f32; L],
}

impl<const L: usize> Loadings<L> {
    /// The branch follows the measured input; at each loading's start
    /// every lane's share still to come shrinks by its `r`.
    #[inline(always)]
    fn follow(&mut self, r: &[f32; L], at: &At<'_, L>) {
        if self.branch.follow(at) {
            for (to_come, r) in self.to_come.iter_mut().zip(r) {
                *to_come *= r;
            }
        }
    }

    fn start(u0: f32) -> Self {
        Loadings {
            branch: Branch::start(u0),
            to_come: [1.0; L],
        }
    }

    /// `1 − r^n` of lane `l`: the share of the growth reached.
    #[inline(always)]
    fn reached(&self, l: usize) -> f32 {
        1.0 - self.to_come[l]
    }
}

impl<const L: usize> Stage<L> for CyclicSoftening {
    /// `s` and `r`.
    type Consts = [[f32; L]; 2];
    type State = Loadings<L>;

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        [p.get(0), p.get(1)]
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], u0: f32) -> Self::State {
        Loadings::start(u0)
    }
}

impl<const L: usize> InputLoop<L> for CyclicSoftening {
    #[inline(always)]
    fn apply([s, r]: &Self::Consts, n: &mut Loadings<L>, ui: &mut [f32; L], at: &At<'_, L>) {
        n.follow(r, at);
        let rest = at.frame.rest;
        for l in 0..L {
            let v = ui[l];
            ui[l] = v + (s[l] * n.reached(l)) * (v - rest);
        }
    }
}
