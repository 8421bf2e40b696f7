// The entry point of every scoring pipeline: one invocation scores one
// candidate on every experiment with the `score` of the driver before it
// (driver.wgsl for a plain family, effects.wgsl for one with effect stages).

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
