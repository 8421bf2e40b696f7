//! Gain tuning with the project's optimizers on short twin episodes: the
//! result is a pure function of the seed, and the reported cost is the cost
//! of the reported gains.

use mckibben::control::session::Interrupted;
use mckibben::control::tuning::{TuningEpisodes, pi_cost, tune_pi};
use mckibben::optim::stop::StopFlag;
use mckibben::twin::TwinConfig;

fn episodes() -> TuningEpisodes {
    TuningEpisodes {
        freqs_rad_s: vec![3.0],
        loads_kg: vec![4.5],
        warmup_s: 2.0,
        duration_s: 3.0,
        steady_from_s: 1.0,
        seed: 1,
    }
}

#[test]
fn tuning_is_deterministic_and_reports_its_own_cost() {
    let config = TwinConfig::default();
    let eps = episodes();
    let go = StopFlag::default();
    let a = tune_pi("pso", 6, 2, 9, &eps, &config, &go).unwrap();
    let b = tune_pi("pso", 6, 2, 9, &eps, &config, &go).unwrap();
    assert_eq!(a.gains, b.gains);
    assert_eq!(a.cost, b.cost);
    assert_eq!(a.evaluations, 12);
    assert_eq!(a.cost, pi_cost(a.gains, &eps, &config));
    assert!(a.best_per_generation.windows(2).all(|w| w[1] <= w[0]));
    assert!(tune_pi("nope", 6, 2, 9, &eps, &config, &go).is_err());
}

/// A raised stop ends the tuning with `Interrupted`, not with the gains
/// of a search cut short.
#[test]
fn a_raised_stop_ends_the_tuning_without_gains() {
    let stop = StopFlag::default();
    stop.raise();
    let err = tune_pi("pso", 6, 2, 9, &episodes(), &TwinConfig::default(), &stop).unwrap_err();
    assert!(err.is::<Interrupted>(), "{err}");
}
