//! The creep's realisations: slow first-order states added to the output,
//! driven by the input, by the output, with two time constants, or one per
//! decade of time. Each starts at `z0` (where the record's history left
//! it; 0 where the model lacks the creep), and a restart takes it from the
//! measurement: the output state is the measurement less the slow states,
//! which creep on.

use super::super::stage::{At, Columns, Frame, OutputLoop, Stage};

/// `z = ρ·z + (1−ρ)·κ·u(k−1)`, `ŷ = x + z`.
#[derive(Debug)]
pub struct Creep;

impl<const L: usize> Stage<L> for Creep {
    /// `ρ`, `κ` and `z0`.
    type Consts = [[f32; L]; 3];
    /// The slow state.
    type State = [f32; L];

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        [p.get(0), p.get(1), p.get(2)]
    }

    fn start(c: Option<&Self::Consts>, _: &[f32; L], _: f32) -> Self::State {
        c.map_or([0.0; L], |[_, _, z0]| *z0)
    }

    #[inline(always)]
    fn restart(z: &mut [f32; L], l: usize, _: f32, x: f32) -> f32 {
        x - z[l]
    }
}

impl<const L: usize> OutputLoop<L> for Creep {
    #[inline(always)]
    fn apply(
        [rho, kappa, _]: &Self::Consts,
        z: &mut [f32; L],
        y: &mut [f32; L],
        ui: &[f32; L],
        _: &[f32; L],
        _: &At<'_, L>,
    ) {
        for l in 0..L {
            z[l] = (rho[l] * z[l]) + (((1.0 - rho[l]) * kappa[l]) * ui[l]);
            y[l] += z[l];
        }
    }
}

/// `z = ρ·z + (1−ρ)·κ·x`, `ŷ = x + z`.
#[derive(Debug)]
pub struct OutputCreep;

impl<const L: usize> Stage<L> for OutputCreep {
    /// `ρ`, `κ` and `z0`.
    type Consts = [[f32; L]; 3];
    /// The slow state.
    type State = [f32; L];

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        [p.get(0), p.get(1), p.get(2)]
    }

    fn start(c: Option<&Self::Consts>, _: &[f32; L], _: f32) -> Self::State {
        c.map_or([0.0; L], |[_, _, z0]| *z0)
    }

    #[inline(always)]
    fn restart(z: &mut [f32; L], l: usize, _: f32, x: f32) -> f32 {
        x - z[l]
    }
}

impl<const L: usize> OutputLoop<L> for OutputCreep {
    #[inline(always)]
    fn apply(
        [rho, kappa, _]: &Self::Consts,
        z: &mut [f32; L],
        y: &mut [f32; L],
        _: &[f32; L],
        xk: &[f32; L],
        _: &At<'_, L>,
    ) {
        for l in 0..L {
            z[l] = (rho[l] * z[l]) + (((1.0 - rho[l]) * kappa[l]) * xk[l]);
            y[l] += z[l];
        }
    }
}

/// Two input-driven slow states, a faster and a slower one, with gains
/// `s·κ` and `(1−s)·κ`.
#[derive(Debug)]
pub struct TwoPoleCreep;

impl<const L: usize> Stage<L> for TwoPoleCreep {
    /// The faster state's pole and gain, the slower one's, and its start.
    type Consts = [[f32; L]; 5];
    /// The faster and the slower slow state.
    type State = [[f32; L]; 2];

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        let (kappa, share) = (p.get(2), p.get(3));
        let kappa_fast: [f32; L] = std::array::from_fn(|l| share[l] * kappa[l]);
        let kappa_slow = std::array::from_fn(|l| kappa[l] - kappa_fast[l]);
        [p.get(0), kappa_fast, p.get(1), kappa_slow, p.get(4)]
    }

    fn start(c: Option<&Self::Consts>, _: &[f32; L], _: f32) -> Self::State {
        [[0.0; L], c.map_or([0.0; L], |c| c[4])]
    }

    #[inline(always)]
    fn restart([fast, slow]: &mut Self::State, l: usize, _: f32, x: f32) -> f32 {
        (x - fast[l]) - slow[l]
    }
}

impl<const L: usize> OutputLoop<L> for TwoPoleCreep {
    #[inline(always)]
    fn apply(
        [rf, kf, rs, ks, _]: &Self::Consts,
        s: &mut Self::State,
        y: &mut [f32; L],
        ui: &[f32; L],
        _: &[f32; L],
        _: &At<'_, L>,
    ) {
        let [fast, slow] = s;
        for l in 0..L {
            fast[l] = (rf[l] * fast[l]) + (((1.0 - rf[l]) * kf[l]) * ui[l]);
            slow[l] = (rs[l] * slow[l]) + (((1.0 - rs[l]) * ks[l]) * ui[l]);
            y[l] += fast[l];
            y[l] += slow[l];
        }
    }
}

/// Three input-driven slow states a decade apart in time constant (poles
/// `ρ^100`, `ρ^10`, `ρ`), each of static gain `κ`.
#[derive(Debug)]
pub struct LogCreep;

impl<const L: usize> Stage<L> for LogCreep {
    /// The poles and input weights `(1 − ρ)·κ`, fastest first, and the
    /// slowest term's start.
    type Consts = [[f32; L]; 7];
    /// The terms, fastest first.
    type State = [[f32; L]; 3];

    fn prepare(p: &Columns<'_, L>, _: &Frame) -> Self::Consts {
        // Poles a decade apart in time constant: ρ^100, ρ^10, ρ.
        let slow = p.get(0);
        let mid = slow.map(tenth_power);
        let fast = mid.map(tenth_power);
        let kappa = p.get(1);
        let weight = |rho: [f32; L]| std::array::from_fn(|l| (1.0 - rho[l]) * kappa[l]);
        [
            fast,
            weight(fast),
            mid,
            weight(mid),
            slow,
            weight(slow),
            p.get(2),
        ]
    }

    fn start(c: Option<&Self::Consts>, _: &[f32; L], _: f32) -> Self::State {
        [[0.0; L], [0.0; L], c.map_or([0.0; L], |c| c[6])]
    }

    #[inline(always)]
    fn restart([fast, mid, slow]: &mut Self::State, l: usize, _: f32, x: f32) -> f32 {
        ((x - fast[l]) - mid[l]) - slow[l]
    }
}

impl<const L: usize> OutputLoop<L> for LogCreep {
    #[inline(always)]
    fn apply(
        [rf, wf, rm, wm, rs, ws, _]: &Self::Consts,
        s: &mut Self::State,
        y: &mut [f32; L],
        ui: &[f32; L],
        _: &[f32; L],
        _: &At<'_, L>,
    ) {
        let [fast, mid, slow] = s;
        for l in 0..L {
            fast[l] = (rf[l] * fast[l]) + (wf[l] * ui[l]);
            mid[l] = (rm[l] * mid[l]) + (wm[l] * ui[l]);
            slow[l] = (rs[l] * slow[l]) + (ws[l] * ui[l]);
            y[l] += fast[l];
            y[l] += mid[l];
            y[l] += slow[l];
        }
    }
}

/// `ρ^10` by products (`ρ²`, `ρ⁴`, `ρ⁸·ρ²`), spelled as in the shader: a
/// pole whose time constant is a tenth of `ρ`'s.
#[inline(always)]
fn tenth_power(rho: f32) -> f32 {
    let p2 = rho * rho;
    let p4 = p2 * p2;
    (p4 * p4) * p2
}
