//! The figures of `mckibben control`: per run, the thesis' figures 27–32
//! (reference and displacement, valve command, error); per design, the
//! model's prediction error and its loop against the twin's.

use std::path::Path;

use anyhow::Context as _;

use super::closed_loop::EpisodeResult;
use super::reference::Waveform;
use super::sweep::{Design, Run};
use crate::report::{Figure, Panel, Series};

/// File stem of a run: `control_<controller>_<load>kg_<ω>rad` (`rig` for
/// the load of an external plant), `_steps` after it for a steps reference.
pub fn stem(run: &Run, waveform: Waveform) -> String {
    let name = run
        .result
        .controller
        .replace([' ', '(', ')', '×'], "")
        .replace('-', "_");
    let load = if run.spec.load_kg.is_nan() {
        "rig".to_string()
    } else {
        format!("{}kg", run.spec.load_kg)
    };
    // A steps run at ω is another run than the sine at ω: its own name, so
    // that one folder holds both.
    let reference = match waveform {
        Waveform::Sine => "",
        Waveform::Steps => "_steps",
    };
    format!(
        "control_{name}_{load}_{}rad{reference}",
        run.spec.freq_rad_s
    )
}

/// Reference and displacement, valve command, tracking error.
pub fn run_figure(run: &Run) -> Figure {
    let r: &EpisodeResult = &run.result;
    let err: Vec<f64> = r
        .reference
        .iter()
        .zip(&r.displacement)
        .map(|(a, b)| a - b)
        .collect();
    let load = if run.spec.load_kg.is_nan() {
        "rig".to_string()
    } else {
        format!("{} kg", run.spec.load_kg)
    };
    Figure::new(format!(
        "{}: {load}, {} rad/s",
        r.controller, run.spec.freq_rad_s
    ))
    .with(
        Panel::new("Reference and displacement", "t (s)", "displacement (mm)")
            .with(Series::line("reference", r.t.clone(), r.reference.clone()))
            .with(Series::line(
                "displacement",
                r.t.clone(),
                r.displacement.clone(),
            )),
    )
    .with(
        Panel::new("Input valve command", "t (s)", "u (V)").with(Series::line(
            "valve_in",
            r.t.clone(),
            r.valve.clone(),
        )),
    )
    .with(
        Panel::new("Tracking error r − y", "t (s)", "error (mm)").with(Series::line(
            "error",
            r.t.clone(),
            err,
        )),
    )
}

/// The model's prediction error by steps ahead, and its loop on the slow
/// triangle against the twin's.
pub fn design_figure(d: &Design) -> Figure {
    let steps: Vec<f64> = (1..=d.prediction.horizon).map(|j| j as f64).collect();
    let mut fig = Figure::new(format!("The controller's model ({})", d.source)).with(
        Panel::new(
            "Prediction error on the validation record",
            "samples ahead",
            "RMS error (mm)",
        )
        .with(Series::line(
            "pressure measured",
            steps.clone(),
            d.prediction.by_step_mm.clone(),
        ))
        .with(Series::line(
            "from the valve voltage",
            steps,
            d.prediction.end_to_end_by_step_mm.clone(),
        )),
    );
    if let Some(l) = &d.loop_check {
        fig = fig.with(
            Panel::new(
                "Loop on a slow valve triangle",
                "pressure (MPa)",
                "displacement (mm)",
            )
            .with(Series::line("twin", l.pressure.clone(), l.plant_mm.clone()))
            .with(Series::line(
                "model",
                l.pressure.clone(),
                l.model_mm.clone(),
            )),
        );
    }
    fig
}

/// The design's figure's file name.
pub const DESIGN_FIGURE: &str = "control_model.svg";

/// Every run's figure and the design's ([`DESIGN_FIGURE`]) as SVG files
/// in `dir` (`--plot`).
pub fn save(
    dir: &Path,
    runs: &[Run],
    waveform: Waveform,
    design: Option<&Design>,
) -> anyhow::Result<()> {
    crate::data::create_dir_all(dir)
        .with_context(|| format!("creating --plot {}", dir.display()))?;
    let mut figs: Vec<(String, Figure)> = runs
        .iter()
        .map(|r| (format!("{}.svg", stem(r, waveform)), run_figure(r)))
        .collect();
    if let Some(d) = design {
        figs.push((DESIGN_FIGURE.into(), design_figure(d)));
    }
    for (name, fig) in figs {
        let path = dir.join(name);
        fig.save(&path)
            .with_context(|| format!("writing --plot {}", path.display()))?;
    }
    Ok(())
}
