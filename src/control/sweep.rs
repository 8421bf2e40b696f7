//! The experiments of `mckibben control`: the controllers, designed and
//! built, run over frequencies and loads on the in-process twin, and the
//! robustness runs. The command line only parses and calls these.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use serde::{Deserialize, Serialize};

use super::chain::{ControlChain, EffectUse};
use super::closed_loop::{Episode, EpisodeResult, run_episode};
use super::controller::{Controller, ControllerStats};
use super::design::{self, OPERATING_BAND_V, PredictionReport, VALVE_IN, scale_hysteresis};
use super::feedforward::FeedforwardPid;
use super::limits::ValveLimits;
use super::model::ControlModel;
use super::mpc::{Mpc, MpcSettings};
use super::pi::{Pi, PiGains};
use super::reference::Waveform;
use super::validation::{self, LoopCheck};
use crate::data::Trace;
use crate::data::csv::{DataError, ReadOptions, read_traces_with_notes};
use crate::data::units::{megapascals_in, millimetres_in, unit_of};
use crate::model::effects::Effect;
use crate::model::{Family, FittedBaseline, ModelFile};
use crate::twin::{self, Rig, TwinConfig};

/// The controllers `mckibben control` knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    /// The thesis' PI (Table 22).
    Pi,
    /// The optimizer-tuned PID.
    PiTuned,
    /// Inverse-hysteresis feedforward plus the tuned PID.
    FfPid,
    /// The MPC.
    Mpc,
}

impl Kind {
    pub fn label(self) -> &'static str {
        match self {
            Kind::Pi => "pi",
            Kind::PiTuned => "pi-tuned",
            Kind::FfPid => "ff-pid",
            Kind::Mpc => "mpc",
        }
    }

    /// Whether the controller needs the identified model.
    pub fn needs_model(self) -> bool {
        matches!(self, Kind::FfPid | Kind::Mpc)
    }

    /// Whether it needs the tuned gains.
    pub fn needs_gains(self) -> bool {
        matches!(self, Kind::PiTuned | Kind::FfPid)
    }

    pub const ALL: [Kind; 4] = [Kind::Pi, Kind::PiTuned, Kind::FfPid, Kind::Mpc];
}

/// A controller's name in any case (`PI`, `ff-pid`), as `--controller`
/// reads it.
impl std::str::FromStr for Kind {
    type Err = crate::names::UnknownName;

    fn from_str(s: &str) -> Result<Kind, Self::Err> {
        crate::names::one_of("controller", s, &Kind::ALL, Kind::label)
    }
}

/// The model a design produced, with how well it predicts and whether it
/// has the plant's loop.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Design {
    pub model: ControlModel,
    /// Where the model came from.
    pub source: String,
    /// Prediction errors on a second record (the validation record).
    pub prediction: PredictionReport,
    /// The model's loop against the twin's (at the design load).
    pub loop_check: Option<LoopCheck>,
    /// How each effect of a model from `--from` entered the controllers
    /// (empty for a baseline).
    #[serde(default)]
    pub effects: Vec<EffectUse>,
}

/// Length of the loop check's valve cycle (s): slow enough to be
/// quasi-static for the rig's 0.2–0.3 s lag.
pub const LOOP_CYCLE_S: f64 = 40.0;

/// Identifies the model from `record` (an open-loop record with a
/// `valve_in` column), validates its predictions on `validation` and, given
/// a twin, its loop on a slow triangle at `load`.
pub fn design_from(
    record: &Trace,
    validation: &Trace,
    horizon: usize,
    twin: Option<(&TwinConfig, f64, u64)>,
) -> anyhow::Result<Design> {
    let model = design::identify(record, OPERATING_BAND_V, horizon)?;
    finish_design(model, record.source.clone(), validation, horizon, twin)
}

