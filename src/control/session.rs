//! A `mckibben control` call, from what it asks for to its rows: the
//! checks, the design, the gain tuning, the runs on the in-process twin and
//! what each row warns of. The command runs it, and so does the Python
//! module's `mckibben.control`; a call on a rig shares its checks, design
//! and tuning, and `rig::control_runs` runs its episodes.
//!
//! Every error and warning names the command's flag (`--freq`), which the
//! Python binding turns into its keyword.

use super::closed_loop::Episode;
pub use super::interrupt::Interrupted;
use super::interrupt::go_on;
use super::limits::ValveLimits;
use super::mpc::MpcSettings;
use super::pi::PiGains;
use super::sweep::{
    self, Design, DesignColumns, DesignRequest, GivenModel, Ingredients, Kind, ROBUST_LOAD_SCALE,
    Run, Shape,
};
use super::table::{self, DesignJson, JsonOutput, RobustRow, Row, RunSettings};
use super::tuning::{self, TunedGains, TuningRun};
use crate::data::signals::nyquist_rad_s;
use crate::data::{same_step, tidy_step};
use crate::names::given_once;
use crate::optim::stop::StopFlag;
use crate::twin::{MAX_LOAD_KG, Rig, TwinConfig};

/// The load (kg) the model is identified at on the twin unless told
/// otherwise: the thesis' lighter one.
pub const DESIGN_LOAD_KG: f64 = 4.5;
/// The gain tuning's optimizer, population and generations unless told.
pub const TUNING_ALGO: &str = "de";
pub const TUNING_POP: usize = 24;
pub const TUNING_GENS: usize = 30;
/// The longest MPC horizon `--horizon` takes (samples).
pub const MAX_HORIZON: usize = 500;

/// What a control call asks for.
#[derive(Debug, Clone)]
pub struct ControlPlan {
    /// The controllers, in the order their rows come.
    pub kinds: Vec<Kind>,
    /// The reference's ω (rad/s).
    pub freqs: Vec<f64>,
    /// The twin's loads (kg); a rig's is its own.
    pub loads: Vec<f64>,
    /// The model-based controllers run again with their model's
    /// hysteresis scaled by each.
    pub hysteresis_scales: Vec<f64>,
    /// The robustness table (`--robustness`).
    pub robustness: bool,
    /// An open-loop record to identify from instead of the twin's design
    /// multisine, and its columns' names.
    pub design_record: Option<std::path::PathBuf>,
    pub design_columns: DesignColumns,
    /// A model whose displacement part replaces the identified one.
    pub model: Option<GivenModel>,
    /// The twin's load for the design multisine and the checks (kg).
    pub design_load_kg: f64,
    /// Gains for `pi-tuned` and `ff-pid`; tuned where `None`.
    pub tuned_gains: Option<PiGains>,
    /// The optimizer, population and generations of that tuning.
    pub algo: String,
    pub pop: usize,
    pub gens: usize,
    pub mpc: MpcSettings,
    pub shape: Shape,
    /// The twin's non-ideal effects (`NAME=VALUE`, as `--effect`).
    pub effects: Vec<String>,
    /// The twin's sensor-noise seed (the design record's; its validation
    /// record's is seed + 1) and the tuning's.
    pub seed: u64,
    /// Raised (Ctrl-C, Python's `KeyboardInterrupt`): the call stops after
    /// the current run on the twin or the tuning's current generation,
    /// with [`Interrupted`].
    pub stop: StopFlag,
}

impl Default for ControlPlan {
    /// The command's defaults: pi and mpc at 1, 2 and 3 rad/s under 4.5
    /// and 7 kg, the thesis' episode.
    fn default() -> ControlPlan {
        ControlPlan {
            kinds: vec![Kind::Pi, Kind::Mpc],
            freqs: vec![1.0, 2.0, 3.0],
            loads: vec![4.5, 7.0],
            hysteresis_scales: Vec::new(),
            robustness: false,
            design_record: None,
            design_columns: DesignColumns::default(),
            model: None,
            design_load_kg: DESIGN_LOAD_KG,
            tuned_gains: None,
            algo: TUNING_ALGO.into(),
            pop: TUNING_POP,
            gens: TUNING_GENS,
            mpc: MpcSettings::default(),
            shape: Shape::thesis(),
            effects: Vec::new(),
            seed: 1,
            stop: StopFlag::default(),
        }
    }
}

