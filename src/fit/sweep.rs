//! The population sweep: the generated cases with a known truth
//! ([`super::cases`]) fitted with `fit`'s defaults at several populations,
//! to see what more compute buys. Per fit: whether it passes
//! ([`Case::judge`]), whether each of its tries would pass alone (the share
//! `p` of single tries that reach the truth's basin), how many tries agree
//! ([`Agreement`]) and the time. `mckibben sweep` runs it on either backend;
//! its tables are [`PopulationRow`]s.

use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::agreement::{Agreement, UNSURE_SHARE};
use super::cases::{Case, CaseSpec, matrix};
use super::objective::{GENERATIONS, staged_plan};
use super::problem::{Admission, Overshoot};
use super::run::run_fit;
use crate::eval::Evaluator;
use crate::model::Family;
use crate::optim::Algorithm;
use crate::optim::engine::StopRules;

/// The seed of the shipped figures' matrix: its cases are named from it
/// (#1000, #1001, …). Another seed draws other cases of the same kinds.
pub const MATRIX_SEED: u64 = 1000;

/// How many cases each family's matrix holds: the classic one 20, the
/// generalized one 30 (ten for each place its sign terms switch).
pub fn matrix_size(family: Family) -> usize {
    match family {
        Family::Generalized => 30,
        _ => 20,
    }
}

/// One case of a family's matrix, by its number (the matrix' seed plus
/// `index`).
#[derive(Debug, Clone, Copy)]
pub struct SweepCase {
    pub family: Family,
    pub index: usize,
    pub spec: CaseSpec,
}

/// The cases of `family`'s matrix drawn from `seed` ([`MATRIX_SEED`] for
/// the shipped figures), all of them or those numbered in `only` (`1000`,
/// `1012`, …: the seed plus the index).
pub fn cases(family: Family, seed: u64, only: Option<&[u64]>) -> Vec<SweepCase> {
    matrix(family, matrix_size(family), seed)
        .into_iter()
        .enumerate()
        .filter(|(i, _)| only.is_none_or(|o| o.contains(&(seed + *i as u64))))
        .map(|(index, spec)| SweepCase {
            family,
            index,
            spec,
        })
        .collect()
}

/// One fit of one case.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseFit {
    pub family: String,
    /// Its index in the family's matrix.
    pub case: usize,
    pub name: String,
    /// The population (all tries together).
    pub n: usize,
    pub seed: u64,
    pub passes: bool,
    /// Validation RMSE over the truth's.
    pub ratio: f64,
    /// Estimation SSE.
    pub sse: f64,
    /// Whether each try alone passes.
    pub tries: Vec<bool>,
    /// Each try's population, in the order of `tries` (empty in results
    /// recorded before tries differed in size: all of `n / tries`).
    #[serde(default)]
    pub try_populations: Vec<usize>,
    /// Tries within the likelihood-ratio threshold of the best.
    pub agreeing: usize,
    /// Wall time of the fit (the judging not counted).
    pub seconds: f64,
}

impl std::fmt::Display for CaseFit {
    /// One line on the fit, as a sweep reports its progress.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:48} N {:>7} seed {}: ratio {:.3} {} p {}/{} agree {} ({:.1} s)",
            self.name,
            self.n,
            self.seed,
            self.ratio,
            if self.passes { "pass" } else { "FAIL" },
            self.tries.iter().filter(|&&t| t).count(),
            self.tries.len(),
            self.agreeing,
            self.seconds
        )
    }
}

/// Fits `case` with `fit`'s defaults at population `n` and `seed` on
/// `evaluator`, loops whose update overshoots admitted or not
/// (`overshoot`, `fit --overshoot`), and judges the fit and each of its
/// tries.
pub fn fit_case(
    case: &SweepCase,
    (n, seed): (usize, u64),
    overshoot: Overshoot,
    evaluator: &mut dyn Evaluator,
) -> anyhow::Result<CaseFit> {
    let generated = Case::generate(case.spec);
    let mut problem = generated.problem();
    problem.admission = Admission::Fit(overshoot);
    let started = Instant::now();
    let plan = staged_plan(&problem, Algorithm::De.staged_settings(n), n, GENERATIONS);
    let try_populations = (0..plan.tries).map(|t| plan.try_size(t).global).collect();
    let (_, outcome) = run_fit(&problem, plan, seed, StopRules::default(), evaluator)?;
    let seconds = started.elapsed().as_secs_f64();
    let judged = generated.judge(&outcome.params, evaluator)?;
    let tries = if outcome.tries.len() > 1 {
        outcome
            .tries
            .iter()
            .map(|t| Ok(!t.params.is_empty() && generated.judge(&t.params, evaluator)?.passes))
            .collect::<anyhow::Result<Vec<bool>>>()?
    } else {
        vec![judged.passes]
    };
    let agreeing = Agreement::of(&outcome.tries, problem.est_samples()).map_or(1, |a| a.agreeing);
    Ok(CaseFit {
        family: case.family.to_string(),
        case: case.index,
        name: generated.name(),
        n,
        seed,
        passes: judged.passes,
        ratio: judged.ratio,
        sse: outcome.sse,
        tries,
        try_populations,
        agreeing,
        seconds,
    })
}

