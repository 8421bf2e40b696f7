//! What a finished fit reports: one type that `mckibben fit --json`, its
//! `result.json` and Python's `FitResult` all serialise, what `fit` writes
//! beside it, and its text for a terminal.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use serde::Serialize;

use super::agreement::Agreement;
use super::edge::{ActiveBound, Widening, active_bounds};
use super::objective::{
    SMALL_TRY_POPULATION, TRY_POPULATION, TryGroup, tries_text, try_groups, try_population,
};
use super::problem::{Admission, FitProblem, Overshoot};
use super::run::{Built, FitRun, StartScores, Switched};
use super::uncertainty::{Assessment, assess};
use crate::data::{Columns, Trace, sources, write_all_atomic};
use crate::ident::arx::is_unstable;
use crate::ident::fit::{SETTLED_POINTS, constant_validation_warning, fit_percent_text};
use crate::model::Family;
use crate::model::bounds::Origin;
use crate::model::file::{Provenance, SearchBox};
use crate::model::{Flow, Model, ModelFile, UserBound};
use crate::optim::Algorithm;
use crate::optim::engine::{Outcome, StageSummary, StopReason};
use crate::optim::stage::Stage;
use crate::report::fit_figures;
use crate::report::history::{convergence_figure, trends_figure};
use crate::report::json::{Named, Versioned};
use crate::report::number::{decimal_column, significant, uncertainty};

/// A fit's report (docs/JSON.md, `mckibben fit`).
#[derive(Debug, Clone, Serialize)]
pub struct FitReport {
    pub model: Family,
    /// The effects after the baseline, in chain order.
    pub effects: Vec<String>,
    pub algo: Algorithm,
    /// Fitted parameters by name, in the family's canonical order, then
    /// the effects' as `effect.param`.
    pub params: Named,
    /// Each parameter's unit by name, written with the units the data's
    /// columns state (`Model::units`: `mm/MPa`; `1` for a pure
    /// number); empty where the fit found no parameters.
    pub units: Named<String>,
    /// Each parameter's standard error on the estimation half, by name
    /// (`fit::uncertainty`: a lower bound; `None` where held, infinite
    /// where the record does not determine it at all).
    pub std_errors: Named<Option<f64>>,
    /// The parameters whose standard error is at least their own size,
    /// an infinite one included: the JSON writes an infinite error as
    /// `null`, as a held one, and this list tells them apart.
    pub undetermined: Vec<String>,
    /// The search coordinates along which a step of a thousandth makes the
    /// estimation free run diverge (`fit::uncertainty::Assessment`):
    /// the fit ends at the edge of divergence there, and the parameters
    /// they move have no standard error.
    pub diverging_probes: Vec<String>,
    /// The search coordinates held for the errors because their probe
    /// step reaches past a bound (`fit::uncertainty::Assessment`): said
    /// in a note, which the JSON's `notes` carry.
    #[serde(skip)]
    pub held_at_bounds: Vec<String>,
    /// Estimation SSE of the free run (`None` where it diverged).
    pub sse: Option<f64>,
    pub val_rmse: Option<f64>,
    pub val_fit_percent: Option<f64>,
    /// The first-order ARX model's validation fit on the same halves
    /// (`Records::linear_yardstick`): what the fit should beat.
    pub linear_val_fit_percent: Option<f64>,
    /// The largest pole modulus of those ARX models (over the records): at
    /// 1 or past it the yardstick drifts or grows, and scores nothing a fit
    /// need clear.
    pub linear_largest_pole: Option<f64>,
    /// With `--effects auto`: the final model on the diagnosis' two parts
    /// of the second half, which `val_fit_percent` pools: the selection
    /// part chose the effects, the test part no choice read (`None` for
    /// every other fit, whose second half chose nothing).
    pub diagnosis_parts: Option<DiagnosisParts>,
    /// The largest step of the output in one sample within which the
    /// fitted hysteresis update settles (`Family::stable_step`; `None`
    /// where no branch of the loop bends or effect stages stand between the
    /// state and the output), and the measured output's largest
    /// step on the record (both halves): a record or a start that steps
    /// further makes the model overshoot, and at larger steps diverge.
    pub stable_step: Option<f64>,
    pub largest_step: Option<f64>,
    /// The largest step of the model's own run over its records, which
    /// the hysteresis update steps on (the measured one holds the noise,
    /// and the fast moves the model does not follow).
    #[serde(skip)]
    pub simulated_largest_step: Option<f64>,
    /// With a warm start: the start model as it was, on this record's
    /// halves (`None` without one, or where it diverges).
    pub start_sse: Option<f64>,
    pub start_val_fit_percent: Option<f64>,
    /// With effects from scratch: the search from scratch against the
    /// chain built one effect at a time, and which was kept (`None`
    /// otherwise).
    pub built: Option<Built>,
    /// A generalized fit from the default switching's two starts: each
    /// start's estimation SSE and which was kept (`None` otherwise).
    pub switching: Option<Switched>,
    pub evaluations: u64,
    pub generations: usize,
    pub seconds: f64,
    pub backend: String,
    pub flow: Flow,
    /// Whether loops whose update overshoots were admitted (`--overshoot`;
    /// `allow` where the thesis' flow or the diagnosis' admission set the
    /// rule).
    pub overshoot: Overshoot,
    pub seed: u64,
    pub population: usize,
    /// Independent tries the population ran, the first one's population
    /// and the tries by population (`fit::objective::try_populations`).
    pub tries: usize,
    pub try_population: usize,
    pub try_sizes: Vec<TryGroup>,
    /// How far the tries agree (`None` for a single try).
    pub agreement: Option<Agreement>,
    /// A refined fit's rounds and the tries they ran out on (`None` where
    /// the fit has no refining rounds: every family but the generalized).
    pub refining: Option<Refining>,
    pub stop: StopReason,
    pub stages: Vec<StageSummary>,
    /// Search coordinates that ended on a bound of the box, with where
    /// each bound comes from (after the edge rule's widenings).
    pub on_edge: Vec<ActiveBound>,
    /// The edge rule's widenings and refits, in order.
    pub widened: Vec<Widening>,
    /// The search box's coordinates (`names`) and bounds, after widening.
    pub search_box: SearchBox,
    /// The data files, `, `-separated where several.
    pub data: String,
    /// The records' input and output columns and their units: what `sse`,
    /// `val_rmse` and the parameters are in (`None` without records).
    pub columns: Option<Columns>,
    /// Each record's validation scores on its own second half, in the
    /// order read (one record: the figures above again).
    pub records: Vec<RecordScore>,
    /// What `fit` says on stderr of the data and of the fit: the notes
    /// before it ran and [`FitReport::after_notes`], in the order printed.
    pub notes: Vec<Note>,
    /// Where the fit's files were written (`None` where nothing was).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub out: Option<PathBuf>,
}

