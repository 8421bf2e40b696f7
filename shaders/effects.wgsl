// The scoring loop of a family with effect stages: src/model/effects.rs
// `Prepared::step` and `Prepared::restart`, spelled with the same
// operations in the same order (every product that is then added kept
// rounded, minima and maxima as comparisons). The generated header says
// which effects are present (`HAS_*`), where their parameters start in the
// candidate's row (`AT_*`) and each experiment's constants (`U_MEAN`,
// `Y_MEAN`, `BRANCH_TOL`, `INV_DT`, `DRIVES_UP`, indexed by experiment).

// effects.rs `larger`: `a` if it is the larger, else `b`.
fn larger(a: f32, b: f32) -> f32 {
    if (a > b) {
        return a;
    }
    return b;
}

// effects.rs `smaller`: `a` if it is the smaller, else `b`.
fn smaller(a: f32, b: f32) -> f32 {
    if (a < b) {
        return a;
    }
    return b;
}

fn input(span: vec2<u32>, k: u32) -> f32 {
    return samples[span.x + k].x;
}

// Scores candidate `i` (chunk-local) on experiment `e`, which is the
// effects' dataset `e`; as driver.wgsl's `score` otherwise.
fn score(i: u32, e: u32) -> f32 {
    let span = spans[e];
    if (span.y == 0u) {
        return 0.0;
    }
    let p = i * STRIDE;
    let th = load_theta(p);
    let r0 = i * cfg.residual_len + span.x - e;
    let u_mean = U_MEAN[e];
    let tol = BRANCH_TOL[e];
    // effects.rs `Augmented::prepare`.
    // The delay in whole samples and the fraction of a sample beyond them.
    var whole = 0u;
    var frac = 0.0;
    if (HAS_DELAY) {
        let d = larger(params[p + AT_DELAY], 0.0);
        let fl = floor(d);
        whole = u32(fl);
        frac = d - fl;
    }
    var p0 = 0.0;
    if (HAS_DEADZONE) {
        p0 = params[p + AT_DEADZONE];
    }
    var bound = 0.0;
    if (HAS_SATURATION) {
        bound = params[p + AT_SATURATION] - Y_MEAN[e];
    }
    var eps = 0.0;
    if (HAS_ASYMMETRY) {
        eps = params[p + AT_ASYMMETRY];
    }
    var a2 = 0.0;
    if (HAS_INERTIA) {
        a2 = params[p + AT_INERTIA];
    }
    var play_width = 0.0;
    if (HAS_BACKLASH) {
        play_width = larger(params[p + AT_BACKLASH], 0.0);
    }
    var rho = 0.0;
    var kappa = 0.0;
    if (HAS_CREEP) {
        rho = params[p + AT_CREEP];
        kappa = params[p + AT_CREEP + 1u];
    }
    var eta = 0.0;
    if (HAS_RATE) {
        eta = params[p + AT_RATE];
    }
    // The load gain of dataset e ≥ 1 (dataset 0 is the reference).
    let has_load = HAS_LOAD && e >= 1u;
    var g = 0.0;
    if (has_load) {
        g = params[p + AT_LOAD + e - 1u];
    }
    let big_a = stiffness(th);
    // effects.rs `Prepared::start`.
    let u0 = input(span, 0u);
    var x = samples[span.x].y + th.x0;
    var w = 0.0;
    var before = u0;
    var x_prev2 = x;
    var play = 0.0;
    var has_play = false;
    var dir = 0.0;
    var extreme = u0;
    var z = 0.0;
    var acc = 0.0;
    var next_restart = cfg.horizon;
    for (var k = 1u; k < span.y; k = k + 1u) {
        // Input side: delay, deadzone, play, branch gain, load gain.
        let raw = input(span, k - 1u);
        var ui = raw;
        if (HAS_DELAY) {
            // effects.rs `delayed`: u(j) moved by `frac` toward u(j−1), the
            // u(j) of the sample before.
            var j = 0u;
            if (k - 1u > whole) {
                j = k - 1u - whole;
            }
            let now = input(span, j);
            let moved = now + rounded(frac * (before - now));
            before = now;
            if (frac == 0.0) {
                ui = now;
            } else {
                ui = moved;
            }
        }
        if (HAS_DEADZONE) {
            ui = larger(ui - p0, -u_mean);
        }
        if (HAS_BACKLASH) {
            let half = rounded(0.5 * play_width);
            var prev = ui;
            if (has_play) {
                prev = play;
            }
            let v = smaller(ui + half, larger(ui - half, prev));
            play = v;
            has_play = true;
            ui = v;
        }
        if (HAS_ASYMMETRY) {
            if (dir >= 0.0) {
                extreme = larger(raw, extreme);
                if (raw < extreme - tol) {
                    dir = -1.0;
                    extreme = raw;
                } else if (raw > u0 + tol) {
                    dir = 1.0;
                }
            } else {
                extreme = smaller(raw, extreme);
                if (raw > extreme + tol) {
                    dir = 1.0;
                    extreme = raw;
                }
            }
            ui = ui + rounded(rounded(dir * eps) * (ui + u_mean));
        }
        if (has_load) {
            ui = ui + rounded(g * (ui + u_mean));
        }
        // State: the family's equations, the extra pole and the end stop.
        var xk = linear(th, State(x, w), ui);
        if (HAS_INERTIA) {
            xk = xk + rounded(a2 * (x - x_prev2));
        }
        if (HAS_SATURATION) {
            if (DRIVES_UP[e]) {
                xk = smaller(xk, bound);
            } else {
                xk = larger(xk, bound);
            }
        }
        let delta = xk - x;
        var a_eff = big_a;
        if (HAS_RATE) {
            var prev = u0;
            if (k >= 2u) {
                prev = input(span, k - 2u);
            }
            a_eff = rounded(big_a * (1.0 + rounded(eta * rounded(abs(raw - prev) * INV_DT[e]))));
        }
        w = hysteresis(th, a_eff, w, xk, delta);
        x_prev2 = x;
        x = xk;
        // Output side: the creep's slow state.
        var yk = xk;
        if (HAS_CREEP) {
            z = rounded(rho * z) + rounded(rounded((1.0 - rho) * kappa) * ui);
            yk = xk + z;
        }
        if (!(in_bounds(x) && in_bounds(w) && in_bounds(yk))) {
            if (RESIDUALS) {
                for (var j = k; j < span.y; j = j + 1u) {
                    out[r0 + j - 1u] = infinity();
                }
            }
            return infinity();
        }
        let measured = samples[span.x + k].y;
        let err = yk - measured;
        if (RESIDUALS) {
            out[r0 + k - 1u] = err;
        } else {
            acc = acc + rounded(err * err);
        }
        // effects.rs `Prepared::restart`.
        if (k == next_restart) {
            let xr = measured - z;
            w = w + rounded(big_a * (xr - x));
            x = xr;
            next_restart = next_restart + cfg.horizon;
        }
    }
    return acc;
}