/// The design and the gains the controllers are built from.
#[derive(Debug)]
pub struct Prepared {
    /// `None` where no controller needs a model.
    pub design: Option<Design>,
    /// `None` where no controller needs tuned gains.
    pub tuned: Option<TunedGains>,
    pub ingredients: Ingredients,
}

/// A call's runs, on the in-process twin or on a rig.
#[derive(Debug)]
pub struct Outcome {
    pub prepared: Prepared,
    pub rows: Vec<Row>,
    pub runs: Vec<Run>,
    pub robust: Vec<RobustRow>,
}

impl ControlPlan {
    /// Whether the values make sense at all, before anything runs.
    pub fn check(&self) -> anyhow::Result<()> {
        anyhow::ensure!(
            !self.kinds.is_empty() && !self.freqs.is_empty() && !self.loads.is_empty(),
            "--controller, --freq and --load need values"
        );
        let twice = "each run would be made, and reported, twice";
        let labels: Vec<&str> = self.kinds.iter().map(|k| k.label()).collect();
        given_once("--controller", &labels, twice)?;
        given_once("--freq", &self.freqs, twice)?;
        given_once("--load", &self.loads, twice)?;
        given_once("--hysteresis-scale", &self.hysteresis_scales, twice)?;
        for &w in &self.freqs {
            anyhow::ensure!(
                w > 0.0 && w.is_finite(),
                "--freq: {w} is not a positive frequency (rad/s)"
            );
        }
        // The twin carries at most MAX_LOAD_KG; the robustness table runs
        // it at the design load × 1.3 too.
        let heaviest = |flag: &str, m: f64, scale: f64| {
            anyhow::ensure!(
                m > 0.0 && m.is_finite(),
                "{flag}: {m} is not a positive mass (kg)"
            );
            anyhow::ensure!(
                m * scale <= MAX_LOAD_KG,
                "{flag} {m}: the twin carries at most {MAX_LOAD_KG} kg{}",
                if scale > 1.0 {
                    format!(
                        ", and --robustness runs it at {scale} × the design load (so at most \
                         {:.2} kg)",
                        MAX_LOAD_KG / scale
                    )
                } else {
                    String::new()
                }
            );
            Ok(())
        };
        for &m in &self.loads {
            heaviest("--load", m, 1.0)?;
        }
        let perturbed = match self.robustness {
            true => ROBUST_LOAD_SCALE,
            false => 1.0,
        };
        heaviest("--design-load", self.design_load_kg, perturbed)?;
        for &s in &self.hysteresis_scales {
            anyhow::ensure!(
                s > 0.0 && s.is_finite(),
                "--hysteresis-scale: {s} must be positive"
            );
            // The nominal run is made anyway: a 1 would make it, and report
            // it, twice under one label.
            anyhow::ensure!(
                s != 1.0,
                "--hysteresis-scale: 1 is the nominal model, which runs anyway; give the other \
                 scales alone (e.g. 0.8,1.2)"
            );
        }
        anyhow::ensure!(
            (2..=MAX_HORIZON).contains(&self.mpc.horizon),
            "--horizon {}: the MPC's horizon must be 2 to {MAX_HORIZON} samples (its QP is \
             dense, its time a step grows about as the horizon's cube: past a few hundred \
             samples one step takes seconds)",
            self.mpc.horizon
        );
        anyhow::ensure!(
            self.mpc.r_move > 0.0 && self.mpc.r_move.is_finite(),
            "--r-move {}: the weight on valve moves must be a positive, finite number",
            self.mpc.r_move
        );
        let shape = &self.shape;
        anyhow::ensure!(
            shape.warmup_s >= 0.0
                && shape.duration_s > 0.0
                && (0.0..shape.duration_s).contains(&shape.steady_from_s),
            "--warmup {} ≥ 0, --duration {} > 0 and 0 ≤ --steady-from {} < --duration: \
             each is in seconds, and a shorter --duration needs a --steady-from below it \
             (its default is {} s)",
            shape.warmup_s,
            shape.duration_s,
            shape.steady_from_s,
            Shape::thesis().steady_from_s
        );
        if let Some(g) = &self.tuned_gains {
            anyhow::ensure!(
                [g.kp, g.ki, g.kd]
                    .iter()
                    .all(|v| v.is_finite() && *v >= 0.0),
                "--tuned-gains takes three non-negative numbers kp,ki,kd (got {},{},{})",
                g.kp,
                g.ki,
                g.kd
            );
        }
        Ok(())
    }

