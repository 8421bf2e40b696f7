// The scoring loop of a family with effect stages: src/model/effects/step.rs
// `Prepared::step` and `Prepared::restart`, and each realisation's stage,
// the twin of its CPU stage in src/model/effects/stages/ (the same
// operations in the same order: every product that is then added kept
// rounded, minima and maxima as comparisons).
//
// The generated header (src/eval/gpu/stages.rs) holds every realisation's
// parameter struct `<Stage>Params` (a field per parameter of the
// catalogue's list) and, for the realisations the model has, the private
// variables of their constants and states and the functions `score` calls
// here: `stages_prepare`, `stages_start`, `stages_input`, `stages_state`,
// `stages_output` and `stages_restart`, which call each realisation's
// stage in the catalogue's step order. It also holds each experiment's
// constants (`U_MEAN`, `Y_MEAN`, `BRANCH_TOL`, `INV_DT`, `DRIVES_UP`,
// `KNEE_*`, `REST`, indexed by experiment), which `Frame` gathers.
//
// A realisation's stage is named after its CPU stage's type (the
// catalogue's variant), `TwoPoleCreep` here as an example:
// - `TwoPoleCreepConsts` and `fn two_pole_creep_prepare(q:
//   TwoPoleCreepParams, frame: Frame) -> TwoPoleCreepConsts`: what the step
//   needs of its parameters, once per candidate and experiment (`Stage::
//   prepare`);
// - where its CPU stage has states (`Stage::State` is not `()`),
//   `TwoPoleCreepState`, `fn two_pole_creep_start(c, x: f32, u0: f32) ->
//   TwoPoleCreepState` and `fn two_pole_creep_restart(s: ptr<private,
//   TwoPoleCreepState>, y: f32, x: f32) -> f32` (the output state `x` less
//   what it adds to the output; it may restart its states);
// - `fn two_pole_creep_step(c, [s: ptr<private, TwoPoleCreepState>,] ...)`,
//   by the side of the step it moves: on the input side `(ui: f32, at: At)
//   -> f32`, the new input; on the state side `(xk: ptr<function, f32>,
//   a_eff: ptr<function, f32>, at: At)`, the new output state and the
//   Bouc-Wen stiffness; on the output side `(y: f32, ui: f32, xk: f32, at:
//   At) -> f32`, the new prediction.
// tests/wgsl_variants.rs checks with naga that every pipeline's source is
// valid WGSL; the lavapipe tests that it gives the CPU's bits.

// What a stage may read of the experiment besides its own parameters
// (stage.rs `Frame`).
struct Frame {
    // Which experiment (the load gain is per dataset).
    e: u32,
    u_mean: f32,
    y_mean: f32,
    branch_tol: f32,
    // Whether the input drives the output up: the side of the end stops.
    drives_up: bool,
    // Context::knee: the soft stop's half-width h, 2h and 1/(4h).
    knee_h: f32,
    knee_2h: f32,
    knee_inv_4h: f32,
    // Context::rest_input.
    rest: f32,
    // 1/dt: the input rate is multiplied by it, so that no stage divides.
    inv_dt: f32,
}

// An experiment's constant as the CPU sees it: a value, not a literal.
// With one experiment its array is indexed by 0 for sure, so the compiler
// may fold the read into a literal, and Mesa's NIR reassociates sums around
// literals (`(b + h) − x` into `(b − x) + h`), which rounds differently
// (measured: the soft stop of a contracting muscle, docs/PERFORMANCE.md).
// The integer round trip of `rounded` hides the value from it.
fn unfolded(v: f32) -> f32 {
    return rounded(v);
}

fn frame_of(e: u32) -> Frame {
    return Frame(e, unfolded(U_MEAN[e]), unfolded(Y_MEAN[e]), unfolded(BRANCH_TOL[e]), DRIVES_UP[e],
        unfolded(KNEE_H[e]), unfolded(KNEE_2H[e]), unfolded(KNEE_INV_4H[e]), unfolded(REST[e]),
        unfolded(INV_DT[e]));
}

// What a stage may read of the sample being stepped, k ≥ 1 (stage.rs `At`).
struct At {
    // The experiment's samples in `samples`: (first, length).
    span: vec2<u32>,
    k: u32,
    // The measured input u(k−1).
    raw: f32,
    // Whether a step was taken before this one (the play and the lags start
    // at the first input).
    started: bool,
    // The output state x(k−1).
    x: f32,
    frame: Frame,
}

