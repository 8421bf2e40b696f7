//! `mckibben control`: closed-loop sine tracking on the rig twin with the
//! thesis' PI, the optimizer-tuned PI and the MPC (chapter 6).

use std::path::PathBuf;

use anyhow::Context;
use serde::Serialize;

use mckibben::control::design::{self, scale_hysteresis};
use mckibben::control::tuning::{self, TuningEpisodes};
use mckibben::control::{
    ControlModel, Controller, Episode, EpisodeResult, Mpc, MpcSettings, Pi, PiGains, ValveLimits,
    run_episode,
};
use mckibben::data::Trace;
use mckibben::data::csv::write_trace;
use mckibben::data::signals::{Multisine, Stair};
use mckibben::report::{Figure, Panel, Series};
use mckibben::twin::{self, Rig, TwinConfig};

/// Track the sine reference of appendix A.1.2 (30 mm bias, 10 mm amplitude)
/// on the rig twin, closing the loop on the input valve voltage (0–10 V, the
/// output valve at 10 − u) every 10 ms, and report the steady-state RMS and
/// maximum tracking error (the last 10 s of a 20 s sine, after 10 s of
/// settling at 30 mm), the valve effort and the controller's step time.
///
/// Controllers: `pi` — the thesis' gains (Table 22) with anti-windup;
/// `pi-tuned` — PI(D) gains chosen by an optimizer on short episodes over
/// every frequency and load; `mpc` — a QP-based MPC on a model identified
/// from the twin's stair at the design load (never the twin's internals).
///
/// Example: `mckibben control --controller pi,mpc --freq 3 --load 4.5,7 --plot figs/`
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Controllers to run (comma-separated): pi, pi-tuned, mpc. `pi-tuned`
    /// without `--tuned-gains` runs the tuning first (minutes on 2 cores).
    #[arg(long, value_delimiter = ',', default_value = "pi,mpc")]
    controller: Vec<Kind>,
    /// Reference frequencies ω (rad/s), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,2,3")]
    freq: Vec<f64>,
    /// Hanging loads (kg), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "4.5,7")]
    load: Vec<f64>,
    /// Load (kg) at which the MPC's model is identified (the thesis designed at 4.5 kg).
    #[arg(long, default_value_t = 4.5)]
    design_load: f64,
    /// Open-loop twin experiment the MPC's model is identified from: the
    /// identification stair of A.1.1, or a 120 s multisine (5 ± 4 V,
    /// 0.02–1 Hz), which excites the dynamics the 1–3 rad/s references need.
    #[arg(long, value_enum, default_value = "multisine")]
    design_experiment: DesignExperiment,
    /// Use this displacement model (pressure → displacement, a model JSON
    /// written by `identify --out` or `fit`) in the MPC instead of the
    /// control-oriented fit; the valve → pressure model is still identified
    /// from the design experiment.
    #[arg(long, value_name = "MODEL.json")]
    from: Option<PathBuf>,
    /// Also run the MPC with its hysteresis parameters (A, α, β, γ) scaled by
    /// these factors, to test robustness to model error (e.g. 0.8,1.2).
    #[arg(long, value_delimiter = ',')]
    hysteresis_scale: Vec<f64>,
    /// PI(D) gains `kp,ki,kd` (V/mm, V/(mm·s), V·s/mm) for pi-tuned, instead of tuning now.
    #[arg(long, value_delimiter = ',', value_name = "KP,KI,KD")]
    tuned_gains: Option<Vec<f64>>,
    /// Optimizer for the gain tuning: ga, mfa, pso or de.
    #[arg(long, default_value = "de")]
    algo: String,
    /// Population size of the gain tuning.
    #[arg(long, default_value_t = 16)]
    pop: usize,
    /// Generations of the gain tuning.
    #[arg(long, default_value_t = 12)]
    gens: usize,
    /// MPC prediction horizon (samples of 10 ms).
    #[arg(long, default_value_t = MpcSettings::default().horizon)]
    horizon: usize,
    /// MPC weight on valve moves (per V²) against tracking error (per mm²).
    #[arg(long, default_value_t = MpcSettings::default().r_move)]
    r_move: f64,
    /// Seed of the twin's sensor noise and of the tuning optimizer.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Write one SVG per run (reference vs displacement, valve, error) into this folder.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Write one CSV per run (t, reference, displacement, pressure, valve_in) into this folder.
    #[arg(long, value_name = "DIR")]
    csv: Option<PathBuf>,
    /// Print JSON (one object per run) instead of a table.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum DesignExperiment {
    Stair,
    Multisine,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Kind {
    Pi,
    PiTuned,
    Mpc,
}

