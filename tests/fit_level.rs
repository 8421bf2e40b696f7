//! A constant added to a column (an encoder's counts, a position measured
//! from the frame, a pressure gauge's atmosphere) changes nothing in a
//! classic fit: the fit works in deviations from the estimation means, and
//! every box is sized from how far the data move, never from their distance
//! to zero. Checked on the search box itself and on a short fit.

use mckibben::data::Trace;
use mckibben::eval::cpu::CpuEvaluator;
use mckibben::fit::objective::staged_plan;
use mckibben::fit::problem::FitProblem;
use mckibben::fit::run::run_fit;
use mckibben::fit::synthetic::Synthetic;
use mckibben::model::{Family, Flow, SearchSpace};
use mckibben::optim::Algorithm;
use mckibben::optim::engine::StopRules;

fn shifted(trace: &Trace, input: f64, output: f64) -> Trace {
    Trace {
        input: trace.input.iter().map(|u| u + input).collect(),
        output: trace.output.iter().map(|y| y + output).collect(),
        ..trace.clone()
    }
}

fn close(a: f64, b: f64, tolerance: f64) -> bool {
    (a - b).abs() <= tolerance * a.abs().max(b.abs()).max(1e-12)
}

fn assert_same_box(a: &SearchSpace, b: &SearchSpace, what: &str) {
    for (i, name) in a.names().iter().enumerate() {
        assert!(
            close(a.lower[i], b.lower[i], 1e-9) && close(a.upper[i], b.upper[i], 1e-9),
            "{what}: `{name}` spans [{}, {}] instead of [{}, {}]",
            b.lower[i],
            b.upper[i],
            a.lower[i],
            a.upper[i]
        );
    }
}

fn fit_problem(trace: &Trace) -> FitProblem {
    FitProblem::new(trace, Family::Classic, Flow::Joint, None, false).unwrap()
}

#[test]
fn a_constant_level_leaves_the_fit_and_diagnosis_boxes_where_they_were() {
    let s = Synthetic::new(Family::Classic, 800, 0.05, 4);
    let base = fit_problem(&s.trace);
    // Levels far beyond the output's swing (about 30) and the input's
    // (about 0.4): the box of the intercept used to grow with them.
    for (input, output) in [(0.0, 100.0), (0.0, 1000.0), (1.0, 0.0), (-5.0, -250.0)] {
        let other = fit_problem(&shifted(&s.trace, input, output));
        let what = format!("input +{input}, output +{output}");
        assert_same_box(&base.space, &other.space, &what);
        let prior = other.records.prior;
        let thesis_box = |p| SearchSpace::from_prior(Family::Classic, None, p, Flow::Joint, false);
        assert_same_box(
            &thesis_box(base.records.prior),
            &thesis_box(prior),
            &format!("{what} (the diagnosis' box)"),
        );
    }
}

#[test]
fn a_constant_level_gives_the_same_classic_fit() {
    let s = Synthetic::new(Family::Classic, 800, 0.05, 4);
    let fit = |trace: &Trace| {
        let problem = fit_problem(trace);
        let mut plan = staged_plan(&problem, Algorithm::De.staged_settings(60), 60, 30);
        if let Some(polish) = plan.polish.as_mut() {
            polish.iterations = 6;
        }
        let (_, outcome) = run_fit(
            &problem,
            plan,
            2,
            StopRules::default(),
            &mut CpuEvaluator::new(),
        )
        .unwrap();
        outcome
    };
    let base = fit(&s.trace);
    let other = fit(&shifted(&s.trace, 0.5, 500.0));
    assert!(
        close(base.sse, other.sse, 1e-6),
        "estimation SSE {} with the level against {} without",
        other.sse,
        base.sse
    );
    for (i, (a, b)) in base.params.iter().zip(&other.params).enumerate() {
        assert!(close(*a, *b, 1e-6), "parameter {i}: {b} against {a}");
    }
}