fn input(span: vec2<u32>, k: u32) -> f32 {
    return samples[span.x + k].x;
}

// The measured input u(k−2), u(0) at k = 1.
fn input_before(at: At) -> f32 {
    var prev = input(at.span, 0u);
    if (at.k >= 2u) {
        prev = input(at.span, at.k - 2u);
    }
    return prev;
}

// stage.rs `larger`: `a` if it is the larger, else `b`.
fn larger(a: f32, b: f32) -> f32 {
    if (a > b) {
        return a;
    }
    return b;
}

// stage.rs `smaller`: `a` if it is the smaller, else `b`.
fn smaller(a: f32, b: f32) -> f32 {
    if (a < b) {
        return a;
    }
    return b;
}

// One step of a first-order lag of pole `rho` from `prev` toward `v`.
fn lag(rho: f32, prev: f32, v: f32) -> f32 {
    return rounded(rho * prev) + rounded((1.0 - rho) * v);
}

// Scores candidate `i` (chunk-local) on experiment `e`, which is the
// effects' dataset `e`; as driver.wgsl's `score` otherwise.
fn score(i: u32, e: u32) -> f32 {
    let span = spans[e];
    if (span.y == 0u) {
        return 0.0;
    }
    let p = i * STRIDE;
    let th = load_theta(p, e);
    let r0 = i * cfg.residual_len + span.x - e;
    // step.rs `Augmented::prepare`: each realisation's constants from its
    // parameters.
    let frame = frame_of(e);
    stages_prepare(p, frame);
    let big_a = stiffness(th);
    // step.rs `Prepared::start`.
    var x = samples[span.x].y + th.x0;
    var w = 0.0;
    stages_start(x, input(span, 0u));
    var started = false;
    var acc = 0.0;
    var next_restart = cfg.horizon;
    for (var k = 1u; k < span.y; k = k + 1u) {
        // step.rs `Prepared::step`: the input side, the state side (the
        // family's equations, then the state side's stages), the Bouc-Wen
        // state, the output side.
        let at = At(span, k, input(span, k - 1u), started, x, frame);
        started = true;
        let ui = stages_input(at.raw, at);
        var xk = linear(th, State(x, w), ui);
        var a_eff = big_a;
        stages_state(&xk, &a_eff, at);
        let delta = xk - x;
        w = hysteresis(th, a_eff, w, xk, delta);
        x = xk;
        let yk = stages_output(xk, ui, xk, at);
        if (!(in_bounds(x) && in_bounds(w) && in_bounds(yk))) {
            if (RESIDUALS) {
                for (var j = k; j < span.y; j = j + 1u) {
                    out[r0 + j - 1u] = infinity();
                }
            }
            return infinity();
        }
        let measured = samples[span.x + k].y;
        let err = yk - measured;
        if (RESIDUALS) {
            out[r0 + k - 1u] = err;
        } else {
            acc = acc + rounded(err * err);
        }
        // step.rs `Prepared::restart`: the output state is the measurement
        // less each realisation's restart term, in the step order; the
        // Bouc-Wen state takes the jump's elastic part.
        if (k == next_restart) {
            let xr = stages_restart(measured);
            w = w + rounded(big_a * (xr - x));
            x = xr;
            next_restart = next_restart + cfg.horizon;
        }
    }
    return acc;
}

// ---- stages/delay.rs -------------------------------------------------------

// `Delay`: u(k−1−d) for u(k−1), d ≥ 0 samples, interpolated.
struct DelayConsts {
    // The delay in whole samples and the fraction of a sample beyond them.
    whole: u32,
    frac: f32,
}

fn delay_prepare(q: DelayParams, frame: Frame) -> DelayConsts {
    let d = larger(q.d, 0.0);
    return DelayConsts(u32(floor(d)), d - floor(d));
}

// The delayed input of the sample before, u(j−1) for the interpolation.
alias DelayState = f32;

fn delay_start(c: DelayConsts, x: f32, u0: f32) -> DelayState {
    return u0;
}

// `delayed`: u(j) moved by `frac` toward u(j−1), the u(j) of the sample
// before.
fn delay_step(c: DelayConsts, s: ptr<private, DelayState>, ui: f32, at: At) -> f32 {
    var j = 0u;
    if (at.k - 1u > c.whole) {
        j = at.k - 1u - c.whole;
    }
    let now = input(at.span, j);
    let moved = now + rounded(c.frac * (*s - now));
    *s = now;
    if (c.frac == 0.0) {
        return now;
    }
    return moved;
}

