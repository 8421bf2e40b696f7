//! The rig twin behaves like a muscle rig, its effect switches are real, and
//! the shipped data regenerate byte for byte.

use mckibben::data::Trace;
use mckibben::data::signals::Stair;
use mckibben::ident::ArxOrders;
use mckibben::ident::arx::identify;
use mckibben::twin::experiment::{Kind, RunSpec};
use mckibben::twin::{EFFECT_NAMES, Rig, TwinConfig, TwinExperiment, run};

/// Holds the valve at `u` volts for `seconds` and returns the true state.
fn hold(rig: &mut Rig, u: f64, seconds: f64) -> mckibben::twin::TrueState {
    let n = (seconds / rig.dt()).round() as usize;
    for _ in 0..n {
        rig.advance(u);
    }
    rig.true_state()
}

/// Shoelace area of the closed path through `(x, y)`.
fn loop_area(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len();
    let mut a = 0.0;
    for i in 0..n {
        let j = (i + 1) % n;
        a += x[i] * y[j] - x[j] * y[i];
    }
    0.5 * a.abs()
}

/// A short stair (one cycle, 0.3 s per level: 600 samples) for the effect tests.
fn short_stair() -> TwinExperiment {
    TwinExperiment::Stair(Stair {
        hold_s: 0.3,
        cycles: 1,
        ..Stair::default()
    })
}

#[test]
fn contraction_grows_with_static_pressure_within_the_geometric_limit() {
    let config = TwinConfig::default();
    let mut rig = Rig::new(&config, 4.5, 1);
    let limit = rig.muscle().geometric_limit();
    let mut last = rig.true_state();
    let mut rises = 0;
    for level in 2..=10 {
        let s = hold(&mut rig, level as f64, 2.0);
        assert!(
            s.pressure_pa > last.pressure_pa - 1.0,
            "pressure fell at {level} V: {} → {} Pa",
            last.pressure_pa,
            s.pressure_pa
        );
        if s.pressure_pa > last.pressure_pa + 1e3 {
            rises += 1;
            assert!(
                s.contraction_m > last.contraction_m + 1e-4,
                "contraction did not grow at {level} V: {} → {} m",
                last.contraction_m,
                s.contraction_m
            );
        } else {
            assert!(s.contraction_m > last.contraction_m - 1e-6);
        }
        assert!(
            s.contraction_m < limit,
            "{} ≥ limit {limit}",
            s.contraction_m
        );
        last = s;
    }
    // Past the dead band of the output valve (9.2 V) the pressure is the
    // supply's; every level below rises.
    assert!(rises >= 7, "only {rises} levels raised the pressure");
    // At full supply the muscle contracts tens of millimetres (the thesis'
    // PI runs ask for 20–40 mm), short of the braid's limit (≈ 140 mm here).
    assert!(last.contraction_m > 0.035 && last.contraction_m < 0.05);
    assert!(limit > 0.1);
}

#[test]
fn without_end_stops_or_friction_the_braid_limit_still_holds() {
    let mut config = TwinConfig::default();
    config.effects.remove("endstop").unwrap();
    config.effects.remove("friction").unwrap();
    // Twice the tap pressure, still short of the geometric limit: the
    // force of eq. 9 falls to zero before cos²ψ = 1/3.
    config.hydraulics.supply_pa = 0.8e6;
    let mut rig = Rig::new(&config, 4.5, 1);
    let s = hold(&mut rig, 10.0, 4.0);
    assert!(s.contraction_m > 0.05);
    assert!(s.contraction_m < rig.muscle().geometric_limit());
}

/// The quasi-static loop of a one-cycle stair: the mean pressure and
/// displacement over the last 0.3 s of each 1 s level, in level order.
fn settled_points(trace: &Trace) -> (Vec<f64>, Vec<f64>) {
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    (0..trace.len() / 100)
        .map(|l| {
            let r = l * 100 + 70..l * 100 + 100;
            (mean(&trace.input[r.clone()]), mean(&trace.output[r]))
        })
        .unzip()
}

#[test]
fn stair_shows_a_hysteresis_loop_of_clearly_nonzero_area() {
    let config = TwinConfig::default();
    let stair = TwinExperiment::Stair(Stair {
        cycles: 1,
        ..Stair::default()
    });
    let with = run(&config, 4.5, 1, &stair);
    let mut ideal = config.clone();
    ideal.effects.remove("friction").unwrap();
    let without = run(&ideal, 4.5, 1, &stair);
    // The loop through the settled levels, so that the lag of the
    // transients (rate-dependent, present without friction) does not count.
    let (p, x) = settled_points(&with);
    let a_with = loop_area(&p, &x);
    let (p0, x0) = settled_points(&without);
    let a_without = loop_area(&p0, &x0);
    // MPa·mm. The loop spans about 0.4 MPa × 42 mm = 17 MPa·mm.
    assert!(a_with > 1.0, "loop area {a_with} MPa·mm");
    assert!(
        a_without < 0.1 * a_with,
        "friction makes the loop: {a_with} vs {a_without} MPa·mm without it"
    );
    // At the same valve level (5 V, same pressure once settled) the muscle
    // is more contracted coming down: friction holds it.
    let (up, down) = (x[5], x[15]);
    assert!((p[5] - p[15]).abs() < 0.005, "{} vs {} MPa", p[5], p[15]);
    assert!(down > up + 3.0, "up {up} mm, down {down} mm");
}