/// Validates `model` (see [`design_from`]).
pub fn finish_design(
    model: ControlModel,
    source: String,
    validation: &Trace,
    horizon: usize,
    twin: Option<(&TwinConfig, f64, u64)>,
) -> anyhow::Result<Design> {
    let prediction = design::prediction_report(&model, validation, OPERATING_BAND_V, horizon)?;
    let loop_check = match twin {
        Some((config, load, seed)) => {
            let mut rig = Rig::new(config, load, seed);
            let dt = rig.dt();
            let valve = validation::triangle(OPERATING_BAND_V, LOOP_CYCLE_S, dt);
            let (p, x) = validation::record(&mut rig, &valve);
            let cycle = (LOOP_CYCLE_S / dt).round() as usize;
            Some(validation::check_loop(&model, &p, &x, cycle)?)
        }
        None => None,
    };
    Ok(Design {
        model,
        source,
        prediction,
        loop_check,
        effects: Vec::new(),
    })
}

/// The design from an open-loop record of the plant (a `valve_in`
/// column): identified on its first half, validated on its second.
pub fn design_from_record(record: &Trace, horizon: usize) -> anyhow::Result<Design> {
    let half = record.len() / 2;
    let (est, val) = (record.slice(0..half), record.slice(half..record.len()));
    design_from(&est, &val, horizon, None)
}

/// The design on the twin at `load`: identified on the design multisine
/// (seed `seed`), validated on another run of it (seed `seed + 1`), its
/// loop checked against the twin's.
pub fn design_on_twin(
    config: &TwinConfig,
    load: f64,
    seed: u64,
    horizon: usize,
) -> anyhow::Result<Design> {
    let (record, validation) = twin_records(config, load, seed);
    design_from(&record, &validation, horizon, Some((config, load, seed)))
}

/// `design` with its displacement model replaced by `displacement` (a
/// model fitted elsewhere, named `source`) and the effects `chain` of
/// that model, validated on the twin at `load` as [`design_on_twin`]
/// does. The valve map stays; the curvature `b2` goes, since it belonged
/// to the replaced displacement model. Its Bouc-Wen state starts at rest
/// ([`ControlModel::rest_start`]).
#[allow(clippy::too_many_arguments)]
pub fn with_displacement(
    design: &Design,
    displacement: FittedBaseline,
    chain: Option<ControlChain>,
    source: String,
    config: &TwinConfig,
    load: f64,
    seed: u64,
    horizon: usize,
) -> anyhow::Result<Design> {
    let mut model = design.model.clone();
    model.displacement = displacement;
    model.curvature = 0.0;
    model.chain = chain;
    model.rest_start = true;
    let (_, validation) = twin_records(config, load, seed);
    finish_design(
        model,
        source,
        &validation,
        horizon,
        Some((config, load, seed)),
    )
}

/// The design multisine run on the twin at `load` (seed `seed`) and its
/// validation twin (seed `seed + 1`).
pub fn twin_records(config: &TwinConfig, load: f64, seed: u64) -> (Trace, Trace) {
    let experiment = twin::TwinExperiment::Multisine(design::design_multisine());
    (
        twin::run(config, load, seed, &experiment),
        twin::run(config, load, seed + 1, &experiment),
    )
}

/// Where `mckibben control`'s controllers get their model: its
/// `--design-data`, `--from`, `--design-load`, `--seed` and `--horizon`.
/// Every error names the flag it is about.
#[derive(Debug, Clone, PartialEq)]
pub struct DesignRequest {
    /// An open-loop record (a `valve_in` column) to identify from instead
    /// of the twin's design multisine ([`design_from_record`]).
    pub record: Option<PathBuf>,
    /// The names of the record's columns (`--design-columns`).
    pub columns: DesignColumns,
    /// A model file whose displacement model replaces the identified one
    /// ([`with_displacement`]), read and checked by [`given_model`].
    pub model: Option<GivenModel>,
    /// The twin's load (kg) for the design multisine and the checks.
    pub load_kg: f64,
    pub seed: u64,
    pub horizon: usize,
}