fn delay_restart(s: ptr<private, DelayState>, y: f32, x: f32) -> f32 {
    return x;
}

// `InputLag`: a first-order lag on the input.
alias InputLagConsts = InputLagParams;

fn input_lag_prepare(q: InputLagParams, frame: Frame) -> InputLagConsts {
    return q;
}

// The lag's output of the sample before.
alias InputLagState = f32;

fn input_lag_start(c: InputLagConsts, x: f32, u0: f32) -> InputLagState {
    return 0.0;
}

fn input_lag_step(c: InputLagConsts, s: ptr<private, InputLagState>, ui: f32, at: At) -> f32 {
    var prev = ui;
    if (at.started) {
        prev = *s;
    }
    let v = lag(c.rho, prev, ui);
    *s = v;
    return v;
}

fn input_lag_restart(s: ptr<private, InputLagState>, y: f32, x: f32) -> f32 {
    return x;
}

// `OutputLag`: a first-order lag on the predicted output.
alias OutputLagConsts = OutputLagParams;

fn output_lag_prepare(q: OutputLagParams, frame: Frame) -> OutputLagConsts {
    return q;
}

// The lag's output of the sample before.
alias OutputLagState = f32;

fn output_lag_start(c: OutputLagConsts, x: f32, u0: f32) -> OutputLagState {
    return x;
}

fn output_lag_step(c: OutputLagConsts, s: ptr<private, OutputLagState>, y: f32, ui: f32, xk: f32, at: At) -> f32 {
    let v = lag(c.rho, *s, y);
    *s = v;
    return v;
}

// The lag restarts at the measurement.
fn output_lag_restart(s: ptr<private, OutputLagState>, y: f32, x: f32) -> f32 {
    *s = y;
    return x;
}

// ---- stages/deadzone.rs ----------------------------------------------------

// `Deadzone`: max(p − p0, 0) on the absolute input.
alias DeadzoneConsts = DeadzoneParams;

fn deadzone_prepare(q: DeadzoneParams, frame: Frame) -> DeadzoneConsts {
    return q;
}

fn deadzone_step(c: DeadzoneConsts, ui: f32, at: At) -> f32 {
    return larger(ui - c.p0, -at.frame.u_mean);
}

// `OnOffThreshold`: on above p_on, off below p_off, as it was in between;
// while off the input is the lowest one recorded.
struct OnOffThresholdConsts {
    // In deviation coordinates.
    p_on: f32,
    p_off: f32,
}

fn on_off_threshold_prepare(q: OnOffThresholdParams, frame: Frame) -> OnOffThresholdConsts {
    let p_on = q.p_on - frame.u_mean;
    return OnOffThresholdConsts(p_on, p_on - q.gap);
}

// 1 while on, else 0.
alias OnOffThresholdState = f32;

fn on_off_threshold_start(c: OnOffThresholdConsts, x: f32, u0: f32) -> OnOffThresholdState {
    return 0.0;
}

fn on_off_threshold_step(c: OnOffThresholdConsts, s: ptr<private, OnOffThresholdState>, ui: f32, at: At) -> f32 {
    if (ui > c.p_on) {
        *s = 1.0;
    } else if (ui < c.p_off) {
        *s = 0.0;
    }
    if (!(*s > 0.0)) {
        return at.frame.rest;
    }
    return ui;
}

fn on_off_threshold_restart(s: ptr<private, OnOffThresholdState>, y: f32, x: f32) -> f32 {
    return x;
}

// ---- stages/backlash.rs ----------------------------------------------------

// `Backlash`: play of width r ≥ 0 on the input.
struct BacklashConsts {
    width: f32,
}

fn backlash_prepare(q: BacklashParams, frame: Frame) -> BacklashConsts {
    return BacklashConsts(larger(q.r, 0.0));
}

// The play's output, from the first step on.
alias BacklashState = f32;

fn backlash_start(c: BacklashConsts, x: f32, u0: f32) -> BacklashState {
    return 0.0;
}

fn backlash_step(c: BacklashConsts, s: ptr<private, BacklashState>, ui: f32, at: At) -> f32 {
    let half = rounded(0.5 * c.width);
    var prev = ui;
    if (at.started) {
        prev = *s;
    }
    let v = smaller(ui + half, larger(ui - half, prev));
    *s = v;
    return v;
}

fn backlash_restart(s: ptr<private, BacklashState>, y: f32, x: f32) -> f32 {
    return x;
}

// ---- stages/asymmetry.rs ---------------------------------------------------

