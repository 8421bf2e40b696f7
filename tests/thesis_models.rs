//! The thesis' models on the thesis' identification input: ARX recovers the
//! linear model of eq. 12, and the Bouc-Wen presets (tables 1 and 2) are
//! finite and hysteretic.

use mckibben::data::Trace;
use mckibben::data::signals::Stair;
use mckibben::ident::arx::identify;
use mckibben::ident::{ArxOrders, loop_area};
use mckibben::model::presets::{THESIS_A, THESIS_B, thesis_params};
use mckibben::model::{Family, simulate};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const DT: f64 = 0.01;

/// The stair of appendix A.1.1 as a pressure (MPa): 0.05 MPa per volt.
fn stair_pressure() -> Vec<f64> {
    Stair::default()
        .generate(DT)
        .iter()
        .map(|v| 0.05 * v)
        .collect()
}

/// Eq. 12 in absolute units: l(k) = a·l(k−1) + b·p(k−1), plus output noise.
fn eq12_trace(noise_mm: f64, seed: u64) -> Trace {
    let p = stair_pressure();
    let mut l = vec![0.0; p.len()];
    for k in 1..p.len() {
        l[k] = THESIS_A * l[k - 1] + THESIS_B * p[k - 1];
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, noise_mm).unwrap();
    let measured = l
        .iter()
        .map(|v| {
            v + if noise_mm > 0.0 {
                noise.sample(&mut rng)
            } else {
                0.0
            }
        })
        .collect();
    Trace::uniform("eq12", DT, p, measured)
}

#[test]
fn arx_recovers_eq_12_from_the_stair() {
    let id = identify(&eq12_trace(0.0, 0), ArxOrders::default()).unwrap();
    assert!((id.arx.a[0] - THESIS_A).abs() < 1e-3, "a = {}", id.arx.a[0]);
    assert!((id.arx.b[0] - THESIS_B).abs() < 1e-3, "b = {}", id.arx.b[0]);
}

#[test]
fn arx_with_noise_stays_within_noise_sized_error() {
    // 0.05 mm of sensor noise on a response of about 300 mm.
    let id = identify(&eq12_trace(0.05, 7), ArxOrders::default()).unwrap();
    assert!((id.arx.a[0] - THESIS_A).abs() < 2e-3, "a = {}", id.arx.a[0]);
    assert!(
        (id.arx.b[0] - THESIS_B).abs() / THESIS_B < 2e-2,
        "b = {}",
        id.arx.b[0]
    );
    assert!(
        id.validation_fit_percent > 95.0,
        "fit {}",
        id.validation_fit_percent
    );
}

#[test]
fn thesis_presets_are_finite_and_hysteretic_on_the_stair() {
    let p = stair_pressure();
    let mean = p[..p.len() / 2].iter().sum::<f64>() / (p.len() / 2) as f64;
    let u: Vec<f32> = p.iter().map(|v| (v - mean) as f32).collect();
    for family in [Family::Classic, Family::Generalized] {
        let theta: Vec<f32> = thesis_params(family).iter().map(|&v| v as f32).collect();
        let sim = simulate(family, &theta, 0.0, &u, 0.0);
        assert_eq!(sim.diverged_at, None, "{family} diverged");
        assert!(sim.x.iter().all(|v| v.is_finite()));
        let x: Vec<f64> = sim.x.iter().map(|&v| v as f64).collect();
        let (lo, hi) = x
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
                (l.min(v), h.max(v))
            });
        let (plo, phi) = (0.0, 0.5);
        let area = loop_area(&p, &x);
        // A loop of at least 1 % of the bounding box: clearly not a line.
        assert!(
            area > 0.01 * (hi - lo) * (phi - plo),
            "{family}: loop area {area}, box {}",
            (hi - lo) * (phi - plo)
        );
    }
}

/// `static` draws eq. 7 and 9 for an inflated muscle: a pressure below
/// ambient, and each bad braid setting, is an error that names its flag.
#[test]
fn static_refuses_what_the_force_model_does_not_hold_for() {
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_mckibben"))
            .arg("static")
            .args(args)
            .output()
            .unwrap()
    };
    for (args, needle) in [
        (&["--pressures=0.2,-0.1"][..], "--pressures: -0.1"),
        (&["--turns", "0"][..], "--turns must be positive"),
        (
            &["--thread-length", "inf"][..],
            "--thread-length must be positive",
        ),
        (&["--thickness-mm=-1"][..], "--thickness-mm"),
        (
            &["--thickness-mm", "100"][..],
            "is no wider than its wall (--thickness-mm 100): the wall must be thinner",
        ),
        // A braid of 1e300 turns, behind a default wall: the braid named first.
        (
            &["--turns", "1e300"][..],
            "--thread-length 0.35 and --turns 1e300 give a muscle whose widest radius",
        ),
        (
            &["--points", "100000000"][..],
            "--points must be 2 to 100000",
        ),
    ] {
        let out = run(args);
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(out.stdout.is_empty(), "{args:?}: no table after an error");
    }
    assert!(
        run(&["--pressures", "0,0.3", "--points", "3"])
            .status
            .success()
    );
}
