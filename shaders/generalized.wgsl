// Generalized Bouc-Wen family: θ = [A, α, β1..β6, n, a, b, c].

const DIM: u32 = 12u;

// sim.rs `generalized_w`; the sign of a product is the product of signs.
fn generalized_w(big_a: f32, b1: f32, b2: f32, b3: f32, b4: f32, b5: f32, b6: f32, n: f32, w_prev: f32, x: f32, delta: f32) -> f32 {
    let sd = sgn(delta);
    let sw = sgn(w_prev);
    let sx = sgn(x);
    let psi = (((((rounded(b1 * (sd * sw)) + rounded(b2 * (sd * sx))) + rounded(b3 * (sx * sw)))
        + rounded(b4 * sd)) + rounded(b5 * sw)) + rounded(b6 * sx));
    let aw = abs(w_prev);
    let pwn = abs_pow(aw, n - 1.0) * aw;
    return w_prev + rounded(delta * (big_a - rounded(pwn * psi)));
}

fn generalized_sse(p: u32, span: vec2<u32>) -> f32 {
    if (span.y == 0u) {
        return 0.0;
    }
    let big_a = params[p];
    let alpha = params[p + 1u];
    let b1 = params[p + 2u];
    let b2 = params[p + 3u];
    let b3 = params[p + 4u];
    let b4 = params[p + 5u];
    let b5 = params[p + 6u];
    let b6 = params[p + 7u];
    var n = 1.0;
    if (!N_ONE) {
        n = params[p + 8u];
    }
    let a = params[p + 9u];
    let b = params[p + 10u];
    let c = params[p + 11u];
    var x = samples[span.x].y;
    var w = 0.0;
    var acc = 0.0;
    for (var k = 1u; k < span.y; k = k + 1u) {
        let xn = linear_part(a, alpha, b, c, x, w, samples[span.x + k - 1u].x);
        let wn = generalized_w(big_a, b1, b2, b3, b4, b5, b6, n, w, xn, xn - x);
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
        sse_out[e * cfg.count + i] = generalized_sse(i * DIM, spans[e]);
    }
}