/// Each parameter whose standard error is at least its own size, an
/// infinite error included, with its value and error.
fn loose<'a>(
    params: &'a Named,
    errors: &'a Named<Option<f64>>,
) -> impl Iterator<Item = (&'a str, f64, f64)> {
    params
        .0
        .iter()
        .zip(&errors.0)
        .filter_map(|((name, v), (_, e))| {
            let e = (*e)?;
            (e >= v.abs()).then_some((name.as_str(), *v, e))
        })
}

/// `fit --effects auto`'s model on the parts of the second half that the
/// diagnosis cut: the figure to quote is the test part's.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiagnosisParts {
    /// On the selection part, which chose the effects: flattered.
    pub selection_fit_percent: Option<f64>,
    /// On the test part, read once the effects were chosen (`None` where
    /// the run diverged there).
    pub test_rmse: Option<f64>,
    pub test_fit_percent: Option<f64>,
}

/// One record's validation scores in a fit of several
/// ([`crate::fit::records::Records::validate_each`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecordScore {
    /// Where the record came from.
    pub data: String,
    /// Its samples; the second half, from sample `samples / 2` on, is scored.
    pub samples: usize,
    pub val_rmse: Option<f64>,
    pub val_fit_percent: Option<f64>,
    /// Its own first-order ARX model's validation fit on the same halves.
    pub linear_val_fit_percent: Option<f64>,
    /// That ARX model's largest pole modulus.
    pub linear_largest_pole: Option<f64>,
}

/// One line `fit` prints on stderr, `mckibben: LEVEL: TEXT`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Note {
    /// `note` or `warning`.
    pub level: &'static str,
    pub text: String,
}

impl Note {
    /// A line at the level `note`.
    pub fn plain(text: String) -> Note {
        Note {
            level: "note",
            text,
        }
    }
}

/// The refining rounds of a generalized fit: the most a try may run, and
/// the tries whose last allowed round still lowered their SSE by more than
/// the rule's thousandth (they would have gone on).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Refining {
    pub rounds: usize,
    /// Tries cut short by the cap.
    pub cut_tries: usize,
    /// The largest share of its SSE a cut try's last round took off
    /// (`None` where no try was cut).
    pub largest_last_gain: Option<f64>,
}

impl Refining {
    /// What `fit` says when the cap cut a try short.
    pub fn advice(&self, tries: usize) -> Option<String> {
        let gain = self.largest_last_gain?;
        let which = if tries == 1 {
            "the fit".to_string()
        } else {
            format!("{} of {tries} tries", self.cut_tries)
        };
        Some(format!(
            "refining ran out of rounds: after {} round{} {which} still lowered the estimation \
             SSE by {:.2} % in the last one; --refine-rounds {} lets it go on (check the \
             validation fit: where the estimation half barely settles the model, a lower \
             SSE can validate either way)",
            self.rounds,
            if self.rounds == 1 { "" } else { "s" },
            100.0 * gain,
            2 * self.rounds.max(2)
        ))
    }
}

/// `v` where it is finite.
fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

