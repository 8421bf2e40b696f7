//! A constant level added to a column (an encoder's counts, a position
//! measured from the frame, a gauge that reads the atmosphere) moves what
//! a fit sees only up to `model::bounds::LEVEL_REACH` times the column's span:
//! the fit works in deviations from the estimation means, and the
//! intercept's box, sized from the largest absolute values, stops growing
//! there. A record that starts near its zero keeps its box exactly.

use mckibben::data::{Trace, range};
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

fn largest_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

#[test]
fn a_level_far_past_the_swing_leaves_the_box_where_any_such_level_puts_it() {
    let s = Synthetic::new(Family::Classic, 800, 0.05, 4);
    let est = 0..400;
    // Near its zero, a record keeps the box of its largest absolute values.
    let near = fit_problem(&s.trace).records.prior;
    assert_eq!(
        near.max_abs_output,
        largest_abs(&s.trace.output[est.clone()])
    );
    assert_eq!(near.max_abs_input, largest_abs(&s.trace.input[est.clone()]));
    // Levels of fifty spans and more on both columns (the output swings
    // about 30, the input about 0.4): one box, the fit's and the
    // diagnosis' alike.
    let swing = (
        range(&s.trace.input[est.clone()]),
        range(&s.trace.output[est.clone()]),
    );
    let far = fit_problem(&shifted(&s.trace, 50.0 * swing.0, 50.0 * swing.1));
    for (input, output) in [(60.0, 1e4), (-50.0, -1e6), (1e3, 2e5)] {
        let other = fit_problem(&shifted(&s.trace, input, output));
        let what = format!("input +{input}, output +{output}");
        assert_same_box(&far.space, &other.space, &what);
        let diagnosis_box =
            |p| SearchSpace::from_prior(Family::Classic, None, p, Flow::Joint, false);
        assert_same_box(
            &diagnosis_box(far.records.prior),
            &diagnosis_box(other.records.prior),
            &format!("{what} (the diagnosis' box)"),
        );
    }
}

#[test]
fn a_level_far_past_the_swing_fits_as_well_as_none() {
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
    // A level's last bits differ from another's, and so the searches'
    // paths, a little. Without the cap the output 5000 above its swing of
    // about 30 ended at an SSE 10⁵ times the others'.
    let near = fit(&s.trace);
    for (input, output) in [(0.0, 5e3), (40.0, 5e4)] {
        let far = fit(&shifted(&s.trace, input, output));
        assert!(
            close(near.sse, far.sse, 1e-4),
            "estimation SSE {} with input +{input}, output +{output} against {} without",
            far.sse,
            near.sse
        );
    }
}