/// One run, as `--json` prints it.
#[derive(Debug, Serialize)]
struct Row {
    controller: String,
    freq_rad_s: f64,
    load_kg: f64,
    rms_error_mm: f64,
    max_error_mm: f64,
    max_step_time_us: f64,
    mean_step_time_us: f64,
    max_step_cpu_us: f64,
    constraint_violations: usize,
    effort_rms_v: f64,
    effort_travel_v_per_s: f64,
    diverged: bool,
    /// Hysteresis parameters of the MPC's model scaled by this factor (1: as identified).
    hysteresis_scale: f64,
    solver_failures: usize,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(!args.freq.is_empty(), "--freq needs at least one frequency");
    anyhow::ensure!(!args.load.is_empty(), "--load needs at least one load");
    for &w in &args.freq {
        anyhow::ensure!(
            w > 0.0 && w.is_finite(),
            "--freq: {w} is not a positive frequency (rad/s)"
        );
    }
    for &m in args.load.iter().chain([args.design_load].iter()) {
        anyhow::ensure!(
            m > 0.0 && m.is_finite(),
            "--load/--design-load: {m} is not a positive mass (kg)"
        );
    }
    for &s in &args.hysteresis_scale {
        anyhow::ensure!(
            s > 0.0 && s.is_finite(),
            "--hysteresis-scale: {s} must be positive"
        );
    }
    anyhow::ensure!(args.horizon >= 2, "--horizon must be at least 2 samples");
    if let Some(g) = &args.tuned_gains {
        anyhow::ensure!(
            g.len() == 3 && g.iter().all(|v| v.is_finite()),
            "--tuned-gains takes three numbers kp,ki,kd (got {g:?})"
        );
    }
    let config = TwinConfig::default();

    // The MPC's model: identified on the twin's stair at the design load.
    let model = if args.controller.contains(&Kind::Mpc) {
        let experiment = match args.design_experiment {
            DesignExperiment::Stair => twin::Experiment::Stair(Stair::default()),
            DesignExperiment::Multisine => twin::Experiment::Multisine(Multisine {
                duration_s: 120.0,
                ..Multisine::default()
            }),
        };
        let record = twin::run(&config, args.design_load, args.seed, &experiment);
        let (mut model, fit) = design::identify(&record, design::OPERATING_BAND_V, args.horizon)
            .context("identifying the MPC's model")?;
        if let Some(path) = &args.from {
            let m = mckibben::model::FittedModel::load(path)
                .map_err(|e| anyhow::anyhow!("--from: {e:#}"))?;
            anyhow::ensure!(
                (m.dt - 0.01).abs() < 1e-9,
                "--from {}: the model was fitted at a {} s sample time; the loop runs at 0.01 s",
                path.display(),
                m.dt
            );
            model.displacement = m;
        }
        if !args.json {
            let origin = match &args.from {
                Some(path) => format!("from {}", path.display()),
                None => format!("{}-step prediction RMSE {:.3} mm", fit.horizon, fit.rmse_mm),
            };
            eprintln!(
                "MPC model from the twin's {} at {} kg: {} ({origin}), valve: p(k+1) = {:.4}·p + {:.5}·v + {:.5}",
                experiment.name(),
                args.design_load,
                fmt_params(&model.displacement),
                model.valve.pole,
                model.valve.gain,
                model.valve.offset
            );
        }
        Some(model)
    } else {
        None
    };

    let tuned = if args.controller.contains(&Kind::PiTuned) {
        Some(match &args.tuned_gains {
            Some(g) => PiGains {
                kp: g[0],
                ki: g[1],
                kd: g[2],
            },
            None => {
                if !args.json {
                    eprintln!(
                        "tuning the PID gains: {} × {} gain vectors, each on {} episodes ...",
                        args.pop,
                        args.gens,
                        TuningEpisodes::default().freqs_rad_s.len()
                            * TuningEpisodes::default().loads_kg.len()
                    );
                }
                let t = tuning::tune_pi(
                    &args.algo,
                    args.pop,
                    args.gens,
                    args.seed,
                    &TuningEpisodes::default(),
                    &config,
                )?;
                if !args.json {
                    eprintln!(
                        "tuned PI ({} pop {} gens {}, {} gain vectors × every frequency and load, {:.1} s): kp {:.5} ki {:.5} kd {:.5}, mean RMS {:.3} mm (thesis gains {:.3} mm)",
                        args.algo,
                        args.pop,
                        args.gens,
                        t.evaluations,
                        t.seconds,
                        t.gains.kp,
                        t.gains.ki,
                        t.gains.kd,
                        t.cost,
                        t.baseline_cost
                    );
                }
                t.gains
            }
        })
    } else {
        None
    };

