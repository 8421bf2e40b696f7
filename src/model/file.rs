//! The model file: one versioned JSON document that `fit`, `identify` and
//! `diagnose --out` write and `simulate`, `fit --from`, `diagnose --from`
//! and `control` read. It holds the baseline family and its effect chain,
//! every parameter by name, the box it was searched in, the data's columns,
//! units and coordinates, and where it came from (docs/JSON.md, "The model
//! file").

use std::path::Path;

use anyhow::Context as _;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::effects::{Context, Effect, ModelDescription, Unit};
use super::experiment::Experiment;
use super::family::Family;
use super::fitted::FittedBaseline;
use super::sim::DIVERGENCE_BOUND;
use super::user_bound::UserBound;
use crate::data::units::{SHIPPED, UnitPair, unit_of};
use crate::data::write_atomic;
use crate::data::{same_step, tidy_step};

/// What the `format` field of a model file says.
pub const MODEL_FORMAT: &str = "mckibben-model";
/// The model file's version. Version 1 is the bare model (family,
/// canonical vector, means, `dt`, column names), which still reads;
/// version 2 adds the effect chain, the box, units and provenance.
pub const MODEL_VERSION: u32 = 2;

/// A baseline's effect stages with their parameters and the constants they
/// were fitted with (the [`Context`] of the first dataset: the soft stop's
/// knee, the branch tolerance and the rest input come from it, so a model
/// keeps them when it runs on other data).
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    pub effects: Vec<Effect>,
    /// The effects' parameters, in chain order (after the baseline's).
    pub params: Vec<f64>,
    pub context: Context,
    /// Datasets the chain was fitted on (the `load` effect's gains).
    pub datasets: usize,
}

/// A fitted model: the baseline and, where the diagnosis or `fit
/// --effects` found them, its effects.
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    pub base: FittedBaseline,
    pub chain: Option<Chain>,
}

/// A free run of a [`Model`] in absolute units.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    pub output: Vec<f64>,
    /// The hysteretic state `w` (the baseline alone; none with effects,
    /// whose stages change what `w` means, nor for the linear family, which
    /// has none).
    pub w: Option<Vec<f64>>,
    pub diverged_at: Option<usize>,
}

/// The longest a chain is held at its first input to settle
/// ([`Model::simulate_from_rest`]): 2¹⁷ samples, over six time constants of
/// the slowest creep pole the effects' boxes admit.
const MAX_SETTLE: usize = 1 << 17;

/// How still an output held at one input must be, relative to its size,
/// over the last quarter of the hold to count as at rest: `f32` resolution.
const SETTLED: f64 = 1e-6;

impl Model {
    /// A baseline without effects.
    pub fn plain(base: FittedBaseline) -> Model {
        Model { base, chain: None }
    }

    /// The effects, in chain order (none for a baseline).
    pub fn effects(&self) -> &[Effect] {
        self.chain.as_ref().map_or(&[], |c| &c.effects)
    }

    /// The model description the evaluator and the diagnosis use.
    pub fn augmented(&self) -> ModelDescription {
        let datasets = self.chain.as_ref().map_or(1, |c| c.datasets);
        ModelDescription::new(self.base.family, self.effects().to_vec(), datasets)
    }

    /// The first sample at which `output`, a free run of this model, stepped
    /// further in one sample than its hysteresis update settles within
    /// ([`Family::stable_step`]): `(sample, step, limit)`. Only for a model
    /// without effect stages, whose output is the state the update steps
    /// on; with them, or where the loop never saturates, `None`.
    pub fn overstep(&self, output: &[f64]) -> Option<(usize, f64, f64)> {
        if !self.effects().is_empty() {
            return None;
        }
        let limit = self.base.family.stable_step(&self.base.params)?;
        (1..output.len())
            .map(|k| (k, (output[k] - output[k - 1]).abs()))
            .find(|&(_, step)| step > limit)
            .map(|(k, step)| (k, step, limit))
    }

    /// The same model for an input read in units `per_input` times the
    /// fitted ones and an output `per_output` times, both above 0 (psi and
    /// m wanted in MPa and mm: 0.006895 and 1000). The baseline converts as
    /// [`FittedBaseline::rescaled`] says; each effect parameter takes the
    /// factor of the unit the catalogue gives it ([`Unit::factor`](super::effects::Unit::factor): a
    /// threshold the input's, a gain both), and the chain's context (its
    /// means, ranges and branch tolerance) the factor of its side. It
    /// predicts the same motion, each number in the new units; the columns
    /// keep their names.
    pub fn rescaled(&self, per_input: f64, per_output: f64) -> Model {
        let chain = self.chain.as_ref().map(|c| {
            let units = c
                .effects
                .iter()
                .flat_map(|e| e.params(c.datasets))
                .map(|p| p.unit.factor(per_input, per_output));
            Chain {
                params: c.params.iter().zip(units).map(|(v, f)| v * f).collect(),
                context: c.context.rescaled(per_input, per_output),
                ..c.clone()
            }
        });
        Model {
            base: self.base.rescaled(per_input, per_output),
            chain,
        }
    }

    /// Every parameter: the baseline's canonical vector, then the effects'.
    pub fn theta(&self) -> Vec<f64> {
        let mut theta = self.base.params.clone();
        if let Some(c) = &self.chain {
            theta.extend_from_slice(&c.params);
        }
        theta
    }