impl FitReport {
    /// The report of `fit` once [`FitRun::run`] returned `outcome` and
    /// `widened`, its populations scored on `backend`, on the records
    /// `traces` (the fit's, in its order).
    pub fn of(
        fit: &FitRun,
        (outcome, widened): (&Outcome, &[Widening]),
        backend: &str,
        traces: &[Trace],
    ) -> FitReport {
        let (problem, engine) = (&fit.problem, &fit.engine);
        let start = fit.start_scores();
        let found = !outcome.params.is_empty();
        // Each record simulated once, its ARX model identified once: the
        // pooled figures and each record's come from the same runs.
        let val = problem
            .records
            .validate_each(&problem.model, &outcome.params);
        let linear = problem.records.linear_yardstick();
        // What was asked (the announce's), not the kept start's plan.
        let asked = &fit.asked;
        let global = asked.global.as_ref();
        let names = problem.model.param_names();
        let params = Named::zip(&names, &outcome.params);
        let Assessment {
            std_errors,
            diverging_probes,
            held_at_bounds,
        } = match found {
            true => assess(problem, &outcome.params),
            // No parameters, no errors: `std_errors` has `params`' names.
            false => Assessment {
                std_errors: Vec::new(),
                diverging_probes: Vec::new(),
                held_at_bounds: Vec::new(),
            },
        };
        let std_errors: Named<Option<f64>> = names.iter().zip(std_errors).collect();
        let undetermined = loose(&params, &std_errors)
            .map(|(name, _, _)| name.to_string())
            .collect();
        let units = match found {
            true => Named(problem.fitted_model(&outcome.params).units()),
            false => Named(Vec::new()),
        };
        FitReport {
            model: problem.model.family,
            effects: problem
                .model
                .effects
                .iter()
                .map(|e| e.name().to_string())
                .collect(),
            algo: global.map_or(Algorithm::De, |g| g.algorithm()),
            params,
            std_errors,
            undetermined,
            diverging_probes,
            held_at_bounds,
            units,
            sse: finite(outcome.sse),
            val_rmse: finite(val.pooled.rmse),
            val_fit_percent: finite(val.pooled.fit_percent),
            linear_val_fit_percent: linear.as_ref().and_then(|l| finite(l.0.pooled.fit_percent)),
            linear_largest_pole: linear
                .as_ref()
                .and_then(|l| l.1.iter().copied().reduce(f64::max)),
            diagnosis_parts: None,
            // The effect stages move the output off the state the update
            // steps on: the step is the plain families' figure.
            stable_step: (found && problem.model.effects.is_empty())
                .then(|| problem.model.family.stable_step(&outcome.params))
                .flatten(),
            largest_step: problem.records.largest_measured_step(),
            simulated_largest_step: problem
                .records
                .largest_simulated_step(&problem.model, &outcome.params),
            start_sse: start.and_then(|s| finite(s.est_sse)),
            start_val_fit_percent: start.and_then(|s| finite(s.validation.fit_percent)),
            built: fit.built,
            switching: fit.switched,
            evaluations: outcome.evaluations,
            generations: outcome.generations,
            seconds: outcome.seconds,
            backend: backend.to_string(),
            flow: problem.flow,
            overshoot: match problem.admission {
                Admission::Fit(rule) if problem.flow != Flow::Thesis => rule,
                _ => Overshoot::Allow,
            },
            seed: engine.seed,
            population: (0..asked.tries).map(|t| try_population(asked, t)).sum(),
            tries: asked.tries,
            try_population: try_population(asked, 0),
            try_sizes: try_groups(asked),
            agreement: fit.agreement.clone(),
            refining: engine.plan.refine.as_ref().map(|r| {
                let cut: Vec<f64> = outcome.tries.iter().filter_map(|t| t.cut_gain).collect();
                Refining {
                    rounds: r.rounds,
                    cut_tries: cut.len(),
                    largest_last_gain: cut.into_iter().reduce(f64::max),
                }
            }),
            stop: outcome.stop,
            stages: outcome.stages.clone(),
            on_edge: active_bounds(problem, &outcome.params),
            widened: widened.to_vec(),
            search_box: SearchBox::of(&problem.space),
            data: sources(traces),
            columns: traces.first().map(Trace::columns),
            // A fit that found no model has no runs: its records score none.
            records: traces
                .iter()
                .enumerate()
                .map(|(i, t)| RecordScore {
                    data: t.source.clone(),
                    samples: t.len(),
                    val_rmse: val.each.get(i).and_then(|v| finite(v.rmse)),
                    val_fit_percent: val.each.get(i).and_then(|v| finite(v.fit_percent)),
                    linear_val_fit_percent: linear
                        .as_ref()
                        .and_then(|l| finite(l.0.each[i].fit_percent)),
                    linear_largest_pole: linear.as_ref().map(|l| l.1[i]),
                })
                .collect(),
            notes: Vec::new(),
            out: None,
        }
    }

    /// Writes the fit to `out`: `result.json` (this report), the history
    /// (`history.csv`, `history.json`), `trends.svg`, `convergence.svg`
    /// and, where a model was found, `model.json` (with the user's
    /// `bounds` and its `provenance`), `loop.svg` and `trace.svg` on each
    /// of `traces` (`model_files`). The
    /// files are written all or none: a failure leaves `out` as it was.
    pub fn write(
        &mut self,
        out: &Path,
        (fit, params): (&FitRun, &[f64]),
        traces: &[Trace],
        bounds: &[UserBound],
        provenance: Provenance,
    ) -> anyhow::Result<()> {
        let (problem, engine) = (&fit.problem, &fit.engine);
        let title = format!("{} {} fit", self.algo, problem.model.family);
        let trends = format!("{title}: best parameters");
        let mut files = vec![
            ("history.csv".into(), engine.history.to_csv().into_bytes()),
            (
                "history.json".into(),
                serde_json::to_string_pretty(&engine.history)?.into_bytes(),
            ),
            (
                "trends.svg".into(),
                trends_figure(&engine.history, &trends, &engine.space.free())
                    .to_svg()?
                    .into_bytes(),
            ),
            (
                "convergence.svg".into(),
                convergence_figure(&engine.history, &format!("{title}: convergence"))
                    .to_svg()?
                    .into_bytes(),
            ),
        ];
        if !params.is_empty() {
            let file = model_file(problem, params, bounds, provenance);
            files.extend(model_files(
                &file,
                &problem.fitted_model(params),
                traces,
                &title,
            )?);
        }
        self.write_with_result(out, files)
    }

    /// Writes a model found otherwise than by a fit's run (`fit --effects
    /// auto`: the diagnosis' selection) to `out`: `result.json` (this
    /// report), `model.json`, `loop.svg` and `trace.svg`, all or none.
    pub fn write_model(
        &mut self,
        out: &Path,
        model: &Model,
        trace: &Trace,
        provenance: Provenance,
    ) -> anyhow::Result<()> {
        let file = ModelFile::new(model, None, provenance);
        let title = format!("diagnosed {} fit", self.model);
        let files = model_files(&file, model, std::slice::from_ref(trace), &title)?;
        self.write_with_result(out, files)
    }