/// A model file for [`DesignRequest::model`], read and checked before any
/// run, so that a file that cannot steer the controllers fails at once,
/// not after the seconds of the design ([`GivenModel::checked`]).
pub fn given_model(path: &Path, note: &dyn Fn(String)) -> anyhow::Result<GivenModel> {
    let m = ModelFile::load(path)
        .and_then(|f| f.model())
        .map_err(|e| anyhow::anyhow!("--from: {e:#}"))?;
    GivenModel::checked(
        m,
        format!("--from {}", path.display()),
        path.display().to_string(),
        note,
    )
}

/// A model for [`DesignRequest::model`] ([`given_model`]).
#[derive(Debug, Clone, PartialEq)]
pub struct GivenModel {
    /// How messages name it: the flag and its path (`--from m.json`).
    pub named: String,
    /// Where it came from, as the design's `source` says it.
    pub source: String,
    pub model: crate::model::Model,
}

impl GivenModel {
    /// `m`, once it is a model the controllers can steer with: of the
    /// pressure and the displacement (a column that states no unit is
    /// taken in MPa and mm, with a `note`; one in another pressure or length
    /// unit is converted to them, effects and all, with a `note`), classic
    /// or linear, its output rising with the pressure.
    /// `named` says it in messages.
    pub fn checked(
        mut m: crate::model::Model,
        named: String,
        source: String,
        note: &dyn Fn(String),
    ) -> anyhow::Result<GivenModel> {
        // The controllers drive pressures in MPa and displacements in mm
        // (the twin's, and the rig protocol's): a model fitted in other
        // units would be off by a factor, silently.
        let per_mpa: fn(&str) -> Option<f64> = megapascals_in;
        let mut factors = [1.0, 1.0];
        for (k, (which, column, want, per_unit)) in [
            ("input", &m.base.input_name, "MPa", per_mpa),
            ("output", &m.base.output_name, "mm", millimetres_in),
        ]
        .into_iter()
        .enumerate()
        {
            match unit_of(column) {
                Some(unit) if unit != want => {
                    let Some(factor) = per_unit(&unit) else {
                        // A valve voltage is another signal, not another unit.
                        let fix = if which == "input" && matches!(unit.as_str(), "V" | "mV") {
                            format!(
                                "the controllers read a model of the pressure (their valve \
                                 model is their own): fit on the pressure column, in {want}"
                            )
                        } else {
                            format!("convert the column to {want} and refit")
                        };
                        anyhow::bail!(
                            "{named}: the model's {which} is in {unit} (column `{column}`), \
                             the controllers' in {want}: {fix}"
                        );
                    };
                    factors[k] = factor;
                    note(format!(
                        "{named}: the model's {which} (column `{column}`, in {unit}) is read \
                         in {want}, the controllers' unit, its parameters converted"
                    ));
                }
                Some(_) => {}
                None => note(format!(
                    "{named}: the model's {which} column `{column}` states no unit; it is \
                     taken in {want}, the controllers' (a model of another signal, such as a \
                     valve voltage, predicts nonsense here)"
                )),
            }
        }
        if factors != [1.0, 1.0] {
            m = m.rescaled(factors[0], factors[1]);
            // The shipped data's names, which state MPa and mm.
            m.base.input_name = "pressure".into();
            m.base.output_name = "displacement".into();
        }
        // Found now, not after the design's seconds of identification.
        anyhow::ensure!(
            m.base.family != Family::Generalized,
            "{named}: the controller's model must be the classic or the linear family (got \
             the generalized one)"
        );
        // The controllers push the displacement up with the pressure (the
        // twin's and the thesis' contraction, positive): a model whose
        // output falls as the pressure rises (an extension, or a
        // contraction logged negative) steers every correction the wrong
        // way, and the MPC holds the valve shut while the run diverges.
        let b = m.base.params[m.base.family.linear_indices()[1]];
        anyhow::ensure!(
            b > 0.0,
            "{named}: the model's output falls as the pressure rises (its input gain b = {}): \
             the controllers move a displacement that grows with the pressure (contraction, \
             positive): flip the output column's sign and refit",
            crate::report::number::significant(b, 4)
        );
        Ok(GivenModel {
            named,
            source,
            model: m,
        })
    }
}