// `Asymmetry`: the input gain is b·(1+ε) on the rising branch and b·(1−ε)
// on the falling one.
alias AsymmetryConsts = AsymmetryParams;

fn asymmetry_prepare(q: AsymmetryParams, frame: Frame) -> AsymmetryConsts {
    return q;
}

// `Branch`: the branch of the measured input, which follows it only (+1
// loading, −1 unloading, 0 not yet moved; the input's extreme on it).
struct Branch {
    dir: f32,
    extreme: f32,
}

// `Branch::follow`: the branch after this sample. (By value, as
// `largest_so_far`.) A loading began where `dir` turned positive.
fn branch_follow(before: Branch, at: At) -> Branch {
    var s = before;
    let raw = at.raw;
    let tol = at.frame.branch_tol;
    if (s.dir >= 0.0) {
        s.extreme = larger(raw, s.extreme);
        if (raw < s.extreme - tol) {
            s.dir = -1.0;
            s.extreme = raw;
        } else if (raw > input(at.span, 0u) + tol) {
            s.dir = 1.0;
        }
    } else {
        s.extreme = smaller(raw, s.extreme);
        if (raw > s.extreme + tol) {
            s.dir = 1.0;
            s.extreme = raw;
        }
    }
    return s;
}

alias AsymmetryState = Branch;

fn asymmetry_start(c: AsymmetryConsts, x: f32, u0: f32) -> AsymmetryState {
    return Branch(0.0, u0);
}

fn asymmetry_step(c: AsymmetryConsts, s: ptr<private, AsymmetryState>, ui: f32, at: At) -> f32 {
    *s = branch_follow(*s, at);
    return ui + rounded(rounded((*s).dir * c.eps) * (ui + at.frame.u_mean));
}

fn asymmetry_restart(s: ptr<private, AsymmetryState>, y: f32, x: f32) -> f32 {
    return x;
}

// `DrainLag`: the input passes at once on one branch and through a
// first-order lag |ρ| on the other (ρ > 0: drains slower than it fills).
alias DrainLagConsts = DrainLagParams;

fn drain_lag_prepare(q: DrainLagParams, frame: Frame) -> DrainLagConsts {
    return q;
}

// The stage's output of the sample before.
alias DrainLagState = f32;

fn drain_lag_start(c: DrainLagConsts, x: f32, u0: f32) -> DrainLagState {
    return 0.0;
}

fn drain_lag_step(c: DrainLagConsts, s: ptr<private, DrainLagState>, ui: f32, at: At) -> f32 {
    var prev = ui;
    if (at.started) {
        prev = *s;
    }
    var slow = ui > prev;
    var r = -c.rho;
    if (c.rho >= 0.0) {
        slow = ui < prev;
        r = c.rho;
    }
    let lagged = lag(r, prev, ui);
    var v = ui;
    if (slow) {
        v = lagged;
    }
    *s = v;
    return v;
}

fn drain_lag_restart(s: ptr<private, DrainLagState>, y: f32, x: f32) -> f32 {
    return x;
}

// ---- stages/load.rs --------------------------------------------------------

// `Load`: the input gain of dataset e ≥ 1 is b·(1 + g_e) on the absolute
// input; dataset 0 is the reference (its `g` is 0, and unused).
alias LoadConsts = LoadParams;

fn load_prepare(q: LoadParams, frame: Frame) -> LoadConsts {
    return q;
}

fn load_step(c: LoadConsts, ui: f32, at: At) -> f32 {
    if (at.frame.e >= 1u) {
        return ui + rounded(c.g * (ui + at.frame.u_mean));
    }
    return ui;
}

// ---- stages/softening.rs ---------------------------------------------------

// `largest_so_far`: the largest `v` so far (the input after the stages
// before, or the set's displacement toward the drive), from the first step
// on, given the one of the sample before. (By value: naga's SPIR-V writer
// fails on a pointer to a state's field.)
fn largest_so_far(peak: f32, v: f32, at: At) -> f32 {
    var prev = v;
    if (at.started) {
        prev = peak;
    }
    return larger(v, prev);
}

// `Softening`: the input above the lowest one gains s·(p̂ − p_rest), p̂ the
// largest input so far.
alias SofteningConsts = SofteningParams;

fn softening_prepare(q: SofteningParams, frame: Frame) -> SofteningConsts {
    return q;
}

// The largest input so far.
alias SofteningState = f32;

fn softening_start(c: SofteningConsts, x: f32, u0: f32) -> SofteningState {
    return 0.0;
}