#[test]
fn heavier_load_lengthens_the_muscle_at_equal_pressure() {
    let config = TwinConfig::default();
    for u in [0.0, 4.0, 6.0, 10.0] {
        let light = hold(&mut Rig::new(&config, 4.5, 1), u, 3.0);
        let heavy = hold(&mut Rig::new(&config, 7.0, 1), u, 3.0);
        assert!(
            (light.pressure_pa - heavy.pressure_pa).abs() < 2e3,
            "{u} V: {} vs {} Pa",
            light.pressure_pa,
            heavy.pressure_pa
        );
        assert!(
            heavy.length_m > light.length_m + 1e-3,
            "{u} V: 7 kg {} m, 4.5 kg {} m",
            heavy.length_m,
            light.length_m
        );
    }
}

/// For every effect: scale 0 gives exactly the trace of the model without
/// the effect, and the nominal effect (scale 1, which `creep` and `ringing`
/// are not by default) changes the trace (the switch is live).
#[test]
fn every_effect_at_zero_equals_the_effect_removed() {
    for name in EFFECT_NAMES {
        let mut base = TwinConfig::default();
        if name == "endstop" {
            // Bring the bracket down into the stair's range so it is touched.
            base.endstop.max_contraction_m = 0.03;
        }
        let mut zero = base.clone();
        zero.effects.set(name, 0.0).unwrap();
        let mut removed = base.clone();
        removed.effects.remove(name).unwrap();
        let mut nominal = base.clone();
        nominal.effects.set(name, 1.0).unwrap();
        let stair = short_stair();
        let a = run(&zero, 4.5, 3, &stair);
        let b = run(&removed, 4.5, 3, &stair);
        let nominal = run(&nominal, 4.5, 3, &stair);
        assert_traces_equal(name, &a, &b);
        assert_ne!(nominal, b, "effect {name} at scale 1 changes nothing");
    }
}

fn assert_traces_equal(name: &str, a: &Trace, b: &Trace) {
    for (k, (x, y)) in a.output.iter().zip(&b.output).enumerate() {
        assert!(
            x.to_bits() == y.to_bits(),
            "effect {name}: displacement differs at sample {k}: {x} vs {y}"
        );
    }
    for (k, (x, y)) in a.input.iter().zip(&b.input).enumerate() {
        assert!(
            x.to_bits() == y.to_bits(),
            "effect {name}: pressure differs at sample {k}: {x} vs {y}"
        );
    }
    assert_eq!(a, b, "effect {name}");
}

/// `creep` and `ringing` are off by default: the default stair is bit for
/// bit the one with both set to 0, so no published number moves.
#[test]
fn creep_and_ringing_are_off_by_default() {
    let spec = |effects: &[&str]| RunSpec {
        kind: Kind::Stair,
        load_kg: 4.5,
        seed: 1,
        freq_rad_s: 1.0,
        effects: effects.iter().map(|e| e.to_string()).collect(),
    };
    let default = spec(&[]).run().unwrap();
    let zeroed = spec(&["creep=0", "ringing=0"]).run().unwrap();
    assert_traces_equal(
        "creep and ringing",
        &default,
        &Trace {
            source: default.source.clone(),
            ..zeroed
        },
    );
}

#[test]
fn runs_are_deterministic_given_the_seed() {
    let config = TwinConfig::default();
    let a = run(&config, 4.5, 11, &short_stair());
    assert_eq!(a, run(&config, 4.5, 11, &short_stair()));
    assert_ne!(a, run(&config, 4.5, 12, &short_stair()));
}

#[test]
fn linear_identification_of_the_stair_misses_the_hysteresis() {
    let spec = RunSpec {
        kind: Kind::Stair,
        load_kg: 4.5,
        seed: 1,
        freq_rad_s: 1.0,
        effects: vec![],
    };
    let id = identify(&spec.run().unwrap(), ArxOrders::default()).unwrap();
    let a = id.arx.a[0];
    assert!(a > 0.85 && a < 0.995, "first-order pole {a}");
    assert!(
        id.validation_fit_percent > 50.0 && id.validation_fit_percent < 90.0,
        "validation fit {} %",
        id.validation_fit_percent
    );
}

