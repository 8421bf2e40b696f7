//! Closed loops on the rig twin, short episodes: the MPC (model identified
//! from a twin multisine, never the twin's internals) against the thesis'
//! PI at 3 rad/s, within the valve and slew limits.

use mckibben::control::design::{self, OPERATING_BAND_V};
use mckibben::control::{Episode, Mpc, MpcSettings, Pi, PiGains, ValveLimits, run_episode};
use mckibben::data::signals::Multisine;
use mckibben::twin::{self, Rig, TwinConfig};

#[test]
fn mpc_beats_thesis_pi_on_the_twin_at_3_rad_s() {
    let config = TwinConfig::default();
    let record = twin::run(
        &config,
        4.5,
        1,
        &twin::Experiment::Multisine(Multisine {
            duration_s: 60.0,
            ..Multisine::default()
        }),
    );
    let settings = MpcSettings::default();
    let (model, _) = design::identify(&record, OPERATING_BAND_V, settings.horizon).unwrap();
    let ep = Episode::short(3.0, 4.0, 8.0, 4.0);
    for load in [4.5, 7.0] {
        let mut rig = Rig::new(&config, load, 2);
        let mut pi = Pi::new(PiGains::default(), ValveLimits::default(), rig.dt(), "pi");
        let pi_run = run_episode(&mut rig, &mut pi, &ep);
        let mut rig = Rig::new(&config, load, 2);
        let mut mpc = Mpc::new(&model, settings, ValveLimits::default(), "mpc");
        let mpc_run = run_episode(&mut rig, &mut mpc, &ep);
        let (p, m) = (&pi_run.metrics, &mpc_run.metrics);
        eprintln!(
            "{load} kg: pi {} mm, mpc {} mm",
            p.rms_error_mm, m.rms_error_mm
        );
        assert!(!p.diverged && !m.diverged);
        assert_eq!(p.constraint_violations + m.constraint_violations, 0);
        assert_eq!(mpc.solver_failures, 0);
        assert!(
            m.rms_error_mm < 0.6 * p.rms_error_mm,
            "{load} kg: mpc {} mm vs pi {} mm",
            m.rms_error_mm,
            p.rms_error_mm
        );
    }
}