    /// Creates `out` and writes `files` there with `result.json` (this
    /// report, with `out` in it), all or none.
    fn write_with_result(
        &mut self,
        out: &Path,
        mut files: Vec<(String, Vec<u8>)>,
    ) -> anyhow::Result<()> {
        crate::data::create_dir_all(out)
            .with_context(|| format!("cannot create --out {}", out.display()))?;
        self.out = Some(out.to_path_buf());
        files.insert(
            0,
            (
                "result.json".into(),
                Versioned::new(&*self).to_string_pretty()?.into_bytes(),
            ),
        );
        let paths: Vec<PathBuf> = files.iter().map(|(name, _)| out.join(name)).collect();
        let set: Vec<(&Path, &[u8])> = paths
            .iter()
            .zip(&files)
            .map(|(path, (_, bytes))| (path.as_path(), bytes.as_slice()))
            .collect();
        if let Err(e) = write_all_atomic(&set) {
            // The report printed after a failed write must not say where
            // it was written.
            self.out = None;
            return Err(e).with_context(|| format!("cannot write --out {}", out.display()));
        }
        // An earlier fit of more records left figures of records this one
        // does not have: beside this fit's, they would pass for its own.
        let drawn = files
            .iter()
            .filter(|(name, _)| name.starts_with("loop"))
            .count();
        for k in drawn.max(1) + 1.. {
            let stale = [format!("loop-{k}.svg"), format!("trace-{k}.svg")].map(|f| out.join(f));
            if !stale.iter().any(|f| f.exists()) {
                break;
            }
            for f in stale {
                let _ = std::fs::remove_file(f);
            }
        }
        Ok(())
    }

    /// The report for a terminal: the fit, its parameters (`fixed`: which
    /// of them the box held), its scores against its yardsticks, the two
    /// starts where there were two, its stages and where it was written.
    pub fn to_text(&self, fixed: &[bool]) -> String {
        let mut s = String::new();
        let mut line = |l: String| {
            s.push_str(&l);
            s.push('\n');
        };
        let tries = match self.tries {
            1 => String::new(),
            _ => format!(" ({})", tries_text(&self.try_sizes)),
        };
        line(format!(
            "{} {} fit of {} ({} flow), N = {}{tries}, seed {}",
            self.algo,
            self.model,
            self.data,
            match self.flow {
                Flow::Joint => "joint",
                Flow::Thesis => "thesis",
            },
            self.population,
            self.seed
        ));
        if !self.effects.is_empty() {
            line(format!("  effects: {}", self.effects.join(", ")));
        }
        let names = self.params.0.iter().map(|(name, _)| name.chars().count());
        let name_width = names.max().unwrap_or(0).max(7);
        let figures: Vec<String> = self
            .params
            .0
            .iter()
            .map(|(_, v)| significant(*v, 6))
            .collect();
        // Where some parameters have errors (a smooth family) and no probe
        // diverged, a free one without its error is held by a bound its
        // probe step reaches past (JSON.md, `std_errors.*`): say so, where
        // a bare figure would read as a parameter that was never assessed.
        let assessed =
            self.std_errors.0.iter().any(|(_, e)| e.is_some()) && self.diverging_probes.is_empty();
        // A pure number's unit is left blank: `1` on every pole and share
        // would hide the few that carry one.
        let units: Vec<&str> = (0..figures.len())
            .map(|i| match self.units.0.get(i).map(|(_, u)| u.as_str()) {
                Some("1") | None => "",
                Some(u) => u,
            })
            .collect();
        let unit_width = units.iter().map(|u| u.chars().count()).max().unwrap_or(0);
        for (i, ((name, _), figure)) in self
            .params
            .0
            .iter()
            .zip(decimal_column(&figures))
            .enumerate()
        {
            let held = if fixed.get(i) == Some(&true) {
                "  (fixed)"
            } else {
                ""
            };
            let error = match self.std_errors.0.get(i) {
                Some((_, Some(e))) if held.is_empty() => format!("  ± {}", uncertainty(*e)),
                Some((_, None)) if held.is_empty() && assessed => {
                    "  (next to a bound of its box: no ±)".to_string()
                }
                _ => String::new(),
            };
            let unit = match unit_width {
                0 => String::new(),
                _ => format!(" {:<unit_width$}", units[i]),
            };
            let row = format!("  {name:<name_width$} {figure:>14}{unit}{held}{error}");
            line(row.trim_end().to_string());
        }
        let percent = |v: Option<f64>, rmse: Option<f64>| fit_percent_text(v, rmse.is_some(), 4);
        let constant = self.val_fit_percent.is_none() && self.val_rmse.is_some();
        // SSEs and RMSEs are in the output's units, squared or not; an RMSE
        // says its unit where the output column's name states one.
        let figure = |v: Option<f64>| v.map_or("diverged".to_string(), |v| significant(v, 4));
        let unit = self
            .columns
            .as_ref()
            .map_or(String::new(), |c| c.output.unit_tail());
        let rmse = |v: Option<f64>| match v {
            Some(_) => format!("{}{unit}", figure(v)),
            None => figure(v),
        };
        if !self.diverging_probes.is_empty() {
            line(format!(
                "  (a step of a thousandth along {} makes the free run diverge on the estimation \
                 half: the fit ends at the edge of divergence, and what those move has no ±)",
                self.diverging_probes.join(", ")
            ));
        }
        line(format!("  SSE (estimation)     {}", figure(self.sse)));
        let pooled = match self.records.len() {
            1 => String::new(),
            k => format!("; the {k} records' second halves pooled"),
        };
        let constant_why = match constant {
            true => {
                "; the output is constant over the validation half: fit % divides by its spread"
            }
            false => "",
        };
        line(format!(
            "  validation fit       {}   (RMSE {}{pooled}{constant_why})",
            percent(self.val_fit_percent, self.val_rmse),
            rmse(self.val_rmse)
        ));
        if self.records.len() > 1 {
            let width = self.records.iter().map(|r| r.data.chars().count()).max();
            let width = width.unwrap_or(0).max(16);
            for r in &self.records {
                line(format!(
                    "    {:<width$} {}   (RMSE {}; its own ARX {})",
                    r.data,
                    percent(r.val_fit_percent, r.val_rmse),
                    rmse(r.val_rmse),
                    percent(r.linear_val_fit_percent, r.val_rmse)
                ));
            }
        }
        line(format!(
            "  validation fit, ARX  {}   ({}{})",
            percent(self.linear_val_fit_percent, self.val_rmse),
            match self.records.len() {
                0 | 1 => "the first-order linear model on the same halves",
                // One linear model a record, not one for all as `identify`
                // fits: a yardstick the one hysteretic model must clear.
                _ => "each record's own first-order linear model on its halves, pooled",
            },
            unstable_yardstick(&self.records)
        ));
        if let (Some(stable), Some(largest)) = (self.stable_step, self.largest_step) {
            line(format!(
                "  stable steps         up to {} a sample   ({} largest: {}; past it \
                 the hysteresis update overshoots)",
                significant(stable, 4),
                match self.records.len() {
                    1 => "the record's",
                    _ => "the records'",
                },
                significant(largest, 4)
            ));
        } else if self.stable_step.is_none() && self.effects.is_empty() && self.sse.is_some() {
            // Said rather than left out: a reader of another fit's report
            // looks for the line.
            line(
                "  stable steps         not bounded   (no branch of the fitted loop bends toward a bound or \
                 back through zero, so its hysteresis update has no step past which it \
                 overshoots)"
                    .to_string(),
            );
        }
        if self.start_sse.is_some() || self.start_val_fit_percent.is_some() {
            line(format!(
                "  validation fit, from  {}   (the --from model as it was, on the same halves; SSE {})",
                percent(
                    self.start_val_fit_percent,
                    self.val_rmse.filter(|_| constant)
                ),
                figure(self.start_sse)
            ));
        }
        if let Some(sw) = self.switching {
            line(format!(
                "  switching: x_s at the estimation mean ended at SSE {}, at the sensor's zero at \
                 {}: kept the {}",
                significant(sw.mean_sse, 4),
                significant(sw.zero_sse, 4),
                if sw.kept_zero { "zero" } else { "mean" }
            ));
        }
        if let Some(a) = &self.agreement {
            line(format!("  tries: {}", a.to_text()));
            if let Some(r) = a.runner_up {
                line(format!(
                    "  runner-up            estimation SSE {} ({:+.1} % of the best); its model \
                     runs {} from this one over the validation half (read from the input alone; \
                     this model's own RMSE there: {})",
                    significant(r.sse, 6),
                    100.0 * (r.sse / self.sse.unwrap_or(f64::NAN) - 1.0),
                    if r.apart_rmse.is_finite() {
                        format!("{} RMS", rmse(Some(r.apart_rmse)))
                    } else {
                        "away: its run diverges".to_string()
                    },
                    rmse(self.val_rmse)
                ));
            }
        } else if self.tries == 1 && self.flow == Flow::Joint {
            // The default population runs one try: say what it cannot tell.
            line(format!(
                "  tries: 1, which cannot tell whether another try would end in the same \
                 basin (from --pop {} on, a fit runs tries of {TRY_POPULATION} and \
                 {SMALL_TRY_POPULATION})",
                2 * TRY_POPULATION
            ));
        }
        if let Some(b) = self.built {
            line(format!(
                "  built: the search from scratch ended at SSE {}, the chain built one effect at a \
                 time at {}: kept the {}",
                significant(b.scratch_sse, 4),
                significant(b.chain_sse, 4),
                if b.kept_chain {
                    "chain"
                } else {
                    "search from scratch"
                }
            ));
        }
        for (k, st) in self.stages.iter().enumerate() {
            // The polish goes through the prediction horizons before the
            // free run, so its starts may end above the stage before it
            // under the same measure: each try keeps the lower, which the
            // line says, where it read as the polish making the fit worse.
            let kept = match k.checked_sub(1).map(|j| &self.stages[j]) {
                Some(before)
                    if st.stage == Stage::Polish
                        && before.measure == st.measure
                        && before.best_cost < st.best_cost =>
                {
                    format!("; the {} stage's lower best is kept", before.stage.name())
                }
                _ => String::new(),
            };
            line(format!(
                "  stage {:<9} {:>4} steps, {:>9} evaluations, {:>7.2} s, best {:.4e} ({}), ended: {:?}{kept}",
                st.stage.name(),
                st.steps,
                st.evaluations,
                st.seconds,
                st.best_cost,
                st.measure,
                st.ended
            ));
        }
        line(format!(
            "  {} evaluations in {} generations, {:.2} s, stopped: {:?}",
            self.evaluations, self.generations, self.seconds, self.stop
        ));
        if let (Some(_), Some(out)) = (self.sse, &self.out) {
            line(format!(
                "  wrote model.json, result.json, history.csv/json and figures to {}",
                out.display()
            ));
        }
        s
    }