fn softening_step(c: SofteningConsts, s: ptr<private, SofteningState>, ui: f32, at: At) -> f32 {
    let rest = at.frame.rest;
    *s = largest_so_far(*s, ui, at);
    return ui + rounded(rounded(c.s * (*s - rest)) * (ui - rest));
}

fn softening_restart(s: ptr<private, SofteningState>, y: f32, x: f32) -> f32 {
    return x;
}

// `Loadings`: the branch, which counts the loadings, and r^n, the share of
// the growth still to come.
struct Loadings {
    branch: Branch,
    to_come: f32,
}

// `Loadings::follow`: at each loading's start the share still to come
// shrinks by r.
fn loadings_follow(before: Loadings, r: f32, at: At) -> Loadings {
    var s = before;
    let was_loading = s.branch.dir > 0.0;
    s.branch = branch_follow(s.branch, at);
    if (s.branch.dir > 0.0 && !was_loading) {
        s.to_come = s.to_come * r;
    }
    return s;
}

// `CyclicSoftening`: the input above the lowest one gains s·(1 − r^n)
// after n loadings.
alias CyclicSofteningConsts = CyclicSofteningParams;

fn cyclic_softening_prepare(q: CyclicSofteningParams, frame: Frame) -> CyclicSofteningConsts {
    return q;
}

alias CyclicSofteningState = Loadings;

fn cyclic_softening_start(c: CyclicSofteningConsts, x: f32, u0: f32) -> CyclicSofteningState {
    return Loadings(Branch(0.0, u0), 1.0);
}

fn cyclic_softening_step(c: CyclicSofteningConsts, s: ptr<private, CyclicSofteningState>, ui: f32, at: At) -> f32 {
    *s = loadings_follow(*s, c.r, at);
    let rest = at.frame.rest;
    let reached = 1.0 - (*s).to_come;
    return ui + rounded(rounded(c.s * reached) * (ui - rest));
}

fn cyclic_softening_restart(s: ptr<private, CyclicSofteningState>, y: f32, x: f32) -> f32 {
    return x;
}

// ---- stages/set.rs ---------------------------------------------------------

// `Set`: the output moves by share·(x̂ − x) toward the drive, x̂ the muscle's
// largest displacement toward its drive so far.
struct SetConsts {
    // toward · share (times ±1: exact), and toward.
    share: f32,
    toward: f32,
}

fn set_prepare(q: SetParams, frame: Frame) -> SetConsts {
    let toward = select(-1.0, 1.0, frame.drives_up);
    return SetConsts(toward * q.share, toward);
}

struct SetState {
    // The largest displacement toward the drive so far (toward · x), and
    // the offset it adds to the output.
    peak: f32,
    offset: f32,
}

fn set_start(c: SetConsts, x: f32, u0: f32) -> SetState {
    return SetState(0.0, 0.0);
}

fn set_step(c: SetConsts, s: ptr<private, SetState>, y: f32, ui: f32, xk: f32, at: At) -> f32 {
    let reach = c.toward * xk;
    (*s).peak = largest_so_far((*s).peak, reach, at);
    (*s).offset = rounded(c.share * ((*s).peak - reach));
    return y + (*s).offset;
}

fn set_restart(s: ptr<private, SetState>, y: f32, x: f32) -> f32 {
    return x - (*s).offset;
}

// `Ratchet`: the output moves by a at the first loading, and at the n-th by
// the step before times 1 − q/n.
alias RatchetConsts = RatchetParams;

fn ratchet_prepare(q: RatchetParams, frame: Frame) -> RatchetConsts {
    return q;
}

// `Walk`: the branch, the offset the loadings add to the output, the step
// the last one added, and their number.
struct RatchetState {
    branch: Branch,
    offset: f32,
    step: f32,
    count: f32,
}

fn ratchet_start(c: RatchetConsts, x: f32, u0: f32) -> RatchetState {
    return RatchetState(Branch(0.0, u0), 0.0, 0.0, 0.0);
}

// set.rs `count_reciprocal`: 1/n by a guess from the bits and three Newton
// steps, no division.
fn count_reciprocal(n: f32) -> f32 {
    var y = bitcast<f32>(0x7EF311C3u - bitcast<u32>(n));
    for (var i = 0; i < 3; i++) {
        y = y * (2.0 - rounded(n * y));
    }
    return y;
}

