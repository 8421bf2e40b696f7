// The scoring loop of a family with effect stages: src/model/effects/step.rs
// `Prepared::step` and `Prepared::restart` with each realisation's stage
// (src/model/effects/stages/, in the step order of catalogue.rs), spelled
// with the same operations in the same order (every product that is then
// added kept rounded, minima and maxima as comparisons). The generated header says
// which effects are present (`HAS_*`), loads their parameters from the
// candidate's row (`load_effect_params`, generated from the catalogue) and
// holds each experiment's constants (`U_MEAN`,
// `Y_MEAN`, `BRANCH_TOL`, `INV_DT`, `DRIVES_UP`, `KNEE_*`, `REST`, indexed by
// experiment).

// An experiment's constant as the CPU sees it: a value, not a literal.
// With one experiment its array is indexed by 0 for sure, so the compiler
// may fold the read into a literal, and Mesa's NIR reassociates sums around
// literals (`(b + h) − x` into `(b − x) + h`), which rounds differently
// (measured: the soft stop of a contracting muscle, docs/PERFORMANCE.md).
// The integer round trip of `rounded` hides the value from it.
fn unfolded(v: f32) -> f32 {
    return rounded(v);
}

// stage.rs `larger`: `a` if it is the larger, else `b`.
fn larger(a: f32, b: f32) -> f32 {
    if (a > b) {
        return a;
    }
    return b;
}

// stage.rs `smaller`: `a` if it is the smaller, else `b`.
fn smaller(a: f32, b: f32) -> f32 {
    if (a < b) {
        return a;
    }
    return b;
}

// stages/saturation.rs `soft_stop`, which the CPU applies to `±x` and
// `±bound` (`Frame::toward`); written out per direction here, the same
// bits since negation is exact (`tests/eval_effects.rs` checks both
// directions).
fn soft_stop(x: f32, bound: f32, e: u32) -> f32 {
    let h = unfolded(KNEE_H[e]);
    var into = (bound + h) - x;
    if (DRIVES_UP[e]) {
        into = x - (bound - h);
    }
    let bend = rounded(rounded(into * into) * unfolded(KNEE_INV_4H[e]));
    var bent = x + bend;
    if (DRIVES_UP[e]) {
        bent = x - bend;
    }
    if (into <= 0.0) {
        return x;
    } else if (into >= unfolded(KNEE_2H[e])) {
        return bound;
    }
    return bent;
}

// stages/saturation.rs: the end stop on the side the input drives the
// output, on the CPU `±min(±x, ±bound)` (`Frame::toward`), the same bits
// as this.
fn clip(x: f32, bound: f32, e: u32) -> f32 {
    if (DRIVES_UP[e]) {
        return smaller(x, bound);
    }
    return larger(x, bound);
}

// stages/creep.rs `tenth_power`: ρ^10 by products.
fn tenth_power(rho: f32) -> f32 {
    let p2 = rounded(rho * rho);
    let p4 = rounded(p2 * p2);
    return rounded(rounded(p4 * p4) * p2);
}