    /// Every parameter by name (`creep:two-pole.kappa` for an effect's).
    pub fn named_params(&self) -> Vec<(String, f64)> {
        self.augmented()
            .param_names()
            .into_iter()
            .zip(self.theta())
            .collect()
    }

    /// The dynamics of this model's effects among `effects` (poles, delays,
    /// how fast steps fall: [`Effect::is_dynamics`]), each held at its value
    /// as `--fix effect.param=VALUE` holds it: a chain carried to another
    /// record of the same muscle keeps how its effects evolve in time and
    /// refits how large they are, in that record's own scale. An estimation
    /// half of a few loadings pins a gain far better than the time
    /// constant of a state slower than the record.
    pub fn held_dynamics(&self, effects: &[Effect]) -> Vec<UserBound> {
        let description = self.augmented();
        let theta = self.theta();
        let mut held = Vec::new();
        for &e in self.effects().iter().filter(|e| effects.contains(e)) {
            let at = description.offset_of(e).expect("the model's own effect");
            for (i, p) in e.params(description.datasets).into_iter().enumerate() {
                if e.is_dynamics(&p.name) {
                    let value = theta[at + i];
                    held.push(UserBound {
                        name: format!("{e}.{}", p.name),
                        lower: value,
                        upper: value,
                    });
                }
            }
        }
        held
    }

    /// This model in the units of `trace`'s columns, where a column's name
    /// states another unit of the same kind than the model's (a record in
    /// kPa for a model fitted in psi, in m for one in mm:
    /// [`crate::data::units::between`]), converted as [`Model::rescaled`]
    /// converts it and named after the record's columns, with a note for
    /// each side converted; the model as it is otherwise. `whose` names the
    /// model in the notes ("the start model"). What is still off (another
    /// kind of unit, another sample time) is left for [`Model::check_data`].
    pub fn in_units_of(&self, trace: &crate::data::Trace, whose: &str) -> (Model, Vec<String>) {
        let [input, output] = self.units_to(trace);
        if input.is_none() && output.is_none() {
            return (self.clone(), Vec::new());
        }
        let factor = |pair: &Option<UnitPair>| pair.as_ref().map_or(1.0, UnitPair::to_record);
        let base = &self.base;
        let mut model = self.rescaled(factor(&input), factor(&output));
        let mut notes = Vec::new();
        for (pair, fitted, column, name) in [
            (
                &input,
                &base.input_name,
                &trace.input_name,
                &mut model.base.input_name,
            ),
            (
                &output,
                &base.output_name,
                &trace.output_name,
                &mut model.base.output_name,
            ),
        ] {
            if let Some(pair) = pair {
                notes.push(format!(
                    "{}: {whose}'s `{fitted}` ({}) is read in {}, the unit of `{column}` (×{}): \
                     its parameters converted",
                    trace.source,
                    pair.model,
                    pair.record,
                    crate::data::readable(pair.to_record())
                ));
                *name = column.clone();
            }
        }
        (model, notes)
    }

    /// How this model's input and output units pair with `trace`'s, where
    /// a column's name states another unit of the same kind
    /// ([`crate::data::units::between`]).
    fn units_to(&self, trace: &crate::data::Trace) -> [Option<UnitPair>; 2] {
        use crate::data::units::{between, megapascals_in, millimetres_in};
        [
            between(&trace.input_name, &self.base.input_name, megapascals_in),
            between(&trace.output_name, &self.base.output_name, millimetres_in),
        ]
    }

    /// The factor [`Model::rescaled`] takes the parameter `name` by (a
    /// canonical name, or an effect's `effect.param`); 1 for a search
    /// coordinate, a pure number (`gain`, `loading`: `crate::model::coords`),
    /// and for a name the model does not hold.
    pub fn factor_of(&self, name: &str, per_input: f64, per_output: f64) -> f64 {
        self.unit_of(name)
            .map_or(1.0, |u| u.factor(per_input, per_output))
    }

    /// What the parameter `name` is measured in (a canonical name, or an
    /// effect's `effect.param`); `None` for a name the model does not hold.
    pub fn unit_of(&self, name: &str) -> Option<Unit> {
        if let Some(i) = self.base.family.index_of(name) {
            return Some(self.base.unit(i));
        }
        let datasets = self.augmented().datasets;
        self.effects()
            .iter()
            .flat_map(|e| e.params(datasets).into_iter().map(move |p| (e, p)))
            .find(|(e, p)| format!("{e}.{}", p.name) == name)
            .map(|(_, p)| p.unit)
    }

    /// Every parameter's unit by name, in [`Model::named_params`]' order,
    /// written with the units the model's columns state (`mm/MPa`, `1/mm`;
    /// `1` for a pure number; `output` and `input` for a column that
    /// states none).
    pub fn units(&self) -> Vec<(String, String)> {
        let stated = |column: &str, none: &str| unit_of(column).unwrap_or(none.into());
        let input = stated(&self.base.input_name, "input");
        let output = stated(&self.base.output_name, "output");
        (self.named_params().into_iter())
            .map(|(name, _)| {
                let unit = self.unit_of(&name).map(|u| u.text(&input, &output));
                (name, unit.expect("a parameter of the model's own"))
            })
            .collect()
    }