fn ratchet_step(c: RatchetConsts, s: ptr<private, RatchetState>, y: f32, ui: f32, xk: f32, at: At) -> f32 {
    var walk = *s;
    let was_loading = walk.branch.dir > 0.0;
    walk.branch = branch_follow(walk.branch, at);
    if (walk.branch.dir > 0.0 && !was_loading) {
        walk.count = walk.count + 1.0;
        if (walk.count == 1.0) {
            walk.step = c.a;
        } else {
            walk.step = rounded(walk.step * (1.0 - rounded(c.q * count_reciprocal(walk.count))));
        }
        walk.offset = walk.offset + walk.step;
    }
    *s = walk;
    return y + walk.offset;
}

fn ratchet_restart(s: ptr<private, RatchetState>, y: f32, x: f32) -> f32 {
    return x - (*s).offset;
}

// ---- stages/inertia.rs -----------------------------------------------------

// `Inertia`: x(k) += a2·(x(k−1) − x(k−2)).
alias InertiaConsts = InertiaParams;

fn inertia_prepare(q: InertiaParams, frame: Frame) -> InertiaConsts {
    return q;
}

// x(k−2), the output state of the step before the last.
alias InertiaState = f32;

fn inertia_start(c: InertiaConsts, x: f32, u0: f32) -> InertiaState {
    return x;
}

fn inertia_step(c: InertiaConsts, s: ptr<private, InertiaState>, xk: ptr<function, f32>, a_eff: ptr<function, f32>, at: At) {
    *xk = *xk + rounded(c.a2 * (at.x - *s));
    // The next step's x(k−2) is this one's x(k−1) (a restart moves x(k−1),
    // not it).
    *s = at.x;
}

fn inertia_restart(s: ptr<private, InertiaState>, y: f32, x: f32) -> f32 {
    return x;
}

// `LoadMode`: a second-order mode of the hanging load on the output,
// q = a1·q(k−1) − a2·q(k−2) + (1 − a1 + a2)·ŷ.
struct LoadModeConsts {
    a1: f32,
    a2: f32,
    // The input weight (1 − a1) + a2.
    gain: f32,
}

fn load_mode_prepare(q: LoadModeParams, frame: Frame) -> LoadModeConsts {
    return LoadModeConsts(q.a1, q.a2, (1.0 - q.a1) + q.a2);
}

// The mode's output at the sample before and the one before that.
struct LoadModeState {
    mode1: f32,
    mode2: f32,
}

fn load_mode_start(c: LoadModeConsts, x: f32, u0: f32) -> LoadModeState {
    return LoadModeState(x, x);
}

fn load_mode_step(c: LoadModeConsts, s: ptr<private, LoadModeState>, y: f32, ui: f32, xk: f32, at: At) -> f32 {
    let q = (rounded(c.a1 * (*s).mode1) - rounded(c.a2 * (*s).mode2)) + rounded(c.gain * y);
    (*s).mode2 = (*s).mode1;
    (*s).mode1 = q;
    return q;
}

// The mode restarts at rest at the measurement.
fn load_mode_restart(s: ptr<private, LoadModeState>, y: f32, x: f32) -> f32 {
    (*s).mode1 = y;
    (*s).mode2 = y;
    return x;
}

// `Ringing`: a mode excited by the input's change, added to the output,
// r = a1·r(k−1) − a2·r(k−2) + g·(u(k−1) − u(k−2)).
alias RingingConsts = RingingParams;

fn ringing_prepare(q: RingingParams, frame: Frame) -> RingingConsts {
    return q;
}

// The ringing at the sample before and the one before that.
struct RingingState {
    ring1: f32,
    ring2: f32,
}

fn ringing_start(c: RingingConsts, x: f32, u0: f32) -> RingingState {
    return RingingState(0.0, 0.0);
}

fn ringing_step(c: RingingConsts, s: ptr<private, RingingState>, y: f32, ui: f32, xk: f32, at: At) -> f32 {
    let prev = input_before(at);
    let r = (rounded(c.a1 * (*s).ring1) - rounded(c.a2 * (*s).ring2)) + rounded(c.g * (at.raw - prev));
    (*s).ring2 = (*s).ring1;
    (*s).ring1 = r;
    return y + r;
}

// The output state is the measurement less the ringing, which rings on.
fn ringing_restart(s: ptr<private, RingingState>, y: f32, x: f32) -> f32 {
    return x - (*s).ring1;
}

// ---- stages/saturation.rs --------------------------------------------------

// The end stops' bound in deviation coordinates.
fn end_stop(l_max: f32, frame: Frame) -> f32 {
    return l_max - frame.y_mean;
}

