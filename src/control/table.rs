//! The rows `mckibben control` prints and writes as JSON: one per run, and
//! the robustness runs with their ratio to the nominal run; the `--json`
//! document they go in, the text tables they print as, and the CSV of each
//! run's samples (`--csv`).

use std::path::Path;

use anyhow::Context as _;
use serde::Serialize;

use super::chain::EffectUse;
use super::design::PredictionReport;
use super::figures;
use super::interrupt::go_on;
use super::model::ControlModel;
use super::mpc::MpcSettings;
use super::reference::Waveform;
use super::sweep::{self, Design, Ingredients, Kind, Run, Shape};
use super::tuning::TunedGains;
use super::validation::LoopShape;
use crate::data::Trace;
use crate::data::csv::write_log_with_comments;
use crate::optim::stop::StopFlag;
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
    /// Steps whose time exceeded the sample time ([`Metrics::overrun_steps`]).
    ///
    /// [`Metrics::overrun_steps`]: super::metrics::Metrics::overrun_steps
    pub overrun_steps: usize,
    /// The error of a muscle held still at the reference's mean over the
    /// same samples: a run above it tracks worse than doing nothing.
    pub holding_rms_mm: f64,
    /// Whether the run tracked worse than that where the reference moves
    /// ([`Metrics::worse_than_holding`]): what the command warns of.
    ///
    /// [`Metrics::worse_than_holding`]: super::metrics::Metrics::worse_than_holding
    #[serde(skip)]
    pub worse_than_holding: bool,
    pub diverged: bool,
    pub solver_failures: usize,
    pub capped_solves: usize,
    pub max_qp_iterations: usize,
    /// Samples whose feedforward (`ff-pid`) was at the valve's range or not
    /// finite (0 for the others).
    pub feedforward_at_limit: usize,
}

impl Row {
    pub fn of(run: &Run, plant: &str, load_kg: Option<f64>, late: usize) -> Row {
        let m = &run.result.metrics;
        let s = run.stats.unwrap_or_default();
        Row {
            // The kind alone: the scale has its own field.
            controller: run.spec.kind.label().to_string(),
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
            overrun_steps: m.overrun_steps,
            holding_rms_mm: m.holding_rms_mm,
            worse_than_holding: m.worse_than_holding(run.result.reference_amplitude_mm),
            diverged: m.diverged,
            solver_failures: s.solver_failures,
            capped_solves: s.capped_solves,
            max_qp_iterations: s.max_qp_iterations,
            feedforward_at_limit: s.feedforward_at_limit,
        }
    }
}

/// The runs of `kinds` over `freqs` × `loads` and the hysteresis `scales`
/// ([`sweep::plan`]), each on a fresh in-process twin, with their rows;
/// `progress` hears of each run before it starts, and a raised `stop` ends
/// the call before the next run ([`super::interrupt::Interrupted`]).
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
    stop: &StopFlag,
    progress: &dyn Fn(String),
) -> anyhow::Result<(Vec<Row>, Vec<Run>)> {
    let specs = sweep::plan(kinds, freqs, loads, scales);
    let mut rows = Vec::new();
    let mut runs = Vec::new();
    for (i, spec) in specs.iter().enumerate() {
        go_on(stop)?;
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
/// kind in `kinds` at every frequency, on the in-process twin, until
/// `stop` is raised.
#[allow(clippy::too_many_arguments)]
pub fn robustness(
    kinds: &[Kind],
    freqs: &[f64],
    design_load: f64,
    ing: &Ingredients,
    config: &TwinConfig,
    seed: u64,
    shape: &Shape,
    stop: &StopFlag,
    progress: &dyn Fn(String),
) -> anyhow::Result<Vec<RobustRow>> {
    let mut out = Vec::new();
    for &kind in kinds.iter().filter(|k| k.needs_model()) {
        for &freq in freqs {
            let mut nominal = f64::NAN;
            for (name, spec) in sweep::robustness_specs(kind, freq, design_load) {
                go_on(stop)?;
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

/// The `--json` document.
#[derive(Debug, Serialize)]
pub struct JsonOutput<'a> {
    /// What every run was scored on and with.
    pub settings: RunSettings,
    /// The identified model; null when no controller needs one.
    pub design: Option<DesignJson<'a>>,
    /// The PID gains of pi-tuned and ff-pid; null when neither runs.
    pub tuned: Option<&'a TunedGains>,
    pub runs: &'a [Row],
    pub robustness: &'a [RobustRow],
}

/// What every run of a `control` call was scored on and with: a script
/// tells a sine's rows from a step's, and a short episode's from the
/// thesis', by these.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct RunSettings {
    /// The reference's waveform (`sine` or `steps`).
    pub reference: Waveform,
    /// Regulation at the bias before the reference starts (s).
    pub warmup_s: f64,
    /// The reference's length (s).
    pub duration_s: f64,
    /// Where the scored part starts, from the reference's start (s).
    pub steady_from_s: f64,
    /// The twin's sensor-noise seed and the tuning's.
    pub seed: u64,
    /// The MPC's horizon (samples) and weight on valve moves; `None` where
    /// no MPC ran.
    pub horizon: Option<usize>,
    pub r_move: Option<f64>,
}

impl RunSettings {
    /// The settings of runs of `shape`, with `mpc` where an MPC ran.
    pub fn of(shape: &Shape, seed: u64, mpc: Option<&MpcSettings>) -> RunSettings {
        RunSettings {
            reference: shape.waveform,
            warmup_s: shape.warmup_s,
            duration_s: shape.duration_s,
            steady_from_s: shape.steady_from_s,
            seed,
            horizon: mpc.map(|m| m.horizon),
            r_move: mpc.map(|m| m.r_move),
        }
    }
}

/// A design without its figure curves, which only the plots need.
#[derive(Debug, Serialize)]
pub struct DesignJson<'a> {
    source: &'a str,
    model: &'a ControlModel,
    prediction: &'a PredictionReport,
    loop_check: Option<LoopCheckJson<'a>>,
    /// How each effect of a `--from` model entered the controllers.
    effects: &'a [EffectUse],
}

/// The loop check's verdict without its curves.
#[derive(Debug, Serialize)]
struct LoopCheckJson<'a> {
    plant: &'a LoopShape,
    model: &'a LoopShape,
    rmse_mm: f64,
}

impl DesignJson<'_> {
    pub fn of(d: &Design) -> DesignJson<'_> {
        DesignJson {
            source: &d.source,
            model: &d.model,
            prediction: &d.prediction,
            loop_check: d.loop_check.as_ref().map(|l| LoopCheckJson {
                plant: &l.plant,
                model: &l.model,
                rmse_mm: l.rmse_mm,
            }),
            effects: &d.effects,
        }
    }
}

