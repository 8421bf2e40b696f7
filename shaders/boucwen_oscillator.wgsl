// The Bouc-Wen benchmark oscillator (Noël & Schoukens 2016), one invocation
// per candidate: Newmark integration from rest on the upsampled input, scored
// against the measured displacement at every `stride`-th integration step.
//
// This is the twin of `sse_f32` in src/benchmark/boucwen.rs: the same
// operations in the same order, every sum parenthesised, nothing fused, so
// that lavapipe returns the same bits. Candidate layout (7 floats):
// [m, c, k, alpha, beta*gamma, beta*delta, nu].

struct Dims {
    n_cand: u32,
    n_out: u32,
    stride: u32,
    row_width: u32, // invocations per row of the 2-D dispatch
    h: f32,
    bound: f32,
    newton_iters: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> dims: Dims;
@group(0) @binding(1) var<storage, read> params: array<f32>;
@group(0) @binding(2) var<storage, read> u: array<f32>;
@group(0) @binding(3) var<storage, read> y_meas: array<f32>;
@group(0) @binding(4) var<storage, read_write> sse_out: array<f32>;

// |v|^e for v >= 0 with v^0 = 1 and 0^e = 0 (as model::sim::abs_pow).
fn abs_pow(v: f32, e: f32) -> f32 {
    if (e == 0.0) {
        return 1.0;
    }
    if (v == 0.0) {
        return 0.0;
    }
    return pow(v, e);
}

const INF_BITS: u32 = 0x7f800000u;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let idx = gid.y * dims.row_width + gid.x;
    if (idx >= dims.n_cand) {
        return;
    }
    let base = idx * 7u;
    let m = params[base];
    let c = params[base + 1u];
    let k = params[base + 2u];
    let alpha = params[base + 3u];
    let bg = params[base + 4u];
    let bd = params[base + 5u];
    let nu = params[base + 6u];

    let h = dims.h;
    let half_h = 0.5 * h;
    let quarter_hh = 0.25 * (h * h);
    let meff = (m + (c * half_h)) + (k * quarter_hh);
    let dv_ds = -((half_h * half_h) / meff);
    let num1 = nu - 1.0;

    var y = 0.0;
    var v = 0.0;
    var z = 0.0;
    var zd = 0.0;
    var acc = (((u[0] - (c * v)) - (k * y)) - z) / m;
    let d0 = y - y_meas[0];
    var sse = d0 * d0;
    let last = (dims.n_out - 1u) * dims.stride;
    var next_scored = dims.stride;
    var j = 1u;
    for (var i = 1u; i <= last; i = i + 1u) {
        let u1 = u[i];
        let vp = v + (half_h * acc);
        let yp = (y + (h * v)) + (quarter_hh * acc);
        let zp = z + (half_h * zd);
        let rhs = ((u1 - (c * vp)) - (k * yp)) - zp;
        var s = 0.0;
        for (var it = 0u; it < dims.newton_iters; it = it + 1u) {
            let a1 = (rhs - (half_h * s)) / meff;
            let v1 = vp + (half_h * a1);
            let z1 = zp + (half_h * s);
            let az = abs(z1);
            let pz = abs_pow(az, num1);
            let f = ((alpha * v1) - ((bg * abs(v1)) * (pz * z1))) - ((bd * v1) * (pz * az));
            let f_v = (alpha - ((bg * sign(v1)) * (pz * z1))) - (bd * (pz * az));
            let f_z = (-(nu * pz)) * ((bg * abs(v1)) + ((bd * v1) * sign(z1)));
            let g = s - f;
            let dg = (1.0 - (f_v * dv_ds)) - (f_z * half_h);
            s = s - (g / dg);
        }
        acc = (rhs - (half_h * s)) / meff;
        v = vp + (half_h * acc);
        y = yp + (quarter_hh * acc);
        z = zp + (half_h * s);
        zd = s;
        if (i == next_scored) {
            if (!(abs(y) <= dims.bound)) {
                sse_out[idx] = bitcast<f32>(INF_BITS);
                return;
            }
            let d = y - y_meas[j];
            sse = sse + (d * d);
            j = j + 1u;
            next_scored = next_scored + dims.stride;
        }
    }
    // sse - sse is 0 for finite values and NaN for an infinite one.
    if (!((sse - sse) == 0.0)) {
        sse_out[idx] = bitcast<f32>(INF_BITS);
        return;
    }
    sse_out[idx] = sse;
}
