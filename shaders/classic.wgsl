// Classic Bouc-Wen family: θ = [A, α, β, γ, n, a, b, c].

const DIM: u32 = 8u;

// sim.rs `classic_w`.
fn classic_w(big_a: f32, beta: f32, gamma: f32, n: f32, w_prev: f32, delta: f32) -> f32 {
    let aw = abs(w_prev);
    let pw = abs_pow(aw, n - 1.0);
    return ((w_prev + rounded(big_a * delta)) - rounded((beta * abs(delta)) * (pw * w_prev)))
        - rounded((gamma * delta) * (pw * aw));
}

fn classic_sse(p: u32, span: vec2<u32>) -> f32 {
    if (span.y == 0u) {
        return 0.0;
    }
    let big_a = params[p];
    let alpha = params[p + 1u];
    let beta = params[p + 2u];
    let gamma = params[p + 3u];
    var n = 1.0;
    if (!N_ONE) {
        n = params[p + 4u];
    }
    let a = params[p + 5u];
    let b = params[p + 6u];
    let c = params[p + 7u];
    var x = samples[span.x].y;
    var w = 0.0;
    var acc = 0.0;
    for (var k = 1u; k < span.y; k = k + 1u) {
        let xn = linear_part(a, alpha, b, c, x, w, samples[span.x + k - 1u].x);
        let wn = classic_w(big_a, beta, gamma, n, w, xn - x);
        if (!(in_bounds(xn) && in_bounds(wn))) {
            return infinity();
        }
        let err = xn - samples[span.x + k].y;
        acc = acc + rounded(err * err);
        x = xn;
        w = wn;
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
        sse_out[e * cfg.count + i] = classic_sse(i * DIM, spans[e]);
    }
}
