//! The effect chain of a model in the controllers' prediction
//! (`control::chain`): its linear form against the step of record, the
//! MPC's prediction and sensitivities against the chain's open-loop
//! simulation, a "how used" line for every realisation of the catalogue,
//! and a model without effects at today's numbers. Fast (seconds).

use mckibben::control::chain::{ControlChain, EffectUse};
use mckibben::control::feedforward::FeedforwardPid;
use mckibben::control::model::{Predictor, State};
use mckibben::control::{
    ControlModel, Controller, Measurement, Mpc, MpcSettings, Pi, PiGains, Plant, StandIn,
    ValveLimits, ValveModel,
};
use mckibben::model::effects::{Context, Effect, effect_box};
use mckibben::model::file::Chain;
use mckibben::model::{Family, FittedBaseline, Model};

const BIN: &str = env!("CARGO_BIN_EXE_mckibben");

/// A classic baseline about 0.25 MPa and 30 mm, `x0 = 0`.
fn base() -> FittedBaseline {
    FittedBaseline {
        family: Family::Classic,
        // A, alpha, beta, gamma, n, a, b, c, x0
        params: vec![1.0, 0.9, 0.4, 0.3, 1.0, 0.97, 3.0, 0.01, 0.0],
        input_mean: 0.25,
        output_mean: 30.0,
        dt: 0.01,
        input_name: "pressure".into(),
        output_name: "displacement".into(),
    }
}

fn context() -> Context {
    Context {
        u_mean: 0.25,
        y_mean: 30.0,
        dt: 0.01,
        branch_tol: 0.008,
        drives_up: true,
        input_min: 0.05,
        input_max: 0.45,
        output_min: 10.0,
        output_max: 50.0,
        max_step: 0.05,
    }
}

/// `base()` with `effects` at `params` (each creep starting at 0).
fn with_effects(effects: &[(Effect, Vec<f64>)]) -> Model {
    Model {
        base: base(),
        chain: Some(Chain {
            effects: effects.iter().map(|(e, _)| *e).collect(),
            params: effects.iter().flat_map(|(_, p)| p.clone()).collect(),
            context: context(),
            datasets: 1,
        }),
    }
}

/// Every linear realisation at once, with a dead zone before them.
fn linear_chain() -> Model {
    with_effects(&[
        (Effect::Deadzone, vec![0.04]),
        (Effect::Creep, vec![0.99, 8.0, 0.0]),
        (Effect::TwoPoleCreep, vec![0.95, 0.998, 12.0, 0.4, 0.0]),
        (Effect::OutputCreep, vec![0.985, 0.1, 0.0]),
        (Effect::LogCreep, vec![0.9995, 2.0, 0.0]),
        (Effect::Ringing, vec![1.6, 0.85, 40.0]),
    ])
}

fn valve() -> ValveModel {
    ValveModel {
        pole: 0.9,
        map: (0..11).map(|i| 0.005 * i as f64).collect(),
    }
}

fn control_model(m: &Model) -> ControlModel {
    ControlModel {
        displacement: m.base.clone(),
        curvature: 0.0,
        valve: valve(),
        chain: ControlChain::of(m).0,
        rest_start: false,
    }
}

/// A pressure record (MPa) with steps, a ramp and noise-like wiggles.
fn pressure(n: usize) -> Vec<f64> {
    let mut state = 12345u64;
    let mut rand = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut level = 0.2;
    (0..n)
        .map(|k| {
            if k % 60 == 0 {
                level = 0.02 + 0.4 * rand();
            }
            level + 0.01 * (rand() - 0.5)
        })
        .collect()
}

/// The controllers' prediction driven by the measured pressure `p`, from
/// the step of record's start (`e = 0`, `w = 0`, `x = y0`).
fn predicted(m: &Model, p: &[f64], y0: f64) -> Vec<f64> {
    let pr = Predictor::new(&control_model(m)).unwrap();
    let mut s = State::new(p[0], y0 - pr.output_mean, 0.0);
    let mut out = vec![y0];
    for k in 0..p.len() - 1 {
        let input = State {
            p: p[k],
            p_prev: p[k.saturating_sub(1)],
            ..s
        };
        let x = pr.next_x(&input);
        s = pr.moved(&input, p[k], x, pr.hysteresis.step(s.w, x - s.x));
        out.push(pr.output(&s) + pr.output_mean);
    }
    out
}