    /// Refuses a record this model's chain cannot be carried to (`diagnose
    /// --transfer`): another sample time, or a column in another kind of unit.
    /// The dynamics it holds are pure numbers, so a record in other units
    /// of the same kinds ([`Model::in_units_of`]) takes them as they are.
    pub fn check_carried_to(&self, trace: &crate::data::Trace) -> anyhow::Result<()> {
        self.in_units_of(trace, "the carried model")
            .0
            .check_data(trace)
    }

    /// Refuses data this model cannot run on as it stands: a column whose
    /// name states other units than the model's (a model fitted in psi run
    /// on kPa is off by a factor, silently), or another sample time (the
    /// model is discrete-time: its poles are per sample). Names without a
    /// unit are taken at their word.
    pub fn check_data(&self, trace: &crate::data::Trace) -> anyhow::Result<()> {
        let base = &self.base;
        check_units("the model's", &base.input_name, &base.output_name, trace)?;
        let dt = trace.dt();
        anyhow::ensure!(
            same_step(dt, base.dt),
            "{} is sampled every {} s, the model every {} s: a discrete-time model's poles \
             are per sample, so resample the data onto its time base (--resample {})",
            trace.source,
            tidy_step(dt),
            tidy_step(base.dt),
            tidy_step(base.dt)
        );
        Ok(())
    }

    /// Free run on a trace's input from its first measured output.
    pub fn simulate_trace(&self, trace: &crate::data::Trace) -> Vec<f64> {
        let y0 = trace
            .output
            .first()
            .copied()
            .unwrap_or(self.base.output_mean);
        self.simulate_absolute(&trace.input, y0).output
    }

    /// Free run on an input in absolute units from rest at its first value,
    /// as a muscle that has sat at that pressure: the baseline starts where
    /// it stays ([`FittedBaseline::rest_output`]), and a chain, whose
    /// effects' slow states start at zero, first runs held at that value
    /// until its output stops moving (at most `MAX_SETTLE`, 2¹⁷ samples, not
    /// part of the run returned). A model with no stable rest starts at its
    /// output mean.
    pub fn simulate_from_rest(&self, input: &[f64]) -> Run {
        let Some(&first) = input.first() else {
            return self.simulate_absolute(input, self.base.output_mean);
        };
        let y0 = self
            .base
            .rest_output(first)
            .unwrap_or(self.base.output_mean);
        if self.chain.is_none() {
            return self.simulate_absolute(input, y0);
        }
        let mut held = 1024;
        while held < MAX_SETTLE {
            let y = self.simulate_absolute(&vec![first; held], y0).output;
            let end = y[held - 1];
            let settled = y[held - held / 4..]
                .iter()
                .all(|v| (v - end).abs() <= SETTLED * (1.0 + end.abs()));
            if settled || !end.is_finite() {
                break;
            }
            held *= 2;
        }
        let mut prefixed = vec![first; held];
        prefixed.extend_from_slice(input);
        let mut run = self.simulate_absolute(&prefixed, y0);
        run.output.drain(..held);
        if let Some(w) = &mut run.w {
            w.drain(..held);
        }
        run.diverged_at = run.diverged_at.map(|k| k.saturating_sub(held));
        run
    }

    /// Free run on an input in absolute units from the absolute output `y0`
    /// (dataset 0 of a chain fitted on several).
    pub fn simulate_absolute(&self, input: &[f64], y0: f64) -> Run {
        let Some(chain) = &self.chain else {
            let (output, sim) = self.base.simulate_absolute(input, y0);
            let hysteretic = self.base.family.exponent_index().is_some();
            return Run {
                output,
                w: hysteretic.then(|| sim.w.iter().map(|&w| w as f64).collect()),
                diverged_at: sim.diverged_at,
            };
        };
        let base = &self.base;
        let exp = Experiment {
            name: "simulation".into(),
            dt: base.dt,
            u: input
                .iter()
                .map(|&p| (p - base.input_mean) as f32)
                .collect(),
            y: vec![(y0 - base.output_mean) as f32],
            u_mean: base.input_mean,
            y_mean: base.output_mean,
        };
        let theta: Vec<f32> = self.theta().iter().map(|&v| v as f32).collect();
        let y = self.augmented().simulate(&theta, 0, &chain.context, &exp);
        let diverged_at = y
            .iter()
            .position(|v| !v.is_finite() || v.abs() > DIVERGENCE_BOUND);
        Run {
            output: y.iter().map(|&v| v as f64 + base.output_mean).collect(),
            w: None,
            diverged_at,
        }
    }
}

/// One column of the data a model was fitted on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Column {
    pub column: String,
    /// Read off the column's name (`pressure_psi` → psi); `null` when the
    /// name states none.
    pub unit: Option<String>,
    /// The mean removed before fitting: the model's coordinates.
    pub mean: f64,
}

/// The data's columns and the coordinates a model runs in.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DataCoords {
    pub input: Column,
    pub output: Column,
    /// Sample time the model was fitted at (s).
    pub dt: f64,
    /// The effects' constants ([`Chain::context`]); `null` without effects.
    pub effect_context: Option<Context>,
}

/// How the data file was read: what `simulate --from` reads new data with
/// unless told otherwise.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ReadSettings {
    pub time: Option<String>,
    pub resample: Option<f64>,
    pub split_gaps: bool,
    /// A file without a time column, its rows this many seconds apart
    /// (`--dt`); absent from files written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dt: Option<f64>,
}

/// One data file a model was fitted on, with its SHA-256.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Source {
    pub file: String,
    pub sha256: Option<String>,
}

