//! The physical effects the independent self-test realises and the ways it
//! realises each: the rows of its confusion table, each realisation's one
//! size and what that size means (0 always neutral). The harness and the
//! judging (`super`) read this list; the equations that realise each entry
//! are [`super::generator`]'s.

use serde::Serialize;

/// A physical effect of the list (the rows of the confusion table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Physical {
    Lag,
    Inertia,
    Asymmetry,
    EndStop,
    Creep,
    Threshold,
    Rate,
    Backlash,
    Load,
    Softening,
    Set,
    /// No catalogued effect: the check that the diagnosis says "not
    /// explained by the catalogue" instead of a wrong name.
    Outside,
}

impl Physical {
    pub fn name(self) -> &'static str {
        match self {
            Physical::Lag => "lag",
            Physical::Inertia => "inertia",
            Physical::Asymmetry => "asymmetry",
            Physical::EndStop => "end stop",
            Physical::Creep => "creep",
            Physical::Threshold => "threshold",
            Physical::Rate => "rate",
            Physical::Backlash => "backlash",
            Physical::Load => "load",
            Physical::Softening => "softening",
            Physical::Set => "set",
            Physical::Outside => "outside the catalogue",
        }
    }
}

/// One way a physical effect is realised. Each has one size, 0 neutral.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mechanism {
    /// The input `d` samples late (linear interpolation): size `d` (samples).
    PureDelay,
    /// The input through `v(k) = ρ·v(k−1) + (1−ρ)·p(k)`: size its mean delay
    /// `τ = ρ/(1−ρ)` (samples).
    InputLag,
    /// The measured output through the same first-order lag: size `τ` (samples).
    OutputLag,
    /// A load the muscle drives through a first-order lag, `q(k) = ρ·q(k−1)
    /// + (1−ρ)·x(k)`, with the Bouc-Wen state driven by the load's motion
    /// `Δq`: an extra real pole inside the loop; size the pole `ρ`.
    ExtraPole,
    /// The measured output through an underdamped second-order mode (unit
    /// static gain, damping 0.1): size its natural period (samples).
    LoadMode,
    /// Input gain `1 + ε` on the rising branch, `1 − ε` on the falling one
    /// (absolute input, the branch switching after a 2 %-of-range reversal):
    /// size `ε`.
    GainAsymmetry,
    /// The chamber fills at once but drains through a first-order lag (the
    /// input follows a rising command at once, a falling one with time
    /// constant `τ`): size `τ` (samples).
    DrainLag,
    /// The muscle's state stops at the end stop (the Bouc-Wen state sees the
    /// stopped motion): size the stop's distance below the nominal peak.
    StateClip,
    /// Only the measured output is clipped (a stop after the sensor's
    /// linkage; the state runs on): size as [`StateClip`](Self::StateClip).
    OutputClip,
    /// A smooth stop on the state: identity up to a knee, then
    /// `knee + h·tanh((x − knee)/h)` (`h` 5 % of the output range): size the
    /// knee's distance below the nominal peak.
    SoftLimit,
    /// `z(k) = ρ·z(k−1) + (1−ρ)·κ·u(k−1)` added to the output, ρ = 0.995:
    /// size `κ` (output per input unit).
    CreepInput,
    /// `z(k) = ρ·z(k−1) + (1−ρ)·κ·x(k)` added to the output (driven by the
    /// muscle's own displacement, not the pressure), ρ = 0.995: size `κ`.
    CreepOutput,
    /// Two input-driven creep states, ρ = 0.99 and 0.999, half the gain
    /// each: size the total gain `κ` (output per input unit).
    CreepTwo,
    /// The muscle does not respond to the first `p0` above the input's
    /// lowest level: size `p0` (input units).
    DeadZone,
    /// Contraction starts when the input rises above `p_on = p_lo + s` and
    /// releases when it falls below `p_off = p_lo + s/2`; while released the
    /// muscle sees the lowest level: size `s` (input units).
    HystereticThreshold,
    /// The Bouc-Wen stiffness grows with the smoothed input rate:
    /// `v(k) = ½·v(k−1) + ½·|p(k−1) − p(k−2)|/dt`, `A·(1 + η·v)`: size `η`.
    ViscousRate,
    /// A play operator of width `r` on the input: size `r` (input units).
    Play,
    /// A second dataset (another load) whose input gain is `1 + g` on the
    /// absolute input: size `g`.
    LoadGain,
    /// A softer muscle moves further from its rest for the same pressure:
    /// the measured displacement from the nominal rest (at the lowest
    /// input) grows by `s·q̂`, `q̂` the largest input so far as a share of
    /// the excitation's range (a Mullins-type damage that grows with the
    /// largest load): size `s`, the growth once the largest input is
    /// reached.
    MullinsSoftening,
    /// The same drive grows with the number of loadings `n` so far: times
    /// `1 + s·n/(n + 1)` (a loading begins when the input rises 2 % of its
    /// range above its low since the last fall): size `s`.
    CyclicSoftening,
    /// The sensor sees the muscle kept away from its drive by `s·(x̂ −
    /// x)/range`, `x̂` the muscle's largest displacement toward its drive so
    /// far and `range` the nominal output's: a set that grows with the
    /// largest strain and vanishes at it (Dorfmann and Ogden's): size `s`
    /// (output units at rest, once the largest displacement is reached).
    PermanentSet,
    /// The sensor sees the muscle's rest walk away from its drive by
    /// `s·ln(1 + n)/ln 5` after `n` loadings, a walk that slows down
    /// without stopping: size `s` (output units, the walk after four).
    Ratchet,
    /// The displacement sensor picks up the valve's pressure transients
    /// (electrical cross-talk): `κ·(p(k−1) − v(k))` added to the measured
    /// output, `v` the input through a first-order lag of 3 samples, i.e. a
    /// high-pass of the input. No catalogued effect has a lead: size `κ`
    /// (output per input unit).
    CrossTalk,
}

