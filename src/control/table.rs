//! The rows `mckibben control` prints and writes as JSON: one per run, and
//! the robustness runs with their ratio to the nominal run.

use serde::Serialize;

use super::sweep::{self, Ingredients, Kind, Run, Shape};
use crate::twin::TwinConfig;

/// One run.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub controller: String,
    /// `twin` or the `--plant` spec.
    pub plant: String,
    pub freq_rad_s: f64,
    /// The twin's load (`None` on an external rig).
    pub load_kg: Option<f64>,
    pub hysteresis_scale: f64,
    pub rms_error_mm: f64,
    pub max_error_mm: f64,
    pub effort_rms_v: f64,
    pub effort_travel_v_per_s: f64,
    pub constraint_violations: usize,
    pub missing_measurements: usize,
    pub late_measurements: usize,
    pub max_step_time_us: f64,
    pub max_step_cpu_us: f64,
    pub mean_step_time_us: f64,
    pub diverged: bool,
    pub solver_failures: usize,
    pub capped_solves: usize,
    pub max_qp_iterations: usize,
}

impl Row {
    pub fn of(run: &Run, plant: &str, load_kg: Option<f64>, late: usize) -> Row {
        let m = &run.result.metrics;
        let s = run.stats.unwrap_or_default();
        Row {
            controller: run.result.controller.clone(),
            plant: plant.to_string(),
            freq_rad_s: run.spec.freq_rad_s,
            load_kg,
            hysteresis_scale: run.spec.hysteresis_scale,
            rms_error_mm: m.rms_error_mm,
            max_error_mm: m.max_error_mm,
            effort_rms_v: m.effort_rms_v,
            effort_travel_v_per_s: m.effort_travel_v_per_s,
            constraint_violations: m.constraint_violations,
            missing_measurements: m.missing_measurements,
            late_measurements: late,
            max_step_time_us: m.max_step_time_us,
            max_step_cpu_us: m.max_step_cpu_us,
            mean_step_time_us: m.mean_step_time_us,
            diverged: m.diverged,
            solver_failures: s.solver_failures,
            capped_solves: s.capped_solves,
            max_qp_iterations: s.max_qp_iterations,
        }
    }
}

/// The runs of `kinds` over `freqs` × `loads` and the hysteresis `scales`
/// ([`sweep::plan`]), each on a fresh in-process twin, with their rows;
/// `progress` hears of each run before it starts.
#[allow(clippy::too_many_arguments)]
pub fn on_twin(
    kinds: &[Kind],
    freqs: &[f64],
    loads: &[f64],
    scales: &[f64],
    ing: &Ingredients,
    config: &TwinConfig,
    seed: u64,
    shape: &Shape,
    progress: &dyn Fn(String),
) -> anyhow::Result<(Vec<Row>, Vec<Run>)> {
    let specs = sweep::plan(kinds, freqs, loads, scales);
    let mut rows = Vec::new();
    let mut runs = Vec::new();
    for (i, spec) in specs.iter().enumerate() {
        progress(format!(
            "[{}/{}] {} at {} rad/s, {} kg",
            i + 1,
            specs.len(),
            sweep::run_label(spec.kind, spec.hysteresis_scale),
            spec.freq_rad_s,
            spec.load_kg
        ));
        let run = sweep::run_on_twin(spec, ing, config, seed, shape)?;
        rows.push(Row::of(&run, "twin", Some(spec.load_kg), 0));
        runs.push(run);
    }
    Ok((rows, runs))
}

/// One robustness run.
#[derive(Debug, Clone, Serialize)]
pub struct RobustRow {
    pub controller: String,
    pub perturbation: String,
    pub freq_rad_s: f64,
    pub load_kg: f64,
    pub rms_error_mm: f64,
    /// RMS over the nominal run's RMS.
    pub ratio: f64,
    pub constraint_violations: usize,
    pub diverged: bool,
}

/// The robustness runs ([`sweep::robustness_specs`]) of every model-based
/// kind in `kinds` at every frequency, on the in-process twin.
#[allow(clippy::too_many_arguments)]
pub fn robustness(
    kinds: &[Kind],
    freqs: &[f64],
    design_load: f64,
    ing: &Ingredients,
    config: &TwinConfig,
    seed: u64,
    shape: &Shape,
    progress: &dyn Fn(String),
) -> anyhow::Result<Vec<RobustRow>> {
    let mut out = Vec::new();
    for &kind in kinds.iter().filter(|k| k.needs_model()) {
        for &freq in freqs {
            let mut nominal = f64::NAN;
            for (name, spec) in sweep::robustness_specs(kind, freq, design_load) {
                progress(format!(
                    "robustness: {} {name} at {freq} rad/s",
                    kind.label()
                ));
                let r = sweep::run_on_twin(&spec, ing, config, seed, shape)?.result;
                if name == "nominal" {
                    nominal = r.metrics.rms_error_mm;
                }
                out.push(RobustRow {
                    controller: kind.label().into(),
                    perturbation: name,
                    freq_rad_s: freq,
                    load_kg: spec.load_kg,
                    rms_error_mm: r.metrics.rms_error_mm,
                    ratio: r.metrics.rms_error_mm / nominal,
                    constraint_violations: r.metrics.constraint_violations,
                    diverged: r.metrics.diverged,
                });
            }
        }
    }
    Ok(out)
}
