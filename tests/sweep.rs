//! `mckibben sweep`: generated cases fitted at several populations, on the
//! CPU and, with the same fits, on lavapipe.

mod common;

use std::process::{Command, Output};

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_mckibben");

/// `mckibben sweep --pop 100 --family classic ARGS`: a small population.
fn small_sweep(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(["sweep", "--pop", "100", "--family", "classic"])
        .args(args)
        .output()
        .expect("run mckibben")
}

/// A sweep's `--json` document, once it succeeded.
fn json_of(out: Output) -> Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

/// `mckibben sweep ARGS --json` on the smallest case's run, parsed.
fn sweep(args: &[&str]) -> Value {
    json_of(small_sweep(
        &[&["--cases", "1000"], args, &["--json"]].concat(),
    ))
}

#[test]
fn a_row_counts_the_first_seed_as_the_cases_and_every_seed_as_single_tries() {
    let json = sweep(&["--seeds", "1,2", "--backend", "cpu"]);
    let fits = json["fits"].as_array().unwrap();
    assert_eq!(fits.len(), 2);
    assert!(
        fits[0]["name"].as_str().unwrap().ends_with("#1000"),
        "{json}"
    );
    assert_eq!(
        (fits[0]["seed"].as_u64(), fits[1]["seed"].as_u64()),
        (Some(1), Some(2))
    );
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 1);
    let row = &rows[0];
    assert_eq!(
        (row["family"].as_str(), row["n"].as_u64()),
        (Some("classic"), Some(100))
    );
    assert_eq!(
        (row["cases"].as_u64(), row["single_tries"].as_u64()),
        (Some(1), Some(2))
    );
    let pass = u64::from(fits[0]["passes"].as_bool().unwrap());
    assert_eq!(row["pass"].as_u64(), Some(pass));
}

/// A sweep says which overshoot rule its fits ran under (`--overshoot`).
#[test]
fn a_sweep_says_whether_its_fits_refused_overshooting_loops() {
    for rule in ["allow", "refuse"] {
        let json = sweep(&["--overshoot", rule, "--backend", "cpu"]);
        assert_eq!(json["overshoot"].as_str(), Some(rule), "{json}");
    }
}

/// The table of several seeds says whose fits its pass and time columns
/// count, wherever it is pasted (it showed seed 1's alone without a word),
/// and the lowest seed's whatever the order given.
#[test]
fn a_table_of_several_seeds_says_which_seed_its_columns_count() {
    let out = small_sweep(&["--cases", "1000", "--seeds", "2,1", "--backend", "cpu"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.starts_with(
            "Seeds 2, 1: pass, within 5 %, the agreement columns and the time are seed 1's fits"
        ),
        "{text}"
    );
    let one = small_sweep(&["--cases", "1000", "--backend", "cpu"]);
    assert!(!String::from_utf8_lossy(&one.stdout).contains("Seeds"));
}

/// A population from two tries on runs as whole tries, as `fit` runs it:
/// 3050 is 3000 (two tries of 1000 and ten of 100; the next try would hold
/// 1000), said once and fitted once beside a 3000 asked for (its rows said
/// N 3050 of a fit of 3000).
#[test]
fn a_population_runs_and_is_reported_as_whole_tries() {
    let out = Command::new(BIN)
        .args(["sweep", "--pop", "3050,3000", "--family", "classic"])
        .args(["--cases", "1000", "--backend", "cpu", "--json"])
        .output()
        .expect("run mckibben");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("--pop 3050 runs 3000 candidates (2 tries of 1000 and 10 of 100)"),
        "{stderr}"
    );
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let fits = json["fits"].as_array().unwrap();
    let ns: Vec<u64> = fits.iter().map(|f| f["n"].as_u64().unwrap()).collect();
    assert_eq!(ns, [3000]);
    assert_eq!(json["rows"][0]["n"], 3000);
    assert_eq!(fits[0]["tries"].as_array().unwrap().len(), 12);
}

#[test]
fn lavapipe_fits_the_cases_as_the_cpu_does() {
    if common::require_lavapipe_adapter().is_none() {
        return;
    }
    let cpu = sweep(&["--backend", "cpu"]);
    let gpu = sweep(&["--backend", "gpu"]);
    assert!(gpu["backend"].as_str().unwrap().starts_with("gpu"), "{gpu}");
    let (c, g) = (&cpu["fits"][0], &gpu["fits"][0]);
    for key in ["sse", "ratio", "passes", "tries", "agreeing"] {
        assert_eq!(c[key], g[key], "{key}");
    }
}

/// `--matrix` draws the cases afresh from another seed and numbers them
/// from it; a number of the shipped matrix then picks nothing, and the
/// error says which numbers there are.
#[test]
fn another_matrix_draws_other_cases_numbered_from_its_seed() {
    let shipped = sweep(&["--backend", "cpu"]);
    assert_eq!(shipped["matrix"], 1000);
    let first_of_matrix_5000 = |output: &str| {
        small_sweep(&[
            "--matrix",
            "5000",
            "--cases",
            "5000",
            "--backend",
            "cpu",
            output,
        ])
    };
    let other = json_of(first_of_matrix_5000("--json"));
    assert_eq!(other["matrix"], 5000);
    let (a, b) = (&shipped["fits"][0], &other["fits"][0]);
    assert_eq!((a["case"].as_u64(), b["case"].as_u64()), (Some(0), Some(0)));
    assert!(b["name"].as_str().unwrap().ends_with("#5000"), "{b}");
    assert_ne!(a["sse"], b["sse"], "the same record drawn twice");
    // The table says which cases it holds, wherever it is pasted.
    let out = first_of_matrix_5000("--markdown");
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(
        table.starts_with("Cases of --matrix 5000 (#5000 on):\n\n| backend |"),
        "{table}"
    );
    let out = small_sweep(&["--matrix", "5000", "--cases", "1000"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("--matrix 5000 has these numbers (classic: 5000–5019)"),
        "{stderr}"
    );
}

#[test]
fn cases_and_populations_out_of_reach_are_refused() {
    for (args, flag) in [
        (["--cases", "4242"], "--cases"),
        (["--pop", "3"], "--pop"),
        (["--family", "linear"], "--family"),
        // Given twice, a case was fitted and counted twice.
        (["--seeds", "1,1"], "--seeds names 1 twice"),
        (["--pop", "100,100"], "--pop names 100 twice"),
        (["--cases", "1000,1000"], "--cases names 1000 twice"),
        // Its last case would be numbered past the seeds' exact range.
        (
            ["--matrix", "9007199254740991"],
            "--matrix <SEED>': at most 9007199254740962",
        ),
        (
            ["--family", "classic,classic"],
            "--family names classic twice",
        ),
    ] {
        let out = Command::new(BIN)
            .arg("sweep")
            .args(args)
            .output()
            .expect("run mckibben");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(stderr.contains(flag), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}
