// Linear family (eq. 12 plus intercept): θ = [a, b, c, x0].

struct Theta {
    a: f32,
    b: f32,
    c: f32,
    x0: f32,
}

// Candidate row `p` (on any experiment).
fn load_theta(p: u32, e: u32) -> Theta {
    return Theta(params[p], params[p + 1u], params[p + 2u], params[p + 3u]);
}

// sim.rs `Stepper::step` for the linear family (eq. 12).
fn linear(th: Theta, s: State, u_prev: f32) -> f32 {
    return linear_step(th.a, th.b, th.c, s.x, u_prev);
}

// No hysteresis: a restart has no elastic part, the rate effect nothing to scale.
fn stiffness(th: Theta) -> f32 {
    return 0.0;
}

fn hysteresis(th: Theta, big_a: f32, w_prev: f32, x: f32, delta: f32) -> f32 {
    return 0.0;
}
