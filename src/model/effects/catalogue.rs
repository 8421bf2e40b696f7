//! The catalogue: one entry per realisation (docs/DIAGNOSIS.md, "The
//! effects catalogue"), from which [`Effect`] and everything asked of it
//! are generated or looked up (`table.rs`), and the step order, which
//! places each realisation's CPU stage (`stages/`) in the step
//! (`stage.rs`). Its GPU stage is in `shaders/effects.wgsl`, the CPU
//! stage's twin, named after it and called in the same order (the calls
//! are generated from the step order: `eval::gpu::stages`), which the
//! bit-identity tests keep equal.

use super::Realisation;
// What the step order's `stages!` names.
use super::stage::{
    At, Columns, Frame, InputLoop, Lane, OutputLoop, Placed, Side, Slot, Stage, StateLoop, stages,
};
use super::stages::*;
use super::table::{EffectBox, Param, Params, StartHint, Unit, catalogue};

catalogue! {
    physical {
        /// Input transport delay: `u(k−1−d)` replaces `u(k−1)`; `d ≥ 0` samples,
        /// fractional `d` interpolates linearly between neighbouring samples.
        Delay => Realisation {
            name: "delay",
            physical: None,
            realisation: "pure delay",
            signature: "residual–input cross-correlation peaks at a positive lag; energy right after each input step",
            params: Params::Fixed(&[Param::pure("d", "input delay (samples)")]),
            dynamics: &["d"],
            primary: 0,
            bounds: |_, _| EffectBox::new(vec![0.0], vec![0.0], vec![30.0]),
            size_text: Some(|p, dt| format!("{:.1} samples ({:.0} ms)", p[0], 1000.0 * p[0] * dt)),
            ..PLAIN
        },
        /// Threshold `p0` (absolute input units) below which the muscle does not
        /// respond: `p_eff = max(p − p0, 0)`.
        Deadzone => Realisation {
            name: "deadzone",
            physical: None,
            realisation: "input dead zone",
            signature: "residual energy concentrated in the lowest input band",
            params: Params::Fixed(&[Param::input("p0", "input threshold (absolute input units)")]),
            primary: 0,
            bounds: |ctx, _| {
                let lo = ctx.input_min.min(0.0);
                EffectBox::new(vec![0.0], vec![lo], vec![ctx.input_min.max(0.0) + 0.6 * ctx.input_range()])
            },
            ..PLAIN
        },
        /// End stop: the output cannot pass `l_max` (absolute output units) in the
        /// direction the input drives it (hard bound).
        Saturation => Realisation {
            name: "saturation",
            physical: None,
            realisation: "state clip",
            ..END_STOP
        },
        /// Loading and unloading differ: the input gain is `b·(1+ε)` on the rising
        /// branch and `b·(1−ε)` on the falling one, i.e. `b_up`, `b_down`.
        Asymmetry => Realisation {
            name: "asymmetry",
            physical: None,
            realisation: "in gain",
            signature: "rising and falling branches carry unequal residual energy",
            params: Params::Fixed(&[Param::pure(
                "eps",
                "gain asymmetry: b_up = b·(1+eps), b_down = b·(1−eps)",
            )]),
            primary: 0,
            bounds: |_, _| EffectBox::new(vec![0.0], vec![-0.5], vec![0.5]),
            ..PLAIN
        },
        /// An extra pole (load mass, hose compliance): `x(k) += a2·(x(k−1) − x(k−2))`,
        /// a second-order linear part with the same static gain.
        Inertia => Realisation {
            name: "inertia",
            physical: None,
            realisation: "extra real pole",
            signature: "energy in the transient after steps (overshoot or sluggish rise), mid frequencies",
            params: Params::Fixed(&[Param::pure("a2", "weight of x(k−1) − x(k−2): the extra pole")]),
            dynamics: &["a2"],
            primary: 0,
            bounds: |_, _| EffectBox::new(vec![0.0], vec![-0.5], vec![0.9]),
            ..PLAIN
        },
        /// Play of width `r` (input units) on the input (braid stick–slip).
        Backlash => Realisation {
            name: "backlash",
            physical: None,
            realisation: "play on the input",
            signature: "residual right after input reversals; loop too narrow",
            params: Params::Fixed(&[Param::input("r", "play width (input units)")]),
            primary: 0,
            bounds: |ctx, _| EffectBox::new(vec![0.0], vec![0.0], vec![0.5 * ctx.input_range()]),
            ..PLAIN
        },
        /// A slow first-order state added to the output:
        /// `z(k) = ρ·z(k−1) + (1−ρ)·κ·u(k−1)`, `ŷ = x + z`; `κ` is its static
        /// gain (output per input unit), `ρ` its pole, `z(0) = z0` where the
        /// record's history left it.
        Creep => Realisation {
            name: "creep",
            physical: None,
            realisation: "driven by the input",
            params: Params::Fixed(&[
                Param::pure("rho", "pole of the slow state (close to 1)"),
                Param::gain("kappa", "static gain of the slow state (output per input unit)"),
                Param::output(
                    "z0",
                    "the slow state at the first sample (output units): where the record's history left it",
                ),
            ]),
            dynamics: &["rho"],
            // A creep's slow state starts where the record's history left
            // it, `z0`, anywhere within the output range: a state at rest in
            // some other frame (the deviation coordinates of another record,
            // or absolute units) starts a transient that neither `x0` nor
            // the intercept can take (docs/lab/diagnosis.md, "Which: the
            // effects catalogue").
            bounds: |ctx, _| {
                let ry = ctx.output_range();
                let g = 2.0 * ry / ctx.input_range();
                EffectBox::new(vec![0.995, 0.0, 0.0], vec![0.98, -g, -ry], vec![0.9995, g, ry])
            },
            ..CREEP
        },
        /// Rate-dependent hysteresis: the Bouc-Wen stiffness grows with the input
        /// rate, `A_eff = A·(1 + η·|u(k−1) − u(k−2)|/dt)`, so the loop widens with
        /// rate; `η` in seconds per input unit.
        Rate => Realisation {
            name: "rate",
            physical: None,
            realisation: "stiffness grows with input rate",
            signature: "residual grows with input rate: rising/falling branches, high frequencies",
            params: Params::Fixed(&[Param::seconds_per_input("eta", "growth of A with input rate (s per input unit)")]),
            primary: 0,
            bounds: |ctx, _| {
                let v = (ctx.max_step / ctx.dt).max(f64::MIN_POSITIVE);
                EffectBox::new(vec![0.0], vec![-0.9 / v], vec![10.0 / v])
            },
            ..PLAIN
        },
        /// Parameters that depend on the hanging load: the input gain of dataset
        /// `e ≥ 1` is `b·(1 + g_e)` on the absolute input (dataset 0 is the
        /// reference). Needs several datasets.
        Load => Realisation {
            name: "load",
            physical: None,
            realisation: "input gain per dataset",
            signature: "one dataset (load) carries most of the residual energy",
            params: Params::PerLaterDataset {
                name: "g",
                meaning: "relative input gain of this dataset against dataset 0",
                unit: Unit::Pure,
            },
            primary: 0,
            bounds: |_, datasets| {
                let k = datasets.max(1) - 1;
                EffectBox::new(vec![0.0; k], vec![-0.5; k], vec![0.5; k])
            },
            min_datasets: 2,
            ..PLAIN
        },
        /// Mullins-type softening: the input above the record's lowest one,
        /// `p − p_rest`, gains `s·(p̂ − p_rest)`, `p̂` the largest input so
        /// far, so a muscle once driven harder responds more at every input
        /// (a damage driven by the largest load so far, as Ogden and
        /// Roxburgh's); equal pulses change only the first rise.
        Softening => Realisation {
            name: "softening",
            physical: None,
            realisation: "driven by the largest input so far (Mullins)",
            signature: "the response deepens after each new largest input and stays deeper below it",
            params: Params::Fixed(&[Param::per_input(
                "s",
                "growth of the input gain per input unit of the largest input so far above the lowest",
            )]),
            primary: 0,
            bounds: |ctx, _| {
                let ru = ctx.input_range();
                EffectBox::new(vec![0.0], vec![-0.5 / ru], vec![1.0 / ru])
            },
            ..PLAIN
        },
        /// Permanent set: the output moves by `share·(x̂ − x)` toward the
        /// drive, `x̂` the muscle's largest displacement toward its drive so
        /// far: at `x̂` the muscle is where it was when first driven there,
        /// short of it it keeps that share of the way back, an offset that
        /// at rest grows with every new largest displacement and never
        /// shrinks (as Dorfmann and Ogden's set grows with the largest
        /// strain).
        Set => Realisation {
            name: "set",
            physical: None,
            realisation: "grows with the largest displacement so far",
            signature: "the rest level moves for good after the largest displacement so far and stays there",
            params: Params::Fixed(&[Param::pure(
                "share",
                "share of the way back from the largest displacement so far that the muscle keeps (positive: toward the drive)",
            )]),
            primary: 0,
            // Either way, at most the whole way back: at 1 the output would
            // stay at the largest displacement.
            bounds: |_, _| EffectBox::new(vec![0.0], vec![-1.0], vec![1.0]),
            ..PLAIN
        },
    }
    realisations {
        /// Lag as a first-order lag on the input, `v = ρ·v + (1−ρ)·p` (pressure
        /// reaching the muscle through the hose); mean delay `ρ/(1−ρ)` samples.
        InputLag => Realisation {
            name: "delay:input-lag",
            realisation: "first-order lag on the input",
            ..LAG
        },
        /// Lag as a first-order lag on the measured output, `ŷ ← ρ·ŷ(k−1) +
        /// (1−ρ)·ŷ` (a slow sensor).
        OutputLag => Realisation {
            name: "delay:output-lag",
            realisation: "first-order lag on the output",
            ..LAG
        },
        /// Inertia as a second-order mode of the hanging load on the output,
        /// `q = a1·q(k−1) − a2·q(k−2) + (1 − a1 + a2)·ŷ`, unit static gain:
        /// underdamped (ringing) when `a1² < 4·a2`, with pole radius `√a2` and
        /// angle `acos(a1/(2√a2))` per sample.
        LoadMode => Realisation {
            name: "inertia:mode",
            physical: Some(Effect::Inertia),
            realisation: "second-order load mode",
            signature: MODE_SIGNATURE,
            params: Params::Fixed(&[MODE_A1, MODE_A2]),
            dynamics: &["a1", "a2"],
            primary: 1,
            // Every stable mode lies in a2 < 1, |a1| < 1 + a2.
            bounds: |_, _| EffectBox::new(vec![0.0, 0.0], vec![-1.9, 0.0], vec![1.98, 0.98]),
            size_text: Some(mode_size),
            min_datasets: 1,
            admits: None,
            hint: StartHint::ResidualPeak {
                kick: None,
                only_on_a_peak: false,
            },
            on_request: false,
        },
        /// Asymmetry in time constant: the input passes at once on one branch
        /// and through a first-order lag `|ρ|` on the other (`ρ > 0`: drains
        /// slower than it fills; `ρ < 0`: fills slower).
        DrainLag => Realisation {
            name: "asymmetry:drain",
            physical: Some(Effect::Asymmetry),
            realisation: "in time constant (fill vs drain)",
            signature: "falling branches carry more residual energy, later in the step",
            params: Params::Fixed(&[Param::pure(
                "rho",
                "pole of the slow branch: > 0 drains slower, < 0 fills slower",
            )]),
            dynamics: &["rho"],
            primary: 0,
            bounds: |_, _| EffectBox::new(vec![0.0], vec![-0.97], vec![0.97]),
            size_text: Some(|p, dt| {
                let side = if p[0] >= 0.0 { "drain" } else { "fill" };
                format!("{side} time constant {}", lag_samples(p[0].abs(), dt))
            }),
            ..PLAIN
        },
        /// End stop on the measured output only (the state runs on).
        OutputClip => Realisation {
            name: "saturation:output",
            physical: Some(Effect::Saturation),
            realisation: "output clip",
            ..END_STOP
        },
        /// End stop as a smooth knee: a quadratic blend into `l_max` over a
        /// fixed half-width of 2.5 % of the output range on each side.
        SoftStop => Realisation {
            name: "saturation:soft",
            physical: Some(Effect::Saturation),
            realisation: "soft limit",
            ..END_STOP
        },
        /// Creep driven by the muscle's output: `z = ρ·z + (1−ρ)·κ·x`,
        /// `ŷ = x + z`; `κ` per output unit; `z(0) = z0`.
        OutputCreep => Realisation {
            name: "creep:output",
            physical: Some(Effect::Creep),
            realisation: "driven by the output",
            params: Params::Fixed(&[
                Param::pure("rho", "pole of the slow state (close to 1)"),
                Param::pure("kappa", "static gain of the slow state (per output unit)"),
                Param::output(
                    "z0",
                    "the slow state at the first sample (output units): where the record's history left it",
                ),
            ]),
            dynamics: &["rho"],
            bounds: |ctx, _| {
                let ry = ctx.output_range();
                EffectBox::new(vec![0.995, 0.0, 0.0], vec![0.98, -0.5, -ry], vec![0.9995, 0.5, ry])
            },
            ..CREEP
        },
        /// Creep with two time constants: two input-driven slow states, a
        /// faster and a slower one, two terms of a Prony series: gains `s·κ`
        /// and `(1−s)·κ` of one sign; the slower starts at `z0`.
        TwoPoleCreep => Realisation {
            name: "creep:two-pole",
            physical: Some(Effect::Creep),
            realisation: "two time constants",
            params: Params::Fixed(&[
                Param::pure("rho_fast", "pole of the faster slow state"),
                Param::pure("rho_slow", "pole of the slower slow state"),
                Param::gain("kappa", "static gain of both together (output per input unit)"),
                Param::pure("fast_share", "the faster state's share of kappa, in [0, 1]"),
                Param::output(
                    "z0",
                    "the slower state at the first sample (output units): where the record's history left it",
                ),
            ]),
            dynamics: &["rho_fast", "rho_slow", "fast_share"],
            primary: 2,
            // Two terms of a Prony series: a passive material creeps the
            // same way at every time scale, so the two gains share a sign (a
            // total and the faster state's share of it). With gains of
            // either sign the pair is a band-pass of the input, not creep,
            // and is named on the twin's stair, which has no creep
            // (docs/lab/diagnosis.md, "Which: the effects catalogue"). The
            // faster state forgets its start within a few hundred samples;
            // the slower one gets `z0`. The slower state is no slower than
            // the one-pole creeps' slowest (2 000 samples, the estimation
            // half of the shipped records): over a record shorter than its
            // time constant a slow state shows only as a ramp, whose gain
            // and pole trade along `κ·(1 − ρ)`, and the fit ran that gain
            // out to four times the true one (docs/lab/diagnosis.md, "A
            // slow state the record can pin").
            bounds: |ctx, _| {
                let ry = ctx.output_range();
                let g = 2.0 * ry / ctx.input_range();
                EffectBox::new(
                    vec![0.98, 0.999, 0.0, 0.5, 0.0],
                    vec![0.9, 0.995, -g, 0.0, -ry],
                    vec![0.995, 0.9995, g, 1.0, ry],
                )
            },
            ..CREEP
        },
        /// Hysteretic threshold: the muscle starts to contract when the input
        /// passes `p_on` and lets go below `p_off = p_on − gap`; while off it
        /// rests where the lowest input recorded leaves it (it sees that input).
        OnOffThreshold => Realisation {
            name: "deadzone:on-off",
            physical: Some(Effect::Deadzone),
            realisation: "hysteretic threshold (on/off)",
            signature: "residual in the lowest input band, unlike on rising and falling branches",
            params: Params::Fixed(&[
                Param::input("p_on", "input above which the muscle contracts (absolute input units)"),
                Param::input("gap", "p_on − p_off, the input it lets go below (input units)"),
            ]),
            primary: 0,
            bounds: |ctx, _| {
                // Neutral: on below every input, so the muscle is always on.
                let ru = ctx.input_range();
                let never = ctx.input_min.min(0.0) - 0.05 * ru;
                EffectBox::new(
                    vec![never, 0.0],
                    vec![never, 0.0],
                    vec![ctx.input_min.max(0.0) + 0.6 * ru, 0.3 * ru],
                )
            },
            ..PLAIN
        },
        /// Inertia as the hanging load ringing after each input step, on top of
        /// a muscle that follows the force quasi-statically: a mode excited by
        /// the input's change, `r = a1·r(k−1) − a2·r(k−2) + g·(u(k−1) − u(k−2))`,
        /// `ŷ = x + r`. Unlike [`Effect::LoadMode`], it rings however slowly the
        /// baseline's own output moves (a real muscle's force follows the
        /// pressure at once while the baseline's slow pole describes creep of
        /// the rubber, as on the Cavatappi muscle: docs/lab/diagnosis.md,
        /// "Which: the effects catalogue").
        Ringing => Realisation {
            name: "inertia:ringing",
            physical: Some(Effect::Inertia),
            realisation: "load rings after input steps",
            signature: MODE_SIGNATURE,
            params: Params::Fixed(&[
                MODE_A1,
                MODE_A2,
                Param::gain("g", "kick of an input step (output per input unit)"),
            ]),
            dynamics: &["a1", "a2"],
            primary: 2,
            // A kick of g·Δu rings at most about 1/sin θ times higher; a
            // whole input range's step then spans the output range at θ ≈ 1
            // rad. Neutral at any mode without a kick; this mode rings (the
            // diagnosis admits only ringing ones).
            bounds: |ctx, _| {
                let g = ctx.output_range() / ctx.input_range();
                EffectBox::new(vec![0.0, 0.5, 0.0], vec![-1.9, 0.0, -g], vec![1.98, 0.98, g])
            },
            size_text: Some(mode_size),
            min_datasets: 1,
            admits: Some(|p| rings(p[0], p[1])),
            // Looked for only where the residual rings: a mode kicked by the
            // input and damped near 1/√2 is a high-pass of the input, and
            // without a peak to explain it fits the independent self-test's
            // sensor cross-talk, a high-pass added to the output
            // (docs/lab/diagnosis.md, "Which: the effects catalogue").
            hint: StartHint::ResidualPeak {
                kick: Some(2),
                only_on_a_peak: true,
            },
            on_request: false,
        },
        /// Log-time creep of the rubber: three input-driven slow states a
        /// decade apart in time constant (poles `ρ^100`, `ρ^10`, `ρ`), each
        /// of static gain `κ`, a Prony series with one term per decade, so
        /// after an input step the output creeps by about `κ·Δu` per decade
        /// of time, from a hundredth of the slowest time constant to it;
        /// the slowest starts at `z0`. A rubber's creep has no one time constant: the
        /// two-pole creep fitted to the Cavatappi records puts its two
        /// poles more than a decade apart, and the response deepens from
        /// pulse to pulse beyond the slower (docs/DIAGNOSIS.md, "Real data:
        /// the Cavatappi muscle"), with five parameters where this has
        /// three.
        LogCreep => Realisation {
            name: "creep:log",
            physical: Some(Effect::Creep),
            realisation: "log-time (a term per decade)",
            params: Params::Fixed(&[
                Param::pure("rho", "pole of the slowest term; the others are rho^10 and rho^100"),
                Param::gain(
                    "kappa",
                    "static gain of each term: creep per decade of time (output per input unit)",
                ),
                Param::output(
                    "z0",
                    "the slowest term at the first sample (output units): where the record's history left it",
                ),
            ]),
            dynamics: &["rho"],
            // The slowest time constant from 1 000 to 20 000 samples (10 to
            // 200 s at 100 Hz), the fastest a hundredth of it; three terms
            // of the creep's whole gain each at most.
            bounds: |ctx, _| {
                let ry = ctx.output_range();
                let g = 2.0 * ry / ctx.input_range();
                EffectBox::new(vec![0.9995, 0.0, 0.0], vec![0.999, -g, -ry], vec![0.99995, g, ry])
            },
            size_text: Some(|p, dt| {
                let tau = |n: f64| -dt / (n * p[0].ln());
                format!(
                    "time constants {:.2} s, {:.1} s, {:.0} s",
                    tau(100.0),
                    tau(10.0),
                    tau(1.0)
                )
            }),
            // On the independent self-test it takes the two-pole creep's
            // case on the multisine and sizes it far off (its slowest term
            // has not settled within a record), and no Cavatappi record
            // selects it (docs/DIAGNOSIS.md, "The effects catalogue"):
            // tried when named.
            on_request: true,
            ..CREEP
        },
        /// Cyclic softening: the input above the record's lowest one gains
        /// `s·(1 − r^n)` after `n` loadings (a loading begins where the
        /// asymmetry's rising branch does), so equal pulses go deeper one
        /// after the other, by less each time, and a rest does not undo it,
        /// where a creep recovers.
        CyclicSoftening => Realisation {
            name: "softening:cyclic",
            physical: Some(Effect::Softening),
            realisation: "driven by the number of loadings",
            signature: "equal pulses go deeper one after the other, and the rests do not undo it",
            params: Params::Fixed(&[
                Param::pure("s", "growth of the input gain once trained (relative)"),
                Param::pure("r", "share of the growth still to come that each loading leaves"),
            ]),
            dynamics: &["r"],
            primary: 0,
            // `r` from 0.2: a growth reached at the first loading acts like
            // the baseline's own gain, since the input above the lowest one
            // is 0 before it.
            bounds: |_, _| EffectBox::new(vec![0.0, 0.6], vec![-0.5, 0.2], vec![1.0, 0.95]),
            size_text: Some(|p, _| loadings_to_half(p[1])),
            ..PLAIN
        },
        /// Ratchet: the output moves by `a` at the first loading, and at the
        /// `n`-th by the step before times `1 − q/n`: an offset that walks
        /// with every cycle, its steps falling about as `n^−q`. Ratchetting
        /// slows after the first cycles, to a steady rate or to a stop
        /// (shakedown): `q = 0` walks steadily, `q = 1` as the log of the
        /// count, `q > 1` settles, and at `q = 2` the first step is all. A
        /// product per loading, where the power itself would need a `pow`,
        /// which the GPU does not round as the CPU does.
        Ratchet => Realisation {
            name: "set:ratchet",
            physical: Some(Effect::Set),
            realisation: "walks with every loading",
            signature: "the rest level walks with every loading",
            params: Params::Fixed(&[
                Param::output("a", "step at the first loading (output units)"),
                Param::pure(
                    "q",
                    "how fast the later steps fall: the n-th is the one before times 1 − q/n (0: a steady walk, 1: a walk as the log of the count, above 1 it settles)",
                ),
            ]),
            dynamics: &["q"],
            primary: 0,
            bounds: |ctx, _| {
                let ry = ctx.output_range();
                EffectBox::new(vec![0.0, 1.0], vec![-0.5 * ry, 0.0], vec![0.5 * ry, 2.0])
            },
            size_text: Some(|p, _| ratchet_text(p[0], p[1])),
            ..PLAIN
        },
    }
}