#[test]
fn shipped_stair_regenerates_byte_for_byte() {
    let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv");
    let want = std::fs::read(shipped).expect("data/stair_4.5kg.csv is shipped");
    let spec = RunSpec {
        kind: Kind::Stair,
        load_kg: 4.5,
        seed: 1,
        freq_rad_s: 1.0,
        effects: vec![],
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("stair.csv");
    spec.write_csv(&path, &spec.run().unwrap()).unwrap();
    let got = std::fs::read(&path).unwrap();
    assert!(
        got == want,
        "regenerated stair differs from {shipped}; see data/README.md"
    );
}

/// `twin --out -` writes the recording a file would get to standard
/// output (here the shipped stair, byte for byte) and its summary line to
/// standard error.
#[test]
fn the_twin_writes_its_recording_to_standard_output_for_a_dash() {
    let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_mckibben"))
        .args(["twin", "--experiment", "stair", "--out", "-"])
        .output()
        .expect("run mckibben");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.stdout == std::fs::read(shipped).unwrap(),
        "standard output differs from {shipped}"
    );
    let summary = String::from_utf8_lossy(&out.stderr);
    assert!(
        summary.starts_with("standard output: 4000 samples"),
        "{summary}"
    );
}

/// A recording and its figure are written both or neither: a `--plot`
/// that cannot be written leaves no CSV behind.
#[test]
fn the_twin_writes_its_recording_and_figure_both_or_neither() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("a_folder")).unwrap();
    let twin = |plot: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_mckibben"))
            .args(["twin", "--out", "run.csv", "--plot", plot])
            .current_dir(dir.path())
            .output()
            .expect("run mckibben")
    };
    let out = twin("a_folder");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("--plot a_folder") && err.contains("is a folder"),
        "{err}"
    );
    assert!(
        !dir.path().join("run.csv").exists(),
        "a CSV without its figure"
    );
    assert!(twin("run.svg").status.success());
    assert!(dir.path().join("run.csv").is_file() && dir.path().join("run.svg").is_file());
}

#[test]
fn sine_run_tracks_the_reference_with_the_thesis_pi() {
    let spec = RunSpec {
        kind: Kind::Sine,
        load_kg: 4.5,
        seed: 1,
        freq_rad_s: 1.0,
        effects: vec![],
    };
    let tr = spec.run().unwrap();
    let r = tr.column("reference").unwrap();
    assert!((r[0] - 30.0).abs() < 1e-12);
    let n = tr.len();
    let rms = ((n / 2..n)
        .map(|k| (r[k] - tr.output[k]).powi(2))
        .sum::<f64>()
        / (n - n / 2) as f64)
        .sqrt();
    assert!(rms < 2.0, "rms tracking error {rms} mm at 1 rad/s");
}

#[test]
fn cli_lists_effects_and_rejects_unknown_ones() {
    let exe = env!("CARGO_BIN_EXE_mckibben");
    let help = std::process::Command::new(exe)
        .args(["twin", "--help"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&help.stdout);
    for name in EFFECT_NAMES {
        assert!(text.contains(name), "--help does not list effect {name}");
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.csv");
    let bad = std::process::Command::new(exe)
        .args(["twin", "--effect", "frcition=0", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("frcition") && err.contains("friction"),
        "{err}"
    );
    assert!(!out.exists());
    let heavy = std::process::Command::new(exe)
        .args(["twin", "--load", "40", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!heavy.status.success());
    assert!(String::from_utf8_lossy(&heavy.stderr).contains("--load 40"));
    assert!(!out.exists());
}

/// A sine at or above Nyquist's frequency would be recorded as a slower
/// sine: the twin refuses it and names the limit, and runs just below it.
#[test]
fn a_sine_above_nyquist_is_refused_with_its_limit() {
    let dt = TwinConfig::default().sample_time_s;
    let nyquist = std::f64::consts::PI / dt;
    let sine = |freq_rad_s: f64| RunSpec {
        kind: Kind::Sine,
        load_kg: 4.5,
        seed: 1,
        freq_rad_s,
        effects: Vec::new(),
    };
    for freq in [nyquist, 2.0 * nyquist, 1e9] {
        let err = sine(freq).run().unwrap_err().to_string();
        assert!(err.contains(&format!("{nyquist:.1} rad/s")), "{err}");
    }
    assert!(sine(0.99 * nyquist).run().is_ok());
}

/// The command of data/README.md, through the binary, gives the shipped bytes.
#[test]
fn cli_regenerates_the_shipped_stair() {
    let exe = env!("CARGO_BIN_EXE_mckibben");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("stair.csv");
    let status = std::process::Command::new(exe)
        .args([
            "twin",
            "--experiment",
            "stair",
            "--load",
            "4.5",
            "--seed",
            "1",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(status.status.success());
    let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv");
    assert!(std::fs::read(&out).unwrap() == std::fs::read(shipped).unwrap());
    // --freq sets the sine alone: on the stair it is an error, not ignored.
    let refused = std::process::Command::new(exe)
        .args(["twin", "--experiment", "stair", "--freq", "3", "--out"])
        .arg(dir.path().join("stair3.csv"))
        .output()
        .unwrap();
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--experiment sine"));
}
