//! A self-test run end to end, as `mckibben diagnose --self-test` runs it:
//! the nominal model fitted to the data, the cases a filter keeps, each
//! generated and diagnosed, and the report of the whole run as text and as
//! the `--json` document. The catalogue's check is [`selftest`]'s cases and
//! twin check; the independent one is [`blind`]'s.

use std::fmt::Write as _;
use std::time::Instant;

use serde::Serialize;

use super::blind::{self, BlindOutcome, generator::Plant};
use super::selftest::{self, CaseOutcome, Nominal, TwinOutcome};
use super::{Effect, Settings};
use crate::data::Trace;
use crate::model::Family;

/// Whether the case `name` is run: it contains one of `filter`'s strings, or
/// the filter is empty.
fn selected(filter: &[String], name: &str) -> bool {
    filter.is_empty() || filter.iter().any(|f| name.contains(f.as_str()))
}

/// Refuses a filter string that keeps no case: a typo in `--cases` would
/// otherwise run nothing and report "0 of 0 cases pass".
fn check_filter(filter: &[String], names: &[&str]) -> anyhow::Result<()> {
    let idle: Vec<&str> = filter
        .iter()
        .map(String::as_str)
        .filter(|f| !names.iter().any(|n| n.contains(f)))
        .collect();
    if idle.is_empty() {
        return Ok(());
    }
    const SHOWN: usize = 6;
    let more = names.len().saturating_sub(SHOWN);
    anyhow::bail!(
        "--cases {}: no case's name contains it; the {} cases are named like {}{}",
        idle.join(","),
        names.len(),
        names[..names.len().min(SHOWN)].join(", "),
        if more > 0 {
            format!(" and {more} more")
        } else {
            String::new()
        }
    )
}

/// The catalogue's check on the nominal model fitted to `trace`: the cases
/// of [`selftest::cases`] that `filter` keeps, then the twin check. Case `i`
/// of the whole list draws its noise from `settings.seed + i`, so a filtered
/// run repeats the full run's cases. `progress` gets one line before each
/// step.
pub fn catalogue(
    trace: &Trace,
    family: Family,
    effects: &[Effect],
    settings: &Settings,
    filter: &[String],
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<CatalogueRun> {
    let nominal = Nominal::fit(trace, family, settings)?;
    let cases = selftest::cases(&nominal, effects);
    let names: Vec<&str> = cases.iter().map(|c| c.name.as_str()).collect();
    check_filter(filter, &names)?;
    let mut outcomes = Vec::new();
    for (i, case) in cases.iter().enumerate() {
        if !selected(filter, &case.name) {
            continue;
        }
        progress(&format!("self-test: {} ...", case.name));
        outcomes.push(selftest::run_case(
            &nominal,
            case,
            effects,
            settings,
            settings.seed + i as u64,
        )?);
    }
    progress("self-test: twin check ...");
    let twin = selftest::twin_check(family, effects, settings)?;
    Ok(CatalogueRun {
        nominal,
        effects: effects.to_vec(),
        outcomes,
        twin,
    })
}

/// The independent check on the nominal model fitted to `trace`: the cases
/// of [`blind::cases`] that `filter` keeps. `progress` gets one line before
/// each case, with the seconds since the run began.
pub fn independent(
    trace: &Trace,
    family: Family,
    effects: &[Effect],
    settings: &Settings,
    filter: &[String],
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<IndependentRun> {
    let started = Instant::now();
    let nominal = Nominal::fit(trace, family, settings)?;
    let setup = blind::Setup::new(&nominal, settings.seed)?;
    let cases = blind::cases(&setup, settings.seed);
    let names: Vec<&str> = cases.iter().map(|c| c.name.as_str()).collect();
    check_filter(filter, &names)?;
    let mut outcomes = Vec::new();
    for case in cases {
        if !selected(filter, &case.name) {
            continue;
        }
        progress(&format!(
            "self-test: {} ... ({:.0} s)",
            case.name,
            started.elapsed().as_secs_f64()
        ));
        outcomes.push(blind::run_case(&setup, &case, effects, settings)?);
    }
    Ok(IndependentRun {
        nominal,
        setup,
        outcomes,
        wall_s: started.elapsed().as_secs_f64(),
    })
}

/// What [`catalogue`] found.
#[derive(Debug)]
pub struct CatalogueRun {
    pub nominal: Nominal,
    /// The effects the diagnoses tried: the confusion table's columns.
    pub effects: Vec<Effect>,
    pub outcomes: Vec<CaseOutcome>,
    pub twin: Vec<TwinOutcome>,
}

impl CatalogueRun {
    pub fn passed(&self) -> usize {
        self.outcomes.iter().filter(|o| o.pass).count()
    }

    /// `--self-test=catalogue --json`'s document.
    pub fn json(&self) -> CatalogueSelfTest<'_> {
        CatalogueSelfTest {
            kind: "catalogue",
            nominal: NominalJson::of(&self.nominal),
            cases: &self.outcomes,
            passed: self.passed(),
            twin_check: &self.twin,
            total: self.outcomes.len(),
        }
    }

    /// The report: the cases' confusion table and verdicts, then the twin
    /// check's.
    pub fn to_text(&self) -> String {
        let mut o = String::new();
        let _ = writeln!(
            o,
            "Self-test on the nominal {} model fitted to {}",
            self.nominal.family, self.nominal.trace.source
        );
        o += &selftest::table(&self.outcomes, &self.effects);
        let _ = writeln!(o, "{} of {} cases pass", self.passed(), self.outcomes.len());
        let _ = writeln!(
            o,
            "\nTwin check (stair, 4.5 kg): one twin effect on vs all off; gap energy in mm²"
        );
        let _ = writeln!(
            o,
            "{:<12} {:<9} {:>9} {:>9} {:>11} {:>11} {:>7}  {:<24} result",
            "twin effect",
            "input",
            "RMSE on",
            "RMSE off",
            "attributed",
            "disappears",
            "ratio",
            "named (on)"
        );
        for t in &self.twin {
            let named: Vec<_> = t.verdict_on.iter().map(|e| e.name()).collect();
            let _ = writeln!(
                o,
                "{:<12} {:<9} {:>9.4} {:>9.4} {:>11.4} {:>11.4} {:>7.2}  {:<24} {}",
                t.twin_effect,
                t.input,
                t.baseline_on,
                t.baseline_off,
                t.attributed,
                t.disappears,
                t.ratio,
                if named.is_empty() {
                    "none".to_string()
                } else {
                    named.join("+")
                },
                if t.pass { "pass" } else { "fail" }
            );
        }
        let held = self.twin.iter().filter(|t| t.pass).count();
        let _ = writeln!(o, "{held} of {} twin effects within 20 %", self.twin.len());
        o
    }
}

/// What [`independent`] found.
#[derive(Debug)]
pub struct IndependentRun {
    pub nominal: Nominal,
    /// The generator's plant and excitations, with their noise levels.
    pub setup: blind::Setup,
    pub outcomes: Vec<BlindOutcome>,
    /// Seconds from the nominal fit's start to the last case's end.
    pub wall_s: f64,
}

impl IndependentRun {
    pub fn passed(&self) -> usize {
        self.outcomes.iter().filter(|o| o.pass).count()
    }

    /// `--self-test --json`'s document.
    pub fn json(&self) -> IndependentSelfTest<'_> {
        IndependentSelfTest {
            kind: "independent",
            nominal: NominalJson::of(&self.nominal),
            plant: &self.setup.plant,
            noise_sigma: &self.setup.sigmas,
            cases: &self.outcomes,
            confusion: Confusion::of(&self.outcomes),
            passed: self.passed(),
            total: self.outcomes.len(),
            wall_s: self.wall_s,
        }
    }

    /// The report: the confusion table and each case's verdict.
    pub fn to_text(&self) -> String {
        let mut o = String::new();
        let _ = writeln!(
            o,
            "Independent self-test on the nominal {} model fitted to {} (noise σ: stair {:.4}, multisine {:.4})",
            self.nominal.family,
            self.nominal.trace.source,
            self.setup.sigmas[0],
            self.setup.sigmas[1]
        );
        o += &blind::table(&self.outcomes);
        let _ = writeln!(
            o,
            "{} of {} cases pass ({:.0} s wall)",
            self.passed(),
            self.outcomes.len(),
            self.wall_s
        );
        o
    }
}

