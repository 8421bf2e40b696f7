// The one scoring loop of every family (src/model/sim.rs `run_scored`; the
// family's file before this one defines `Theta`, `load_theta`, `step` and
// `restart`). The state restarts from the measurement after every
// `cfg.horizon`-th sample (never for 0, the free run).

// Scores candidate `i` (chunk-local) on experiment `e`: its SSE, or +inf from
// the first out-of-bounds state. In RESIDUALS mode the errors are written to
// `out` (+inf from the divergence on) and the sum is not formed.
fn score(i: u32, e: u32) -> f32 {
    let span = spans[e];
    if (span.y == 0u) {
        return 0.0;
    }
    let th = load_theta(i * DIM);
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

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = candidate(gid);
    if (i >= cfg.count) {
        return;
    }
    for (var e = 0u; e < cfg.experiments; e = e + 1u) {
        let sse = score(i, e);
        if (!RESIDUALS) {
            out[e * cfg.count + i] = sse;
        }
    }
}
