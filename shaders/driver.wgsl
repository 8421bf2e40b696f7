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
    var acc = 0.0;
    var next_restart = cfg.horizon;
    for (var k = 1u; k < span.y; k = k + 1u) {
        s = step(th, s, samples[span.x + k - 1u].x);
        if (!(in_bounds(s.x) && in_bounds(s.w))) {
            if (RESIDUALS) {
                for (var j = k; j < span.y; j = j + 1u) {
                    out[r0 + j - 1u] = infinity();
                }
            }
            return infinity();
        }
        let yk = samples[span.x + k].y;
        let err = s.x - yk;
        if (RESIDUALS) {
            out[r0 + k - 1u] = err;
        } else {
            acc = acc + rounded(err * err);
        }
        if (k == next_restart) {
            s = restart(th, s, yk);
            next_restart = next_restart + cfg.horizon;
        }
    }
    return acc;
}
