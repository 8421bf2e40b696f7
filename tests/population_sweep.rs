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
//! from that file and draws docs/figures/population_sweep.svg.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use mckibben::eval::cpu::CpuEvaluator;
use mckibben::fit::agreement::{Agreement, UNSURE_SHARE};
use mckibben::fit::cases::{Case, matrix};
use mckibben::fit::objective::{GENERATIONS, staged_plan};
use mckibben::fit::run::run_fit;
use mckibben::model::Family;
use mckibben::optim::Algorithm;
use mckibben::optim::engine::StopRules;
use mckibben::report::{Figure, Panel, Series};
use serde::{Deserialize, Serialize};

/// One fit of one case.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Result {
    family: String,
    case: usize,
    name: String,
    n: usize,
    seed: u64,
    passes: bool,
    ratio: f64,
    sse: f64,
    /// Whether each try alone passes.
    tries: Vec<bool>,
    /// Tries within the likelihood-ratio threshold of the best.
    agreeing: usize,
    seconds: f64,
}

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
    [(Family::Classic, 20), (Family::Generalized, 30)]
        .into_iter()
        .filter(|(f, _)| only.as_deref().is_none_or(|o| o == f.to_string()))
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
    let cases = std::env::var("SWEEP_CASES")
        .ok()
        .map(|_| list("SWEEP_CASES", ""));
    for n in list("SWEEP_N", "100,1000,10000") {
        let n = n as usize;
        let seeds = match std::env::var("SWEEP_SEEDS") {
            Ok(_) => list("SWEEP_SEEDS", "1"),
            Err(_) if n < 1000 => vec![1, 2, 3, 4, 5],
            Err(_) => vec![1],
        };
        for (family, count) in families() {
            for (i, spec) in matrix(family, count, 1000).into_iter().enumerate() {
                if cases
                    .as_ref()
                    .is_some_and(|c| !c.contains(&(1000 + i as u64)))
                {
                    continue;
                }
                for &seed in &seeds {
                    let known = done.iter().any(|r| {
                        r.family == family.to_string() && r.case == i && r.n == n && r.seed == seed
                    });
                    if known {
                        continue;
                    }
                    let case = Case::generate(spec);
                    let problem = case.problem();
                    let started = Instant::now();
                    let plan =
                        staged_plan(&problem, Algorithm::De.staged_settings(n), n, GENERATIONS);
                    let (_, outcome) =
                        run_fit(&problem, plan, seed, StopRules::default(), &mut cpu).unwrap();
                    let seconds = started.elapsed().as_secs_f64();
                    let judged = case.judge(&outcome.params, &mut cpu).unwrap();
                    let tries = if outcome.tries.len() > 1 {
                        outcome
                            .tries
                            .iter()
                            .map(|t| {
                                !t.params.is_empty()
                                    && case.judge(&t.params, &mut cpu).unwrap().passes
                            })
                            .collect()
                    } else {
                        vec![judged.passes]
                    };
                    let agreeing = Agreement::of(&outcome.tries, problem.est_samples())
                        .map_or(1, |a| a.agreeing);
                    let r = Result {
                        family: family.to_string(),
                        case: i,
                        name: case.name(),
                        n,
                        seed,
                        passes: judged.passes,
                        ratio: judged.ratio,
                        sse: outcome.sse,
                        tries,
                        agreeing,
                        seconds,
                    };
                    eprintln!(
                        "{:48} N {n:>6} seed {seed}: ratio {:.3} {} p {}/{} agree {} ({:.1} s)",
                        r.name,
                        r.ratio,
                        if r.passes { "pass" } else { "FAIL" },
                        r.tries.iter().filter(|&&t| t).count(),
                        r.tries.len(),
                        r.agreeing,
                        seconds
                    );
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
    for (family, count) in families() {
        let name = family.to_string();
        let of_family: Vec<&Result> = results.iter().filter(|r| r.family == name).collect();
        let mut by_n: BTreeMap<usize, Vec<&Result>> = BTreeMap::new();
        for r in &of_family {
            by_n.entry(r.n).or_default().push(r);
        }
        println!("\n{name} ({count} cases), seed 1 unless said:\n");
        println!(
            "| N | tries | pass | within 5 % | p (single tries that pass) | agreeing > {:.0} %: missed | agreeing ≤ {:.0} %: missed | time a case (mean; range) |",
            100.0 * UNSURE_SHARE,
            100.0 * UNSURE_SHARE
        );
        println!("|---:|---:|---:|---:|---:|---:|---:|---:|");
        let (mut xs, mut pass_y, mut time_y) = (Vec::new(), Vec::new(), Vec::new());
        for (n, rs) in &by_n {
            let first: Vec<&&Result> = rs.iter().filter(|r| r.seed == 1).collect();
            if first.len() < count {
                println!("| {n} | (incomplete: {} of {count} cases) |", first.len());
                continue;
            }
            let pass = first.iter().filter(|r| r.passes).count();
            let within = first.iter().filter(|r| r.ratio <= 1.05).count();
            let (p_pass, p_all): (usize, usize) = rs.iter().fold((0, 0), |(a, b), r| {
                (
                    a + r.tries.iter().filter(|&&t| t).count(),
                    b + r.tries.len(),
                )
            });
            let sure = |r: &&&Result| r.agreeing as f64 > UNSURE_SHARE * r.tries.len() as f64;
            let (sure_n, sure_miss) = first
                .iter()
                .filter(|r| r.tries.len() > 1 && sure(r))
                .fold((0, 0), |(a, b), r| (a + 1, b + usize::from(!r.passes)));
            let (unsure_n, unsure_miss) = first
                .iter()
                .filter(|r| r.tries.len() > 1 && !sure(r))
                .fold((0, 0), |(a, b), r| (a + 1, b + usize::from(!r.passes)));
            let secs: Vec<f64> = first.iter().map(|r| r.seconds).collect();
            let mean = secs.iter().sum::<f64>() / secs.len() as f64;
            let (lo, hi) = secs
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
            let agreement = |k: usize, miss: usize| {
                if k == 0 {
                    "—".to_string()
                } else {
                    format!("{miss} of {k}")
                }
            };
            println!(
                "| {n} | {} | {pass}/{count} | {within} | {p_pass}/{p_all} ({:.0} %) | {} | {} | {mean:.1} s ({lo:.1}–{hi:.1}) |",
                first[0].tries.len(),
                100.0 * p_pass as f64 / p_all as f64,
                agreement(sure_n, sure_miss),
                agreement(unsure_n, unsure_miss),
            );
            xs.push((*n as f64).log10());
            pass_y.push(pass as f64);
            time_y.push(mean);
        }
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