/// Where a model came from.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The command line that wrote it.
    pub command: String,
    pub tool_version: String,
    pub seed: Option<u64>,
    pub data: Vec<Source>,
    pub read: ReadSettings,
}

impl Provenance {
    /// This process's command line, the files (hashed) and how they were read.
    pub fn here(files: &[String], seed: Option<u64>, read: ReadSettings) -> Provenance {
        // `args()` panics on a name that is not UTF-8 (a file from another
        // system); the record keeps it readable, its odd bytes replaced.
        let command: Vec<String> = std::env::args_os()
            .map(|a| a.to_string_lossy().into_owned())
            .collect();
        Provenance {
            command: command.join(" "),
            tool_version: env!("CARGO_PKG_VERSION").into(),
            seed,
            data: files
                .iter()
                .map(|f| Source {
                    file: f.clone(),
                    sha256: sha256_of(Path::new(f)),
                })
                .collect(),
            read,
        }
    }
}

impl Provenance {
    /// Whether the file at `path` holds the very bytes of one the model was
    /// fitted on (its SHA-256 is among `data`'s): its scores there include
    /// the part that fitted, or chose, the model.
    pub fn fitted_on(&self, path: &Path) -> bool {
        let Some(digest) = sha256_of(path) else {
            return false;
        };
        self.data
            .iter()
            .any(|d| d.sha256.as_deref() == Some(digest.as_str()))
    }
}

/// The hex SHA-256 of a file's bytes (none for a generated trace, and none
/// for a pipe or standard input: what it held was read once, and opening
/// it again waits for a writer that never comes, or hashes nothing).
fn sha256_of(path: &Path) -> Option<String> {
    if path == Path::new(crate::data::input::STANDARD_INPUT)
        || !std::fs::metadata(path).ok()?.is_file()
    {
        return None;
    }
    let bytes = crate::data::input::read(path).ok()?;
    let digest = Sha256::digest(&bytes);
    Some(digest.iter().map(|b| format!("{b:02x}")).collect())
}

/// The box a model's parameters were searched in: its coordinates (the
/// data's own scale for the baseline, the effects' own parameters), their
/// bounds and where each bound comes from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SearchBox {
    pub names: Vec<String>,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    /// `data`, `class` or `user` for each `[lower, upper]`.
    pub origin: Vec<[super::bounds::Origin; 2]>,
}

impl SearchBox {
    /// The box of a fit's search space.
    pub fn of(space: &super::bounds::SearchSpace) -> SearchBox {
        SearchBox {
            names: space.names(),
            lower: space.lower.clone(),
            upper: space.upper.clone(),
            origin: space.origin.clone(),
        }
    }
}

/// A model file as written: [`Model`] plus its box and provenance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelFile {
    pub format: String,
    pub version: u32,
    pub family: Family,
    /// Effect realisations in chain order (`creep:two-pole`, ...).
    pub effects: Vec<String>,
    /// Every parameter by name: the baseline's in canonical order, then the
    /// effects' as `effect.param`.
    pub params: serde_json::Map<String, serde_json::Value>,
    /// Datasets the model was fitted on together (the `load` effect).
    pub datasets: usize,
    pub data: DataCoords,
    /// The search box; `null` for a model not searched in one (ARX).
    pub search_box: Option<SearchBox>,
    /// The `--bound` and `--fix` the fit was given (`NAME=LO:HI`): `fit
    /// --from` applies them again.
    #[serde(default)]
    pub user_bounds: Vec<String>,
    pub provenance: Provenance,
}

impl ModelFile {
    /// The file of `model`.
    pub fn new(model: &Model, search_box: Option<SearchBox>, provenance: Provenance) -> ModelFile {
        let base = &model.base;
        let params = model
            .named_params()
            .into_iter()
            .map(|(n, v)| (n, serde_json::json!(v)))
            .collect();
        ModelFile {
            format: MODEL_FORMAT.into(),
            version: MODEL_VERSION,
            family: base.family,
            effects: model.effects().iter().map(|e| e.name().into()).collect(),
            params,
            datasets: model.chain.as_ref().map_or(1, |c| c.datasets),
            data: DataCoords {
                input: Column {
                    column: base.input_name.clone(),
                    unit: unit_of(&base.input_name),
                    mean: base.input_mean,
                },
                output: Column {
                    column: base.output_name.clone(),
                    unit: unit_of(&base.output_name),
                    mean: base.output_mean,
                },
                dt: base.dt,
                effect_context: model.chain.as_ref().map(|c| c.context),
            },
            search_box,
            user_bounds: Vec::new(),
            provenance,
        }
    }

