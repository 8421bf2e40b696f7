// Classic Bouc-Wen family: θ = [A, α, β, γ, n, a, b, c, x0].

struct Theta {
    big_a: f32,
    alpha: f32,
    beta: f32,
    gamma: f32,
    n: f32,
    a: f32,
    b: f32,
    c: f32,
    x0: f32,
}

// Candidate row `p` (on any experiment).
fn load_theta(p: u32, e: u32) -> Theta {
    var n = 1.0;
    if (!N_ONE) {
        n = params[p + 4u];
    }
    return Theta(params[p], params[p + 1u], params[p + 2u], params[p + 3u], n,
        params[p + 5u], params[p + 6u], params[p + 7u], params[p + 8u]);
}

// sim.rs `classic_w`.
fn classic_w(big_a: f32, beta: f32, gamma: f32, n: f32, w_prev: f32, delta: f32) -> f32 {
    let aw = abs(w_prev);
    let pw = abs_pow(aw, n - 1.0);
    return ((w_prev + rounded(big_a * delta)) - rounded((beta * abs(delta)) * (pw * w_prev)))
        - rounded((gamma * delta) * (pw * aw));
}

// sim.rs `Stepper::step`'s linear part for the classic family.
fn linear(th: Theta, s: State, u_prev: f32) -> f32 {
    return linear_part(th.a, th.alpha, th.b, th.c, s.x, s.w, u_prev);
}

// A: the stiffness a restart's elastic part and the rate effect scale.
fn stiffness(th: Theta) -> f32 {
    return th.big_a;
}

// sim.rs `Stepper::hysteresis`, with the stiffness `big_a`.
fn hysteresis(th: Theta, big_a: f32, w_prev: f32, x: f32, delta: f32) -> f32 {
    return classic_w(big_a, th.beta, th.gamma, th.n, w_prev, delta);
}