/// The names of a design record's columns (`control --design-columns`):
/// its time (s, or a unit its name states), the input valve's voltage
/// (V), the pressure (MPa) and the displacement (mm). By default those
/// `mckibben twin` writes.
#[derive(Debug, Clone, PartialEq)]
pub struct DesignColumns {
    pub time: String,
    pub valve: String,
    pub pressure: String,
    pub displacement: String,
}

impl DesignColumns {
    /// `--design-columns`' four names, in its order
    /// TIME,VALVE,PRESSURE,DISPLACEMENT, or why not.
    pub fn from_names(names: &[String]) -> anyhow::Result<DesignColumns> {
        let [time, valve, pressure, displacement] = names else {
            anyhow::bail!(
                "--design-columns: {} name{} given; it takes four, in this order: \
                 TIME,VALVE,PRESSURE,DISPLACEMENT (e.g. t,valve_in,pressure,displacement)",
                names.len(),
                if names.len() == 1 { "" } else { "s" }
            );
        };
        let named: Vec<&str> = names.iter().map(|n| n.trim()).collect();
        anyhow::ensure!(
            named.iter().all(|n| !n.is_empty()),
            "--design-columns: an empty name in \"{}\"; give four column names",
            names.join(",")
        );
        crate::names::given_once(
            "--design-columns",
            &named,
            "a column is one signal: time, valve, pressure and displacement are four",
        )?;
        Ok(DesignColumns {
            time: time.trim().into(),
            valve: valve.trim().into(),
            pressure: pressure.trim().into(),
            displacement: displacement.trim().into(),
        })
    }
}

impl Default for DesignColumns {
    fn default() -> Self {
        DesignColumns {
            time: "t".into(),
            valve: VALVE_IN.into(),
            pressure: "pressure".into(),
            displacement: "displacement".into(),
        }
    }
}