impl Mechanism {
    /// Every realisation, grouped by physical effect.
    pub const ALL: [Mechanism; 23] = [
        Mechanism::PureDelay,
        Mechanism::InputLag,
        Mechanism::OutputLag,
        Mechanism::ExtraPole,
        Mechanism::LoadMode,
        Mechanism::GainAsymmetry,
        Mechanism::DrainLag,
        Mechanism::StateClip,
        Mechanism::OutputClip,
        Mechanism::SoftLimit,
        Mechanism::CreepInput,
        Mechanism::CreepOutput,
        Mechanism::CreepTwo,
        Mechanism::DeadZone,
        Mechanism::HystereticThreshold,
        Mechanism::ViscousRate,
        Mechanism::Play,
        Mechanism::LoadGain,
        Mechanism::MullinsSoftening,
        Mechanism::CyclicSoftening,
        Mechanism::PermanentSet,
        Mechanism::Ratchet,
        Mechanism::CrossTalk,
    ];

    pub fn physical(self) -> Physical {
        use Mechanism::*;
        match self {
            PureDelay | InputLag | OutputLag => Physical::Lag,
            ExtraPole | LoadMode => Physical::Inertia,
            GainAsymmetry | DrainLag => Physical::Asymmetry,
            StateClip | OutputClip | SoftLimit => Physical::EndStop,
            CreepInput | CreepOutput | CreepTwo => Physical::Creep,
            DeadZone | HystereticThreshold => Physical::Threshold,
            ViscousRate => Physical::Rate,
            Play => Physical::Backlash,
            LoadGain => Physical::Load,
            MullinsSoftening | CyclicSoftening => Physical::Softening,
            PermanentSet | Ratchet => Physical::Set,
            CrossTalk => Physical::Outside,
        }
    }

    pub fn name(self) -> &'static str {
        use Mechanism::*;
        match self {
            PureDelay => "pure delay",
            InputLag => "input lag",
            OutputLag => "output lag",
            ExtraPole => "extra real pole",
            LoadMode => "underdamped load",
            GainAsymmetry => "in gain",
            DrainLag => "in time constant",
            StateClip => "state clip",
            OutputClip => "output clip",
            SoftLimit => "soft limit",
            CreepInput => "input-driven",
            CreepOutput => "output-driven",
            CreepTwo => "two time constants",
            DeadZone => "dead zone",
            HystereticThreshold => "hysteretic",
            ViscousRate => "viscous",
            Play => "play",
            LoadGain => "input gain",
            MullinsSoftening => "largest input so far",
            CyclicSoftening => "number of loadings",
            PermanentSet => "grows with the largest input",
            Ratchet => "walks with every loading",
            CrossTalk => "sensor cross-talk",
        }
    }

    /// `physical: realisation`, the confusion table's row label.
    pub fn label(self) -> String {
        format!("{}: {}", self.physical().name(), self.name())
    }

    /// Whether the realisation shows only where a muscle is loaded again
    /// and again: its cases are on the pulse trains, not on the stair and
    /// the multisine.
    pub fn on_pulses(self) -> bool {
        self.physical() == Physical::Softening || self.physical() == Physical::Set
    }

    /// Datasets the realisation needs (a load needs a second one).
    pub fn datasets(self) -> usize {
        if self == Mechanism::LoadGain { 2 } else { 1 }
    }
}