    /// Of several records, each that the one model validates on worse than
    /// that record's own first-order ARX model: the pooled figure may
    /// still look good, and the model does not hold there.
    fn missed_records(&self) -> impl Iterator<Item = String> + '_ {
        let several = self.records.len() > 1;
        self.records
            .iter()
            .filter(move |_| several)
            .filter_map(|r| {
                let (fit, linear) = (r.val_fit_percent?, r.linear_val_fit_percent?);
                (fit < linear).then(|| {
                    format!(
                        "{} validates at {fit:.1} % on its second half, below its own first-order \
                     ARX model ({linear:.1} %): the one model does not hold on this record (a \
                     different load or condition, or a start far from rest); fit it apart, or \
                     run `diagnose` on the records",
                        r.data
                    )
                })
            })
    }

    /// [`Agreement::advice`], with how far the runner-up's model runs from
    /// the fit's beside the fit's own validation error: a larger population
    /// may find a lower SSE, and this says how much the basins already
    /// found differ in what they predict.
    fn tries_advice(&self) -> Option<String> {
        let a = self.agreement.as_ref()?;
        let advice = a.advice()?;
        let share = match (a.runner_up, self.val_rmse) {
            (Some(r), Some(own)) if r.apart_rmse.is_finite() && own > 0.0 => r.apart_rmse / own,
            _ => return Some(advice),
        };
        Some(format!(
            "{advice}; the runner-up basin's model strays from this one over the validation \
             half by {:.0} % of this model's own error there",
            100.0 * share
        ))
    }

    /// What the fit says of itself once it has run, in the order `fit`
    /// prints it: the box ([`FitReport::edge_notes`]), tries that agree
    /// too little, refining rounds cut short, parameters the estimation
    /// half does not determine, and a validation fit the yardsticks find
    /// wanting ([`yardstick_warnings`], with the warm start's `start`).
    pub fn after_notes(&self, start: Option<StartScores>) -> Vec<Note> {
        let mut notes: Vec<Note> = self
            .edge_notes()
            .into_iter()
            .map(|(level, text)| Note { level, text })
            .collect();
        let advice = [
            self.tries_advice(),
            self.refining.and_then(|r| r.advice(self.tries)),
            self.undetermined(),
        ];
        notes.extend(advice.into_iter().flatten().map(Note::plain));
        if !self.held_at_bounds.is_empty() {
            notes.push(Note::plain(format!(
                "no standard error along {}: {} within its probe step (a thousandth of the \
                 value) of a bound the data or --bound set, so the errors hold it there; the \
                 parameters it moves have no ±, and the others' are those given it held. \
                 `--bound NAME=LO:HI` with room around the value gives it one",
                self.held_at_bounds.join(", "),
                match self.held_at_bounds.len() {
                    1 => "it ended",
                    _ => "each ended",
                }
            )));
        }
        if let (Some(sse), Some(val)) = (self.sse, self.val_fit_percent) {
            let warnings =
                yardstick_warnings(sse, val, self.linear_val_fit_percent, start, self.tries);
            notes.extend(warnings.into_iter().map(|text| Note {
                level: "warning",
                text,
            }));
        }
        notes.extend(self.missed_records().map(|text| Note {
            level: "warning",
            text,
        }));
        notes.extend(self.past_the_stable_step().map(|text| Note {
            level: "warning",
            text,
        }));
        notes.extend(self.constant_validation().map(|text| Note {
            level: "warning",
            text,
        }));
        notes
    }

    /// Where the model's own run over its records steps further in one
    /// sample than its hysteresis update settles within
    /// ([`Family::stable_step`]): the update overshoots there, and a record
    /// that moves faster (another load, a start far from the model's rest)
    /// can make the run diverge, as the Cavatappi 400 g model does on the
    /// 300 g record.
    fn past_the_stable_step(&self) -> Option<String> {
        stable_step_warning(
            self.stable_step?,
            self.simulated_largest_step?,
            self.records.len(),
        )
    }

    /// The records whose output is constant over their validation half (a
    /// sensor frozen or at an end stop), as a warning: their fit % is
    /// undefined, and their RMSE says only how near the model holds that
    /// one level, not whether it follows a motion it never saw.
    fn constant_validation(&self) -> Option<String> {
        let constant: Vec<&str> = self
            .records
            .iter()
            .filter(|r| r.val_fit_percent.is_none() && r.val_rmse.is_some())
            .map(|r| r.data.as_str())
            .collect();
        (!constant.is_empty())
            .then(|| constant_validation_warning(&format!(" of {}", constant.join(", "))))
    }

    /// The parameters whose standard error is at least their own size, as
    /// a note: the estimation half does not determine them.
    pub fn undetermined(&self) -> Option<String> {
        let loose: Vec<String> = loose(&self.params, &self.std_errors)
            .map(|(name, v, e)| format!("{name} ({} ± {})", significant(v, 4), uncertainty(e)))
            .collect();
        (!loose.is_empty()).then(|| {
            format!(
                "the estimation half does not determine {}: a standard error as large as the \
                 value (and the errors are a lower bound: the residuals of a free run are \
                 correlated)",
                loose.join(", ")
            )
        })
    }

    /// What the user should know of the box: each widening the edge rule
    /// made, and each bound the fit still ends on with where it comes from,
    /// as `(level, message)` with level `note` or `warning`.
    pub fn edge_notes(&self) -> Vec<(&'static str, String)> {
        let mut notes: Vec<(&'static str, String)> = self
            .widened
            .iter()
            .map(|w| ("note", widening_note(w)))
            .collect();
        for e in &self.on_edge {
            let why = match e.origin {
                Origin::Data => {
                    "a bound the data set, still active after the widenings: the box \
                             stopped it, not the data; widen it with --bound"
                }
                Origin::User => "your --bound or --fix",
                Origin::Class if e.param.contains('.') => {
                    "the edge of the effect's range: where it is neutral, or as far as \
                     the record lets it go"
                }
                Origin::Class => {
                    "the edge of its range or of the bounded class (--loop=free lifts \
                              the class)"
                }
            };
            let level = if e.origin == Origin::Data {
                "warning"
            } else {
                "note"
            };
            notes.push((
                level,
                format!(
                    "{} ended {} the {} bound of its search box ({why})",
                    e.param,
                    if e.inside > 0.0 {
                        format!("{:.2} % of the box's width inside", 100.0 * e.inside)
                    } else {
                        "on".to_string()
                    },
                    e.bound
                ),
            ));
        }
        notes
    }
}

