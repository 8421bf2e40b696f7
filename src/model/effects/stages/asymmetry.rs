//! The asymmetry's realisations: in gain and in time constant.

use super::super::stage::{At, Columns, Frame, InputLoop, Lane, Stage, larger, smaller};

/// The input gain is `b·(1+ε)` on the rising branch and `b·(1−ε)` on the
/// falling one.
#[derive(Debug)]
pub struct Asymmetry;

/// The branch, which follows the measured input only, so it is the same in
/// every lane. Aligned to a cache line, so that the lane arrays after it in
/// the effect state start on one ([`Stage::State`]).
#[derive(Debug, Clone)]
#[repr(C, align(64))]
pub struct Branch {
    /// +1 loading, −1 unloading, 0 not yet moved.
    dir: f32,
    /// The input's extreme on the current branch.
    extreme: f32,
}

impl Branch {
    /// Where a record starts: not yet moved, at its first input `u0`.
    pub fn start(u0: f32) -> Branch {
        Branch {
            dir: 0.0,
            extreme: u0,
        }
    }

    /// Follows the measured input `u(k−1)` one sample: the branch switches
    /// once the input has moved back from its extreme by the context's
    /// tolerance (the first loading once it has left the first input by
    /// it). Returns whether a loading began at this sample.
    #[inline(always)]
    pub fn follow<const L: usize>(&mut self, at: &At<'_, L>) -> bool {
        let (raw, tol) = (at.raw, at.frame.branch_tol);
        let was_loading = self.dir > 0.0;
        if self.dir >= 0.0 {
            self.extreme = larger(raw, self.extreme);
            if raw < self.extreme - tol {
                (self.dir, self.extreme) = (-1.0, raw);
            } else if raw > at.u[0] + tol {
                self.dir = 1.0;
            }
        } else {
            self.extreme = smaller(raw, self.extreme);
            if raw > self.extreme + tol {
                (self.dir, self.extreme) = (1.0, raw);
            }
        }
        self.dir > 0.0 && !was_loading
    }
}

impl<const L: usize> Stage<L> for Asymmetry {
    /// `ε`.
    type Consts = [f32; L];
    type State = Branch;

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        p.get(0)
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], u0: f32) -> Branch {
        Branch::start(u0)
    }
}

impl<const L: usize> Lane<L> for Asymmetry {
    #[inline(always)]
    fn before(_: &[f32; L], s: &mut Branch, at: &At<'_, L>) {
        s.follow(at);
    }

    #[inline(always)]
    fn lane(eps: &[f32; L], s: &mut Branch, l: usize, v: f32, at: &At<'_, L>) -> f32 {
        v + (s.dir * eps[l]) * (v + at.frame.u_mean)
    }
}

/// The input passes at once on one branch and through a first-order lag
/// `|ρ|` on the other (`ρ > 0`: drains slower than it fills).
#[derive(Debug)]
pub struct DrainLag;

impl<const L: usize> Stage<L> for DrainLag {
    /// `ρ`.
    type Consts = [f32; L];
    /// The stage's output of the sample before.
    type State = [f32; L];

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        p.get(0)
    }

    fn start(_: Option<&Self::Consts>, _: &[f32; L], _: f32) -> Self::State {
        [0.0; L]
    }
}

impl<const L: usize> InputLoop<L> for DrainLag {
    #[inline(always)]
    fn apply(rho: &[f32; L], s: &mut [f32; L], ui: &mut [f32; L], at: &At<'_, L>) {
        for l in 0..L {
            // The slow branch follows through the lag; the other passes.
            let v = ui[l];
            let prev = if at.started { s[l] } else { v };
            let slow = if rho[l] >= 0.0 { v < prev } else { v > prev };
            let r = if rho[l] >= 0.0 { rho[l] } else { -rho[l] };
            let lagged = (r * prev) + ((1.0 - r) * v);
            ui[l] = if slow { lagged } else { v };
            s[l] = ui[l];
        }
    }
}