    /// Writes the file atomically (a failed write leaves the old one).
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        let text = serde_json::to_string_pretty(self)?;
        write_atomic(path, text.as_bytes())
            .with_context(|| format!("cannot write {}", path.display()))
    }

    /// Reads a model file of this version or version 1 (a bare model, or
    /// `identify --out`'s document whose `model` field holds one).
    pub fn load(path: &Path) -> anyhow::Result<ModelFile> {
        let text = crate::data::input::read_to_string(path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let value: serde_json::Value =
            serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))?;
        // `identify --out` writes its report with the model in `model`:
        // `null` for ARX orders other than the model file's first order, a
        // list of reports for the pieces of `--split-gaps`.
        if value.get("arx").is_some() && value.get("model").is_none_or(|m| m.is_null()) {
            anyhow::bail!(
                "{}: an `identify` report without a model: only the first-order ARX \
                 (--na 1 --nb 1 --nk 1, the default) is a model `simulate` and `fit` read",
                path.display()
            );
        }
        if value
            .as_array()
            .is_some_and(|a| a.first().is_some_and(|r| r.get("arx").is_some()))
        {
            anyhow::bail!(
                "{}: `identify` reports of several pieces (--split-gaps): a model file holds \
                 one model: identify one piece at a time",
                path.display()
            );
        }
        let whole = value.clone();
        let value = match value.get("model") {
            Some(inner) if value.get("format").is_none() && inner.get("format").is_some() => {
                inner.clone()
            }
            _ => value,
        };
        let Some(format) = value.get("format") else {
            let legacy = legacy_model(path, value)?;
            return Ok(ModelFile::new(
                &Model::plain(legacy),
                None,
                Provenance::default(),
            ));
        };
        anyhow::ensure!(
            format.as_str() == Some(MODEL_FORMAT),
            "{}: `format` is {format}, not \"{MODEL_FORMAT}\": not a model file",
            path.display()
        );
        let version = value.get("version").and_then(|v| v.as_u64());
        // Only a version past this build's is a newer mckibben's.
        let why = match version {
            Some(v) if v > MODEL_VERSION as u64 => "a newer mckibben wrote it",
            _ => "no mckibben writes it",
        };
        anyhow::ensure!(
            version.is_some_and(|v| (1..=MODEL_VERSION as u64).contains(&v)),
            "{}: model file version {}: this mckibben ({}) reads versions 1 to {MODEL_VERSION}; \
             {why}",
            path.display(),
            version.map_or("missing".to_string(), |v| v.to_string()),
            env!("CARGO_PKG_VERSION")
        );
        let file: ModelFile = serde_json::from_value(value.clone())
            .map_err(|e| {
                // A value carries no positions: where the whole text is the
                // model, reading the text again says at which line and column
                // the field is wrong.
                let positioned = (value == whole)
                    .then(|| serde_json::from_str::<ModelFile>(&text).err())
                    .flatten();
                anyhow::anyhow!("{}", positioned.unwrap_or(e))
            })
            .with_context(|| format!("{}: not a valid model file", path.display()))?;
        file.model()
            .with_context(|| format!("{}: not a valid model file", path.display()))?;
        Ok(file)
    }

    /// This file in the units of `trace`'s columns, where a column's name
    /// states another unit of the same kind than the model's: its model as
    /// [`Model::in_units_of`] converts it (the notes are its), and its
    /// `user_bounds`, which `fit --from` applies again, each by its
    /// parameter's factor ([`Model::factor_of`]). The search box, in the
    /// old units, is dropped: no start reads it. The file as it is
    /// otherwise.
    pub fn in_units_of(
        &self,
        trace: &crate::data::Trace,
        whose: &str,
    ) -> anyhow::Result<(ModelFile, Vec<String>)> {
        let model = self.model()?;
        let (converted, notes) = model.in_units_of(trace, whose);
        if notes.is_empty() {
            return Ok((self.clone(), notes));
        }
        let [per_input, per_output] = model
            .units_to(trace)
            .map(|p| p.as_ref().map_or(1.0, UnitPair::to_record));
        let user_bounds = (self.user_bounds.iter())
            .map(|given| {
                let b: UserBound = given.parse().map_err(anyhow::Error::msg)?;
                let f = model.factor_of(&b.name, per_input, per_output);
                Ok(UserBound {
                    lower: b.lower * f,
                    upper: b.upper * f,
                    ..b
                }
                .to_string())
            })
            .collect::<anyhow::Result<_>>()
            .context("its user_bounds")?;
        let mut file = ModelFile::new(&converted, None, self.provenance.clone());
        file.user_bounds = user_bounds;
        Ok((file, notes))
    }

    /// The model the file holds; an error names a parameter missing or
    /// unknown (they are read by name, in any order), or an unknown effect. A generalized model
    /// whose file has no switching level `x_s` switches at its estimation
    /// mean, so it reads with `x_s` = its output mean: the same model, to
    /// the bit ([`crate::model::sim::switch_threshold`]).
    pub fn model(&self) -> anyhow::Result<Model> {
        let effects: Vec<Effect> = self
            .effects
            .iter()
            .map(|e| Ok(e.parse::<Effect>()?))
            .collect::<anyhow::Result<_>>()?;
        if let Some(why) = Effect::chain_conflict(&effects) {
            anyhow::bail!("`effects` {why}");
        }
        anyhow::ensure!(self.datasets >= 1, "`datasets` must be at least 1");
        // The poles are per sample: without a sample time the model cannot
        // run on any record (every command would blame its own flags).
        anyhow::ensure!(
            self.data.dt > 0.0 && self.data.dt.is_finite(),
            "`data.dt` is {}: a model needs the sample time it was fitted at (positive \
             seconds)",
            self.data.dt
        );
        // The unit is read off the column's name wherever data meet the
        // model: a `unit` edited alone would say one unit and act another.
        // (`null` states none; a file written before a name's unit was
        // recognised has one.)
        for (which, column) in [("input", &self.data.input), ("output", &self.data.output)] {
            let named = unit_of(&column.column);
            if let Some(unit) = &column.unit {
                anyhow::ensure!(
                    named.as_ref() == Some(unit),
                    "`data.{which}.unit` is `{unit}`, but its column `{}` names {}: the unit \
                     is read off the column's name, so edit the name to change it",
                    column.column,
                    named
                        .as_deref()
                        .map_or("no unit".into(), |u| format!("`{u}`")),
                );
            }
        }
        // Checked before the names are listed: a count far past the values
        // asked for more names than memory holds.
        if let Some(e) = effects.iter().find(|e| e.per_later_dataset()) {
            anyhow::ensure!(
                self.datasets <= self.params.len() + 1,
                "`datasets` is {}, but `params` holds {} values: `{e}` has a parameter for \
                 each dataset after the first",
                self.datasets,
                self.params.len()
            );
        }
        let augmented = ModelDescription::new(self.family, effects.clone(), self.datasets);
        let names = augmented.param_names();
        let mut params = self.params.clone();
        if self.family.switch_index().is_some() && !params.contains_key("x_s") {
            params.insert("x_s".into(), serde_json::json!(self.data.output.mean));
        }
        let given: Vec<&String> = params.keys().collect();
        if let Some(missing) = names.iter().find(|n| !params.contains_key(*n)) {
            anyhow::bail!(
                "parameter `{missing}` is missing: a {} model{} has {}",
                self.family,
                chain_text(&effects),
                names.join(", ")
            );
        }
        if let Some(unknown) = given.iter().find(|g| !names.contains(g)) {
            anyhow::bail!(
                "unknown parameter `{unknown}`: a {} model{} has {}",
                self.family,
                chain_text(&effects),
                names.join(", ")
            );
        }
        let theta: Vec<f64> = names
            .iter()
            .map(|n| {
                params[n]
                    .as_f64()
                    .with_context(|| format!("parameter `{n}` is not a number"))
            })
            .collect::<anyhow::Result<_>>()?;
        let d = self.family.dim();
        if let Some(why) = self
            .family
            .exponent_index()
            .and_then(|i| Family::exponent_refused(theta[i]))
        {
            anyhow::bail!("parameter `n`: {why}");
        }
        let base = FittedBaseline {
            family: self.family,
            params: theta[..d].to_vec(),
            input_mean: self.data.input.mean,
            output_mean: self.data.output.mean,
            dt: self.data.dt,
            input_name: self.data.input.column.clone(),
            output_name: self.data.output.column.clone(),
        };
        let chain = if effects.is_empty() {
            None
        } else {
            let context = self
                .data
                .effect_context
                .context("a model with effects needs `data.effect_context`")?;
            Some(Chain {
                effects,
                params: theta[d..].to_vec(),
                context,
                datasets: self.datasets,
            })
        };
        Ok(Model { base, chain })
    }
}