// The step order: where each realisation's stage runs in
// `Prepared::step` (`step.rs`), and the order the GPU's step calls the
// stages of `shaders/effects.wgsl` in (`STEP_ORDER`, `eval::gpu::stages`).
// The input side moves the input: loops of their own, then the first
// realisations' shared loop over the lanes, then late loops. The state
// side moves the new output state: the shared loop with the baseline's
// linear part, then loops (the rate moves the Bouc-Wen stiffness). The
// output side moves the predicted output; the restart subtracts the
// realisations' terms in this order. A new realisation gets a loop of its
// own (`input`, `input_late`, `state` or `output`): one more stage in a
// shared loop made it scalar.
stages! {
    input: Delay, InputLag, OnOffThreshold;
    input_lanes: Deadzone, Backlash, Asymmetry, Load;
    input_late: DrainLag, Softening, CyclicSoftening;
    state_lanes: Inertia, Saturation;
    state: SoftStop, Rate;
    output: Creep, OutputCreep, TwoPoleCreep, LogCreep, Set, Ratchet, Ringing, LoadMode, OutputClip, OutputLag;
}

/// The defaults of an entry: fitted on one dataset, admitting its whole
/// box, no start hint, no size in words; the fields every entry sets are
/// placeholders here.
const PLAIN: Realisation = Realisation {
    name: "",
    physical: None,
    realisation: "",
    signature: "",
    params: Params::Fixed(&[]),
    dynamics: &[],
    primary: 0,
    bounds: |_, _| EffectBox::new(Vec::new(), Vec::new(), Vec::new()),
    size_text: None,
    min_datasets: 1,
    admits: None,
    hint: StartHint::None,
    on_request: false,
};

