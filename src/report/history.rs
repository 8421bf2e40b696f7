//! The figures of a run's history: the thesis' parameter trends (figures
//! 9–24) and a convergence curve.

use super::plot::{Figure, Panel, Series};
use crate::optim::{GenerationRecord, History};

/// Best-so-far parameters over the fit, one panel per free parameter (the
/// thesis' figures 9–11, 13, 15, 17–19, 22, 24). `free` lists the canonical
/// indices that were searched.
pub fn trends_figure(history: &History, title: &str, free: &[usize]) -> Figure {
    let mut fig = Figure::new(title);
    fig.panel_height = 200;
    for &i in free {
        let (x, y): (Vec<f64>, Vec<f64>) = history
            .records
            .iter()
            .filter_map(|r| r.best_params.get(i).map(|&v| (r.generation as f64, v)))
            .unzip();
        let name = history.names.get(i).map_or("?", String::as_str);
        fig = fig.with(Panel::new(name, "generation", name).with(Series::line("stage best", x, y)));
    }
    fig
}

/// Each stage's best, the best free-run SSE, the generation best and the
/// population mean over the fit, log scale (the global stage's costs are its
/// prediction error, the others' the free-run SSE).
pub fn convergence_figure(history: &History, title: &str) -> Figure {
    let g: Vec<f64> = history
        .records
        .iter()
        .map(|r| r.generation as f64)
        .collect();
    let col = |f: fn(&GenerationRecord) -> Option<f64>| -> Vec<f64> {
        history
            .records
            .iter()
            .map(|r| f(r).unwrap_or(f64::NAN))
            .collect()
    };
    Figure::new(title).with(
        Panel::new(
            "convergence (the global stage's costs are its prediction error, the others' and \
             the best free run's the free-run SSE)",
            "generation",
            "cost on the estimation half",
        )
        .with(Series::line(
            "best free run",
            g.clone(),
            col(|r| r.best_sse),
        ))
        .with(Series::line("stage best", g.clone(), col(|r| r.stage_best)))
        .with(Series::line(
            "generation best",
            g.clone(),
            col(|r| r.generation_best_sse),
        ))
        .with(Series::line("population mean", g, col(|r| r.mean_sse)))
        .log_y(),
    )
}