fn chain_text(effects: &[Effect]) -> String {
    if effects.is_empty() {
        String::new()
    } else {
        let names: Vec<&str> = effects.iter().map(|e| e.name()).collect();
        format!(" with {}", names.join(", "))
    }
}

/// A version-1 model: bare, or in `identify --out`'s `model` field.
fn legacy_model(path: &Path, value: serde_json::Value) -> anyhow::Result<FittedBaseline> {
    let inner = value.get("model").cloned().unwrap_or(value);
    let mut model: FittedBaseline = serde_json::from_value(inner).with_context(|| {
        format!(
            "{}: not a model file (no `format` field, and not a version-1 model written \
             by identify or fit)",
            path.display()
        )
    })?;
    let names: Vec<&str> = model.family.params().iter().map(|p| p.name).collect();
    // No switching level in the file: the model switches at its
    // estimation mean ([`ModelFile::model`]).
    if let Some(is) = model.family.switch_index()
        && model.params.len() + 1 == names.len()
    {
        model.params.insert(is, model.output_mean);
    }
    anyhow::ensure!(
        model.params.len() == names.len(),
        "{}: a {} model has {} parameters ({}), the file has {}; a model written \
         before the start offset x0 was added needs it appended (0 keeps its behaviour)",
        path.display(),
        model.family,
        names.len(),
        names.join(", "),
        model.params.len()
    );
    Ok(model)
}