/// The end stops' common parameter, box and signature.
const END_STOP: Realisation = Realisation {
    signature: "residual energy concentrated in the highest input band",
    params: Params::Fixed(&[Param::output(
        "l_max",
        "output end stop (absolute output units)",
    )]),
    // An end stop sits near the largest output recorded: the box is from
    // 40 % of the range below it to 5 % beyond it, where a model that
    // follows the data never reaches it (the neutral edge).
    bounds: |ctx, _| {
        let ry = ctx.output_range();
        if ctx.drives_up {
            let far = ctx.output_max + 0.05 * ry;
            EffectBox::new(vec![far], vec![ctx.output_max - 0.4 * ry], vec![far])
        } else {
            let far = ctx.output_min - 0.05 * ry;
            EffectBox::new(vec![far], vec![far], vec![ctx.output_min + 0.4 * ry])
        }
    },
    ..PLAIN
};

/// The first-order lags' common parameter, box and size.
const LAG: Realisation = Realisation {
    physical: Some(Effect::Delay),
    signature: "residual–input cross-correlation over a spread of positive lags; rounded steps",
    params: Params::Fixed(&[Param::pure(
        "rho",
        "pole of the lag (mean delay rho/(1−rho) samples)",
    )]),
    dynamics: &["rho"],
    // A pole of 0.97 is a mean delay of about 32 samples, the pure delay's 30.
    bounds: |_, _| EffectBox::new(vec![0.0], vec![0.0], vec![0.97]),
    size_text: Some(|p, dt| format!("time constant {}", lag_samples(p[0], dt))),
    ..PLAIN
};