/// The design record at `path`, its columns named `columns`, as the design
/// reads it: the valve's column under [`VALVE_IN`], the pressure in MPa
/// and the displacement in mm, converted where the column's name states
/// another unit of them (`note` hears of each conversion). Every error
/// names `--design-data` and the file.
fn read_design_record(
    path: &Path,
    columns: &DesignColumns,
    note: &dyn Fn(String),
) -> anyhow::Result<Trace> {
    let opts = ReadOptions {
        time: columns.time.clone(),
        input: columns.pressure.clone(),
        output: columns.displacement.clone(),
        ..ReadOptions::default()
    };
    let (traces, notes) = read_traces_with_notes(path, &opts).map_err(|e| {
        if let DataError::MissingColumn {
            column, available, ..
        } = &e
        {
            return anyhow::anyhow!(
                "--design-data {}: no column \"{column}\" (the file has {}): {}",
                path.display(),
                available.join(", "),
                COLUMNS_FIX
            );
        }
        let e = e
            .with_time_hint(
                "the design record is one experiment: cut the file there",
                "the design record needs a uniform time step: resample it, or cut it \
                 at its gaps, first",
            )
            .with_cell_hint(
                "; the design record needs a number in every sample's cell: fill the \
                 missed reading, or cut the file there",
            );
        anyhow::anyhow!("--design-data: {e}")
    })?;
    let mut trace = traces
        .into_iter()
        .next()
        .ok_or_else(|| anyhow::anyhow!("--design-data {}: no samples", path.display()))?;
    // A valve column with a bad cell is left out with a note, like any
    // column no model reads; here the model reads it, so the cell is the
    // error.
    let left_out = format!("; column \"{}\" left out", columns.valve);
    if trace.column(&columns.valve).is_none()
        && let Some((cell, _)) = notes.iter().find_map(|n| n.split_once(&left_out))
    {
        anyhow::bail!("--design-data: {cell}: the valve → pressure model reads every sample of it");
    }
    // What the reader did to the file (a time converted to seconds, a
    // column left out) is said as `fit` says it.
    for n in notes {
        note(format!("--design-data {n}"));
    }
    if trace.column(&columns.valve).is_none() {
        let mut available = vec![
            trace.time_name.clone(),
            trace.input_name.clone(),
            trace.output_name.clone(),
        ];
        available.extend(trace.extra.iter().map(|(n, _)| n.clone()));
        anyhow::bail!(
            "--design-data {}: no column \"{}\" (the file has {}): the valve → pressure \
             model needs the input valve's voltage; {COLUMNS_FIX}",
            path.display(),
            columns.valve,
            available.join(", ")
        );
    }
    // The design reads the valve under its own name; a column of that name
    // that is not the valve's goes.
    if columns.valve != VALVE_IN {
        trace.extra.retain(|(n, _)| n != VALVE_IN);
        for (name, _) in &mut trace.extra {
            if *name == columns.valve {
                *name = VALVE_IN.into();
            }
        }
    }
    if let Some(unit) = unit_of(&columns.valve).filter(|u| u != "V") {
        anyhow::bail!(
            "--design-data {}: the valve's column \"{}\" is in {unit}, the valve model's in V: \
             convert it to V",
            path.display(),
            columns.valve
        );
    }
    // The controllers and the twin drive pressures in MPa and move
    // displacements in mm: a column that states another unit of either is
    // converted, one that states no unit is taken so.
    let per_mpa: fn(&str) -> Option<f64> = megapascals_in;
    for (role, column, want, per_unit, values) in [
        (
            "pressure",
            &columns.pressure,
            "MPa",
            per_mpa,
            &mut trace.input,
        ),
        (
            "displacement",
            &columns.displacement,
            "mm",
            millimetres_in,
            &mut trace.output,
        ),
    ] {
        let Some(unit) = unit_of(column) else {
            continue;
        };
        let factor = per_unit(&unit).ok_or_else(|| {
            anyhow::anyhow!(
                "--design-data {}: the {role} column \"{column}\" is in {unit}, which is no \
                 {role}'s unit; the design reads the {role} in {want}",
                path.display()
            )
        })?;
        if factor != 1.0 {
            values.iter_mut().for_each(|v| *v *= factor);
            note(format!(
                "--design-data {}: column \"{column}\" read in {unit} and converted to {want}, \
                 the controllers' unit",
                path.display()
            ));
        }
    }
    // The record's pressure is the controllers' and the twin's, in MPa; a
    // muscle's stays well under 10 MPa, so a larger value is another unit
    // under a name that states none, which the design would read as a
    // record that does not settle the model.
    let largest = trace.input.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    anyhow::ensure!(
        largest <= crate::data::csv::IMPLAUSIBLE_MPA,
        "--design-data {}: column \"{}\" reaches {}, but the design record's pressure is in \
         MPa (the controllers' and the twin's): if it is in kPa, Pa, bar or psi, convert it to \
         MPa, or say so in its name (`pressure_kPa`)",
        path.display(),
        columns.pressure,
        crate::report::number::significant(largest, 4)
    );
    Ok(trace)
}

/// How to point the design at a record's own column names.
const COLUMNS_FIX: &str = "name the file's columns with --design-columns \
     TIME,VALVE,PRESSURE,DISPLACEMENT (time in s, valve voltage in V, pressure in MPa, \
     displacement in mm, unless a name states its unit: `t_ms`, `p_kPa`, `x_m`; by default \
     t,valve_in,pressure,displacement), or rename them";

