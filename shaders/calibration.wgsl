// The calibration kernel (src/eval/gpu/calibration.rs): a loop with a known
// number of f32 operations a step, timed by the device's clock, so that a
// model kernel's rate can be read as a share of what the device does.
// The header before this file sets `const VARIANT: u32`:
//   0 (dependent): one chain of 8 mul-adds a step, each waiting on the one
//     before: bound by the latency of one operation;
//   1 (independent): 8 chains of one mul-add a step: as many operations, none
//     waiting on another in the same step: bound by the throughput;
//   2 (pow): 8 chains of `pow` and an add a step.
// Every operand the loop multiplies or adds comes from the uniform block, so
// the compiler cannot fold the loop; every invocation writes its result, so
// it cannot drop it. The multiplier is 0.5 at run time: each product is exact,
// so a fused and an unfused mul-add round alike, and the chains stay bounded
// for any number of steps (each tends to twice its addend).

struct Calibration {
    // Steps of the loop.
    steps: u32,
    // Invocations that write a result.
    count: u32,
    pad0: u32,
    pad1: u32,
    // The multiplier of every mul-add (0.5).
    scale: f32,
    // The exponent of the pow variant (0.5).
    exponent: f32,
    // Chain j's addend is `base + j · spread + (invocation mod 256) · spread / 256`.
    base: f32,
    spread: f32,
}

@group(0) @binding(0) var<uniform> cal: Calibration;
@group(0) @binding(1) var<storage, read_write> out: array<f32>;

// Chain j's addend for invocation i: exact in f32 (small multiples of powers
// of two), so the CPU's reference forms the same value.
fn addend(i: u32, j: u32) -> f32 {
    return (cal.base + f32(j) * cal.spread) + f32(i & 255u) * (cal.spread * 0.00390625);
}

// The eight chains' addends for invocation i.
fn addends(i: u32) -> array<f32, 8> {
    return array<f32, 8>(addend(i, 0u), addend(i, 1u), addend(i, 2u), addend(i, 3u),
        addend(i, 4u), addend(i, 5u), addend(i, 6u), addend(i, 7u));
}

// One mul-add: the unit both mul-add variants count as two operations.
fn mul_add(x: f32, a: f32) -> f32 {
    return x * cal.scale + a;
}

// The eight chains' results summed pairwise, in the order the CPU's reference sums them.
fn total(x: array<f32, 8>) -> f32 {
    return ((x[0] + x[1]) + (x[2] + x[3])) + ((x[4] + x[5]) + (x[6] + x[7]));
}

fn dependent(i: u32) -> f32 {
    let a = addends(i);
    var x = a[0];
    for (var k = 0u; k < cal.steps; k = k + 1u) {
        x = mul_add(x, a[0]);
        x = mul_add(x, a[1]);
        x = mul_add(x, a[2]);
        x = mul_add(x, a[3]);
        x = mul_add(x, a[4]);
        x = mul_add(x, a[5]);
        x = mul_add(x, a[6]);
        x = mul_add(x, a[7]);
    }
    return x;
}

// Eight named chains, written out rather than an array indexed in a loop:
// a private array may live in memory on a GPU, and the loop must time the
// arithmetic alone. `powers` repeats the shape for the same reason.
fn independent(i: u32) -> f32 {
    let a = addends(i);
    var x0 = a[0];
    var x1 = a[1];
    var x2 = a[2];
    var x3 = a[3];
    var x4 = a[4];
    var x5 = a[5];
    var x6 = a[6];
    var x7 = a[7];
    for (var k = 0u; k < cal.steps; k = k + 1u) {
        x0 = mul_add(x0, a[0]);
        x1 = mul_add(x1, a[1]);
        x2 = mul_add(x2, a[2]);
        x3 = mul_add(x3, a[3]);
        x4 = mul_add(x4, a[4]);
        x5 = mul_add(x5, a[5]);
        x6 = mul_add(x6, a[6]);
        x7 = mul_add(x7, a[7]);
    }
    return total(array<f32, 8>(x0, x1, x2, x3, x4, x5, x6, x7));
}

fn powers(i: u32) -> f32 {
    let a = addends(i);
    var x0 = a[0];
    var x1 = a[1];
    var x2 = a[2];
    var x3 = a[3];
    var x4 = a[4];
    var x5 = a[5];
    var x6 = a[6];
    var x7 = a[7];
    let e = cal.exponent;
    for (var k = 0u; k < cal.steps; k = k + 1u) {
        x0 = pow(x0, e) + a[0];
        x1 = pow(x1, e) + a[1];
        x2 = pow(x2, e) + a[2];
        x3 = pow(x3, e) + a[3];
        x4 = pow(x4, e) + a[4];
        x5 = pow(x5, e) + a[5];
        x6 = pow(x6, e) + a[6];
        x7 = pow(x7, e) + a[7];
    }
    return total(array<f32, 8>(x0, x1, x2, x3, x4, x5, x6, x7));
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= cal.count) {
        return;
    }
    var x: f32;
    if (VARIANT == 0u) {
        x = dependent(i);
    } else if (VARIANT == 1u) {
        x = independent(i);
    } else {
        x = powers(i);
    }
    out[i] = x;
}
