//! The twin's two slow-and-fast effects, off by default: the bladder's creep
//! and the load's ringing. Each is checked against the number its
//! derivation in docs/TWIN.md predicts, on the noise-free state.

use mckibben::twin::{Rig, TrueState, TwinConfig, TwinError};

/// The default twin with the named effects at scale 1.
fn with(effects: &[&str]) -> TwinConfig {
    let mut config = TwinConfig::default();
    for name in effects {
        config.effects.set(name, 1.0).unwrap();
    }
    config
}

/// Holds each `(volts, seconds)` in turn and returns the true state after
/// every sample.
fn record(config: &TwinConfig, load_kg: f64, program: &[(f64, f64)]) -> Vec<TrueState> {
    let mut rig = Rig::new(config, load_kg, 1);
    let mut states = Vec::new();
    for &(volts, seconds) in program {
        for _ in 0..(seconds / rig.dt()).round() as usize {
            rig.advance(volts);
            states.push(rig.true_state());
        }
    }
    states
}

/// Index of the sample at `t` seconds.
fn at(states: &[TrueState], t: f64) -> usize {
    states.iter().position(|s| s.t >= t - 1e-9).unwrap()
}

/// Times where `y` crosses zero, linearly interpolated between samples.
fn zero_crossings(t: &[f64], y: &[f64]) -> Vec<f64> {
    (1..y.len())
        .filter(|&k| y[k - 1] != 0.0 && y[k - 1].signum() != y[k].signum())
        .map(|k| t[k - 1] + (t[k] - t[k - 1]) * y[k - 1] / (y[k - 1] - y[k]))
        .collect()
}

/// The largest |y| between consecutive crossings: one per half-cycle.
fn half_cycle_peaks(t: &[f64], y: &[f64], crossings: &[f64]) -> Vec<f64> {
    crossings
        .windows(2)
        .map(|w| {
            t.iter()
                .zip(y)
                .filter(|(tk, _)| **tk > w[0] && **tk < w[1])
                .map(|(_, yk)| yk.abs())
                .fold(0.0, f64::max)
        })
        .collect()
}

/// A valve step 5 → 6 V (mid pressure, ≈ 0.2 → 0.25 MPa) under `load_kg`:
/// with ringing the load swings about the ringing-free trace at
/// `√(k/m)/2π`, `k` the muscle's axial stiffness where it comes to rest,
/// and the swing dies away; without ringing the load rises without a
/// single reversal.
#[test]
fn ringing_swings_the_load_at_the_muscles_own_frequency_and_decays() {
    for load_kg in [4.5, 7.0] {
        let program = [(5.0, 3.0), (6.0, 2.0)];
        let on = record(&with(&["ringing"]), load_kg, &program);
        let off = record(&TwinConfig::default(), load_kg, &program);
        let step = at(&off, 3.0);

        let rising = &off[step..];
        assert!(
            rising
                .windows(2)
                .all(|w| w[1].contraction_m >= w[0].contraction_m),
            "{load_kg} kg: without ringing the load reverses after the step"
        );

        let t: Vec<f64> = on[step..].iter().map(|s| s.t).collect();
        let swing: Vec<f64> = on[step..]
            .iter()
            .zip(rising)
            .map(|(a, b)| a.contraction_m - b.contraction_m)
            .collect();
        let crossings = zero_crossings(&t, &swing);
        assert!(
            crossings.len() >= 8,
            "{load_kg} kg: only {} zero crossings",
            crossings.len()
        );
        let cycles = (crossings.len() - 1) as f64 / 2.0;
        let measured_hz = cycles / (crossings[crossings.len() - 1] - crossings[0]);

        let rig = Rig::new(&TwinConfig::default(), load_kg, 1);
        let end = off.last().unwrap();
        let k = rig
            .muscle()
            .axial_stiffness(end.chamber_pressure_pa, end.contraction_m);
        let predicted_hz = (k / load_kg).sqrt() / (2.0 * std::f64::consts::PI);
        eprintln!(
            "{load_kg} kg: k = {k:.0} N/m, predicted {predicted_hz:.2} Hz, measured {measured_hz:.2} Hz over {cycles} cycles"
        );
        assert!(
            (measured_hz / predicted_hz - 1.0).abs() < 0.1,
            "{load_kg} kg: rings at {measured_hz:.2} Hz, the stiffness predicts {predicted_hz:.2} Hz"
        );

        let peaks = half_cycle_peaks(&t, &swing, &crossings);
        assert!(
            peaks[0] > 0.1e-3,
            "{load_kg} kg: a first swing of {:.3} mm hides in the sensor noise",
            peaks[0] * 1e3
        );
        // Peaks one cycle apart (the two half-cycles differ while the step's
        // own motion still shifts the swing's centre) fall by e^{−2πζ/√(1−ζ²)}
        // once that motion has settled (after four cycles).
        let ratios: Vec<f64> = peaks.windows(3).map(|w| w[2] / w[0]).collect();
        assert!(
            ratios.iter().all(|r| *r < 1.0),
            "{load_kg} kg: the swing does not die away: {peaks:?}"
        );
        let zeta = rig.config().muscle.rubber_loss_factor
            * rig.config().muscle.rubber_stiffness_n_per_m
            / (2.0 * k);
        let per_cycle = (-2.0 * std::f64::consts::PI * zeta / (1.0 - zeta * zeta).sqrt()).exp();
        let late = &ratios[8..16];
        let measured = late.iter().sum::<f64>() / late.len() as f64;
        eprintln!(
            "  ζ = {zeta:.3}: a cycle keeps {per_cycle:.3} of the swing, measured {measured:.3}"
        );
        assert!(
            (measured / per_cycle - 1.0).abs() < 0.05,
            "{load_kg} kg: a cycle keeps {measured:.3} of the swing, ζ = {zeta:.3} predicts {per_cycle:.3}"
        );
    }
}

