//! The figures of a diagnosis (`diagnose --report DIR`).

use std::path::{Path, PathBuf};

use crate::diagnose::Diagnosis;
use crate::diagnose::locate::Share;
use crate::report::{Figure, Panel, Series};

/// The files [`write_figures`] writes, in its order, the spectrum's where
/// there is one (a command checks that none would replace a file it reads).
pub const FIGURES: [&str; 5] = [
    "diagnose_residual.svg",
    "diagnose_fit.svg",
    "diagnose_loop.svg",
    "diagnose_breakdown.svg",
    "diagnose_spectrum.svg",
];

/// Writes the figures into `dir`; returns their paths.
pub fn write_figures(d: &Diagnosis, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    crate::data::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create --report directory {}: {e}", dir.display()))?;
    let mut out = Vec::new();
    let mut save = |name: &str, fig: Figure| -> anyhow::Result<()> {
        let p = dir.join(name);
        fig.save(&p)?;
        out.push(p);
        Ok(())
    };
    let mut time = Figure::new("Second-half residual over time");
    let mut lp = Figure::new("Residual over the hysteresis loop");
    let mut out_panel = Panel::new("output vs input", "input", "output");
    let mut res_panel = Panel::new("residual vs input", "input", "residual");
    let final_label = if d.selection.verdict.is_empty() {
        "baseline (no effect accepted)".to_string()
    } else {
        let names: Vec<_> = d.selection.verdict.iter().map(|e| e.name()).collect();
        format!("with {}", names.join(" + "))
    };
    for c in &d.curves {
        let rb: Vec<f64> = c
            .measured
            .iter()
            .zip(&c.baseline)
            .map(|(m, b)| m - b)
            .collect();
        let rl: Vec<f64> = c.measured.iter().zip(&c.last).map(|(m, b)| m - b).collect();
        time = time.with(
            Panel::new(c.name.clone(), "time (s)", "measured − simulated")
                .with(Series::line("baseline", c.t.clone(), rb.clone()))
                .with(Series::line(final_label.clone(), c.t.clone(), rl)),
        );
        out_panel.series.push(Series::line(
            format!("{} measured", c.name),
            c.input.clone(),
            c.measured.clone(),
        ));
        out_panel.series.push(Series::line(
            format!("{} baseline", c.name),
            c.input.clone(),
            c.baseline.clone(),
        ));
        res_panel.series.push(Series::points(
            format!("{} baseline residual", c.name),
            c.input.clone(),
            rb,
        ));
    }
    save("diagnose_residual.svg", time)?;
    // What a person checks first: does the final model follow the record?
    let mut fit = Figure::new("Measured output against the models (second half)");
    for c in &d.curves {
        fit = fit.with(
            Panel::new(c.name.clone(), "time (s)", "output")
                .with(Series::line("measured", c.t.clone(), c.measured.clone()))
                .with(Series::line("baseline", c.t.clone(), c.baseline.clone()))
                .with(Series::line(
                    final_label.clone(),
                    c.t.clone(),
                    c.last.clone(),
                )),
        );
    }
    save("diagnose_fit.svg", fit)?;
    lp = lp.with(out_panel).with(res_panel);
    save("diagnose_loop.svg", lp)?;

    let w = &d.locate;
    let pair = |title: &str, xlabel: &str, x: Vec<f64>, shares: Vec<Share>| {
        Panel::new(title, xlabel, "share")
            .with(Series::line(
                "residual energy",
                x.clone(),
                shares.iter().map(|s| s.energy).collect(),
            ))
            .with(Series::line(
                "samples",
                x,
                shares.iter().map(|s| s.samples).collect(),
            ))
    };
    let fig = Figure::new("Where the residual energy lies")
        .with(pair(
            "branch: 0 rising, 1 falling, 2 steady; 3 transient, 4 settled",
            "class",
            (0..5).map(f64::from).collect(),
            vec![
                w.branch.rising,
                w.branch.falling,
                w.branch.steady,
                w.after_step.transient,
                w.after_step.settled,
            ],
        ))
        .with(pair(
            "input level (quintile bands, centre)",
            "input",
            w.input_band.iter().map(|b| 0.5 * (b.lo + b.hi)).collect(),
            w.input_band.iter().map(|b| b.share).collect(),
        ))
        .with(pair(
            "frequency band (geometric centre)",
            "frequency (Hz)",
            w.frequency.iter().map(|b| (b.lo * b.hi).sqrt()).collect(),
            w.frequency.iter().map(|b| b.share).collect(),
        ));
    save("diagnose_breakdown.svg", fig)?;

    if let Some(base) = &d.spectrum {
        let mut panel = Panel::new(
            "Welch spectrum of the selection residual (peaks marked)",
            "frequency (Hz)",
            "power density",
        )
        .log_y();
        for (name, spec) in [
            ("baseline", Some(base)),
            (final_label.as_str(), d.final_spectrum.as_ref()),
        ] {
            let Some(spec) = spec else { continue };
            panel.series.push(Series::line(
                name,
                spec.hz[1..].to_vec(),
                spec.power[1..].to_vec(),
            ));
            if !spec.peaks.is_empty() {
                let at = |hz: f64| {
                    spec.power[((hz / spec.hz[1]).round() as usize).min(spec.power.len() - 1)]
                };
                panel.series.push(Series::points(
                    format!("{name}: peaks"),
                    spec.peaks.iter().map(|p| p.hz).collect(),
                    spec.peaks.iter().map(|p| at(p.hz)).collect(),
                ));
            }
        }
        save(
            "diagnose_spectrum.svg",
            Figure::new("Residual spectrum").with(panel),
        )?;
    }
    Ok(out)
}
