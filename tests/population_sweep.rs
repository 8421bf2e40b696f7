//! The population sweep of docs/RESULTS.md, "Larger populations": both
//! families' matrices of generated cases (classic 20, generalized 30) fitted
//! with `fit`'s defaults at several populations on the CPU, recording per
//! case whether the fit passes (`Case::judge`), its validation ratio and
//! estimation SSE, whether each of its tries would pass alone (the share
//! of single tries that reach the truth's basin, `p`), how many tries agree
//! (`fit::agreement`) and the time. A measurement, not a test: it runs for
//! hours at N = 10⁵ on 2 cores.
//!
//! ```sh
//! SWEEP_N=100,1000,10000,100000 cargo test --release --test population_sweep -- --ignored --nocapture
//! ```
//!
//! `SWEEP_N` lists the populations, `SWEEP_FAMILY` (`classic`,
//! `generalized`) limits the families, `SWEEP_CASES` the cases (by their
//! names' numbers: `1012,1016`) and `SWEEP_SEEDS` (default 1) the
//! seeds; single tries at a population below 2000 take more seeds to
//! measure `p` (5 at N = 100 by default). Each result is one line of JSON
//! appended to `target/sweep/results.jsonl`, and a case already there is
//! not fitted again, so an interrupted sweep goes on where it stopped.
//! `population_sweep_summary` then prints the tables of docs/RESULTS.md
//! from that file and draws docs/figures/population_sweep.svg. Each fit is
//! `fit::sweep::fit_case`, as `mckibben sweep` runs it on either backend.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;

use mckibben::eval::cpu::CpuEvaluator;
use mckibben::fit::problem::Overshoot;
use mckibben::fit::sweep::{
    CaseFit as Result, MATRIX_SEED, PopulationRow, cases, fit_case, markdown_table, matrix_size,
    summarize,
};
use mckibben::model::Family;
use mckibben::report::{Figure, Panel, Series};

fn results_file() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/sweep");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join("results.jsonl")
}

fn read_results() -> Vec<Result> {
    std::fs::read_to_string(results_file())
        .unwrap_or_default()
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| serde_json::from_str(l).expect("a sweep result"))
        .collect()
}

fn families() -> Vec<(Family, usize)> {
    let only = std::env::var("SWEEP_FAMILY").ok();
    [Family::Classic, Family::Generalized]
        .into_iter()
        .filter(|f| only.as_deref().is_none_or(|o| o == f.to_string()))
        .map(|f| (f, matrix_size(f)))
        .collect()
}

fn list(var: &str, default: &str) -> Vec<u64> {
    std::env::var(var)
        .unwrap_or_else(|_| default.to_string())
        .split(',')
        .map(|v| v.trim().parse().expect("a number"))
        .collect()
}

#[test]
#[ignore = "measurement: hours on 2 cores; results in docs/RESULTS.md"]
fn population_sweep() {
    let done = read_results();
    let mut out = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(results_file())
        .unwrap();
    let mut cpu = CpuEvaluator::new();
    let only = std::env::var("SWEEP_CASES")
        .ok()
        .map(|_| list("SWEEP_CASES", ""));
    for n in list("SWEEP_N", "100,1000,10000") {
        let n = n as usize;
        let seeds = match std::env::var("SWEEP_SEEDS") {
            Ok(_) => list("SWEEP_SEEDS", "1"),
            Err(_) if n < 1000 => vec![1, 2, 3, 4, 5],
            Err(_) => vec![1],
        };
        for (family, _) in families() {
            for case in cases(family, MATRIX_SEED, only.as_deref()) {
                for &seed in &seeds {
                    let known = done.iter().any(|r| {
                        r.family == family.to_string()
                            && r.case == case.index
                            && r.n == n
                            && r.seed == seed
                    });
                    if known {
                        continue;
                    }
                    let r = fit_case(&case, (n, seed), Overshoot::Allow, &mut cpu).unwrap();
                    eprintln!("{r}");
                    writeln!(out, "{}", serde_json::to_string(&r).unwrap()).unwrap();
                }
            }
        }
    }
}