/// The creeps' common signature and size parameter (the gain).
const CREEP: Realisation = Realisation {
    signature: "low-frequency residual that drifts while the input is steady",
    primary: 1,
    ..PLAIN
};

const MODE_SIGNATURE: &str = "a peak in the residual spectrum: ringing after each input step";
const MODE_A1: Param = Param::pure("a1", "first coefficient of the mode: 2·r·cos θ");
const MODE_A2: Param = Param::pure(
    "a2",
    "second coefficient of the mode: r², the pole radius squared",
);

/// A ratchet in words: its first step and how its steps fall.
fn ratchet_text(a: f64, q: f64) -> String {
    let how = match q {
        q if q < 0.05 => "a steady walk".to_string(),
        q if q < 1.0 => format!("steps falling as n^−{q:.2}: it walks on"),
        q => format!("steps falling as n^−{q:.2}: it settles"),
    };
    format!("first step {a:.3}, {how}")
}

/// How many loadings reach half of a trained effect whose share still to
/// come shrinks by `r` at each.
fn loadings_to_half(r: f64) -> String {
    format!("half of it after {:.1} loadings", 0.5f64.ln() / r.ln())
}

/// A lag of pole `rho` as its time constant in samples and milliseconds.
fn lag_samples(rho: f64, dt: f64) -> String {
    let tau = rho / (1.0 - rho);
    format!("{tau:.1} samples ({:.0} ms)", 1000.0 * tau * dt)
}