/// Whether `trace`'s columns are in the units of `whose` columns (`input`,
/// `output`: a model's, or the records it is fitted on), where both names
/// state one: a model of pressure in bar runs wrong on kPa without a word
/// otherwise.
pub fn check_units(
    whose: &str,
    input: &str,
    output: &str,
    trace: &crate::data::Trace,
) -> anyhow::Result<()> {
    for (which, fitted, column) in [
        ("input", input, &trace.input_name),
        ("output", output, &trace.output_name),
    ] {
        if let (Some(was), Some(now)) = (unit_of(fitted), unit_of(column)) {
            // `pressure`, `displacement`, `valve_in` state no unit: they
            // are the shipped data's names, read in its units.
            let named = if SHIPPED.iter().any(|(name, _)| *name == column.trim()) {
                format!(
                    "`{column}` is read as {now} (its name states no unit: the shipped data's \
                     convention)"
                )
            } else {
                format!("`{column}` is in {now}")
            };
            anyhow::ensure!(
                was == now,
                "{}: {whose} {which} is in {was} (column `{fitted}`), but {named}: convert the \
                 column, or name its unit, or refit the model on data in {now}",
                trace.source
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::presets::thesis_params;

    fn base() -> FittedBaseline {
        FittedBaseline {
            family: Family::Classic,
            params: thesis_params(Family::Classic),
            input_mean: 0.25,
            output_mean: 10.0,
            dt: 0.1,
            input_name: "pressure".into(),
            output_name: "displacement".into(),
        }
    }

    fn chained() -> Model {
        let exp = Experiment {
            name: "x".into(),
            dt: 0.1,
            u: (0..200).map(|k| ((k as f32) * 0.05).sin() * 0.1).collect(),
            y: (0..200).map(|k| ((k as f32) * 0.05).sin() * 3.0).collect(),
            u_mean: 0.25,
            y_mean: 10.0,
        };
        Model {
            base: base(),
            chain: Some(Chain {
                effects: vec![Effect::Creep, Effect::Ringing],
                params: vec![0.99, 2.0, 0.5, 1.2, 0.6, 0.3],
                context: Context::of(&exp, true),
                datasets: 1,
            }),
        }
    }

    #[test]
    fn a_model_with_effects_survives_the_file_bit_for_bit() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("model.json");
        let model = chained();
        ModelFile::new(&model, None, Provenance::default())
            .save(&path)
            .unwrap();
        let back = ModelFile::load(&path).unwrap().model().unwrap();
        assert_eq!(back, model);
        let input: Vec<f64> = (0..300)
            .map(|k| 0.25 + 0.1 * (k as f64 * 0.03).sin())
            .collect();
        let a = model.simulate_absolute(&input, 10.0);
        assert_eq!(a, back.simulate_absolute(&input, 10.0));
        // The chain changes the output: it is not the baseline's.
        let plain = Model::plain(base()).simulate_absolute(&input, 10.0);
        assert_ne!(a.output, plain.output);
    }

    #[test]
    fn version_one_reads_and_bad_files_name_what_is_wrong() {
        let dir = tempfile::tempdir().unwrap();
        let write = |name: &str, text: String| {
            let p = dir.path().join(name);
            std::fs::write(&p, text).unwrap();
            p
        };
        let v1 = write("v1.json", serde_json::to_string(&base()).unwrap());
        let read = ModelFile::load(&v1).unwrap().model().unwrap();
        assert_eq!(read, Model::plain(base()));
        let wrapped = write(
            "id.json",
            format!(
                r#"{{"model": {}}}"#,
                serde_json::to_string(&base()).unwrap()
            ),
        );
        assert_eq!(ModelFile::load(&wrapped).unwrap().model().unwrap(), read);

        let mut file = ModelFile::new(&chained(), None, Provenance::default());
        file.version = 9;
        let newer = write("v9.json", serde_json::to_string(&file).unwrap());
        let e = format!("{:#}", ModelFile::load(&newer).unwrap_err());
        assert!(e.contains("version 9") && e.contains("newer"), "{e}");
        file.version = 0;
        let zero = write("v0.json", serde_json::to_string(&file).unwrap());
        let e = format!("{:#}", ModelFile::load(&zero).unwrap_err());
        assert!(
            e.contains("version 0") && e.contains("no mckibben writes it"),
            "{e}"
        );

        let mut file = ModelFile::new(&chained(), None, Provenance::default());
        file.params.remove("creep.kappa");
        let missing = write("missing.json", serde_json::to_string(&file).unwrap());
        let e = format!("{:#}", ModelFile::load(&missing).unwrap_err());
        assert!(e.contains("`creep.kappa` is missing"), "{e}");

        let mut file = ModelFile::new(&chained(), None, Provenance::default());
        file.effects[0] = "friction".into();
        let unknown = write("unknown.json", serde_json::to_string(&file).unwrap());
        let e = format!("{:#}", ModelFile::load(&unknown).unwrap_err());
        assert!(e.contains("unknown effect `friction`"), "{e}");

        // Every command would otherwise blame its own --dt or --resample.
        let mut file = ModelFile::new(&chained(), None, Provenance::default());
        file.data.dt = 0.0;
        let no_dt = write("no_dt.json", serde_json::to_string(&file).unwrap());
        let e = format!("{:#}", ModelFile::load(&no_dt).unwrap_err());
        assert!(e.contains("`data.dt` is 0"), "{e}");

        // A duplicate would otherwise read as parameters missing from a
        // chain that lists the effect's names twice.
        let mut file = ModelFile::new(&chained(), None, Provenance::default());
        file.effects.push(file.effects[0].clone());
        let twice = write("twice.json", serde_json::to_string(&file).unwrap());
        let e = format!("{:#}", ModelFile::load(&twice).unwrap_err());
        assert!(e.contains("`effects` names `creep` twice"), "{e}");
        // Two realisations of one physical effect: a model holds one.
        let mut file = ModelFile::new(&chained(), None, Provenance::default());
        file.effects.push("creep:output".into());
        let both = write("both.json", serde_json::to_string(&file).unwrap());
        let e = format!("{:#}", ModelFile::load(&both).unwrap_err());
        assert!(
            e.contains("names `creep` and `creep:output`, two realisations of `creep`"),
            "{e}"
        );

        // A count of datasets past `load`'s parameters listed more names
        // than memory holds: the command aborted.
        let mut file = ModelFile::new(&chained(), None, Provenance::default());
        file.effects.push("load".into());
        file.datasets = usize::MAX;
        let huge = write("huge.json", serde_json::to_string(&file).unwrap());
        let e = format!("{:#}", ModelFile::load(&huge).unwrap_err());
        assert!(e.contains("`load` has a parameter for each dataset"), "{e}");

        // A field of the wrong type is named by its place in the file.
        let file = ModelFile::new(&chained(), None, Provenance::default());
        let text = serde_json::to_string_pretty(&file).unwrap().replacen(
            "\"dt\": ",
            "\"dt\": null, \"was\": ",
            1,
        );
        let line = 1 + text[..text.find("\"dt\": null").unwrap()]
            .matches('\n')
            .count();
        let null_dt = write("null_dt.json", text);
        let e = format!("{:#}", ModelFile::load(&null_dt).unwrap_err());
        assert!(
            e.contains("invalid type: null") && e.contains(&format!("at line {line} column")),
            "{e}"
        );
    }

    #[test]
    fn a_generalized_model_from_before_x_s_switches_at_its_estimation_mean() {
        let dir = tempfile::tempdir().unwrap();
        let mut now = FittedBaseline {
            family: Family::Generalized,
            params: thesis_params(Family::Generalized),
            ..base()
        };
        let is = Family::Generalized.switch_index().unwrap();
        now.params[is] = now.output_mean;
        // Version 1: the bare model with 13 parameters.
        let mut before = serde_json::to_value(&now).unwrap();
        before["params"].as_array_mut().unwrap().remove(is);
        let v1 = dir.path().join("v1.json");
        std::fs::write(&v1, before.to_string()).unwrap();
        assert_eq!(
            ModelFile::load(&v1).unwrap().model().unwrap(),
            Model::plain(now.clone())
        );
        // Version 2 without the key.
        let mut file = ModelFile::new(&Model::plain(now.clone()), None, Provenance::default());
        assert!(file.params.remove("x_s").is_some());
        let v2 = dir.path().join("v2.json");
        std::fs::write(&v2, serde_json::to_string(&file).unwrap()).unwrap();
        assert_eq!(
            ModelFile::load(&v2).unwrap().model().unwrap(),
            Model::plain(now)
        );
    }

    /// A model fitted in psi and metres, rescaled to MPa and mm, runs the
    /// same motion on the same pressures: every realisation of the
    /// catalogue, each at a point inside its box away from its neutral
    /// value, and all the linear ones chained at once.
    #[test]
    fn a_rescaled_model_with_effects_predicts_the_same_motion_in_its_new_units() {
        let (per_input, per_output) = (6.894757293168e-3, 1000.0);
        // Steps, ramps and wiggles over 5 to 60 psi.
        let psi: Vec<f64> = (0..1200)
            .map(|k| {
                let level = [10.0, 45.0, 25.0, 60.0, 5.0, 35.0][(k / 200) % 6];
                level + 4.0 * (k as f64 * 0.07).sin() + 0.05 * k as f64 % 3.0
            })
            .collect();
        let mpa: Vec<f64> = psi.iter().map(|p| p * per_input).collect();
        let exp = Experiment {
            name: "psi".into(),
            dt: 0.01,
            u: psi.iter().map(|p| (p - 32.0) as f32).collect(),
            y: psi.iter().map(|p| ((p - 32.0) * 4e-4) as f32).collect(),
            u_mean: 32.0,
            y_mean: 0.011,
        };
        let context = Context::of(&exp, true);
        let base = FittedBaseline {
            family: Family::Classic,
            params: vec![1.0, 0.6, 40.0, 25.0, 1.0, 0.95, 2e-4, 1e-5, 2e-4],
            input_mean: 32.0,
            output_mean: 0.011,
            dt: 0.01,
            input_name: "pressure_psi".into(),
            output_name: "x_m".into(),
        };
        let within = |e: Effect| {
            let b = crate::model::effects::effect_box(e, &context, 1);
            (0..b.neutral.len())
                .map(|i| b.lower[i] + 0.7 * (b.upper[i] - b.lower[i]))
                .collect::<Vec<f64>>()
        };
        let mut models: Vec<Vec<Effect>> = Effect::ALL
            .into_iter()
            .filter(|e| e.applicable(1))
            .map(|e| vec![e])
            .collect();
        models.push(vec![
            Effect::Deadzone,
            Effect::Creep,
            Effect::OutputCreep,
            Effect::Ringing,
            Effect::OutputClip,
        ]);
        for effects in models {
            let model = Model {
                base: base.clone(),
                chain: Some(Chain {
                    params: effects.iter().flat_map(|&e| within(e)).collect(),
                    effects: effects.clone(),
                    context,
                    datasets: 1,
                }),
            };
            let rescaled = model.rescaled(per_input, per_output);
            // Each parameter by the factor its name says (what converts a
            // file's recorded bounds).
            for ((name, v), (_, r)) in model.named_params().iter().zip(rescaled.named_params()) {
                assert_eq!(
                    r,
                    v * model.factor_of(name, per_input, per_output),
                    "{name}"
                );
            }
            let metres = model.simulate_absolute(&psi, 0.012).output;
            let mm = rescaled.simulate_absolute(&mpa, 12.0).output;
            let span = metres.iter().fold(0.0f64, |m, v| m.max((v - 0.011).abs()));
            assert!(
                span > 1e-4,
                "{effects:?}: the model barely moves ({span} m)"
            );
            for (k, (m, x)) in metres.iter().zip(&mm).enumerate() {
                assert!(
                    (m * per_output - x).abs() <= 1e-4 * span * per_output,
                    "{effects:?}, sample {k}: {} mm against {x} mm",
                    m * per_output
                );
            }
        }
    }
}
