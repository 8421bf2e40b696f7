// Generalized Bouc-Wen family: θ = [A, α, β1..β6, n, x_s, a, b, c, x0]. The
// switching level x_s is in the output's own units: the sign terms in x
// switch at x = x_s − ȳ, ȳ the experiment's output mean (`Y_MEAN`, in the
// pipeline's header).

struct Theta {
    big_a: f32,
    alpha: f32,
    b1: f32,
    b2: f32,
    b3: f32,
    b4: f32,
    b5: f32,
    b6: f32,
    n: f32,
    // Where the sign terms in x switch, in experiment e's deviation
    // coordinates: sim.rs `switch_threshold` (the mean read through
    // `rounded`, so that the compiler cannot fold it into a literal).
    threshold: f32,
    a: f32,
    b: f32,
    c: f32,
    x0: f32,
}

// Candidate row `p` on experiment `e`.
fn load_theta(p: u32, e: u32) -> Theta {
    var n = 1.0;
    if (!N_ONE) {
        n = params[p + 8u];
    }
    let threshold = params[p + 9u] - rounded(Y_MEAN[e]);
    return Theta(params[p], params[p + 1u], params[p + 2u], params[p + 3u], params[p + 4u],
        params[p + 5u], params[p + 6u], params[p + 7u], n, threshold, params[p + 10u],
        params[p + 11u], params[p + 12u], params[p + 13u]);
}

// sim.rs `generalized_w`; the sign of a product is the product of signs.
fn generalized_w(th: Theta, big_a: f32, w_prev: f32, x: f32, delta: f32) -> f32 {
    let sd = sgn(delta);
    let sw = sgn(w_prev);
    let sx = sgn(x - th.threshold);
    let psi = (((((rounded(th.b1 * (sd * sw)) + rounded(th.b2 * (sd * sx))) + rounded(th.b3 * (sx * sw)))
        + rounded(th.b4 * sd)) + rounded(th.b5 * sw)) + rounded(th.b6 * sx));
    let aw = abs(w_prev);
    let pwn = abs_pow(aw, th.n - 1.0) * aw;
    return w_prev + rounded(delta * (big_a - rounded(pwn * psi)));
}

// sim.rs `Stepper::step`'s linear part for the generalized family.
fn linear(th: Theta, s: State, u_prev: f32) -> f32 {
    return linear_part(th.a, th.alpha, th.b, th.c, s.x, s.w, u_prev);
}

// A: the stiffness a restart's elastic part and the rate effect scale.
fn stiffness(th: Theta) -> f32 {
    return th.big_a;
}

// sim.rs `Stepper::hysteresis`, with the stiffness `big_a`.
fn hysteresis(th: Theta, big_a: f32, w_prev: f32, x: f32, delta: f32) -> f32 {
    return generalized_w(th, big_a, w_prev, x, delta);
}