// One step of a first-order lag of pole `rho` from `prev` toward `v`.
fn lag(rho: f32, prev: f32, v: f32) -> f32 {
    return rounded(rho * prev) + rounded((1.0 - rho) * v);
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
    let th = load_theta(p, e);
    let r0 = i * cfg.residual_len + span.x - e;
    let u_mean = unfolded(U_MEAN[e]);
    let tol = unfolded(BRANCH_TOL[e]);
    let y_mean = unfolded(Y_MEAN[e]);
    // step.rs `Augmented::prepare`: the parameters as the generated
    // `load_effect_params` loads them (0 for an effect not in the model),
    // and what each realisation derives from them once per candidate (its
    // stage's `prepare`).
    let q = load_effect_params(p, e);
    // The delay in whole samples and the fraction of a sample beyond them.
    let d = larger(q.delay_d, 0.0);
    let whole = u32(floor(d));
    let frac = d - floor(d);
    let p0 = q.deadzone_p0;
    let bound = q.saturation_l_max - y_mean;
    let eps = q.asymmetry_eps;
    let a2 = q.inertia_a2;
    let play_width = larger(q.backlash_r, 0.0);
    let rho = q.creep_rho;
    let kappa = q.creep_kappa;
    let z0 = q.creep_z0;
    let eta = q.rate_eta;
    // The load gain of dataset e ≥ 1 (dataset 0 is the reference).
    let has_load = HAS_LOAD && e >= 1u;
    let g = q.load_g;
    let rho_in = q.delay_input_lag_rho;
    let rho_out = q.delay_output_lag_rho;
    let a1 = q.inertia_mode_a1;
    let a2m = q.inertia_mode_a2;
    let mode_gain = (1.0 - a1) + a2m;
    let rho_drain = q.asymmetry_drain_rho;
    let clip_bound = q.saturation_output_l_max - y_mean;
    let soft_bound = q.saturation_soft_l_max - y_mean;
    let rho_zo = q.creep_output_rho;
    let kappa_zo = q.creep_output_kappa;
    let z0_out = q.creep_output_z0;
    // stages/creep.rs: the two-pole creep's total gain split by the faster
    // state's share.
    let rho_f = q.creep_two_pole_rho_fast;
    let rho_s = q.creep_two_pole_rho_slow;
    let kappa_f = rounded(q.creep_two_pole_fast_share * q.creep_two_pole_kappa);
    let kappa_s = q.creep_two_pole_kappa - kappa_f;
    let z0_slow = q.creep_two_pole_z0;
    // stages/creep.rs: the log-time creep's poles a decade apart in time
    // constant (ρ^100, ρ^10, ρ) and their input weights (1 − ρ)·κ.
    let rho_ls = q.creep_log_rho;
    let rho_lm = tenth_power(rho_ls);
    let rho_lf = tenth_power(rho_lm);
    let w_lf = rounded((1.0 - rho_lf) * q.creep_log_kappa);
    let w_lm = rounded((1.0 - rho_lm) * q.creep_log_kappa);
    let w_ls = rounded((1.0 - rho_ls) * q.creep_log_kappa);
    let p_on = q.deadzone_on_off_p_on - u_mean;
    let p_off = p_on - q.deadzone_on_off_gap;
    let ring_a1 = q.inertia_ringing_a1;
    let ring_a2 = q.inertia_ringing_a2;
    let kick = q.inertia_ringing_g;
    let big_a = stiffness(th);
    // step.rs `Prepared::start` (each stage's `start`).
    let u0 = input(span, 0u);
    var x = samples[span.x].y + th.x0;
    var w = 0.0;
    var before = u0;
    var x_prev2 = x;
    var play = 0.0;
    var started = false;
    var dir = 0.0;
    var extreme = u0;
    var z = z0;
    var lag_in = 0.0;
    var drain = 0.0;
    var lag_out = x;
    var mode1 = x;
    var mode2 = x;
    var z_out = z0_out;
    var z_fast = 0.0;
    var z_slow = z0_slow;
    var log_fast = 0.0;
    var log_mid = 0.0;
    var log_slow = q.creep_log_z0;
    var on = 0.0;
    var ring1 = 0.0;
    var ring2 = 0.0;
    var acc = 0.0;
    var next_restart = cfg.horizon;
    for (var k = 1u; k < span.y; k = k + 1u) {
        // Input side: delay, input lag, on/off threshold, deadzone, play,
        // branch gain, load gain, drain lag (step.rs `Prepared::step`, in
        // the step order of catalogue.rs).
        let raw = input(span, k - 1u);
        var ui = raw;
        if (HAS_DELAY) {
            // stages/delay.rs `delayed`: u(j) moved by `frac` toward
            // u(j−1), the u(j) of the sample before.
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
        if (HAS_DELAY_INPUT_LAG) {
            var prev = ui;
            if (started) {
                prev = lag_in;
            }
            ui = lag(rho_in, prev, ui);
            lag_in = ui;
        }
        if (HAS_DEADZONE_ON_OFF) {
            if (ui > p_on) {
                on = 1.0;
            } else if (ui < p_off) {
                on = 0.0;
            }
            if (!(on > 0.0)) {
                ui = unfolded(REST[e]);
            }
        }
        if (HAS_DEADZONE) {
            ui = larger(ui - p0, -u_mean);
        }
        if (HAS_BACKLASH) {
            let half = rounded(0.5 * play_width);
            var prev = ui;
            if (started) {
                prev = play;
            }
            let v = smaller(ui + half, larger(ui - half, prev));
            play = v;
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
        if (HAS_ASYMMETRY_DRAIN) {
            var prev = ui;
            if (started) {
                prev = drain;
            }
            var slow = ui > prev;
            var r = -rho_drain;
            if (rho_drain >= 0.0) {
                slow = ui < prev;
                r = rho_drain;
            }
            let lagged = lag(r, prev, ui);
            if (slow) {
                ui = lagged;
            }
            drain = ui;
        }
        started = true;
        // State: the family's equations, the extra pole and the end stop.
        var xk = linear(th, State(x, w), ui);
        if (HAS_INERTIA) {
            xk = xk + rounded(a2 * (x - x_prev2));
        }
        if (HAS_SATURATION) {
            xk = clip(xk, bound, e);
        }
        if (HAS_SATURATION_SOFT) {
            xk = soft_stop(xk, soft_bound, e);
        }
        let delta = xk - x;
        var a_eff = big_a;
        if (HAS_RATE) {
            var prev = u0;
            if (k >= 2u) {
                prev = input(span, k - 2u);
            }
            a_eff = rounded(big_a * (1.0 + rounded(eta * rounded(abs(raw - prev) * unfolded(INV_DT[e])))));
        }
        w = hysteresis(th, a_eff, w, xk, delta);
        x_prev2 = x;
        x = xk;
        // Output side: the creeps' slow states (input-driven, output-driven,
        // two-pole, log-time), the ringing, the load mode, the output clip
        // and the output lag.
        var yk = xk;
        if (HAS_CREEP) {
            z = rounded(rho * z) + rounded(rounded((1.0 - rho) * kappa) * ui);
            yk = yk + z;
        }
        if (HAS_CREEP_OUTPUT) {
            z_out = rounded(rho_zo * z_out) + rounded(rounded((1.0 - rho_zo) * kappa_zo) * xk);
            yk = yk + z_out;
        }
        if (HAS_CREEP_TWO_POLE) {
            z_fast = rounded(rho_f * z_fast) + rounded(rounded((1.0 - rho_f) * kappa_f) * ui);
            z_slow = rounded(rho_s * z_slow) + rounded(rounded((1.0 - rho_s) * kappa_s) * ui);
            yk = yk + z_fast;
            yk = yk + z_slow;
        }
        if (HAS_CREEP_LOG) {
            log_fast = rounded(rho_lf * log_fast) + rounded(w_lf * ui);
            log_mid = rounded(rho_lm * log_mid) + rounded(w_lm * ui);
            log_slow = rounded(rho_ls * log_slow) + rounded(w_ls * ui);
            yk = yk + log_fast;
            yk = yk + log_mid;
            yk = yk + log_slow;
        }
        if (HAS_INERTIA_RINGING) {
            var prev = u0;
            if (k >= 2u) {
                prev = input(span, k - 2u);
            }
            let r = (rounded(ring_a1 * ring1) - rounded(ring_a2 * ring2)) + rounded(kick * (raw - prev));
            ring2 = ring1;
            ring1 = r;
            yk = yk + r;
        }
        if (HAS_INERTIA_MODE) {
            let q = (rounded(a1 * mode1) - rounded(a2m * mode2)) + rounded(mode_gain * yk);
            mode2 = mode1;
            mode1 = q;
            yk = q;
        }
        if (HAS_SATURATION_OUTPUT) {
            yk = clip(yk, clip_bound, e);
        }
        if (HAS_DELAY_OUTPUT_LAG) {
            yk = lag(rho_out, lag_out, yk);
            lag_out = yk;
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
        // step.rs `Prepared::restart` (each stage's `restart`, in the step
        // order).
        if (k == next_restart) {
            let creeps = (((measured - z) - z_out) - z_fast) - z_slow;
            let xr = (((creeps - log_fast) - log_mid) - log_slow) - ring1;
            w = w + rounded(big_a * (xr - x));
            x = xr;
            lag_out = measured;
            mode1 = measured;
            mode2 = measured;
            next_restart = next_restart + cfg.horizon;
        }
    }
    return acc;
}