/// The names a fit of `records` records writes in its `--out` folder
/// (`fit --effects auto` writes some of them).
pub fn files_written(records: usize) -> Vec<String> {
    let mut names: Vec<String> = [
        "result.json",
        "history.csv",
        "history.json",
        "trends.svg",
        "convergence.svg",
        "model.json",
    ]
    .map(String::from)
    .to_vec();
    for k in 0..records.max(1) {
        names.extend(["loop", "trace"].map(|f| format!("{f}{}.svg", figure_suffix(k))));
    }
    names
}

/// The suffix of record `k`'s figures: none for the first, `-2` on.
fn figure_suffix(k: usize) -> String {
    match k {
        0 => String::new(),
        k => format!("-{}", k + 1),
    }
}

/// `file` as `model.json` and `model`'s loop and trace on each of
/// `traces` as `loop.svg` and `trace.svg` (the first record's), then
/// `loop-2.svg`, `trace-2.svg` and so on, to write.
fn model_files(
    file: &ModelFile,
    model: &Model,
    traces: &[Trace],
    title: &str,
) -> anyhow::Result<Vec<(String, Vec<u8>)>> {
    let mut files = vec![(
        "model.json".to_string(),
        serde_json::to_string_pretty(file)?.into_bytes(),
    )];
    for (k, trace) in traces.iter().enumerate() {
        let (loop_fig, trace_fig) = fit_figures(model, trace, title);
        let suffix = figure_suffix(k);
        files.push((format!("loop{suffix}.svg"), loop_fig.to_svg()?.into_bytes()));
        files.push((
            format!("trace{suffix}.svg"),
            trace_fig.to_svg()?.into_bytes(),
        ));
    }
    Ok(files)
}