// The end stop on the side the input drives the output, on the CPU
// `±min(±x, ±bound)` (`Frame::toward`), the same bits as this.
fn clip(x: f32, bound: f32, frame: Frame) -> f32 {
    if (frame.drives_up) {
        return smaller(x, bound);
    }
    return larger(x, bound);
}

// `soft_stop`, which the CPU applies to `±x` and `±bound`
// (`Frame::toward`); written out per direction here, the same bits since
// negation is exact (`tests/eval_effects.rs` checks both directions).
fn soft_stop(x: f32, bound: f32, frame: Frame) -> f32 {
    let h = frame.knee_h;
    var into = (bound + h) - x;
    if (frame.drives_up) {
        into = x - (bound - h);
    }
    let bend = rounded(rounded(into * into) * frame.knee_inv_4h);
    var bent = x + bend;
    if (frame.drives_up) {
        bent = x - bend;
    }
    if (into <= 0.0) {
        return x;
    } else if (into >= frame.knee_2h) {
        return bound;
    }
    return bent;
}

// `Saturation`: the output state cannot pass the end stop.
struct SaturationConsts {
    bound: f32,
}

fn saturation_prepare(q: SaturationParams, frame: Frame) -> SaturationConsts {
    return SaturationConsts(end_stop(q.l_max, frame));
}

fn saturation_step(c: SaturationConsts, xk: ptr<function, f32>, a_eff: ptr<function, f32>, at: At) {
    *xk = clip(*xk, c.bound, at.frame);
}

// `OutputClip`: the end stop on the predicted output only (the state runs
// on).
struct OutputClipConsts {
    bound: f32,
}

fn output_clip_prepare(q: OutputClipParams, frame: Frame) -> OutputClipConsts {
    return OutputClipConsts(end_stop(q.l_max, frame));
}

fn output_clip_step(c: OutputClipConsts, y: f32, ui: f32, xk: f32, at: At) -> f32 {
    return clip(y, c.bound, at.frame);
}

// `SoftStop`: the end stop as a smooth knee on the output state.
struct SoftStopConsts {
    bound: f32,
}

fn soft_stop_prepare(q: SoftStopParams, frame: Frame) -> SoftStopConsts {
    return SoftStopConsts(end_stop(q.l_max, frame));
}

fn soft_stop_step(c: SoftStopConsts, xk: ptr<function, f32>, a_eff: ptr<function, f32>, at: At) {
    *xk = soft_stop(*xk, c.bound, at.frame);
}

// ---- stages/rate.rs --------------------------------------------------------

// `Rate`: A_eff = A·(1 + η·|u(k−1) − u(k−2)|/dt).
alias RateConsts = RateParams;

fn rate_prepare(q: RateParams, frame: Frame) -> RateConsts {
    return q;
}

fn rate_step(c: RateConsts, xk: ptr<function, f32>, a_eff: ptr<function, f32>, at: At) {
    let prev = input_before(at);
    *a_eff = rounded(*a_eff * (1.0 + rounded(c.eta * rounded(abs(at.raw - prev) * at.frame.inv_dt))));
}

// ---- stages/creep.rs -------------------------------------------------------
// Slow first-order states added to the output, each starting at z0 (where
// the record's history left it); a restart takes the output state from the
// measurement less the slow states, which creep on.

// `tenth_power`: ρ^10 by products.
fn tenth_power(rho: f32) -> f32 {
    let p2 = rounded(rho * rho);
    let p4 = rounded(p2 * p2);
    return rounded(rounded(p4 * p4) * p2);
}

// `Creep`: z = ρ·z + (1−ρ)·κ·u(k−1), ŷ = x + z.
alias CreepConsts = CreepParams;

fn creep_prepare(q: CreepParams, frame: Frame) -> CreepConsts {
    return q;
}

// The slow state.
alias CreepState = f32;

fn creep_start(c: CreepConsts, x: f32, u0: f32) -> CreepState {
    return c.z0;
}

fn creep_step(c: CreepConsts, s: ptr<private, CreepState>, y: f32, ui: f32, xk: f32, at: At) -> f32 {
    *s = rounded(c.rho * *s) + rounded(rounded((1.0 - c.rho) * c.kappa) * ui);
    return y + *s;
}

fn creep_restart(s: ptr<private, CreepState>, y: f32, x: f32) -> f32 {
    return x - *s;
}

// `OutputCreep`: z = ρ·z + (1−ρ)·κ·x, ŷ = x + z.
alias OutputCreepConsts = OutputCreepParams;