/// The nominal model a self-test generates its data from.
#[derive(Debug, Serialize)]
pub struct NominalJson<'a> {
    model: &'static str,
    params: &'a [f64],
    data: &'a str,
}

impl<'a> NominalJson<'a> {
    fn of(n: &'a Nominal) -> NominalJson<'a> {
        NominalJson {
            model: n.family.name(),
            params: &n.params,
            data: &n.trace.source,
        }
    }
}

/// `--self-test=catalogue --json`.
#[derive(Debug, Serialize)]
pub struct CatalogueSelfTest<'a> {
    kind: &'static str,
    nominal: NominalJson<'a>,
    cases: &'a [CaseOutcome],
    passed: usize,
    twin_check: &'a [TwinOutcome],
    total: usize,
}

/// `--self-test --json` (independent).
#[derive(Debug, Serialize)]
pub struct IndependentSelfTest<'a> {
    kind: &'static str,
    nominal: NominalJson<'a>,
    plant: &'a Plant,
    noise_sigma: &'a [f64],
    cases: &'a [BlindOutcome],
    confusion: Confusion,
    passed: usize,
    total: usize,
    wall_s: f64,
}

/// Cases by true physical effect (rows) and first named one (columns).
#[derive(Debug, Serialize)]
pub struct Confusion {
    columns: Vec<&'static str>,
    rows: Vec<ConfusionRow>,
}

impl Confusion {
    fn of(outcomes: &[BlindOutcome]) -> Confusion {
        // The columns are physical effects: any realisation counts.
        let columns = Effect::PHYSICAL
            .iter()
            .map(|e| e.name())
            .chain(["none"])
            .collect();
        let rows = blind::confusion(outcomes)
            .into_iter()
            .map(|(truth, first_named)| ConfusionRow { truth, first_named })
            .collect();
        Confusion { columns, rows }
    }
}

/// One true effect's row: how many of its cases named each column first.
#[derive(Debug, Serialize)]
pub struct ConfusionRow {
    truth: String,
    first_named: Vec<usize>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_empty_filter_keeps_every_case_and_a_filter_keeps_the_names_containing_one_string() {
        let filter = ["stair".to_string(), "control".to_string()];
        assert!(selected(&[], "delay (small)"));
        assert!(selected(&filter, "control (multisine)"));
        assert!(selected(&filter, "lag: pure delay (small on stair)"));
        assert!(!selected(&filter, "lag: pure delay (small on multisine)"));
    }
}
