// Linear family (eq. 12 plus intercept): θ = [a, b, c].

const DIM: u32 = 3u;

fn linear_sse(a: f32, b: f32, c: f32, span: vec2<u32>) -> f32 {
    if (span.y == 0u) {
        return 0.0;
    }
    var x = samples[span.x].y;
    var acc = 0.0;
    for (var k = 1u; k < span.y; k = k + 1u) {
        let xn = linear_step(a, b, c, x, samples[span.x + k - 1u].x);
        if (!in_bounds(xn)) {
            return infinity();
        }
        let err = xn - samples[span.x + k].y;
        acc = acc + rounded(err * err);
        x = xn;
    }
    return acc;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = candidate(gid);
    if (i >= cfg.count) {
        return;
    }
    let p = i * DIM;
    for (var e = 0u; e < cfg.experiments; e = e + 1u) {
        sse_out[e * cfg.count + i] = linear_sse(params[p], params[p + 1u], params[p + 2u], spans[e]);
    }
}
