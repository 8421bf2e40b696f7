//! The controller's model identified on the rig twin (never its internals)
//! has the twin's hysteresis loop, and the MPC built on it beats the thesis'
//! PI at 3 rad/s within the valve and slew limits. Short episodes.

use mckibben::control::sweep::{self, Ingredients, Kind, RunSpec, Shape};
use mckibben::control::{MpcSettings, ValveLimits};
use mckibben::twin::TwinConfig;

#[test]
fn model_has_the_twins_loop_and_the_mpc_beats_the_thesis_pi() {
    let config = TwinConfig::default();
    let horizon = MpcSettings::default().horizon;
    let (record, validation) = sweep::twin_records(&config, 4.5, 1);
    let design =
        sweep::design_from(&record, &validation, horizon, Some((&config, 4.5, 1))).unwrap();
    let l = design.loop_check.as_ref().unwrap();
    eprintln!(
        "loop: twin {:?}, model {:?}, rms {}",
        l.plant, l.model, l.rmse_mm
    );
    // A model without hysteresis encloses no loop; this one must have the
    // twin's within a fifth, in area and in width.
    assert!(l.plant.width_mm > 3.0, "the twin's loop: {:?}", l.plant);
    for (m, p) in [
        (l.model.area_mpa_mm, l.plant.area_mpa_mm),
        (l.model.width_mm, l.plant.width_mm),
    ] {
        assert!((m / p - 1.0).abs() < 0.2, "model {m} vs twin {p}");
    }
    // Predictions from the valve stay within half a millimetre 0.2 s ahead.
    assert!(
        design.prediction.end_to_end_rmse_mm < 0.5,
        "{:?}",
        design.prediction
    );

    let ing = Ingredients {
        model: Some(design.model),
        gains: None,
        mpc: MpcSettings::default(),
        limits: ValveLimits::default(),
    };
    let shape = Shape {
        warmup_s: 3.0,
        duration_s: 6.0,
        steady_from_s: 2.0,
        ..Shape::thesis()
    };
    for load in [4.5, 7.0] {
        let run = |kind| {
            let spec = RunSpec {
                kind,
                freq_rad_s: 3.0,
                load_kg: load,
                hysteresis_scale: 1.0,
            };
            sweep::run_on_twin(&spec, &ing, &config, 2, &shape).unwrap()
        };
        let (pi, mpc) = (run(Kind::Pi), run(Kind::Mpc));
        let (p, m) = (&pi.result.metrics, &mpc.result.metrics);
        eprintln!(
            "{load} kg: pi {} mm, mpc {} mm",
            p.rms_error_mm, m.rms_error_mm
        );
        assert!(!p.diverged && !m.diverged);
        assert_eq!(p.constraint_violations + m.constraint_violations, 0);
        assert_eq!(mpc.stats.unwrap().solver_failures, 0);
        assert!(
            m.rms_error_mm < 0.2 * p.rms_error_mm,
            "{load} kg: mpc {} mm vs pi {} mm",
            m.rms_error_mm,
            p.rms_error_mm
        );
    }
}