/// What one population bought on one family's cases: the sweep's table row.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PopulationRow {
    pub family: String,
    pub n: usize,
    /// Cases fitted with the first seed (the pass counts are of these).
    pub cases: usize,
    /// Tries a fit.
    pub tries: usize,
    /// Fits of the first seed that pass.
    pub pass: usize,
    /// Fits of the first seed within 5 % of the truth's validation RMSE.
    pub within_5_percent: usize,
    /// Single tries that pass alone, and all single tries (every seed).
    pub single_tries_passing: usize,
    pub single_tries: usize,
    /// Fits of more than one try where more than [`UNSURE_SHARE`] of the
    /// tries agreed, and how many of them missed the truth; then the rest.
    pub agreed: usize,
    pub agreed_missed: usize,
    pub few_agreed: usize,
    pub few_agreed_missed: usize,
    /// Wall time a fit of the first seed: mean, lowest, highest.
    pub mean_seconds: f64,
    pub min_seconds: f64,
    pub max_seconds: f64,
}

/// The table rows of `fits`, one per family and population in the order
/// they first appear; the first seed's fits count as the cases' own.
pub fn summarize(fits: &[CaseFit]) -> Vec<PopulationRow> {
    let mut keys: Vec<(&str, usize)> = Vec::new();
    for f in fits {
        if !keys.contains(&(f.family.as_str(), f.n)) {
            keys.push((f.family.as_str(), f.n));
        }
    }
    keys.into_iter()
        .map(|(family, n)| {
            let all: Vec<&CaseFit> = fits
                .iter()
                .filter(|f| f.family == family && f.n == n)
                .collect();
            let first_seed = all.iter().map(|f| f.seed).min().unwrap_or(0);
            let first: Vec<&CaseFit> = all
                .iter()
                .copied()
                .filter(|f| f.seed == first_seed)
                .collect();
            let agreed = |f: &CaseFit| f.agreeing as f64 > UNSURE_SHARE * f.tries.len() as f64;
            let several: Vec<&CaseFit> = first
                .iter()
                .copied()
                .filter(|f| f.tries.len() > 1)
                .collect();
            let seconds: Vec<f64> = first.iter().map(|f| f.seconds).collect();
            PopulationRow {
                family: family.to_string(),
                n,
                cases: first.len(),
                tries: first.iter().map(|f| f.tries.len()).max().unwrap_or(0),
                pass: first.iter().filter(|f| f.passes).count(),
                within_5_percent: first.iter().filter(|f| f.ratio <= 1.05).count(),
                single_tries_passing: all
                    .iter()
                    .map(|f| f.tries.iter().filter(|&&t| t).count())
                    .sum(),
                single_tries: all.iter().map(|f| f.tries.len()).sum(),
                agreed: several.iter().filter(|f| agreed(f)).count(),
                agreed_missed: several.iter().filter(|f| agreed(f) && !f.passes).count(),
                few_agreed: several.iter().filter(|f| !agreed(f)).count(),
                few_agreed_missed: several.iter().filter(|f| !agreed(f) && !f.passes).count(),
                mean_seconds: seconds.iter().sum::<f64>() / seconds.len().max(1) as f64,
                min_seconds: seconds.iter().copied().fold(f64::INFINITY, f64::min),
                max_seconds: seconds.iter().copied().fold(0.0, f64::max),
            }
        })
        .collect()
}

/// The sweep's table in Markdown, a row a family and population; with
/// `backend`, a first column names it (for docs/PERFORMANCE.md, where
/// both backends' rows meet).
pub fn markdown_table(rows: &[PopulationRow], backend: Option<&str>) -> String {
    let (head, rule, cell) = match backend {
        Some(b) => ("| backend ", "|---", format!("| {b} ")),
        None => ("", "", String::new()),
    };
    let mut table = format!(
        "{head}| family | N | tries | pass | within 5 % | p (single tries that pass) | agreeing > {:.0} %: missed | agreeing ≤ {:.0} %: missed | time a fit (mean; range) |\n{rule}|---|---:|---:|---:|---:|---:|---:|---:|---:|",
        100.0 * UNSURE_SHARE,
        100.0 * UNSURE_SHARE
    );
    for r in rows {
        table.push('\n');
        table.push_str(&cell);
        table.push_str(&markdown_row(r));
    }
    table
}