/// The tables and the figure of docs/RESULTS.md, "Larger populations",
/// from the sweep's results.
#[test]
#[ignore = "prints the sweep's tables from target/sweep/results.jsonl and draws its figure"]
fn population_sweep_summary() {
    let results = read_results();
    let mut figure = Figure::new("Larger populations: generated cases, seed 1, CPU");
    let mut passes = Panel::new("cases that pass", "log10 N", "pass (of the matrix)");
    let mut times = Panel::new("time a case", "log10 N", "seconds").log_y();
    let rows = summarize(&results);
    for (family, count) in families() {
        let name = family.to_string();
        let of_family: Vec<&Result> = results.iter().filter(|r| r.family == name).collect();
        let mut by_n: BTreeMap<usize, Vec<&Result>> = BTreeMap::new();
        for r in &of_family {
            by_n.entry(r.n).or_default().push(r);
        }
        let mut complete: Vec<PopulationRow> = rows
            .iter()
            .filter(|r| r.family == name && r.cases == count)
            .cloned()
            .collect();
        complete.sort_by_key(|r| r.n);
        println!("\n{name} ({count} cases), seed 1 unless said:\n");
        println!("{}", markdown_table(&complete, None));
        for r in rows.iter().filter(|r| r.family == name && r.cases < count) {
            println!("(N = {}: incomplete, {} of {count} cases)", r.n, r.cases);
        }
        let xs: Vec<f64> = complete.iter().map(|r| (r.n as f64).log10()).collect();
        let pass_y: Vec<f64> = complete.iter().map(|r| r.pass as f64).collect();
        let time_y: Vec<f64> = complete.iter().map(|r| r.mean_seconds).collect();
        // Nested tries: a larger population runs the default's try and
        // more, so it never ends at a higher estimation SSE.
        let default_n = 1000;
        let at = |n: usize, i: usize| {
            of_family
                .iter()
                .find(|r| r.n == n && r.case == i && r.seed == 1)
                .map(|r| r.sse)
        };
        for &n in by_n.keys().filter(|&&n| n > default_n) {
            let pairs: Vec<(f64, f64)> = (0..count)
                .filter_map(|i| Some((at(default_n, i)?, at(n, i)?)))
                .collect();
            let nested = pairs.iter().filter(|(d, l)| l <= d).count();
            println!(
                "\nnested: at N = {n} the estimation SSE is no higher than at N = {default_n} on {nested} of {} cases",
                pairs.len()
            );
        }
        // Per case: p at each population, and whether the fit passed.
        println!(
            "\n| case | {} |",
            by_n.keys()
                .map(|n| format!("N = {n}"))
                .collect::<Vec<_>>()
                .join(" | ")
        );
        println!("|---|{}", "---:|".repeat(by_n.len()));
        for i in 0..count {
            let cells: Vec<String> = by_n
                .values()
                .map(|rs| {
                    let own: Vec<&&Result> = rs.iter().filter(|r| r.case == i).collect();
                    let Some(first) = own.iter().find(|r| r.seed == 1) else {
                        return "—".into();
                    };
                    let (p, all) = own.iter().fold((0, 0), |(a, b), r| {
                        (
                            a + r.tries.iter().filter(|&&t| t).count(),
                            b + r.tries.len(),
                        )
                    });
                    format!(
                        "{} {:.3} (p {p}/{all})",
                        if first.passes { "pass" } else { "**FAIL**" },
                        first.ratio
                    )
                })
                .collect();
            let name = of_family
                .iter()
                .find(|r| r.case == i)
                .map_or(String::new(), |r| r.name.clone());
            println!("| {name} | {} |", cells.join(" | "));
        }
        passes = passes.with(Series::line(name.clone(), xs.clone(), pass_y));
        times = times.with(Series::line(name, xs, time_y));
    }
    figure = figure.with(passes).with(times);
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("docs/figures/population_sweep.svg");
    figure.save(&path).unwrap();
    println!("\nwrote {}", path.display());
}
