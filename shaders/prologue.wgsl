// Shared by every shader of the project (the benchmark oscillator's too, after
// its own header: src/eval/gpu/mod.rs `oscillator_source`). A muscle model's
// pipeline source is, in order
// (src/eval/gpu/mod.rs `shader_source`): a header generated from the model
// description (the switches `const N_ONE: bool` — true: the n = 1
// specialisation, bit-exact; false: the free exponent, `pow` within the
// device's accuracy — and `const RESIDUALS: bool` — write every error
// instead of one sum —, `const STRIDE: u32`, the parameters per candidate,
// for effect stages which are present, where their parameters sit and each
// experiment's constants, and for the generalized family each experiment's
// output mean `Y_MEAN`), this prologue, the family's file (its
// `Theta`, `load_theta`, `linear`, `stiffness` and `hysteresis`), the
// scoring loop (driver.wgsl for a plain family, effects.wgsl with effect
// stages) and entry.wgsl. One invocation scores one candidate on every
// experiment.
//
// The helpers spell the operations of src/model/sim.rs in the same order with
// the same parentheses, so that an unfused f32 implementation (lavapipe) gives
// the CPU's bits.

struct Config {
    // Candidates in this dispatch (one chunk of the population).
    count: u32,
    // Experiments (traces) scored in this dispatch.
    experiments: u32,
    // Invocations per row of the 2-D dispatch grid (workgroups in x · 64).
    row_width: u32,
    // 0, unknown to the shader compiler: see `rounded`.
    zero_bits: u32,
    // Restart the output state from the measurement after every `horizon`-th
    // sample (the multi-step-ahead prediction); 0: never (the free run).
    horizon: u32,
    // Errors per candidate in RESIDUALS mode: Σ over experiments of (length − 1).
    residual_len: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
// Row-major candidates, `STRIDE` f32 each (set by the pipeline's header).
@group(0) @binding(1) var<storage, read> params: array<f32>;
// Samples (u(k), y(k)) of every experiment, one after the other.
@group(0) @binding(2) var<storage, read> samples: array<vec2<f32>>;
// (first sample, length) of each experiment in `samples`.
@group(0) @binding(3) var<storage, read> spans: array<vec2<u32>>;
// SSE of candidate i on experiment e at e * count + i; in RESIDUALS mode the
// error of candidate i at sample k ≥ 1 of experiment e at
// i * residual_len + (first sample of e) − e + k − 1.
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

// A product that is then added to something, kept as its own rounded value.
// Shader compilers may fuse `a * b + c` into one fma, and may reassociate
// products to do so (Mesa's NIR does both; lavapipe then runs a real fma on a
// CPU that has one), which rounds once instead of twice and breaks agreement
// with the CPU. Passing the product's bits through an integer operation with
// a value only known at run time (`cfg.zero_bits` = 0) leaves the value
// unchanged but hides from the compiler that it is a product.
fn rounded(product: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(product) ^ cfg.zero_bits);
}

const DIVERGENCE_BOUND: f32 = 1.0e6;

fn infinity() -> f32 {
    return bitcast<f32>(0x7f800000u);
}

// sim.rs `in_bounds`: false for NaN, as the comparison fails.
fn in_bounds(v: f32) -> bool {
    return abs(v) <= DIVERGENCE_BOUND;
}

// sim.rs `sgn`, with sgn(0) = 0.
fn sgn(v: f32) -> f32 {
    if (v > 0.0) {
        return 1.0;
    }
    if (v < 0.0) {
        return -1.0;
    }
    return 0.0;
}

// sim.rs `abs_pow`: |v|^e for v >= 0, exact for e = 0 and v = 0.
fn abs_pow(v: f32, e: f32) -> f32 {
    if (e == 0.0) {
        return 1.0;
    }
    if (v == 0.0) {
        return 0.0;
    }
    return pow(v, e);
}

// sim.rs `linear_step`.
fn linear_step(a: f32, b: f32, c: f32, x_prev: f32, u_prev: f32) -> f32 {
    return (rounded(a * x_prev) + rounded(b * u_prev)) + c;
}

// sim.rs `linear_part`.
fn linear_part(a: f32, alpha: f32, b: f32, c: f32, x_prev: f32, w_prev: f32, u_prev: f32) -> f32 {
    return (rounded(a * (rounded(alpha * x_prev) + rounded((1.0 - alpha) * w_prev))) + rounded(b * u_prev)) + c;
}

// The state every family advances: the output x and the Bouc-Wen state w
// (0 for the linear family).
struct State {
    x: f32,
    w: f32,
}

// The candidate of this invocation in the (possibly 2-D) grid.
fn candidate(gid: vec3<u32>) -> u32 {
    return gid.y * cfg.row_width + gid.x;
}