/// A valve step 0 → 6 V held 40 s, then back to 0 V for 40 s, under 4.5 kg.
/// Without creep the muscle settles within the hydraulics' second. With it
/// the muscle creeps on toward the equilibrium of the fully relaxed rubber,
/// with the retardation time `τ·k/(k − k_1)` of docs/TWIN.md, and on release
/// comes back the same slow way.
#[test]
fn creep_deepens_a_held_step_with_the_documented_time_and_recovers() {
    let load_kg = 4.5;
    let program = [(0.0, 1.0), (6.0, 40.0), (0.0, 40.0)];
    let on = record(&with(&["creep"]), load_kg, &program);
    let off = record(&TwinConfig::default(), load_kg, &program);
    // The fully relaxed rubber: its stiffness k_∞ alone, no arm.
    let mut relaxed = TwinConfig::default();
    let muscle = relaxed.muscle;
    let k1 = muscle.creep_share * muscle.rubber_stiffness_n_per_m;
    relaxed.muscle.rubber_stiffness_n_per_m -= k1;
    let end = record(&relaxed, load_kg, &program);

    let x = |states: &[TrueState], t: f64| states[at(states, t)].contraction_m;
    let settled = 4.0;
    let held = 41.0 - 0.01;
    assert!(
        (x(&off, held) - x(&off, settled)).abs() < 0.02e-3,
        "without creep the muscle still moves after 3 s: {} → {} m",
        x(&off, settled),
        x(&off, held)
    );

    let fast = x(&off, held);
    let target = x(&end, held);
    let fraction = (target - fast) / target;
    let s = &off[at(&off, held)];
    let k = Rig::new(&TwinConfig::default(), load_kg, 1)
        .muscle()
        .axial_stiffness(s.chamber_pressure_pa, s.contraction_m);
    let tau = muscle.creep_time_s * k / (k - k1);
    eprintln!(
        "creep: fast {:.3} mm, relaxed {:.3} mm, fraction {fraction:.4} (k1/k = {:.4}), k = {k:.0} N/m, τ_c = {tau:.2} s",
        fast * 1e3,
        target * 1e3,
        k1 / k
    );
    assert!(
        (fraction / (k1 / k) - 1.0).abs() < 0.15,
        "creep of {fraction:.4} of the step, k1/k predicts {:.4}",
        k1 / k
    );

    let left = |t: f64| target - x(&on, t);
    let reached = 1.0 - left(settled + tau) / left(settled);
    eprintln!(
        "creep: at 3 s {:.3} mm still to go, after τ_c {:.3} mm: {reached:.3} reached; at 40 s {:.4} mm",
        left(settled) * 1e3,
        left(settled + tau) * 1e3,
        left(held) * 1e3
    );
    assert!(
        left(settled) > 0.3 * (target - fast),
        "the creep is over within 3 s"
    );
    assert!(
        (reached - (1.0 - (-1f64).exp())).abs() < 0.05,
        "{reached:.3} of the creep left at 3 s done after τ_c = {tau:.2} s, not 1 − 1/e"
    );
    assert!(left(held).abs() < 0.02 * (target - fast));

    let release = 41.0;
    let held_up = |t: f64| x(&on, t) - x(&off, t);
    let (early, late) = (held_up(release + 3.0), held_up(release + 40.0 - 0.01));
    eprintln!(
        "release: creep run above the plain one by {:.3} mm at 3 s, {:.4} mm at 40 s",
        early * 1e3,
        late * 1e3
    );
    assert!(
        early > 0.3 * (target - fast),
        "on release the creep run is only {early} m above the plain one"
    );
    assert!(
        (x(&on, release + 40.0 - 0.01) - x(&end, release + 40.0 - 0.01)).abs() < 0.02 * early,
        "the creep run does not recover to the relaxed rubber's rest"
    );
    assert!(late < 0.5 * early);
}

/// The swing is linear: it can unload the muscle past the tension that
/// holds the load, where a real muscle would go slack and the load fly.
/// The rig says from which sample it did (`Rig::slack_from`), and the
/// checks and the `twin` command refuse such a run instead of writing
/// displacements no muscle makes. At the documented scale the valve's full
/// steps never do it, under any load the commands hang.
#[test]
fn a_swing_that_would_leave_the_muscle_slack_is_refused() {
    let documented = with(&["ringing"]);
    for load in [0.5, 2.0, 4.5, 7.0, 15.0] {
        let mut rig = Rig::new(&documented, load, 1);
        for volts in [10.0, 0.0, 10.0, 0.0] {
            for _ in 0..100 {
                rig.advance(volts);
            }
        }
        assert_eq!(rig.slack_from(), None, "{load} kg");
        Rig::check_holds(&documented, load, 1).unwrap();
    }

    let mut twenty = TwinConfig::default();
    twenty.effects.set("ringing", 20.0).unwrap();
    let err = Rig::check_holds(&twenty, 4.5, 1).unwrap_err();
    assert!(matches!(err, TwinError::Slack { .. }), "{err}");
    // The valve opens at 1 s: the swing it starts is what unloads.
    let TwinError::Slack { t_s, .. } = err else {
        unreachable!()
    };
    assert!(t_s > 1.0 && t_s < 1.5, "{t_s}");

    // The command writes nothing and names the flag to change.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ringing.csv");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_mckibben"))
        .args(["twin", "--effect", "ringing=20", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("slack") && stderr.contains("--effect ringing"),
        "{stderr}"
    );
    assert!(!out.exists());
}