    /// Whether a controller needs the design: a model-based one, or the
    /// robustness table's.
    pub fn designs(&self) -> bool {
        self.kinds.iter().any(|k| k.needs_model()) || self.robustness
    }

    /// Whether the gains are tuned: a controller needs them, and none are
    /// given.
    pub fn tunes(&self) -> bool {
        self.kinds.iter().any(|k| k.needs_gains()) && self.tuned_gains.is_none()
    }

    /// What was asked for that none of the controllers reads, a warning
    /// each (said, not refused: a script may name its record for every
    /// run). `model_named`: how the call named a model (`--from`), whether
    /// or not it was read.
    pub fn unread(&self, model_named: Option<&str>) -> Vec<String> {
        let asked = || {
            let labels: Vec<&str> = self.kinds.iter().map(|k| k.label()).collect();
            labels.join(", ")
        };
        let designs = self.designs();
        let model_based = self.kinds.iter().any(|k| k.needs_model());
        let mpc = self.kinds.contains(&Kind::Mpc);
        let defaults = ControlPlan::default();
        let mut out = Vec::new();
        for (flag, given, used, by) in [
            (
                model_named.unwrap_or("--from"),
                model_named.is_some(),
                designs,
                "ff-pid or mpc",
            ),
            (
                "--design-data",
                self.design_record.is_some(),
                designs,
                "ff-pid or mpc",
            ),
            (
                "--hysteresis-scale",
                !self.hysteresis_scales.is_empty(),
                model_based,
                "ff-pid or mpc",
            ),
            (
                "--robustness",
                self.robustness,
                model_based,
                "ff-pid or mpc",
            ),
            (
                "--tuned-gains",
                self.tuned_gains.is_some(),
                self.kinds.iter().any(|k| k.needs_gains()),
                "pi-tuned or ff-pid",
            ),
            (
                "--design-load",
                self.design_load_kg != defaults.design_load_kg,
                designs,
                "ff-pid or mpc",
            ),
            (
                "--horizon",
                self.mpc.horizon != defaults.mpc.horizon,
                mpc,
                "mpc",
            ),
            (
                "--r-move",
                self.mpc.r_move != defaults.mpc.r_move,
                mpc,
                "mpc",
            ),
        ] {
            if given && !used {
                out.push(format!(
                    "{flag} is not read: none of the controllers asked for ({}) uses it; add \
                     {by} to --controller for one that does",
                    asked()
                ));
            }
        }
        // The tuning's knobs, where nothing is tuned.
        for (flag, given) in [
            ("--algo", self.algo != defaults.algo),
            ("--pop", self.pop != defaults.pop),
            ("--gens", self.gens != defaults.gens),
        ] {
            if given && !self.tunes() {
                let why = match self.tuned_gains {
                    Some(_) => "the gains are given (--tuned-gains)".to_string(),
                    None => format!(
                        "none of the controllers asked for ({}) is tuned; pi-tuned and ff-pid \
                         are",
                        asked()
                    ),
                };
                out.push(format!(
                    "{flag} is not read: it sets the gain tuning, and {why}"
                ));
            }
        }
        out
    }

    /// The twin with the plan's effects, checked.
    pub fn twin_config(&self) -> anyhow::Result<TwinConfig> {
        let mut config = TwinConfig::default();
        config.effects.apply_args(&self.effects)?;
        config.validate()?;
        Ok(config)
    }