/// The rows as text: the table of runs, then the robustness table when
/// there are robustness runs.
pub fn text(rows: &[Row], robust: &[RobustRow]) -> String {
    let mut lines = vec![format!(
        "{:<24} {:>5} {:>5} {:>8} {:>8} {:>8} {:>7} {:>8} {:>8} {:>8} {:>4} {:>4} {:>4}",
        "controller",
        "ω",
        "kg",
        "RMS mm",
        "max mm",
        "u rms V",
        "u V/s",
        "max µs",
        "cpu µs",
        "mean µs",
        "viol",
        "miss",
        "div"
    )];
    for r in rows {
        let load = r.load_kg.map_or("rig".to_string(), |l| l.to_string());
        lines.push(format!(
            "{:<24} {:>5} {:>5} {:>8.3} {:>8.3} {:>8.3} {:>7.2} {:>8.0} {:>8.0} {:>8.1} {:>4} {:>4} {:>4}",
            sweep::scaled_label(&r.controller, r.hysteresis_scale),
            r.freq_rad_s,
            load,
            r.rms_error_mm,
            r.max_error_mm,
            r.effort_rms_v,
            r.effort_travel_v_per_s,
            r.max_step_time_us,
            r.max_step_cpu_us,
            r.mean_step_time_us,
            r.constraint_violations,
            r.missing_measurements,
            if r.diverged { "yes" } else { "no" }
        ));
    }
    if !robust.is_empty() {
        lines.push(format!(
            "\n{:<8} {:<18} {:>5} {:>6} {:>8} {:>10} {:>4}",
            "", "perturbation", "ω", "kg", "RMS mm", "× nominal", "viol"
        ));
        for r in robust {
            lines.push(format!(
                "{:<8} {:<18} {:>5} {:>6.3} {:>8.3} {:>10.2} {:>4}",
                r.controller,
                r.perturbation,
                r.freq_rad_s,
                r.load_kg,
                r.rms_error_mm,
                r.ratio,
                r.constraint_violations
            ));
        }
    }
    let mut text = lines.join("\n");
    text.push('\n');
    text
}

/// One CSV per run in `dir` (t, reference, displacement, pressure,
/// valve_in), named as its figure ([`figures::stem`]).
pub fn write_csvs(dir: &Path, runs: &[Run], waveform: Waveform) -> anyhow::Result<()> {
    crate::data::create_dir_all(dir)
        .with_context(|| format!("creating --csv {}", dir.display()))?;
    for run in runs {
        let r = &run.result;
        // The plant's sample time, as the run's time base carries it.
        let dt = r.t.get(1).zip(r.t.first()).map_or(f64::NAN, |(b, a)| b - a);
        let path = dir.join(format!("{}.csv", figures::stem(run, waveform)));
        let mut trace = Trace::uniform(
            format!("control {}", r.controller),
            dt,
            r.pressure.clone(),
            r.displacement.clone(),
        );
        trace.t = r.t.clone();
        trace.extra.push(("valve_in".into(), r.valve.clone()));
        trace.extra.push(("reference".into(), r.reference.clone()));
        let load = match run.spec.load_kg {
            kg if kg.is_finite() => format!("{kg} kg"),
            _ => "the rig's load".to_string(),
        };
        let comments = [format!(
            "{}, {} rad/s, {load}: an empty cell is a sample whose measurement was missing \
             (the command in force was held)",
            r.controller, run.spec.freq_rad_s
        )];
        write_log_with_comments(&path, &trace, &comments)
            .with_context(|| format!("writing --csv {}", path.display()))?;
    }
    Ok(())
}
