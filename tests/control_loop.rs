//! Closed loops on the stand-in plant (the project's own classic model fed
//! by a first-order valve → pressure lag): the identification recovers it,
//! and the MPC beats the thesis' PI at 3 rad/s within the valve limits.
//! Short episodes, deterministic.

use mckibben::control::design;
use mckibben::control::{
    ControlLoop, Episode, Measurement, Mpc, MpcSettings, Pi, PiGains, Plant, StandIn, ValveLimits,
    ValveModel, run_episode,
};
use mckibben::data::Trace;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// An open-loop identification record from the stand-in: a seeded random
/// stair of valve voltages held 0.5–2 s each, with a `valve_in` column.
fn record(seconds: f64, seed: u64) -> Trace {
    use rand::RngExt;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut plant = StandIn::thesis_like(5.0);
    let n = (seconds / plant.dt()) as usize;
    let (mut valve, mut p, mut y) = (Vec::new(), Vec::new(), Vec::new());
    let (mut level, mut left) = (5.0, 0usize);
    for _ in 0..n {
        if left == 0 {
            level = rng.random_range(2.0..8.0);
            left = rng.random_range(50..200);
        }
        left -= 1;
        // Row k: the measurement now and the command held from now on.
        let m = plant.step(level);
        valve.push(level);
        p.push(m.pressure_mpa);
        y.push(m.displacement_mm);
    }
    // The stand-in's step returns the reading at the end of the held
    // sample; shift the commands so that row k holds the command after it.
    valve.rotate_left(1);
    let mut trace = Trace::uniform("stand-in stair", plant.dt(), p, y);
    trace.extra.push(("valve_in".into(), valve));
    trace
}

#[test]
fn valve_model_recovers_the_stand_in_lag_and_gain() {
    let trace = record(40.0, 1);
    let valve = trace.column("valve_in").unwrap();
    let (vm, rms) = ValveModel::identify("t", valve, &trace.input, (0.0, 10.0), 20).unwrap();
    // p(k+1) = pole·p(k) + (1 − pole)·(0.15 + 0.02·v(k)), pole = e^(−0.2).
    assert!((vm.pole - (-0.2f64).exp()).abs() < 0.02, "pole {}", vm.pole);
    let gain = (vm.static_pressure(7.0) - vm.static_pressure(3.0)) / 4.0;
    assert!((gain - 0.02).abs() < 2e-3, "static gain {gain} MPa/V");
    assert!(rms < 1e-3, "rms {rms} MPa");
}

#[test]
fn mpc_beats_thesis_pi_at_3_rad_s_within_limits() {
    let model = design::identify(&record(60.0, 7), (0.0, 10.0), 20).unwrap();
    let ep = Episode::short(3.0, 2.0, 6.0, 3.0);
    let mut plant = StandIn::thesis_like(ep.u0);
    let mut pi = Pi::new(PiGains::default(), ValveLimits::default(), plant.dt(), "pi");
    let pi_run = run_episode(&mut plant, &mut pi, &ep);
    let mut plant = StandIn::thesis_like(ep.u0);
    let mut mpc = Mpc::new(
        &model,
        MpcSettings::default(),
        ValveLimits::default(),
        "mpc",
    )
    .unwrap();
    let mpc_run = run_episode(&mut plant, &mut mpc, &ep);
    eprintln!("pi  {:?}\nmpc {:?}", pi_run.metrics, mpc_run.metrics);
    assert_eq!(mpc_run.metrics.constraint_violations, 0);
    assert_eq!(pi_run.metrics.constraint_violations, 0);
    assert_eq!(mpc.stats.solver_failures, 0);
    assert!(!mpc_run.metrics.diverged);
    assert!(
        mpc_run.metrics.rms_error_mm < 0.5 * pi_run.metrics.rms_error_mm,
        "mpc {} mm vs pi {} mm",
        mpc_run.metrics.rms_error_mm,
        pi_run.metrics.rms_error_mm
    );
    let l = ValveLimits::default();
    for w in mpc_run.valve.windows(2) {
        assert!(!l.violated(w[1], w[0]));
    }
}

#[test]
fn a_missing_measurement_holds_the_command_in_force() {
    let mut pi = Pi::new(PiGains::default(), ValveLimits::default(), 0.01, "pi");
    let mut lp = ControlLoop::new(&mut pi, vec![30.0; 10], ValveLimits::default(), 5.0);
    let m = Measurement {
        pressure_mpa: 0.2,
        displacement_mm: 29.0,
    };
    let first = lp.step(Some(m));
    assert!(!first.held && first.volts != 5.0);
    let held = lp.step(None);
    assert!(held.held);
    assert_eq!((held.k, held.volts), (2, first.volts));
    assert_eq!(lp.missed, 1);
}