    /// What the twin decides before any run on it: every load the runs
    /// hang on it, the episode's samples at its sample time and each
    /// reference below its Nyquist frequency.
    pub fn check_on_twin(&self, config: &TwinConfig) -> anyhow::Result<()> {
        // Every load the runs hang on the twin: the tracking runs', the
        // design runs' (× ROBUST_LOAD_SCALE for the robustness table) and
        // the PI tuning's episodes'. The effects can make a load the
        // range checks let through too heavy (a softer rubber).
        let mut hung: Vec<(&str, f64)> = self.loads.iter().map(|&m| ("--load", m)).collect();
        hung.push(("--design-load", self.design_load_kg));
        if self.robustness {
            hung.push(("--design-load", self.design_load_kg * ROBUST_LOAD_SCALE));
        }
        if self.kinds.contains(&Kind::PiTuned) {
            let tuning = tuning::TuningEpisodes::default().loads_kg;
            hung.extend(tuning.into_iter().map(|m| ("the PI tuning's load", m)));
        }
        // An effect can make a load the rig cannot carry (the creep
        // softens the rubber) or take the rig outside its physics (a
        // friction a million times the twin's): the error names the
        // effects beside the load, as much their doing as the load's.
        let effects = match self.effects.as_slice() {
            [] => String::new(),
            given => format!(" with --effect {}", given.join(" --effect ")),
        };
        for (what, load) in hung {
            Rig::check_holds(config, load, self.seed)
                .map_err(|e| anyhow::anyhow!("{what}{effects}: {e}"))?;
        }
        let shape = &self.shape;
        Episode::short(1.0, shape.warmup_s, shape.duration_s, shape.steady_from_s)
            .check(config.sample_time_s)
            .map_err(|e| anyhow::anyhow!("--warmup, --duration, --steady-from: {e}"))?;
        let nyquist = nyquist_rad_s(config.sample_time_s);
        if let Some(w) = self.freqs.iter().find(|&&w| w >= nyquist) {
            anyhow::bail!(
                "--freq {w}: the twin samples every {} s, so a reference must stay below \
                 Nyquist's {nyquist:.1} rad/s (π/dt)",
                config.sample_time_s
            );
        }
        Ok(())
    }

    /// Refuses a model stepping every `dt` s on a twin stepping otherwise:
    /// a discrete-time model's poles are per sample.
    pub fn check_step(&self, dt: f64, config: &TwinConfig) -> anyhow::Result<()> {
        if same_step(dt, config.sample_time_s) {
            return Ok(());
        }
        let source = match (&self.model, &self.design_record) {
            (Some(m), _) => m.named.clone(),
            (None, Some(p)) => format!("--design-data {}", p.display()),
            (None, None) => "the design record".into(),
        };
        anyhow::bail!(
            "{source}: the model steps every {} s, the twin every {} s: a discrete-time \
             model's poles are per sample; give a model fitted on data sampled every {} s",
            tidy_step(dt),
            config.sample_time_s,
            config.sample_time_s
        )
    }

    /// The design and the gains: the design identified (or read) and
    /// validated on the twin set up as `config`, the gains given or tuned
    /// on it (minutes). `on_twin`: the runs go on the twin too, so a model
    /// on another sample time is refused here. `say` hears the design's
    /// summary and the tuning's progress, `note` each note on the data.
    pub fn prepare(
        &self,
        config: &TwinConfig,
        on_twin: bool,
        say: &dyn Fn(String),
        note: &dyn Fn(String),
    ) -> anyhow::Result<Prepared> {
        // A model file's step is known now, a design record's once
        // identified; a rig's once its handshake gives it.
        if let (true, Some(m)) = (on_twin, &self.model) {
            self.check_step(m.model.base.dt, config)?;
        }
        let design = if self.designs() {
            let request = DesignRequest {
                record: self.design_record.clone(),
                columns: self.design_columns.clone(),
                model: self.model.clone(),
                load_kg: self.design_load_kg,
                seed: self.seed,
                horizon: self.mpc.horizon,
            };
            let d = sweep::design_for(&request, config, note)?;
            if on_twin {
                self.check_step(d.model.displacement.dt, config)?;
            }
            say(d.summary());
            go_on(&self.stop)?;
            Some(d)
        } else {
            None
        };
        let tuning_run = TuningRun {
            algo: self.algo.clone(),
            pop: self.pop,
            gens: self.gens,
            seed: self.seed,
        };
        let tuned = tuning::gains_for(
            &self.kinds,
            self.tuned_gains,
            &tuning_run,
            config,
            &self.stop,
            say,
        )?;
        let ingredients = Ingredients {
            model: design.as_ref().map(|d| d.model.clone()),
            gains: tuned.as_ref().map(|t| t.gains),
            mpc: self.mpc,
            limits: ValveLimits::default(),
        };
        Ok(Prepared {
            design,
            tuned,
            ingredients,
        })
    }