fn output_creep_prepare(q: OutputCreepParams, frame: Frame) -> OutputCreepConsts {
    return q;
}

// The slow state.
alias OutputCreepState = f32;

fn output_creep_start(c: OutputCreepConsts, x: f32, u0: f32) -> OutputCreepState {
    return c.z0;
}

fn output_creep_step(c: OutputCreepConsts, s: ptr<private, OutputCreepState>, y: f32, ui: f32, xk: f32, at: At) -> f32 {
    *s = rounded(c.rho * *s) + rounded(rounded((1.0 - c.rho) * c.kappa) * xk);
    return y + *s;
}

fn output_creep_restart(s: ptr<private, OutputCreepState>, y: f32, x: f32) -> f32 {
    return x - *s;
}

// `TwoPoleCreep`: two input-driven slow states, a faster and a slower one,
// with gains s·κ and (1−s)·κ.
struct TwoPoleCreepConsts {
    rho_fast: f32,
    kappa_fast: f32,
    rho_slow: f32,
    kappa_slow: f32,
    z0: f32,
}

// The total gain split by the faster state's share.
fn two_pole_creep_prepare(q: TwoPoleCreepParams, frame: Frame) -> TwoPoleCreepConsts {
    let kappa_fast = rounded(q.fast_share * q.kappa);
    return TwoPoleCreepConsts(q.rho_fast, kappa_fast, q.rho_slow, q.kappa - kappa_fast, q.z0);
}

struct TwoPoleCreepState {
    fast: f32,
    slow: f32,
}

fn two_pole_creep_start(c: TwoPoleCreepConsts, x: f32, u0: f32) -> TwoPoleCreepState {
    return TwoPoleCreepState(0.0, c.z0);
}

fn two_pole_creep_step(c: TwoPoleCreepConsts, s: ptr<private, TwoPoleCreepState>, y: f32, ui: f32, xk: f32, at: At) -> f32 {
    (*s).fast = rounded(c.rho_fast * (*s).fast) + rounded(rounded((1.0 - c.rho_fast) * c.kappa_fast) * ui);
    (*s).slow = rounded(c.rho_slow * (*s).slow) + rounded(rounded((1.0 - c.rho_slow) * c.kappa_slow) * ui);
    let v = y + (*s).fast;
    return v + (*s).slow;
}

fn two_pole_creep_restart(s: ptr<private, TwoPoleCreepState>, y: f32, x: f32) -> f32 {
    return (x - (*s).fast) - (*s).slow;
}

// `LogCreep`: three input-driven slow states a decade apart in time
// constant (poles ρ^100, ρ^10, ρ), each of static gain κ.
struct LogCreepConsts {
    // The poles and input weights (1 − ρ)·κ, fastest first.
    rho_fast: f32,
    w_fast: f32,
    rho_mid: f32,
    w_mid: f32,
    rho_slow: f32,
    w_slow: f32,
    z0: f32,
}

fn log_creep_prepare(q: LogCreepParams, frame: Frame) -> LogCreepConsts {
    let rho_slow = q.rho;
    let rho_mid = tenth_power(rho_slow);
    let rho_fast = tenth_power(rho_mid);
    return LogCreepConsts(rho_fast, rounded((1.0 - rho_fast) * q.kappa), rho_mid,
        rounded((1.0 - rho_mid) * q.kappa), rho_slow, rounded((1.0 - rho_slow) * q.kappa), q.z0);
}

// The terms, fastest first.
struct LogCreepState {
    fast: f32,
    mid: f32,
    slow: f32,
}

fn log_creep_start(c: LogCreepConsts, x: f32, u0: f32) -> LogCreepState {
    return LogCreepState(0.0, 0.0, c.z0);
}

fn log_creep_step(c: LogCreepConsts, s: ptr<private, LogCreepState>, y: f32, ui: f32, xk: f32, at: At) -> f32 {
    (*s).fast = rounded(c.rho_fast * (*s).fast) + rounded(c.w_fast * ui);
    (*s).mid = rounded(c.rho_mid * (*s).mid) + rounded(c.w_mid * ui);
    (*s).slow = rounded(c.rho_slow * (*s).slow) + rounded(c.w_slow * ui);
    let v = (y + (*s).fast) + (*s).mid;
    return v + (*s).slow;
}

fn log_creep_restart(s: ptr<private, LogCreepState>, y: f32, x: f32) -> f32 {
    return ((x - (*s).fast) - (*s).mid) - (*s).slow;
}