/// The design `request` asks for, on the twin set up as `config`. How each
/// effect of a model file enters the controllers is in the design's
/// `effects`, and `note` hears of each as soon as it is known, so that a
/// user sees it even when the validation that follows fails.
pub fn design_for(
    request: &DesignRequest,
    config: &TwinConfig,
    note: &dyn Fn(String),
) -> anyhow::Result<Design> {
    let design = match &request.record {
        Some(path) => {
            let trace = read_design_record(path, &request.columns, note)?;
            let design = design_from_record(&trace, request.horizon).with_context(|| {
                format!(
                    "identifying the model from {} (a design record drives the valve with \
                         a multisine over its operating band, as `mckibben twin --experiment \
                         multisine` records one; a stair's few steps do not settle the model)",
                    path.display()
                )
            })?;
            // A muscle's displacement settles without ringing from one
            // sample to the next: a pole outside (0, 1) is the record's
            // lack of excitation, and an MPC on it holds the valve shut.
            let base = &design.model.displacement;
            let a = base.params[base.family.linear_indices()[0]];
            anyhow::ensure!(
                a > 0.0 && a < 1.0,
                "--design-data {}: the model identified from it has the pole a = {} (outside 0 \
                 to 1: it flips sign every sample or grows), so the record does not settle the \
                 model ({:.1} s of it were read); record a longer multisine of the valve",
                path.display(),
                crate::report::number::significant(a, 4),
                trace.len() as f64 * trace.dt() / 2.0
            );
            design
        }
        None => design_on_twin(config, request.load_kg, request.seed, request.horizon)
            .context("identifying the model on the twin")?,
    };
    let Some(GivenModel {
        named,
        source,
        model: m,
    }) = &request.model
    else {
        return Ok(design);
    };
    // As for a design record: a pole outside (0, 1) is a model whose free
    // run flips sign every sample or grows, and the MPC's prediction and
    // the feedforward's inverse on it are no muscle's.
    let a = m.base.params[m.base.family.linear_indices()[0]];
    anyhow::ensure!(
        a > 0.0 && a < 1.0,
        "{named}: the model's pole a = {} (outside 0 to 1: its free run flips sign every \
         sample or grows), and the controllers predict the muscle with it; refit it (`fit` \
         keeps a inside), or fit a longer record where `identify` put its pole there",
        crate::report::number::significant(a, 4)
    );
    // Each effect enters the controllers' prediction where it can, and
    // the run says how (or why not): a note here, and `design.effects`.
    let (chain, uses) = ControlChain::of(m);
    for u in &uses {
        note(format!(
            "{named}: {} ({})",
            u.line(),
            Effect::physical(u.effect.parse().expect("a catalogue name"))
        ));
    }
    // The valve → pressure model stays the design record's, where one was
    // given: the source says both.
    let source = match &request.record {
        Some(record) => format!("{source} (valve → pressure from {})", record.display()),
        None => source.clone(),
    };
    let mut design = with_displacement(
        &design,
        m.base.clone(),
        chain,
        source,
        config,
        request.load_kg,
        request.seed,
        request.horizon,
    )
    .with_context(|| named.clone())?;
    design.effects = uses;
    Ok(design)
}

