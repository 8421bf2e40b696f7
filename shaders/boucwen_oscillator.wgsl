// The Bouc-Wen benchmark oscillator (Noël & Schoukens 2016), one invocation
// per candidate: Newmark integration from rest on the upsampled input, scored
// against the measured displacement at every `SCORE_EVERY`-th integration
// step.
//
// It follows a header (src/eval/gpu/mod.rs `oscillator_source`: `STRIDE`,
// the 7 parameters per candidate; `SCORE_EVERY`; `NEWTON_ITERS`; the step
// sizes `H`, `HALF_H`, `QUARTER_HH`) and shaders/prologue.wgsl, whose
// bindings it uses with one trace: samples[i] = (u at integration step i,
// the measured displacement where i is a multiple of SCORE_EVERY, else 0),
// spans[0] = (0, integration steps); out[i] = the SSE of candidate i.
//
// This is the twin of `sse_f32` in src/benchmark/boucwen.rs: the same
// operations in the same order, every sum parenthesised, every product that
// is then added kept apart with `rounded` (no fma), so that lavapipe returns
// the same bits. Candidate layout: [m, c, k, alpha, beta*gamma, beta*delta, nu].

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let idx = candidate(gid);
    if (idx >= cfg.count) {
        return;
    }
    let base = idx * STRIDE;
    let m = params[base];
    let c = params[base + 1u];
    let k = params[base + 2u];
    let alpha = params[base + 3u];
    let bg = params[base + 4u];
    let bd = params[base + 5u];
    let nu = params[base + 6u];

    let meff = (m + rounded(c * HALF_H)) + rounded(k * QUARTER_HH);
    let dv_ds = -((HALF_H * HALF_H) / meff);
    let num1 = nu - 1.0;

    var y = 0.0;
    var v = 0.0;
    var z = 0.0;
    var zd = 0.0;
    var acc = (((samples[0].x - rounded(c * v)) - rounded(k * y)) - z) / m;
    let d0 = y - samples[0].y;
    var sse = d0 * d0;
    let last = spans[0].y - 1u;
    for (var i = 1u; i <= last; i = i + 1u) {
        let u1 = samples[i].x;
        let vp = v + rounded(HALF_H * acc);
        let yp = (y + rounded(H * v)) + rounded(QUARTER_HH * acc);
        let zp = z + rounded(HALF_H * zd);
        let rhs = ((u1 - rounded(c * vp)) - rounded(k * yp)) - zp;
        var s = 0.0;
        for (var it = 0u; it < NEWTON_ITERS; it = it + 1u) {
            let a1 = (rhs - rounded(HALF_H * s)) / meff;
            let v1 = vp + rounded(HALF_H * a1);
            let z1 = zp + rounded(HALF_H * s);
            let az = abs(z1);
            let pz = abs_pow(az, num1);
            let f = (rounded(alpha * v1) - rounded((bg * abs(v1)) * rounded(pz * z1)))
                - rounded((bd * v1) * rounded(pz * az));
            let f_v = (alpha - rounded((bg * sgn(v1)) * rounded(pz * z1))) - rounded(bd * rounded(pz * az));
            let f_z = (-(nu * pz)) * (rounded(bg * abs(v1)) + rounded((bd * v1) * sgn(z1)));
            let g = s - f;
            let dg = (1.0 - rounded(f_v * dv_ds)) - rounded(f_z * HALF_H);
            s = s - (g / dg);
        }
        acc = (rhs - rounded(HALF_H * s)) / meff;
        v = vp + rounded(HALF_H * acc);
        y = yp + rounded(QUARTER_HH * acc);
        z = zp + rounded(HALF_H * s);
        zd = s;
        if (i % SCORE_EVERY == 0u) {
            if (!in_bounds(y)) {
                out[idx] = infinity();
                return;
            }
            let d = y - samples[i].y;
            sse = sse + rounded(d * d);
        }
    }
    // sse - sse is 0 for finite values and NaN for an infinite one.
    if (!((sse - sse) == 0.0)) {
        out[idx] = infinity();
        return;
    }
    out[idx] = sse;
}