/// A mode's frequency and damping ratio (`p[0..2]` = `a1`, `a2`), or its
/// real poles when it does not ring.
fn mode_size(p: &[f64], dt: f64) -> String {
    let (a1, a2) = (p[0], p[1]);
    if a2 > 0.0 && a1 * a1 < 4.0 * a2 {
        let r = a2.sqrt();
        let theta = (a1 / (2.0 * r)).acos();
        let zeta = -r.ln() / (r.ln().powi(2) + theta * theta).sqrt();
        format!(
            "rings at {:.2} Hz, damping ratio {zeta:.2}",
            theta / (2.0 * std::f64::consts::PI * dt)
        )
    } else {
        let root = (a1 * a1 - 4.0 * a2).max(0.0).sqrt();
        format!(
            "no ringing: real poles {:.3} and {:.3}",
            0.5 * (a1 + root),
            0.5 * (a1 - root)
        )
    }
}

/// Whether the mode `q = a1·q(k−1) − a2·q(k−2) + …` rings: complex poles
/// `r·e^{±iθ}` (`r = √a2`, `cos θ = a1/(2r)`) with a resonance, i.e. a
/// damping ratio under `1/√2`, which is `−ln r < θ`.
///
/// Why: with real poles a ringing's kick decays as a slow drift driven by
/// the input, which is creep's mark, and a mode damped past `1/√2` has no
/// peak in its spectrum: it is a high-pass of the input, which the
/// independent self-test's sensor cross-talk is. Admitted in either form,
/// the ringing is named for drift or for cross-talk, neither of which it
/// is (docs/lab/diagnosis.md, "Which: the effects catalogue").
pub fn rings(a1: f64, a2: f64) -> bool {
    if !(a2 > 0.0 && a1 * a1 < 4.0 * a2) {
        return false;
    }
    let r = a2.sqrt();
    -r.ln() < (a1 / (2.0 * r)).acos()
}
