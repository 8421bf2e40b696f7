// Generalized Bouc-Wen family: θ = [A, α, β1..β6, n, a, b, c, x0].

const DIM: u32 = 13u;

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
    a: f32,
    b: f32,
    c: f32,
    x0: f32,
}

fn load_theta(p: u32) -> Theta {
    var n = 1.0;
    if (!N_ONE) {
        n = params[p + 8u];
    }
    return Theta(params[p], params[p + 1u], params[p + 2u], params[p + 3u], params[p + 4u],
        params[p + 5u], params[p + 6u], params[p + 7u], n, params[p + 9u], params[p + 10u],
        params[p + 11u], params[p + 12u]);
}

// sim.rs `generalized_w`; the sign of a product is the product of signs.
fn generalized_w(th: Theta, w_prev: f32, x: f32, delta: f32) -> f32 {
    let sd = sgn(delta);
    let sw = sgn(w_prev);
    let sx = sgn(x);
    let psi = (((((rounded(th.b1 * (sd * sw)) + rounded(th.b2 * (sd * sx))) + rounded(th.b3 * (sx * sw)))
        + rounded(th.b4 * sd)) + rounded(th.b5 * sw)) + rounded(th.b6 * sx));
    let aw = abs(w_prev);
    let pwn = abs_pow(aw, th.n - 1.0) * aw;
    return w_prev + rounded(delta * (th.big_a - rounded(pwn * psi)));
}

// sim.rs `Stepper::step` for the generalized family.
fn step(th: Theta, s: State, u_prev: f32) -> State {
    let xn = linear_part(th.a, th.alpha, th.b, th.c, s.x, s.w, u_prev);
    return State(xn, generalized_w(th, s.w, xn, xn - s.x));
}

// sim.rs `Stepper::restart` (`restart_w`): the Bouc-Wen state takes the
// jump's elastic part.
fn restart(th: Theta, s: State, y: f32) -> State {
    return State(y, s.w + rounded(th.big_a * (y - s.x)));
}
