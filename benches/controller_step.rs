//! Time of one controller step, over every step of the thesis' episodes on
//! the twin (1, 2, 3 rad/s × 4.5, 7 kg: 18 000 steps per controller):
//! p50, p99 and the maximum of the thread's CPU time and of the wall clock.
//! The MPC's bar is a worst case of 1 ms of CPU per step. `ff-pid+chain`
//! and `mpc+chain` run with an effect chain of the most states a prediction
//! carries (`control::chain::MAX_EFFECT_STATES`: seven slow states and a
//! ringing mode, small enough to leave the runs as they were).
//!
//! `cargo bench --bench controller_step` (plain `main`: criterion's
//! statistics are of means, this is about the tail).

use mckibben::control::chain::{ControlChain, Drive, Lag, Ring};
use mckibben::control::sweep::{self, Ingredients, Kind, RunSpec, Shape};
use mckibben::control::{MpcSettings, PiGains, ValveLimits};
use mckibben::twin::TwinConfig;

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
}

fn main() {
    let config = TwinConfig::default();
    let horizon = MpcSettings::default().horizon;
    let (record, validation) = sweep::twin_records(&config, 4.5, 1);
    let design = sweep::design_from(&record, &validation, horizon, None).expect("design");
    let ing = Ingredients {
        model: Some(design.model),
        // The tuned gains of docs/CONTROL.md; the step time does not depend on them.
        gains: Some(PiGains {
            kp: 2.2164,
            ki: 65.528,
            kd: 0.0219,
        }),
        mpc: MpcSettings::default(),
        limits: ValveLimits::default(),
    };
    println!(
        "{:<12} {:>7} {:>9} {:>9} {:>9} {:>10} {:>10} {:>10}",
        "", "steps", "cpu p50", "cpu p99", "cpu max", "wall p50", "wall p99", "wall max"
    );
    let mut chained = ing.clone();
    if let Some(m) = chained.model.as_mut() {
        let lag = |rho: f64, drive| Lag {
            rho,
            weight: (1.0 - rho) * 0.5,
            drive,
            start: 0.0,
        };
        let (a1, a2) = (1.8, 0.95);
        m.chain = Some(ControlChain {
            lags: [0.9, 0.95, 0.99, 0.995, 0.999, 0.9995]
                .iter()
                .map(|&r| lag(r, Drive::Input))
                .chain([lag(0.99, Drive::Output)])
                .collect(),
            ring: Some(Ring {
                a1,
                a2,
                g: 1.0,
                gains: Ring::observer_gains(a1, a2),
            }),
            deadzone_mpa: None,
            end_stop: None,
        });
    }
    for (kind, with_chain) in [
        (Kind::Pi, false),
        (Kind::FfPid, false),
        (Kind::Mpc, false),
        (Kind::FfPid, true),
        (Kind::Mpc, true),
    ] {
        let ing = if with_chain { &chained } else { &ing };
        let (mut cpu, mut wall) = (Vec::new(), Vec::new());
        for load in [4.5, 7.0] {
            for freq in [1.0, 2.0, 3.0] {
                let spec = RunSpec {
                    kind,
                    freq_rad_s: freq,
                    load_kg: load,
                    hysteresis_scale: 1.0,
                };
                let run = sweep::run_on_twin(&spec, ing, &config, 1, &Shape::thesis()).unwrap();
                cpu.extend(&run.result.step_cpu_us);
                wall.extend(&run.result.step_wall_us);
            }
        }
        cpu.sort_by(f64::total_cmp);
        wall.sort_by(f64::total_cmp);
        println!(
            "{:<12} {:>7} {:>9.1} {:>9.1} {:>9.1} {:>10.1} {:>10.1} {:>10.1}   (µs)",
            format!("{}{}", kind.label(), if with_chain { "+chain" } else { "" }),
            cpu.len(),
            percentile(&cpu, 0.5),
            percentile(&cpu, 0.99),
            cpu[cpu.len() - 1],
            percentile(&wall, 0.5),
            percentile(&wall, 0.99),
            wall[wall.len() - 1]
        );
    }
}