/// One row of the sweep's Markdown table.
fn markdown_row(r: &PopulationRow) -> String {
    let of = |k: usize, missed: usize| {
        if k == 0 {
            "—".to_string()
        } else {
            format!("{missed} of {k}")
        }
    };
    format!(
        "| {} | {} | {} | {}/{} | {} | {}/{} ({:.0} %) | {} | {} | {:.1} s ({:.1}–{:.1}) |",
        r.family,
        r.n,
        r.tries,
        r.pass,
        r.cases,
        r.within_5_percent,
        r.single_tries_passing,
        r.single_tries,
        100.0 * r.single_tries_passing as f64 / r.single_tries.max(1) as f64,
        of(r.agreed, r.agreed_missed),
        of(r.few_agreed, r.few_agreed_missed),
        r.mean_seconds,
        r.min_seconds,
        r.max_seconds
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fit(n: usize, seed: u64, passes: bool, tries: Vec<bool>, agreeing: usize) -> CaseFit {
        CaseFit {
            family: "classic".into(),
            case: 0,
            name: "#1000".into(),
            n,
            seed,
            passes,
            ratio: if passes { 1.01 } else { 2.0 },
            sse: 1.0,
            try_populations: vec![n / tries.len(); tries.len()],
            tries,
            agreeing,
            seconds: seed as f64,
        }
    }

    #[test]
    fn a_row_counts_the_first_seed_as_the_cases_and_every_seed_as_single_tries() {
        let fits = vec![
            fit(100, 1, true, vec![true], 1),
            fit(100, 2, false, vec![false], 1),
            fit(1000, 1, true, vec![true, false, true, true], 3),
            fit(1000, 1, false, vec![false, false, true, false], 1),
        ];
        assert!(
            fits[2]
                .to_string()
                .ends_with("N    1000 seed 1: ratio 1.010 pass p 3/4 agree 3 (1.0 s)"),
            "{}",
            fits[2]
        );
        let rows = summarize(&fits);
        assert_eq!(rows.len(), 2);
        let (small, large) = (&rows[0], &rows[1]);
        assert_eq!((small.n, small.cases, small.pass), (100, 1, 1));
        assert_eq!((small.single_tries_passing, small.single_tries), (1, 2));
        assert_eq!(
            small.mean_seconds, 1.0,
            "the second seed is no case of its own"
        );
        assert_eq!((large.cases, large.pass, large.tries), (2, 1, 4));
        assert_eq!((large.single_tries_passing, large.single_tries), (4, 8));
        // 3 of 4 agree: more than half; 1 of 4: few, and that one missed.
        assert_eq!((large.agreed, large.agreed_missed), (1, 0));
        assert_eq!((large.few_agreed, large.few_agreed_missed), (1, 1));
        let table = markdown_table(&rows, Some("gpu"));
        let lines: Vec<&str> = table.lines().collect();
        assert_eq!(lines.len(), 4);
        // Every line has the backend's column: as many cells as the header.
        let cells = |l: &str| l.matches('|').count();
        assert!(lines.iter().all(|l| cells(l) == cells(lines[0])), "{table}");
        assert!(
            lines[3].starts_with("| gpu | classic | 1000 | 4 | 1/2 |"),
            "{table}"
        );
    }

    #[test]
    fn cases_are_picked_by_their_numbers() {
        let picked = cases(Family::Classic, MATRIX_SEED, Some(&[1003, 1017]));
        assert_eq!(
            picked.iter().map(|c| c.index).collect::<Vec<_>>(),
            vec![3, 17]
        );
        assert_eq!(cases(Family::Generalized, MATRIX_SEED, None).len(), 30);
        // Another matrix numbers its cases from its own seed, and draws
        // other truths at the same places.
        let other = cases(Family::Classic, 5000, Some(&[5003, 1003]));
        assert_eq!(other.len(), 1);
        assert_eq!((other[0].index, other[0].spec.seed), (3, 5003));
        assert_eq!(other[0].spec.excitation, picked[0].spec.excitation);
        assert_ne!(other[0].spec.samples, picked[0].spec.samples);
    }
}