    /// Every run on the twin, the controllers built from `prepared`: the
    /// table's rows and episodes, then the robustness rows where asked;
    /// `say` hears of each run before it starts.
    pub fn run_on_twin(
        &self,
        prepared: &Prepared,
        config: &TwinConfig,
        say: &dyn Fn(String),
    ) -> anyhow::Result<(Vec<Row>, Vec<Run>, Vec<RobustRow>)> {
        let ing = &prepared.ingredients;
        let (rows, runs) = table::on_twin(
            &self.kinds,
            &self.freqs,
            &self.loads,
            &self.hysteresis_scales,
            ing,
            config,
            self.seed,
            &self.shape,
            &self.stop,
            say,
        )?;
        let robust = match self.robustness {
            true => table::robustness(
                &self.kinds,
                &self.freqs,
                self.design_load_kg,
                ing,
                config,
                self.seed,
                &self.shape,
                &self.stop,
                say,
            )?,
            false => Vec::new(),
        };
        Ok((rows, runs, robust))
    }

    /// The whole call on the in-process twin: checks, design, tuning and
    /// runs.
    pub fn on_twin(&self, say: &dyn Fn(String), note: &dyn Fn(String)) -> anyhow::Result<Outcome> {
        self.check()?;
        let config = self.twin_config()?;
        self.check_on_twin(&config)?;
        let prepared = self.prepare(&config, true, say, note)?;
        let (rows, runs, robust) = self.run_on_twin(&prepared, &config, say)?;
        Ok(Outcome {
            prepared,
            rows,
            runs,
            robust,
        })
    }

    /// What every run was scored on and with.
    pub fn settings(&self) -> RunSettings {
        let mpc_ran = self.kinds.contains(&Kind::Mpc);
        RunSettings::of(&self.shape, self.seed, mpc_ran.then_some(&self.mpc))
    }
}

impl Outcome {
    /// The `--json` document of `plan`'s call.
    pub fn json<'a>(&'a self, plan: &ControlPlan) -> JsonOutput<'a> {
        JsonOutput {
            settings: plan.settings(),
            design: self.prepared.design.as_ref().map(DesignJson::of),
            tuned: self.prepared.tuned.as_ref(),
            runs: &self.rows,
            robustness: &self.robust,
        }
    }
}

/// What a row measures that is not the controller at its best, a warning
/// each: failed QP solves, late steps, a feedforward pinned at the valve's
/// range, a loop that tracks worse than holding still.
pub fn warnings(rows: &[Row], runs: &[Run]) -> Vec<String> {
    let mut out = Vec::new();
    for (r, episode) in rows.iter().zip(runs) {
        let run = format!(
            "{} at {} rad/s{}",
            sweep::scaled_label(&r.controller, r.hysteresis_scale),
            r.freq_rad_s,
            r.load_kg.map_or(String::new(), |m| format!(", {m} kg"))
        );
        if r.solver_failures > 0 {
            out.push(format!(
                "{run}: {} of the MPC's QP solves failed, and the valve held its last command \
                 at each; its row measures that, not the MPC",
                r.solver_failures
            ));
        }
        if r.overrun_steps > 0 {
            out.push(format!(
                "{run}: {} of its steps took longer than the sample time (longest {:.1} ms): on \
                 a real-time rig those commands come late and the measurements queue behind \
                 them (shorten the MPC's --horizon, or run a lighter controller)",
                r.overrun_steps,
                // The clock the steps were counted by: the thread's, the
                // wall's where there is none.
                match r.max_step_cpu_us > 0.0 {
                    true => r.max_step_cpu_us,
                    false => r.max_step_time_us,
                } / 1e3
            ));
        }
        // A feedforward pinned at the valve's range most of the run is no
        // feedforward: the PID's integrator takes it up, and the row is the
        // PID's alone (a model whose inverse asks for more than the valve
        // gives).
        let samples = episode.result.t.len();
        if 2 * r.feedforward_at_limit > samples {
            out.push(format!(
                "{run}: the feedforward was at the valve's range on {} of {samples} samples: \
                 the model's inverse asks for more than the valve gives, and the row measures \
                 the PID alone",
                r.feedforward_at_limit
            ));
        }
        if r.worse_than_holding {
            out.push(format!(
                "{run}: its RMS error {:.3} mm is above the {:.3} mm of a muscle held still at \
                 the reference's mean: the loop tracks worse than doing nothing",
                r.rms_error_mm, r.holding_rms_mm
            ));
        }
    }
    out
}