    let mut rows = Vec::new();
    let mut runs = Vec::new();
    for &kind in &args.controller {
        let scales: Vec<f64> = if kind == Kind::Mpc {
            std::iter::once(1.0)
                .chain(args.hysteresis_scale.iter().copied())
                .collect()
        } else {
            vec![1.0]
        };
        for &scale in &scales {
            for &load in &args.load {
                for &w in &args.freq {
                    let mut rig = Rig::new(&config, load, args.seed);
                    let ep = Episode::thesis(w);
                    let dt = rig.dt();
                    let (result, failures) = match kind {
                        Kind::Pi => {
                            let mut c = Pi::new(PiGains::default(), ep.limits, dt, "pi");
                            (run_episode(&mut rig, &mut c, &ep), 0)
                        }
                        Kind::PiTuned => {
                            let g = tuned.expect("tuned gains were set above");
                            let mut c = Pi::new(g, ep.limits, dt, "pi-tuned");
                            (run_episode(&mut rig, &mut c, &ep), 0)
                        }
                        Kind::Mpc => {
                            let base = model.as_ref().expect("model identified above");
                            let m = ControlModel {
                                displacement: scale_hysteresis(&base.displacement, scale),
                                valve: base.valve,
                            };
                            let settings = MpcSettings {
                                horizon: args.horizon,
                                r_move: args.r_move,
                                ..MpcSettings::default()
                            };
                            let label = if scale == 1.0 {
                                "mpc".to_string()
                            } else {
                                format!("mpc (hysteresis ×{scale})")
                            };
                            let mut c = Mpc::new(&m, settings, ValveLimits::default(), label);
                            let r = run_episode(&mut rig, &mut c as &mut dyn Controller, &ep);
                            (r, c.solver_failures)
                        }
                    };
                    let m = &result.metrics;
                    rows.push(Row {
                        controller: result.controller.clone(),
                        freq_rad_s: w,
                        load_kg: load,
                        rms_error_mm: m.rms_error_mm,
                        max_error_mm: m.max_error_mm,
                        max_step_time_us: m.max_step_time_us,
                        mean_step_time_us: m.mean_step_time_us,
                        max_step_cpu_us: m.max_step_cpu_us,
                        constraint_violations: m.constraint_violations,
                        effort_rms_v: m.effort_rms_v,
                        effort_travel_v_per_s: m.effort_travel_v_per_s,
                        diverged: m.diverged,
                        hysteresis_scale: scale,
                        solver_failures: failures,
                    });
                    runs.push((kind, scale, load, w, result));
                }
            }
        }
    }

    if let Some(dir) = &args.plot {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("creating --plot {}", dir.display()))?;
        for (kind, scale, load, w, result) in &runs {
            let path = dir.join(format!("{}.svg", run_name(*kind, *scale, *load, *w)));
            figure(result, *load, *w)
                .save(&path)
                .with_context(|| format!("writing --plot {}", path.display()))?;
        }
    }

    if let Some(dir) = &args.csv {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("creating --csv {}", dir.display()))?;
        for (kind, scale, load, w, r) in &runs {
            let path = dir.join(format!("{}.csv", run_name(*kind, *scale, *load, *w)));
            let mut trace = Trace::uniform(
                format!("control {}", r.controller),
                0.01,
                r.pressure.clone(),
                r.displacement.clone(),
            );
            trace.t = r.t.clone();
            trace.extra.push(("valve_in".into(), r.valve.clone()));
            trace.extra.push(("reference".into(), r.reference.clone()));
            trace.extra.push(("load_kg".into(), vec![*load; r.t.len()]));
            write_trace(&path, &trace)
                .with_context(|| format!("writing --csv {}", path.display()))?;
        }
    }

    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
        return Ok(());
    }
    println!(
        "{:<22} {:>6} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>5} {:>4}",
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
        "div"
    );
    for r in &rows {
        println!(
            "{:<22} {:>6} {:>6} {:>9.3} {:>9.3} {:>9.3} {:>9.2} {:>9.0} {:>9.0} {:>9.1} {:>5} {:>4}",
            r.controller,
            r.freq_rad_s,
            r.load_kg,
            r.rms_error_mm,
            r.max_error_mm,
            r.effort_rms_v,
            r.effort_travel_v_per_s,
            r.max_step_time_us,
            r.max_step_cpu_us,
            r.mean_step_time_us,
            r.constraint_violations,
            if r.diverged { "yes" } else { "no" }
        );
    }
    println!(
        "steady state: the last 10 s of a 20 s sine after 10 s settling at 30 mm; sample time 10 ms"
    );
    Ok(())
}

/// File stem of one run: `control_<controller>[_h<scale>]_<load>kg_<ω>rad`.
fn run_name(kind: Kind, scale: f64, load: f64, w: f64) -> String {
    let name = match kind {
        Kind::Pi => "pi",
        Kind::PiTuned => "pi_tuned",
        Kind::Mpc => "mpc",
    };
    let suffix = if scale == 1.0 {
        String::new()
    } else {
        format!("_h{scale}")
    };
    format!("control_{name}{suffix}_{load}kg_{w}rad")
}

fn fmt_params(m: &mckibben::model::FittedModel) -> String {
    m.named_params()
        .iter()
        .map(|(n, v)| format!("{n} {v:.4}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The thesis' figures 27–32: reference and displacement, valve voltage, error.
fn figure(r: &EpisodeResult, load: f64, w: f64) -> Figure {
    let err: Vec<f64> = r
        .reference
        .iter()
        .zip(&r.displacement)
        .map(|(a, b)| a - b)
        .collect();
    Figure::new(format!("{}: {load} kg, {w} rad/s", r.controller))
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
            Panel::new("Input valve voltage", "t (s)", "u (V)").with(Series::line(
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
