// Linear family (eq. 12 plus intercept): θ = [a, b, c, x0].

const DIM: u32 = 4u;

struct Theta {
    a: f32,
    b: f32,
    c: f32,
    x0: f32,
}

fn load_theta(p: u32) -> Theta {
    return Theta(params[p], params[p + 1u], params[p + 2u], params[p + 3u]);
}

// sim.rs `Stepper::step` for the linear family.
fn step(th: Theta, s: State, u_prev: f32) -> State {
    return State(linear_step(th.a, th.b, th.c, s.x, u_prev), 0.0);
}

// sim.rs `Stepper::restart`: the linear family has no hysteretic state.
fn restart(th: Theta, s: State, y: f32) -> State {
    return State(y, 0.0);
}
