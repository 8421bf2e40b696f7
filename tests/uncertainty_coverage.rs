//! How far `fit`'s standard errors can be trusted, measured on the generated
//! cases of `fit::cases` (docs/RESULTS.md, "Standard errors"): each case of
//! both matrices fitted with `fit`'s defaults (seed 1), and for every
//! parameter with a linearized error (`fit::uncertainty::linearized_errors`,
//! what `fit` reports for the classic family and withholds for the
//! generalized one), its deviation from the truth in errors,
//! `z = (fitted − truth) / error`. Where the fit reached the truth's basin
//! and the noise is white, as here, `|z| ≤ 2` should hold for about 95 %
//! of the parameters. A measurement, not a test: a minute or two on 2
//! cores.
//!
//! ```sh
//! cargo test --release --test uncertainty_coverage -- --ignored --nocapture
//! ```

use mckibben::eval::cpu::CpuEvaluator;
use mckibben::fit::cases::Case;
use mckibben::fit::objective::{GENERATIONS, POPULATION, staged_plan};
use mckibben::fit::run::FitRun;
use mckibben::fit::sweep::{MATRIX_SEED, cases};
use mckibben::fit::uncertainty::linearized_errors;
use mckibben::model::Family;
use mckibben::optim::Algorithm;
use mckibben::optim::engine::{Engine, StopRules};

#[test]
#[ignore = "measurement: a minute or two on 2 cores; results in docs/RESULTS.md"]
fn standard_error_coverage() {
    let mut cpu = CpuEvaluator::new();
    println!(
        "| family | cases that pass | parameters with a finite error | infinite | |z| ≤ 1 | |z| ≤ 2 | |z| ≤ 3 | largest |z| |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    for family in [Family::Classic, Family::Generalized] {
        let mut z: Vec<f64> = Vec::new();
        let (mut passing, mut all, mut unbounded) = (0, 0, 0);
        for case in cases(family, MATRIX_SEED, None) {
            let generated = Case::generate(case.spec);
            let problem = generated.problem();
            let settings = Algorithm::De.staged_settings(POPULATION);
            let plan = staged_plan(&problem, settings, POPULATION, GENERATIONS);
            let engine =
                Engine::new(plan, problem.engine_space(), 1, StopRules::default()).unwrap();
            let mut fit = FitRun::of(problem, engine).unwrap();
            let (outcome, _) = fit.run(&mut cpu, &mut [], None, None).unwrap();
            all += 1;
            // Only a fit in the truth's basin estimates the truth.
            if !generated.judge(&outcome.params, &mut cpu).unwrap().passes {
                continue;
            }
            passing += 1;
            let errors = linearized_errors(&fit.problem, &outcome.params);
            let own: Vec<f64> = outcome
                .params
                .iter()
                .zip(&generated.truth)
                .zip(&errors)
                .filter_map(|((p, t), e)| e.map(|e| (p - t) / e))
                .collect();
            // An infinite error (a direction the record does not determine)
            // gives z = 0: counted apart.
            eprintln!("{}: {own:.2?}", generated.name());
            unbounded += own.iter().filter(|v| *v == &0.0).count();
            z.extend(own.into_iter().filter(|v| *v != 0.0));
        }
        let share = |k: f64| {
            let within = z.iter().filter(|v| v.abs() <= k).count();
            format!("{:.0} %", 100.0 * within as f64 / z.len() as f64)
        };
        let largest = z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        println!(
            "| {family} | {passing}/{all} | {} | {unbounded} | {} | {} | {} | {largest:.1} |",
            z.len(),
            share(1.0),
            share(2.0),
            share(3.0)
        );
    }
}