/// What `fit`'s ARX line adds where a record's ARX model has a pole on or
/// outside the unit circle: its free run drifts or grows, and a fit that
/// beats it has beaten nothing (`identify` says so at length).
fn unstable_yardstick(records: &[RecordScore]) -> String {
    let unstable: Vec<&RecordScore> = records
        .iter()
        .filter(|r| r.linear_largest_pole.is_some_and(is_unstable))
        .collect();
    match (records.len(), unstable.as_slice()) {
        (_, []) => String::new(),
        (0 | 1, [r]) => format!(
            "; its pole {:.4} is unstable: no yardstick",
            r.linear_largest_pole.unwrap_or(f64::NAN)
        ),
        (n, some) => format!(
            "; unstable on {} of {n} records: {}",
            some.len(),
            some.iter()
                .map(|r| r.data.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// What a fit's scores warn of, against its yardsticks: the first-order ARX
/// model's validation fit on the same halves (`linear`) and, for a warm
/// start, the model it started from (`start`). `sse` and `fit` (validation
/// fit %) are the fit's own.
/// The warning of [`FitReport::past_the_stable_step`]: the model's run
/// over its `records` steps up to `largest` a sample, its update settles
/// within `stable`.
fn stable_step_warning(stable: f64, largest: f64, records: usize) -> Option<String> {
    (largest > stable).then(|| {
        format!(
            "the model's own run over {} steps up to {} a sample, past the {} a sample within \
             which its hysteresis update settles: the update overshoots there, and a record \
             that moves faster may make the run diverge; run the model only on records that \
             move as slowly a sample, or refit on data with the faster moves (or with \
             --overshoot refuse, which admits only loops that settle on the record's steps)",
            match records {
                0 | 1 => "its record",
                _ => "its records",
            },
            significant(largest, 4),
            significant(stable, 4)
        )
    })
}

/// What a widening of the box did, in words: the refit keeps its start,
/// so no lower SSE means the bound did not hold the fit back.
fn widening_note(w: &Widening) -> String {
    let widened = w.bounds.join(", ");
    if w.sse_after < w.sse_before {
        format!(
            "the fit ended on a bound the data set; widened {widened} and refitted from its \
             best point: estimation SSE {:.6e} -> {:.6e}",
            w.sse_before, w.sse_after
        )
    } else {
        format!(
            "the fit ended on a bound the data set; widened {widened} and refitted from its \
             best point, which found no lower estimation SSE ({:.6e}): the bound did not hold \
             the fit back",
            w.sse_before
        )
    }
}

pub fn yardstick_warnings(
    sse: f64,
    fit: f64,
    linear: Option<f64>,
    start: Option<StartScores>,
    tries: usize,
) -> Vec<String> {
    let mut warnings = Vec::new();
    // Below 0 %, the run misses the validation half by more than the
    // half's own mean level does: nothing of the motion is described,
    // whatever ARX scores (on a short record it scores worse still).
    if fit < 0.0 {
        warnings.push(format!(
            "the fit validates at {fit:.1} %: the validation half's own mean level follows it \
             better than the model does, so the model describes none of its motion (a record \
             too short or too little excited for its estimation half to settle the model, \
             different conditions in its two halves, or a column in other units than named)"
        ));
    }
    if let Some(linear) = linear.filter(|v| v.is_finite())
        && fit < linear
    {
        warnings.push(format!(
            "the fit validates worse than the first-order ARX model on the same halves \
             ({fit:.1} % against {linear:.1} %): it follows the estimation half in a way the \
             validation half does not; do not trust it beyond the data it was fitted on (the \
             diagnosis, `diagnose`, looks for what the model lacks){}",
            if tries == 1 {
                ". One search may also have ended in a worse basin than the record has: \
                 --pop 2000 runs two tries and says whether they agree"
            } else {
                ""
            }
        ));
    }
    // A refit that fits the estimation half better and validates clearly
    // worse than its start: the estimation half does not settle the model
    // (as on the Cavatappi 300 g record: docs/ARCHITECTURE.md, "Warm starts").
    if let Some(start) = start
        && start.validation.fit_percent.is_finite()
        && fit < start.validation.fit_percent - SETTLED_POINTS
        && sse <= start.est_sse
    {
        warnings.push(format!(
            "the refit fits the estimation half better than the model it started from \
             (SSE {} against {}) but validates {:.1} points worse ({fit:.1} % against \
             {:.1} %): the estimation half does not settle this model, and the model you \
             started from may be the one to keep",
            significant(sse, 4),
            significant(start.est_sse, 4),
            start.validation.fit_percent - fit,
            start.validation.fit_percent
        ));
    }
    // A refit worse on the estimation half than its own start: the start
    // lies outside this fit's box (each row is clamped into it) or the
    // search lost it.
    if let Some(start) = start
        && sse > start.est_sse
    {
        warnings.push(format!(
            "the refit ends above the estimation SSE of the model it started from ({} \
             against {}): that model lies outside this fit's box (see --bound) or the search \
             lost it; the model you started from fits this record better",
            significant(sse, 4),
            significant(start.est_sse, 4)
        ));
    }
    warnings
}

/// The model file of a fit's `params` on `problem`, as `mckibben fit` writes
/// its `model.json`: the model, the box searched (widened where the edge
/// rule widened it) and `bounds`, the `--bound` and `--fix` in force.
pub fn model_file(
    problem: &FitProblem,
    params: &[f64],
    bounds: &[UserBound],
    provenance: Provenance,
) -> ModelFile {
    let model = problem.fitted_model(params);
    let mut file = ModelFile::new(&model, Some(SearchBox::of(&problem.space)), provenance);
    file.user_bounds = bounds.iter().map(|b| b.to_string()).collect();
    file
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::records::Validation;

    #[test]
    fn a_refit_that_validates_clearly_worse_than_its_start_is_flagged() {
        let v = |fit_percent: f64| Validation {
            rmse: 1.0,
            fit_percent,
        };
        let start = |est_sse: f64, fit: f64| StartScores {
            est_sse,
            validation: v(fit),
        };
        // The Cavatappi 300 g refit: a lower estimation SSE, 3.2 points worse.
        let flagged = yardstick_warnings(6.39, 84.2, Some(62.7), Some(start(6.46, 87.4)), 1);
        assert_eq!(flagged.len(), 1, "{flagged:?}");
        assert!(flagged[0].contains("3.2 points worse"), "{}", flagged[0]);
        // Within the settled points: quiet.
        assert!(yardstick_warnings(6.39, 86.0, None, Some(start(6.46, 87.4)), 1).is_empty());
        // Worse on the estimation half too: the search lost its start.
        let lost = yardstick_warnings(6.50, 84.2, None, Some(start(6.46, 87.4)), 1);
        assert_eq!(lost.len(), 1, "{lost:?}");
        assert!(lost[0].contains("ends above"), "{}", lost[0]);
        // A widening says what it bought, or that the bound held nothing back.
        let widening = |after| Widening {
            bounds: vec!["offset lower bound -6 -> -24".into()],
            sse_before: 1793.536,
            sse_after: after,
        };
        assert!(widening_note(&widening(1500.0)).contains("1.793536e3 -> 1.500000e3"));
        let idle = widening_note(&widening(1793.536));
        assert!(
            idle.contains("found no lower estimation SSE (1.793536e3)"),
            "{idle}"
        );
        // Below ARX's validation fit.
        let below = yardstick_warnings(1.0, 40.2, Some(50.9), None, 1);
        assert_eq!(below.len(), 1);
        assert!(below[0].contains("first-order ARX"), "{}", below[0]);
        // One search may have missed the record's basin; tries said
        // whether they agree, and the report shows that instead.
        assert!(
            below[0].contains("--pop 2000 runs two tries"),
            "{}",
            below[0]
        );
        let tried = yardstick_warnings(1.0, 40.2, Some(50.9), None, 2);
        assert!(!tried[0].contains("--pop 2000"), "{}", tried[0]);
        // Below 0 %, whatever ARX scores (a record's first 25 s: ARX far
        // below, the fit at −206 %).
        let none = yardstick_warnings(1.0, -206.4, Some(-1.47e9), None, 1);
        assert_eq!(none.len(), 1, "{none:?}");
        assert!(
            none[0].contains("describes none of its motion"),
            "{}",
            none[0]
        );
    }

    /// The Cavatappi 400 g fit's own run steps 0.308 a sample past its
    /// 0.134: warned; a smaller one than the update's limit: quiet.
    #[test]
    fn a_run_past_its_stable_step_is_warned_of() {
        let warned = stable_step_warning(0.1339, 0.3082, 1).unwrap();
        assert!(
            warned.contains("own run over its record steps up to 0.3082"),
            "{warned}"
        );
        assert!(stable_step_warning(0.5958, 0.225, 1).is_none());
    }

    /// A yardstick whose pole is past 1 is named on the ARX line: for the
    /// one record by its pole, for several by the records that hold one.
    #[test]
    fn an_unstable_yardstick_is_named_on_the_arx_line() {
        let record = |data: &str, pole: Option<f64>| RecordScore {
            data: data.to_string(),
            samples: 2500,
            val_rmse: Some(1.0),
            val_fit_percent: Some(50.0),
            linear_val_fit_percent: Some(-1.47e9),
            linear_largest_pole: pole,
        };
        let one = unstable_yardstick(&[record("first.csv", Some(1.0085))]);
        assert_eq!(one, "; its pole 1.0085 is unstable: no yardstick");
        // An integrator's pole, computed a rounding below 1, is one.
        assert!(!unstable_yardstick(&[record("a.csv", Some(1.0 - 1e-12))]).is_empty());
        assert_eq!(unstable_yardstick(&[record("a.csv", Some(0.992))]), "");
        assert_eq!(unstable_yardstick(&[record("a.csv", None)]), "");
        let two = unstable_yardstick(&[
            record("a.csv", Some(0.99)),
            record("b.csv", Some(1.02)),
            record("c.csv", Some(1.0)),
        ]);
        assert_eq!(two, "; unstable on 2 of 3 records: b.csv, c.csv");
    }

    /// A parameter is undetermined where its error reaches its own size,
    /// an infinite error too (which the JSON writes as a held one's
    /// `null`); a held parameter and a small error are not.
    #[test]
    fn undetermined_parameters_include_the_infinite_errors_and_not_the_held() {
        let params = Named::zip(
            &["a", "b", "A", "gamma", "beta"],
            &[2.0, -0.5, 1.0, 0.3, 0.0],
        );
        let errors: Named<Option<f64>> = [
            ("a", Some(0.1)),
            ("b", Some(0.5)),
            ("A", None),
            ("gamma", Some(f64::INFINITY)),
            ("beta", Some(0.01)),
        ]
        .into_iter()
        .collect();
        let names: Vec<&str> = loose(&params, &errors).map(|(n, _, _)| n).collect();
        assert_eq!(names, ["b", "gamma", "beta"]);
    }
}