impl Design {
    /// What the design says to a user: the model's parameters, its
    /// prediction errors, its loop against the twin's and how each effect
    /// of a model file was used, a line each.
    pub fn summary(&self) -> String {
        let params: Vec<String> = self
            .model
            .displacement
            .named_params()
            .iter()
            .map(|(n, v)| format!("{n} {v:.4}"))
            .collect();
        let mut s = format!(
            "model ({}): {}, b2 {:.3}; valve pole {:.3}\n  prediction RMSE over 1–{} steps ahead on the validation record: {:.3} mm (pressure measured), {:.3} mm (from the valve)",
            self.source,
            params.join(", "),
            self.model.curvature,
            self.model.valve.pole,
            self.prediction.horizon,
            self.prediction.rmse_mm,
            self.prediction.end_to_end_rmse_mm
        );
        if let Some(l) = &self.loop_check {
            // The width is the falling branch less the rising one: below
            // zero, a loop that turns the other way, which the area (a
            // size) does not say.
            let turned = |w: f64| match w < 0.0 {
                true => " (its falling branch below the rising: turned the other way)",
                false => "",
            };
            s += &format!(
                "\n  loop on a slow {:.0}–{:.0} V triangle: twin {:.2} MPa·mm, {:.2} mm wide{}; model {:.2} MPa·mm, {:.2} mm wide{} (RMS gap {:.2} mm)",
                OPERATING_BAND_V.0,
                OPERATING_BAND_V.1,
                l.plant.area_mpa_mm,
                l.plant.width_mm,
                turned(l.plant.width_mm),
                l.model.area_mpa_mm,
                l.model.width_mm,
                turned(l.model.width_mm),
                l.rmse_mm
            );
        }
        for u in &self.effects {
            s += &format!("\n  {}", u.line());
        }
        s
    }
}

/// What a controller is built from.
#[derive(Debug, Clone)]
pub struct Ingredients {
    pub model: Option<ControlModel>,
    pub gains: Option<PiGains>,
    pub mpc: MpcSettings,
    pub limits: ValveLimits,
}

/// A controller ready for an episode on a plant sampled every `dt` s, its
/// model's hysteresis scaled by `scale` (1: as identified).
pub fn build(
    kind: Kind,
    scale: f64,
    ing: &Ingredients,
    dt: f64,
) -> anyhow::Result<Box<dyn Controller>> {
    let model = || -> anyhow::Result<ControlModel> {
        let m = ing
            .model
            .as_ref()
            .ok_or_else(|| anyhow::anyhow!("{} needs the identified model", kind.label()))?;
        anyhow::ensure!(
            (m.displacement.dt - dt).abs() < 1e-9,
            "the model was identified at a {} s sample time; the plant samples every {dt} s",
            m.displacement.dt
        );
        Ok(scale_hysteresis(m, scale))
    };
    let gains = || {
        ing.gains
            .ok_or_else(|| anyhow::anyhow!("{} needs the tuned gains", kind.label()))
    };
    let label = run_label(kind, scale);
    Ok(match kind {
        Kind::Pi => Box::new(Pi::new(PiGains::default(), ing.limits, dt, label)),
        Kind::PiTuned => Box::new(Pi::new(gains()?, ing.limits, dt, label)),
        Kind::FfPid => Box::new(FeedforwardPid::new(
            Pi::new(gains()?, ing.limits, dt, "pid"),
            &model()?,
            label,
        )?),
        Kind::Mpc => Box::new(Mpc::new(&model()?, ing.mpc, ing.limits, label)?),
    })
}

/// `mpc` or `mpc (hysteresis ×0.8)`.
pub fn run_label(kind: Kind, scale: f64) -> String {
    scaled_label(kind.label(), scale)
}

/// A controller's name with its model's hysteresis scale where it is not 1.
pub fn scaled_label(controller: &str, scale: f64) -> String {
    if scale == 1.0 {
        controller.to_string()
    } else {
        format!("{controller} (hysteresis ×{scale})")
    }
}

/// One run of the table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RunSpec {
    pub kind: Kind,
    pub freq_rad_s: f64,
    pub load_kg: f64,
    /// The model's hysteresis scaled by this (1: as identified).
    pub hysteresis_scale: f64,
}

