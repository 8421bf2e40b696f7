// The scoring loop of every plain family (src/model/sim.rs `run_scored`; the
// family's file before this one defines `Theta`, `load_theta`, `linear`,
// `stiffness` and `hysteresis`). The state restarts from the measurement
// after every `cfg.horizon`-th sample (never for 0, the free run).

// sim.rs `Stepper::step`.
fn step(th: Theta, s: State, u_prev: f32) -> State {
    let xn = linear(th, s, u_prev);
    return State(xn, hysteresis(th, stiffness(th), s.w, xn, xn - s.x));
}

// sim.rs `Stepper::restart` (`restart_w`): the Bouc-Wen state takes the
// jump's elastic part (for the linear family, `0 + 0`).
fn restart(th: Theta, s: State, y: f32) -> State {
    return State(y, s.w + rounded(stiffness(th) * (y - s.x)));
}

// Steps between two looks at the bounds flag: a candidate that leaves the
// bounds runs on to the end of its block instead of returning at once, so
// that a step carries no branch of its own.
const BLOCK: u32 = 16u;

// Scores candidate `i` (chunk-local) on experiment `e`: its SSE, or +inf from
// the first out-of-bounds state. In RESIDUALS mode the errors are written to
// `out` (+inf from the divergence on) and the sum is not formed.
fn score(i: u32, e: u32) -> f32 {
    let span = spans[e];
    if (span.y == 0u) {
        return 0.0;
    }
    let th = load_theta(i * STRIDE, e);
    let r0 = i * cfg.residual_len + span.x - e;
    // sim.rs `Stepper::start`.
    var s = State(samples[span.x].y + th.x0, 0.0);
    // Each sample is read once: its output now, its input at the next step.
    var u_prev = samples[span.x].x;
    var acc = 0.0;
    // Sticky: false from the first out-of-bounds state on. `&` evaluates
    // both sides, where `&&` would branch.
    var ok = true;
    var next_restart = cfg.horizon;
    var k = 1u;
    while (k < span.y) {
        let block_end = min(k + BLOCK, span.y);
        for (; k < block_end; k = k + 1u) {
            s = step(th, s, u_prev);
            ok = ok & in_bounds(s.x) & in_bounds(s.w);
            let sample = samples[span.x + k];
            u_prev = sample.x;
            let err = s.x - sample.y;
            if (RESIDUALS) {
                out[r0 + k - 1u] = select(infinity(), err, ok);
            } else {
                acc = acc + rounded(err * err);
            }
            if (k == next_restart) {
                s = restart(th, s, sample.y);
                next_restart = next_restart + cfg.horizon;
            }
        }
        if (!ok) {
            if (RESIDUALS) {
                for (var j = k; j < span.y; j = j + 1u) {
                    out[r0 + j - 1u] = infinity();
                }
            }
            return infinity();
        }
    }
    return acc;
}