#[test]
fn the_linear_form_of_creeps_and_ringing_matches_the_step_of_record() {
    let p = pressure(3000);
    for m in [
        linear_chain(),
        with_effects(&[(Effect::Ringing, vec![1.6, 0.85, 40.0])]),
        with_effects(&[(Effect::TwoPoleCreep, vec![0.95, 0.998, 12.0, 0.4, 0.0])]),
    ] {
        let reference = m.simulate_absolute(&p, 30.0).output;
        let ours = predicted(&m, &p, 30.0);
        let span = reference
            .iter()
            .fold(0.0f64, |a, &v| a.max((v - 30.0).abs()));
        assert!(span > 5.0, "the record moves the output ({span} mm)");
        let worst = reference
            .iter()
            .zip(&ours)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        // f32 (the step of record) against f64: within 1e-5 of the output's span.
        assert!(worst < 1e-5 * span, "{:?}: {worst} mm", m.effects());
    }
}

#[test]
fn the_mpcs_prediction_with_a_ringing_reproduces_the_chains_simulation() {
    let m = linear_chain();
    let cm = control_model(&m);
    let settings = MpcSettings::default();
    let n = settings.horizon;
    let mut mpc = Mpc::new(&cm, settings, ValveLimits::default(), "mpc").unwrap();
    let plan: Vec<f64> = (0..n)
        .map(|i| 5.0 + 3.0 * ((i as f64) * 0.9).sin())
        .collect();
    let p0 = 0.22;
    let s0 = State::new(p0, 0.0, 0.0);
    let (y, g) = mpc.rollout(s0, &plan).unwrap();
    // The same horizon as an open-loop simulation: the valve model's
    // pressures, then the chain's step of record on them.
    let vm = valve();
    let mut p = vec![p0];
    for j in 0..=n {
        let v = plan[j.min(n - 1)];
        p.push(vm.step(*p.last().unwrap(), v));
    }
    let sim = m.simulate_absolute(&p, 30.0).output;
    for j in 0..=n + 1 {
        assert!(
            (y[j] - sim[j]).abs() < 1e-4,
            "sample {j}: {} against {}",
            y[j],
            sim[j]
        );
    }
    // The sensitivities against finite differences of the prediction.
    let eps = 1e-6;
    for i in 0..n {
        let mut moved = plan.clone();
        moved[i] += eps;
        let (y2, _) = mpc.rollout(s0, &moved).unwrap();
        for j in 0..=n + 1 {
            let fd = (y2[j] - y[j]) / eps;
            let a = g[j * n + i];
            assert!(
                (fd - a).abs() < 1e-4 * (1.0 + a.abs()),
                "∂y({j})/∂V({i}): {a} against {fd}"
            );
        }
    }
}

/// The MPC and the feedforward PID run a few samples on a stand-in plant
/// with `m`'s chain; every command within the valve's range.
fn runs(m: &Model) {
    let cm = control_model(m);
    let limits = ValveLimits::default();
    let mut controllers: Vec<Box<dyn Controller>> = vec![
        Box::new(Mpc::new(&cm, MpcSettings::default(), limits, "mpc").unwrap()),
        Box::new(
            FeedforwardPid::new(
                Pi::new(PiGains::default(), limits, 0.01, "pid"),
                &cm,
                "ff-pid",
            )
            .unwrap(),
        ),
    ];
    for c in &mut controllers {
        let mut plant = StandIn::thesis_like(5.0);
        c.reset(5.0);
        let mut u = 5.0;
        for k in 0..60 {
            let m: Measurement = plant.step(u);
            let r: Vec<f64> = (k..k + 25)
                .map(|j| 30.0 + (j as f64 * 0.03).sin())
                .collect();
            u = c.command(m, &r);
            assert!(
                u.is_finite() && (0.0..=10.0).contains(&u),
                "{}: {u}",
                c.name()
            );
        }
    }
}

