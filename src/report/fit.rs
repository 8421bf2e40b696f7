//! The figures of a fit: the hysteresis loop and the time trace, fitted
//! over measured.

use super::plot::{Figure, Panel, Series};
use crate::data::Trace;
use crate::model::Model;

/// The hysteresis loop (displacement against pressure, figs 12, 14, 16,
/// 20, 21, 23) and the time trace of `model` on the whole `trace`, fitted
/// over measured, in absolute units (a free run from the first sample).
pub fn fit_figures(model: &Model, trace: &Trace, title: &str) -> (Figure, Figure) {
    let fitted = model.simulate_trace(trace);
    let (xin, xout) = (
        format!("{} (input)", trace.input_name),
        format!("{} (output)", trace.output_name),
    );
    let loop_fig = Figure::new(format!("{title}: hysteresis loop")).with(
        Panel::new("output against input", xin.clone(), xout.clone())
            .with(Series::points(
                "measured",
                trace.input.clone(),
                trace.output.clone(),
            ))
            .with(Series::line("fitted", trace.input.clone(), fitted.clone())),
    );
    let half = trace.t.get(trace.len() / 2).copied().unwrap_or(0.0);
    let trace_fig = Figure::new(format!(
        "{title}: free run (estimation before t = {half:.1} s, validation after)"
    ))
    .with(
        Panel::new("output", "t (s)", xout)
            .with(Series::line(
                "measured",
                trace.t.clone(),
                trace.output.clone(),
            ))
            .with(Series::line("fitted", trace.t.clone(), fitted)),
    )
    .with(Panel::new("input", "t (s)", xin).with(Series::line(
        "input",
        trace.t.clone(),
        trace.input.clone(),
    )));
    (loop_fig, trace_fig)
}