/// The runs for `kinds` over `freqs` × `loads`, then every model-based
/// kind again with each hysteresis scale in `scales`.
pub fn plan(kinds: &[Kind], freqs: &[f64], loads: &[f64], scales: &[f64]) -> Vec<RunSpec> {
    let mut runs = Vec::new();
    for &kind in kinds {
        let kind_scales: Vec<f64> = if kind.needs_model() {
            std::iter::once(1.0).chain(scales.iter().copied()).collect()
        } else {
            vec![1.0]
        };
        for &hysteresis_scale in &kind_scales {
            for &load_kg in loads {
                for &freq_rad_s in freqs {
                    runs.push(RunSpec {
                        kind,
                        freq_rad_s,
                        load_kg,
                        hysteresis_scale,
                    });
                }
            }
        }
    }
    runs
}

/// The shape of every episode (see [`Episode`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Shape {
    pub warmup_s: f64,
    pub duration_s: f64,
    pub steady_from_s: f64,
    /// The reference's waveform (the thesis': a sine).
    pub waveform: Waveform,
}

impl Shape {
    /// The thesis' episode: 10 s settling, 20 s of sine, the last 10 s scored.
    pub fn thesis() -> Shape {
        let e = Episode::thesis(1.0);
        Shape {
            warmup_s: e.warmup_s,
            duration_s: e.duration_s,
            steady_from_s: e.steady_from_s,
            waveform: Waveform::Sine,
        }
    }

    pub fn episode(&self, omega: f64) -> Episode {
        let mut e = Episode::short(omega, self.warmup_s, self.duration_s, self.steady_from_s);
        e.reference.waveform = self.waveform;
        e
    }
}

/// A finished run.
#[derive(Debug, Clone)]
pub struct Run {
    pub spec: RunSpec,
    pub result: EpisodeResult,
    pub stats: Option<ControllerStats>,
}

/// Runs `spec` on a fresh in-process twin (sensor-noise seed `seed`).
pub fn run_on_twin(
    spec: &RunSpec,
    ing: &Ingredients,
    config: &TwinConfig,
    seed: u64,
    shape: &Shape,
) -> anyhow::Result<Run> {
    let mut rig = Rig::new(config, spec.load_kg, seed);
    let mut controller = build(spec.kind, spec.hysteresis_scale, ing, rig.dt())?;
    let result = run_episode(
        &mut rig,
        controller.as_mut(),
        &shape.episode(spec.freq_rad_s),
    );
    if let Some(from) = rig.slack_from() {
        anyhow::bail!(
            "{} at {} rad/s under {} kg: the load's ringing left the muscle slack from {:.2} s \
             on, which the twin does not model; its row would measure that, not the \
             controller (a smaller --effect ringing)",
            spec.kind.label(),
            spec.freq_rad_s,
            spec.load_kg,
            from as f64 * rig.dt()
        );
    }
    Ok(Run {
        spec: *spec,
        result,
        stats: controller.stats(),
    })
}

/// The heaviest perturbation of the robustness table: the design load
/// times this.
pub const ROBUST_LOAD_SCALE: f64 = 1.3;

/// The robustness runs of a model-based `kind` at `freq`: the hysteresis
/// ×0.8 and ×1.2 at the design load, and the load 30 % below and above it,
/// each with its ratio to the nominal run (the model as identified, at the
/// design load).
pub fn robustness_specs(kind: Kind, freq: f64, design_load: f64) -> Vec<(String, RunSpec)> {
    let spec = |load_kg, hysteresis_scale| RunSpec {
        kind,
        freq_rad_s: freq,
        load_kg,
        hysteresis_scale,
    };
    vec![
        ("nominal".into(), spec(design_load, 1.0)),
        ("hysteresis ×0.8".into(), spec(design_load, 0.8)),
        ("hysteresis ×1.2".into(), spec(design_load, 1.2)),
        ("load ×0.7".into(), spec(design_load * 0.7, 1.0)),
        (
            format!("load ×{ROBUST_LOAD_SCALE}"),
            spec(design_load * ROBUST_LOAD_SCALE, 1.0),
        ),
    ]
}