#[test]
fn every_realisation_of_the_catalogue_says_how_it_was_used() {
    let ctx = context();
    for effect in Effect::ALL {
        let neutral = effect_box(effect, &ctx, 1).neutral;
        let m = with_effects(&[(effect, neutral)]);
        let (_, uses) = ControlChain::of(&m);
        assert_eq!(uses.len(), 1, "{effect}");
        let EffectUse {
            effect: name,
            used,
            detail,
        } = &uses[0];
        assert_eq!(name, effect.name());
        assert!(
            ["states", "input-path", "constraint", "left-out"].contains(&used.as_str()),
            "{effect}: {used}"
        );
        assert!(!detail.is_empty() && uses[0].line().contains(effect.name()));
        runs(&m);
    }
    // What each is used as.
    let used = |e: Effect| {
        let neutral = effect_box(e, &ctx, 1).neutral;
        ControlChain::of(&with_effects(&[(e, neutral)])).1[0]
            .used
            .clone()
    };
    for e in [
        Effect::Creep,
        Effect::OutputCreep,
        Effect::TwoPoleCreep,
        Effect::LogCreep,
        Effect::Ringing,
    ] {
        assert_eq!(used(e), "states", "{e}");
    }
    assert_eq!(used(Effect::Deadzone), "input-path");
    for e in [Effect::Saturation, Effect::OutputClip, Effect::SoftStop] {
        assert_eq!(used(e), "constraint", "{e}");
    }
    // A state clip with a creep after it bounds x, not the output.
    let with_creep = |stop| {
        let m = with_effects(&[(stop, vec![34.0]), (Effect::Creep, vec![0.99, 8.0, 0.0])]);
        let (chain, uses) = ControlChain::of(&m);
        (chain.unwrap().end_stop, uses[0].used.clone())
    };
    assert_eq!(with_creep(Effect::Saturation), (None, "left-out".into()));
    assert_eq!(with_creep(Effect::SoftStop), (None, "left-out".into()));
    assert_eq!(
        with_creep(Effect::OutputClip),
        (Some((34.0, true)), "constraint".into())
    );
    assert_eq!(used(Effect::Delay), "left-out");
    // The whole catalogue in one chain: what does not fit is left out.
    let all: Vec<(Effect, Vec<f64>)> = Effect::ALL
        .iter()
        .map(|&e| (e, effect_box(e, &ctx, 1).neutral))
        .collect();
    let m = with_effects(&all);
    assert_eq!(ControlChain::of(&m).1.len(), Effect::ALL.len());
    runs(&m);
    runs(&linear_chain());
}

#[test]
fn the_feedforward_inverts_the_whole_chain() {
    // The inverse drives the model's output onto the reference: run the
    // model on the pressures the inverse asked for.
    let m = linear_chain();
    let cm = control_model(&m);
    let pr = Predictor::new(&cm).unwrap();
    let mut inverse = mckibben::control::feedforward::InverseModel::new(&cm).unwrap();
    let r: Vec<f64> = (0..400)
        .map(|k| 30.0 + 6.0 * (k as f64 * 0.02).sin())
        .collect();
    inverse.start(0.25, r[0], r[0]);
    let mut s = pr.at_start(0.25, r[0] - pr.output_mean);
    let mut worst = 0.0f64;
    for k in 0..r.len() - 3 {
        let (p, next) = inverse.pressure_and_state(&r[k..]).unwrap();
        let input = State { p, ..s };
        let x = pr.next_x(&input);
        s = pr.moved(&input, p, x, pr.hysteresis.step(s.w, x - s.x));
        worst = worst.max((pr.output(&s) + pr.output_mean - r[k + 1]).abs());
        assert!((next - (pr.output(&s) + pr.output_mean)).abs() < 1e-9);
    }
    assert!(worst < 1e-6, "{worst} mm");
}

/// `control` on the twin's defaults, a model without effects: the numbers
/// of the code before the chain (the commit before `control::chain`), bit
/// for bit.
#[test]
fn a_model_without_effects_gives_todays_numbers() {
    let out = std::process::Command::new(BIN)
        .args([
            "control",
            "--controller",
            "ff-pid,mpc",
            "--tuned-gains",
            "2.2164,65.528,0.0219",
            "--freq",
            "3",
            "--load",
            "4.5",
            "--warmup",
            "1",
            "--duration",
            "3",
            "--steady-from",
            "1",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let rms: Vec<f64> = v["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["rms_error_mm"].as_f64().unwrap())
        .collect();
    assert_eq!(rms, TODAY, "{rms:?}");
    assert_eq!(v["design"]["effects"], serde_json::json!([]));
}

/// `rms_error_mm` of ff-pid and mpc in the run above, from the binary
/// before the effect chain entered the controllers (commit e7c8139).
const TODAY: [f64; 2] = [0.07738166674381806, 0.10340391227022197];
