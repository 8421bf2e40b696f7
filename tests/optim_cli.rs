//! `mckibben fit` and `mckibben compare` end to end on a small synthetic
//! CSV: the documented JSON keys and files, checkpoint resume, and clear
//! errors for bad flags and bad data.

mod common;

use std::path::Path;
use std::process::{Command, Output};

use mckibben::data::Trace;
use mckibben::data::csv::write_trace;
use mckibben::fit::synthetic::Synthetic;
use mckibben::model::Family;

fn mckibben(args: &[&str], dir: &Path) -> Output {
    command(dir).args(args).output().unwrap()
}

/// The binary, run in `dir`, for a test that sets more than its arguments.
fn command(dir: &Path) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_mckibben"));
    command
        .current_dir(dir)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir());
    command
}

/// `fit` of `csv` at a tiny budget (N = 20, G = 2, CPU): for checks of
/// what the command accepts and says, not of where it ends.
fn short_fit(csv: &str) -> [&str; 8] {
    ["fit", csv, "--pop", "20", "--gens", "2", "--backend", "cpu"]
}

fn data(dir: &Path) -> String {
    let s = Synthetic::new(Family::Classic, 400, 0.05, 21);
    let path = dir.join("synthetic.csv");
    write_trace(&path, &s.trace).unwrap();
    path.display().to_string()
}

/// `mckibben fit` on a Cavatappi record with its columns and time base.
fn fit_cavatappi(path: &Path, extra: &[&str], dir: &Path) -> Output {
    let file = path.display().to_string();
    let mut args = vec!["fit", &file];
    args.extend_from_slice(&common::CAVATAPPI_FLAGS);
    args.extend_from_slice(extra);
    mckibben(&args, dir)
}

fn json(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// A choice's name is read in any case, as the thesis writes it (GA, PSO,
/// MFA) and as `control --algo` and the Python module always read it.
#[test]
fn choices_are_read_in_any_case() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let out = mckibben(
        &[
            "fit",
            &csv,
            "--pop",
            "20",
            "--gens",
            "2",
            "--backend",
            "CPU",
            "--algo",
            "PSO",
            "--model",
            "Classic",
            "--json",
        ],
        dir.path(),
    );
    let v = json(&out);
    assert_eq!(
        (v["algo"].as_str(), v["model"].as_str()),
        (Some("pso"), Some("classic"))
    );
    assert!(v["backend"].as_str().unwrap().starts_with("cpu"), "{v}");
}

#[test]
fn fit_writes_the_documented_json_and_files() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let out = mckibben(
        &[
            "fit",
            &csv,
            "--algo",
            "pso",
            "--pop",
            "40",
            "--gens",
            "5",
            "--seed",
            "3",
            "--backend",
            "cpu",
            "--out",
            "fitdir",
            "--json",
        ],
        dir.path(),
    );
    let v = json(&out);
    for key in [
        "model",
        "algo",
        "params",
        "sse",
        "val_rmse",
        "val_fit_percent",
        "evaluations",
        "seconds",
        "backend",
        "stages",
        "on_edge",
        "stop",
    ] {
        assert!(v.get(key).is_some(), "missing {key} in {v}");
    }
    assert_eq!(v["model"], "classic");
    assert_eq!(v["algo"], "pso");
    // a, b, c, x0, A, α, β, γ, n.
    assert_eq!(v["params"].as_object().unwrap().len(), 9);
    // A standard error a parameter, by the same names; the gauge and the
    // exponent are held.
    let errors = v["std_errors"].as_object().unwrap();
    let names =
        |o: &serde_json::Map<String, serde_json::Value>| o.keys().cloned().collect::<Vec<_>>();
    assert_eq!(names(errors), names(v["params"].as_object().unwrap()));
    assert!(errors["A"].is_null() && errors["n"].is_null(), "{errors:?}");
    assert!(errors["b"].as_f64().unwrap() > 0.0, "{errors:?}");
    let stages: Vec<&str> = v["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["stage"].as_str().unwrap())
        .collect();
    assert_eq!(stages, ["global", "free-run", "polish"]);
    // The global stage: 40 × 5 on the prediction error.
    assert_eq!(v["stages"][0]["evaluations"], 200);
    assert_eq!(v["stop"], "completed");
    for f in [
        "model.json",
        "result.json",
        "history.csv",
        "history.json",
        "trends.svg",
        "convergence.svg",
        "loop.svg",
        "trace.svg",
    ] {
        assert!(dir.path().join("fitdir").join(f).is_file(), "{f}");
    }
    let history = std::fs::read_to_string(dir.path().join("fitdir/history.csv")).unwrap();
    assert!(
        history.lines().nth(1).unwrap().contains(",global,"),
        "{history}"
    );
    assert!(history.contains(",polish,"), "{history}");
    // A polish start has no population: its population figures are empty
    // cells (NaN to pandas and MATLAB), not a cost of `inf`.
    let polish = history.lines().find(|l| l.contains(",polish,")).unwrap();
    let cells: Vec<&str> = polish.split(',').collect();
    assert_eq!(&cells[7..11], ["", "", "", "0"], "{polish}");
    assert!(!history.contains("inf"), "{history}");
    // Its columns name the canonical parameters its rows hold, not the
    // search coordinates (gain, loading, ...).
    assert!(
        history
            .lines()
            .next()
            .unwrap()
            .ends_with(",A,alpha,beta,gamma,n,a,b,c,x0"),
        "{history}"
    );

    // The thesis' flow: one stage on the free run, N × G evaluations, a and
    // b held at the ARX estimate.
    let thesis = json(&mckibben(
        &[
            "fit",
            &csv,
            "--thesis-flow",
            "--algo",
            "ga",
            "--pop",
            "10",
            "--gens",
            "3",
            "--backend",
            "cpu",
            "--out",
            "thesis",
            "--json",
        ],
        dir.path(),
    ));
    assert_eq!(thesis["evaluations"], 30);
    assert_eq!(thesis["stages"].as_array().unwrap().len(), 1);
    assert_eq!(thesis["stages"][0]["measure"], "free-run");
    assert_eq!(thesis["flow"], "thesis");
}

/// A checkpoint resumed under other --pop, --gens, --algo and --seed names
/// each one it overrides: a loop over seeds that reuses one checkpoint
/// path resumed one fit each time, labelled only "its settings win".
#[test]
fn a_resumed_checkpoint_names_the_flags_it_overrides() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let fit = |extra: &[&str]| {
        let args = [&["fit", &csv, "--backend", "cpu", "--json"][..], extra].concat();
        mckibben(&args, dir.path())
    };
    let made = fit(&[
        "--algo",
        "de",
        "--pop",
        "30",
        "--gens",
        "8",
        "--seed",
        "4",
        "--checkpoint",
        "ck.json",
        "--time-budget",
        "0",
    ]);
    assert!(!made.status.success());
    let resumed = json(&fit(&[
        "--algo",
        "ga",
        "--pop",
        "40",
        "--gens",
        "9",
        "--seed",
        "5",
        "--checkpoint",
        "ck.json",
    ]));
    assert_eq!(
        (resumed["seed"].as_u64(), resumed["algo"].as_str()),
        (Some(4), Some("de"))
    );
    let notes = resumed["notes"].to_string();
    for overridden in [
        "N = 30 (not 40)",
        "G = 8 (not 9)",
        "--algo de (not ga)",
        "seed 4 (not 5)",
    ] {
        assert!(notes.contains(overridden), "{overridden}: {notes}");
    }
}

#[test]
fn fit_resumes_from_a_checkpoint_to_the_same_result() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let base = [
        "fit",
        &csv,
        "--algo",
        "de",
        "--pop",
        "30",
        "--seed",
        "4",
        "--backend",
        "cpu",
        "--json",
    ];
    let full = json(&mckibben(
        &[&base[..], &["--gens", "8"]].concat(),
        dir.path(),
    ));
    // A run cut short by its time budget, then resumed without one.
    let first = [
        &base[..],
        &[
            "--gens",
            "8",
            "--checkpoint",
            "ck.json",
            "--time-budget",
            "0",
        ],
    ]
    .concat();
    // Stopped before its first generation: an error that says how to go
    // on, and nothing written beside an older run's files.
    let result = dir.path().join("out/fit/result.json");
    let before = std::fs::read(&result).unwrap();
    let part = mckibben(&first, dir.path());
    let err = String::from_utf8_lossy(&part.stderr);
    assert!(!part.status.success(), "{err}");
    assert!(err.contains("`--checkpoint ck.json` resumes it"), "{err}");
    assert_eq!(std::fs::read(&result).unwrap(), before);
    assert!(dir.path().join("ck.json").exists());
    let resumed = json(&mckibben(
        &[&base[..], &["--gens", "8", "--checkpoint", "ck.json"]].concat(),
        dir.path(),
    ));
    assert_eq!(resumed["generations"], full["generations"]);
    assert_eq!(resumed["params"], full["params"]);
    assert_eq!(resumed["sse"], full["sse"]);
    let resuming = |fit: &serde_json::Value| -> String {
        fit["notes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|n| n["text"].as_str().unwrap().to_string())
            .find(|t| t.starts_with("resuming at generation"))
            .unwrap_or_else(|| panic!("no resuming note: {fit}"))
    };
    assert!(
        resuming(&resumed).ends_with("(its plan, N, G, seed and settings win)"),
        "{resumed}"
    );
    // The same checkpoint on other data is refused: resuming it would
    // report the first record's fit as the second's.
    let other = Synthetic::new(Family::Classic, 400, 0.05, 22);
    write_trace(&dir.path().join("other.csv"), &other.trace).unwrap();
    let mut on_other = base.to_vec();
    on_other[1] = "other.csv";
    let refused = mckibben(
        &[&on_other[..], &["--gens", "8", "--checkpoint", "ck.json"]].concat(),
        dir.path(),
    );
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success(), "{err}");
    assert!(err.contains("made by a fit of other data"), "{err}");
    // And with another box: the checkpoint would resume its own and report
    // the new --fix as applied.
    let refused = mckibben(
        &[
            &base[..],
            &[
                "--gens",
                "8",
                "--checkpoint",
                "ck.json",
                "--fix",
                "alpha=0.5",
            ],
        ]
        .concat(),
        dir.path(),
    );
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success(), "{err}");
    assert!(
        err.contains("searched another box for alpha (made with other --bound, --fix"),
        "{err}"
    );
}

/// Ctrl-C stops a fit after its current generation: the best so far is
/// written, and the command exits with 130, as a program Ctrl-C killed
/// does, so that a script running it stops too.
#[cfg(unix)]
#[test]
fn ctrl_c_writes_the_best_so_far_and_exits_as_interrupted() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    // The line that announces the fit comes once the handler is in place
    // and the data are read; the first generations take milliseconds.
    let out = common::interrupt_once(
        command(dir.path())
            .args(["fit", &csv, "--pop", "200", "--gens", "1000000"])
            .args(["--backend", "cpu", "--checkpoint", "ck.json"]),
        |line| line.starts_with("fitting"),
        std::time::Duration::from_secs(2),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(
        err.contains("interrupted (Ctrl-C): the best so far is written to out/fit"),
        "{err}"
    );
    assert!(err.contains("`--checkpoint ck.json` resumes it"), "{err}");
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(report.contains("stopped: Interrupted"), "{report}");
    let model = std::fs::read_to_string(dir.path().join("out/fit/model.json")).unwrap();
    assert!(model.contains("\"family\""), "{model}");
}

#[test]
fn bad_flags_and_bad_data_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let cases: [(&[&str], &str); 32] = [
        (&["fit", "missing.csv"], "missing.csv"),
        // A population no machine holds: an error, not an aborted
        // allocation.
        (
            &["fit", &csv, "--pop", "18446744073709551615"],
            "for '--pop <POP>': at most 100000000 candidates",
        ),
        (&["fit", &csv, "--algo", "cmaes"], "cmaes"),
        // Each algorithm's own minimum, named with the flag.
        (
            &["fit", &csv, "--pop", "2", "--backend", "cpu"],
            "--pop must be at least 4 for --algo de",
        ),
        (
            &[
                "fit",
                &csv,
                "--algo",
                "ga",
                "--pop",
                "1",
                "--backend",
                "cpu",
            ],
            "--pop must be at least 2 for --algo ga",
        ),
        (
            &["fit", &csv, "--p-mut", "1.5", "--backend", "cpu"],
            "--p-mut",
        ),
        (
            &[
                "fit",
                &csv,
                "--algo",
                "pso",
                "--p-mut",
                "0.3",
                "--backend",
                "cpu",
            ],
            "--p-mut tunes --algo ga, but this fit runs --algo pso",
        ),
        (
            &[
                "fit",
                &csv,
                "--pop",
                "8",
                "--islands",
                "4",
                "--backend",
                "cpu",
            ],
            "islands",
        ),
        // A stall of 0 generations ended every stage after its first
        // (Python's `stall` refused it already).
        (
            &["fit", &csv, "--stall", "0"],
            "invalid value '0' for '--stall <GENS>': at least 1",
        ),
        // An exponent to free in a model without one: accepted silently.
        (
            &["bench", "--model", "linear", "--free-n", "--pop", "10"],
            "--free-n frees the Bouc-Wen exponent n, and --model linear has none",
        ),
        (
            &["fit", &csv, "--gens", "0"],
            "invalid value '0' for '--gens <GENS>': at least 1",
        ),
        // A count past a word less one wrapped once the initial population
        // was added (diagnose said "need at least one generation").
        (
            &["diagnose", &csv, "--generations", "18446744073709551615"],
            "for '--generations <GENERATIONS>': at most 1000000000",
        ),
        // `fit`'s spellings are read where the flag is spelled out.
        (
            &["diagnose", &csv, "--gens", "0"],
            "for '--generations <GENERATIONS>'",
        ),
        (
            &["validate", "boucwen", "--pop", "1"],
            "--population must be at least 4",
        ),
        // Past 500, a fit's seeds ran into its from-scratch seeds or the
        // next salt's: two fits drew the same numbers.
        (
            &["diagnose", &csv, "--seeds", "501"],
            "--seeds 501: at most 500",
        ),
        (
            &["diagnose", &csv, "--scratch-seeds", "501"],
            "--scratch-seeds 501: at most 500",
        ),
        (
            &["compare", &csv, "--seeds", "18446744073709551615"],
            "--seeds 18446744073709551615: at most 9007199254740991",
        ),
        (
            &["compare", &csv, "--sizes", "1000,1000"],
            "--sizes names 1000 twice: Table 21 would hold its rows twice",
        ),
        // Refused before Table 21's first row ran, not after it.
        (
            &["compare", &csv, "--budget-gens", "18446744073709551615"],
            "for '--budget-gens <BUDGET_GENS>': at most 1000000000",
        ),
        // A lone particle stops near its draw: five seeds of seven ended
        // with no model, and a warning that blamed the data.
        (
            &["fit", &csv, "--algo", "pso", "--pop", "1"],
            "--pop must be at least 2 for --algo pso (got 1)",
        ),
        (
            &["fit", &csv, "--target-sse", "nan", "--backend", "cpu"],
            "--target-sse must be a finite SSE of 0 or more",
        ),
        // The synthetic record's estimation half has 200 samples.
        (
            &["fit", &csv, "--horizon", "500", "--backend", "cpu"],
            "--horizon 500: a prediction horizon is 1 to 199 samples here",
        ),
        // Flags that would be ignored without a word: a switching level
        // for a family without sign terms, an exponent both fitted and held.
        (
            &["fit", &csv, "--switch", "zero", "--backend", "cpu"],
            "--switch zero: the switching level belongs to the generalized model's sign terms, \
             and this fit is classic",
        ),
        (
            &["fit", &csv, "--free-n", "--fix", "n=2", "--backend", "cpu"],
            "--free-n fits the exponent n and --fix n holds it",
        ),
        // `simulate --from` runs the model's parameters, not a preset's.
        (
            &["simulate", "--from", "model.json", "--preset", "thesis"],
            "'--from <MODEL.json>' cannot be used with '--preset <PRESET>'",
        ),
        // `-` is no standard output for a folder or a figure: refused,
        // not a file or folder of that name (a CSV trace's `--out` takes
        // it: tests/twin.rs, tests/model_flow.rs).
        (
            &["twin", "--out", "out.csv", "--plot", "-"],
            "'--plot <FILE.svg>': `-` is not standard output here",
        ),
        (
            &["fit", &csv, "--out", "-", "--backend", "cpu"],
            "'--out <DIR>': `-` is not standard output here",
        ),
        (
            &["simulate", "--plot", ""],
            "'--plot <FILE.svg>': an empty name",
        ),
        // A seed the runs add to past 2^64 wrapped to seed 0 (`diagnose
        // --repeat 2` ran seed 0 second); every seed flag takes the same range.
        (
            &[
                "diagnose",
                "--seed",
                "18446744073709551615",
                "--repeat",
                "2",
            ],
            "'--seed <SEED>': seeds run from 0 to 2^53 - 1 = 9007199254740991",
        ),
        (
            &["sweep", "--seeds", "1,9007199254740992"],
            "'--seeds <SEEDS>': seeds run from 0 to 2^53 - 1",
        ),
        // The record itself as the other record: it scored as a transfer
        // or a cross-load check of itself.
        (
            &["diagnose", &csv, "--transfer", &csv],
            "which the diagnosis reads: a transfer scores the chain on another record",
        ),
        (
            &["compare", &csv, "--cross", &csv],
            "the cross-load check scores the fits on another record",
        ),
    ];
    for (args, needle) in cases {
        let out = mckibben(args, dir.path());
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
    }
    assert!(!dir.path().join("-").exists());
    // The reason a file cannot be read is said once, not again as the
    // error's cause.
    let out = mckibben(&["fit", "missing.csv"], dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    std::fs::write(
        dir.path().join("bad.csv"),
        "t,pressure,displacement\n0,0.1,1\n0.1,x,2\n",
    )
    .unwrap();
    let out = mckibben(&["fit", "bad.csv"], dir.path());
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.csv") && err.contains("pressure"), "{err}");
    // A second file's error names the flag that gave it, once.
    let out = mckibben(&["compare", &csv, "--cross", "missing.csv"], dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.starts_with("mckibben: error: --cross: missing.csv"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");

    // Values whose squares overflow the f32 simulation: an error naming the
    // column and its range, and no model written.
    let mut rows = String::from("t,pressure,displacement\n");
    for k in 0..200 {
        let _ = std::fmt::Write::write_fmt(
            &mut rows,
            format_args!(
                "{},{},{}\n",
                k as f64 * 0.01,
                0.1 + 0.001 * k as f64,
                1e19 * (k % 7) as f64
            ),
        );
    }
    std::fs::write(dir.path().join("huge.csv"), rows).unwrap();
    let out = mckibben(
        &["fit", "huge.csv", "--backend", "cpu", "--out", "huge"],
        dir.path(),
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("`displacement`") && err.contains("6e19"),
        "{err}"
    );
    assert!(!dir.path().join("huge/model.json").exists());

    // A stroke in nanometres: no overflow, but past the bound at which a
    // simulated state counts as diverged, so even the truth would: refused
    // with the column's range (every candidate "diverged" before).
    let synthetic = std::fs::read_to_string(&csv).unwrap();
    let mut lines = synthetic.lines();
    let mut nm = vec![lines.next().unwrap().to_string()];
    nm.extend(lines.map(|l| {
        let mut cells: Vec<String> = l.split(',').map(String::from).collect();
        cells[2] = format!("{}", cells[2].parse::<f64>().unwrap() * 1e6);
        cells.join(",")
    }));
    std::fs::write(dir.path().join("nm.csv"), nm.join("\n") + "\n").unwrap();
    let out = mckibben(&short_fit("nm.csv"), dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("the output `displacement` of nm.csv spans")
            && err.contains("counts a state beyond ±1e6 as diverged"),
        "{err}"
    );

    // A stroke a trillion trillion times smaller: squared errors under
    // f32's smallest normal number, where every model scored an SSE of 0.
    let tiny: Vec<String> = nm
        .iter()
        .enumerate()
        .map(|(k, l)| match k {
            0 => l.clone(),
            _ => {
                let mut cells: Vec<String> = l.split(',').map(String::from).collect();
                cells[2] = format!("{}", cells[2].parse::<f64>().unwrap() * 1e-30);
                cells.join(",")
            }
        })
        .collect();
    std::fs::write(dir.path().join("tiny.csv"), tiny.join("\n") + "\n").unwrap();
    let out = mckibben(&short_fit("tiny.csv"), dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("the output `displacement` of tiny.csv spans")
            && err.contains("every model would score an SSE of 0"),
        "{err}"
    );
}

/// A warm start keeps its model's family: another `--model`, or an ARX
/// model from `identify`, is a clear error, not a start vector read as
/// another family's parameters (which panicked, or ran on nonsense).
/// Values no muscle or rig has, files named twice and flags that contradict
/// each other: each an error naming what is wrong, never a panic, an
/// aborted allocation or a run that scores nothing (found by a robustness
/// sweep over every command's flags).
#[test]
fn values_out_of_any_rigs_range_and_contradicting_flags_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let control = [
        "control",
        "--controller",
        "pi",
        "--freq",
        "1",
        "--load",
        "4.5",
        "--warmup",
        "1",
    ];
    let cases: Vec<(Vec<&str>, &str)> = vec![
        // A creep that softens the rubber until the load stretches the
        // braid straight (it panicked).
        (
            vec!["twin", "--effect", "creep=8", "--out", "t.csv"],
            "stretches the muscle at rest",
        ),
        (
            [
                &control[..],
                &["--duration", "2", "--steady-from", "1"],
                &["--effect", "creep=8"],
            ]
            .concat(),
            "stretches the muscle at rest",
        ),
        // Episodes of more samples than a record holds (an aborted
        // allocation), or whose scored part holds none (NaN metrics) or
        // one (a NaN valve travel).
        (
            [&control[..], &["--duration", "1e12", "--steady-from", "1"]].concat(),
            "more than the 10000000 a record may hold",
        ),
        (
            [&control[..], &["--duration", "2", "--steady-from", "1.999"]].concat(),
            "hold fewer than two samples from 1.999 s on",
        ),
        (
            [&control[..], &["--duration", "0.005", "--steady-from", "0"]].concat(),
            "hold fewer than two samples from 0 s on",
        ),
        (
            vec!["bench", "--backend", "cpu", "--synthetic", "10000000000"],
            "--synthetic 10000000000: at least 2 samples and at most 10000000",
        ),
        // Waits no clock holds (they panicked).
        (
            vec!["twin", "serve", "--idle-timeout", "1e20"],
            "--idle-timeout must be a positive number of seconds, at most a day",
        ),
        (
            [
                &control[..],
                &["--duration", "2", "--steady-from", "1"],
                &["--deadline", "1e300"],
            ]
            .concat(),
            "--deadline must be a positive number of milliseconds, at most a day",
        ),
        // A twin whose physics overflow: named as the twin's, not as a
        // bad data file.
        (
            vec!["twin", "--effect", "thickness=5", "--out", "t.csv"],
            "the twin's `displacement` is not finite",
        ),
        (
            vec!["static", "--turns", "1e-300"],
            "is not a finite number",
        ),
        // Files named twice: the input would be replaced by the output.
        (
            vec!["simulate", "--input", &csv, "--out", &csv],
            "the command reads that file as --input",
        ),
        (
            vec!["identify", &csv, "--out", &csv],
            "the command reads that file as DATA",
        ),
        (
            vec!["twin", "--out", "x.csv", "--plot", "./x.csv"],
            "--plot ./x.csv: the command writes that file as --out",
        ),
        // Contradicting or repeated flags: one would win without a word.
        (
            vec![
                "fit",
                &csv,
                "--model",
                "generalized",
                "--switch",
                "zero",
                "--fix",
                "x_s=1",
            ],
            "--switch zero: the switching level is searched or held by it, and also boxed",
        ),
        (
            vec!["simulate", "--params", "alpha=1,alpha=2"],
            "`alpha` is given twice",
        ),
        (
            vec![
                "twin", "--effect", "noise=1", "--effect", "noise=2", "--out", "t.csv",
            ],
            "--effect noise is given twice",
        ),
        (
            vec!["simulate", "--input", "stair", "--input-col", "p"],
            "--input-col read(s) a CSV --input, and --input stair is generated",
        ),
        // Counts whose plan or layout would be built before the run (a
        // hang, an aborted allocation).
        (
            vec![
                "fit",
                &csv,
                "--model",
                "generalized",
                "--refine-rounds",
                "1000000",
            ],
            "--refine-rounds 1000000: at most 100",
        ),
        (
            vec!["diagnose", &csv, "--blocks", "4294967296"],
            "it needs at least",
        ),
        (
            vec![
                "diagnose",
                &csv,
                "--self-test=catalogue",
                "--cases",
                "no-such-case",
            ],
            "--cases no-such-case: no case's name contains it",
        ),
    ];
    for (args, needle) in cases {
        let out = mckibben(&args, dir.path());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
    let written: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(written, ["synthetic.csv"], "a refused run wrote files");
}

#[test]
fn a_warm_start_from_another_family_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let fit = short_fit(&csv);
    let saved = mckibben(&[&fit[..], &["--out", "classic"]].concat(), dir.path());
    assert!(
        saved.status.success(),
        "{}",
        String::from_utf8_lossy(&saved.stderr)
    );
    let arx = mckibben(&["identify", &csv, "--out", "arx.json"], dir.path());
    assert!(
        arx.status.success(),
        "{}",
        String::from_utf8_lossy(&arx.stderr)
    );
    let cases: [(&[&str], &str); 3] = [
        (
            &["--from", "classic/model.json", "--model", "generalized"],
            "--from: the model is classic and a warm start keeps its family: --model generalized",
        ),
        (
            &["--from", "arx.json"],
            "--from: the model is linear (`identify`'s)",
        ),
        (
            &["--from", "arx.json", "--model", "classic"],
            "--from: the model is linear (`identify`'s)",
        ),
    ];
    for (extra, needle) in cases {
        let out = mckibben(&[&fit[..], extra].concat(), dir.path());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{extra:?}: {err}");
        assert!(err.contains(needle), "{extra:?}: {err}");
    }
}

/// A fit that finds no model writes nothing, so that an earlier fit's
/// files in `--out` still describe one fit; an `--out` that cannot be a
/// folder fails before any fit or study runs.
#[test]
fn a_failed_fit_leaves_out_as_it_was_and_a_bad_out_fails_first() {
    let dir = tempfile::tempdir().unwrap();
    let csv = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv");
    let fit = ["fit", csv, "--pop", "20", "--gens", "5", "--backend", "cpu"];
    let first = mckibben(&[&fit[..], &["--out", "o"]].concat(), dir.path());
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let files = |d: &str| {
        let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir.path().join(d))
            .unwrap()
            .map(|e| e.unwrap())
            .filter(|e| e.path().is_file())
            .map(|e| {
                (
                    e.file_name().to_string_lossy().into(),
                    std::fs::read(e.path()).unwrap(),
                )
            })
            .collect();
        v.sort();
        v
    };
    let before = files("o");
    // A pole of 1.5 diverges on every candidate over the stair's 2000
    // estimation samples.
    let failed = mckibben(
        &[&fit[..], &["--out", "o", "--fix", "a=1.5", "--json"]].concat(),
        dir.path(),
    );
    let err = String::from_utf8_lossy(&failed.stderr);
    assert_eq!(failed.status.code(), Some(1), "{err}");
    assert!(
        err.contains("every candidate diverged: nothing was written to o")
            && err.contains("--fix and --bound"),
        "{err}"
    );
    // The report still says what ran, with no parameters and so no errors.
    let report: serde_json::Value = serde_json::from_slice(&failed.stdout).unwrap();
    assert_eq!(report["params"], serde_json::json!({}), "{report}");
    assert_eq!(report["std_errors"], serde_json::json!({}), "{report}");
    assert_eq!(report["sse"], serde_json::Value::Null, "{report}");
    assert!(before == files("o"), "--out changed");

    // A folder where a file goes fails before the fit, and leaves every
    // file of the last run (the model, its report, its history).
    let svg = dir.path().join("o/trace.svg");
    std::fs::remove_file(&svg).unwrap();
    std::fs::create_dir(&svg).unwrap();
    let before = files("o");
    let other_seed = mckibben(
        &[&fit[..], &["--out", "o", "--seed", "7"]].concat(),
        dir.path(),
    );
    let err = String::from_utf8_lossy(&other_seed.stderr);
    assert!(!other_seed.status.success());
    assert!(err.contains("trace.svg is a folder"), "{err}");
    assert!(before == files("o"), "--out changed in part");
    std::fs::remove_dir(&svg).unwrap();

    // A write that fails after the fit (a link to a device where the
    // model goes): the report is still printed, and the set of files is
    // written whole or not at all.
    #[cfg(unix)]
    {
        std::fs::create_dir_all(dir.path().join("blocked")).unwrap();
        std::os::unix::fs::symlink("/dev/null", dir.path().join("blocked/model.json")).unwrap();
        let out = mckibben(&[&fit[..], &["--out", "blocked"]].concat(), dir.path());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success());
        assert!(err.contains("model.json"), "{err}");
        let report = String::from_utf8_lossy(&out.stdout);
        assert!(report.contains("validation fit"), "{report}");
        assert!(!dir.path().join("blocked/result.json").exists());
    }

    std::fs::write(dir.path().join("afile"), "").unwrap();
    let out = mckibben(&[&fit[..], &["--out", "afile"]].concat(), dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("afile is a file, not a folder"), "{err}");
    assert!(!err.contains("fitting"), "the fit ran first: {err}");
    // A cross-load record of another sample time: refused before the
    // study, as a bad --out is.
    let stair = std::fs::read_to_string(csv).unwrap();
    let every_other: Vec<&str> = stair
        .lines()
        .filter(|l| !l.starts_with('#'))
        .enumerate()
        .filter(|(i, _)| *i == 0 || i % 2 == 1)
        .map(|(_, l)| l)
        .collect();
    std::fs::write(dir.path().join("slow.csv"), every_other.join("\n") + "\n").unwrap();
    for (flag, value, needle) in [
        (
            "--out",
            "afile/x",
            "afile is a file, so afile/x cannot be a folder",
        ),
        (
            "--cross",
            "slow.csv",
            "--cross slow.csv: sampled every 0.02 s",
        ),
    ] {
        let out = mckibben(
            &["compare", csv, "--backend", "cpu", flag, value],
            dir.path(),
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success());
        assert!(err.contains(needle), "{err}");
        assert!(!err.contains("comparing on"), "the study ran first: {err}");
    }
}

#[test]
fn compare_writes_markdown_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let out = mckibben(
        &[
            "compare",
            &csv,
            "--thesis-sizes",
            "10",
            "--sizes",
            "0",
            "--gens",
            "3",
            "--seeds",
            "2",
            "--budget-pop",
            "8",
            "--budget-gens",
            "3",
            "--backend",
            "cpu",
            "--json",
        ],
        dir.path(),
    );
    let v = json(&out);
    assert_eq!(v["table21"].as_array().unwrap().len(), 8);
    // Six thesis-flow variants and four staged fits, per model.
    assert_eq!(v["budget"].as_array().unwrap().len(), 20);
    assert_eq!(v["flows"].as_array().unwrap().len(), 4);
    let md = std::fs::read_to_string(dir.path().join("out/compare/compare.md")).unwrap();
    assert!(md.contains("Table 21") && md.contains("Equal population budgets"));
}

/// On the real Cavatappi muscle at 300 g (data nobody here produced) the
/// estimation half's best classic model used to have β + γ < 0 and diverge
/// on the validation half; `fit` now only writes models that stay bounded
/// on the whole record's input. Skipped locally when the external data are
/// absent; fails then under `CI=true` (`common::require_external`).
#[test]
fn fit_of_the_real_muscle_stays_bounded_on_validation() {
    let Some(path) = common::require_external("cavatappi_muscle/sample1_300g.csv") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = fit_cavatappi(&path, &["--json", "--out", "out"], dir.path());
    let v = json(&out);
    let fit = v["val_fit_percent"].as_f64();
    assert!(
        fit.is_some_and(|f| f.is_finite() && f > 0.0),
        "validation fit {:?}",
        v["val_fit_percent"]
    );
    let p = &v["params"];
    let (beta, gamma) = (p["beta"].as_f64().unwrap(), p["gamma"].as_f64().unwrap());
    assert!(beta + gamma >= 0.0, "β + γ = {}", beta + gamma);
}

/// On the real Cavatappi muscle at 400 g the classic fit ends at the edge
/// of divergence: a step of a thousandth of its loop shape, pole or gain
/// makes the estimation free run diverge, so those have no standard error,
/// and the report says why rather than leave them blank. Its loop settles
/// within 0.134 mm a sample (`stable_step`), below the record's largest
/// step.
#[test]
fn a_fit_at_the_edge_of_divergence_says_why_its_parameters_have_no_error() {
    let Some(path) = common::require_external("cavatappi_muscle/sample1_400g.csv") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let v = json(&fit_cavatappi(
        &path,
        &["--json", "--out", "out"],
        dir.path(),
    ));
    let diverging: Vec<&str> = v["diverging_probes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    assert_eq!(diverging, ["loading", "beta_range", "a", "gain"], "{v}");
    let errors = &v["std_errors"];
    for name in ["beta", "gamma", "a", "b"] {
        assert!(errors[name].is_null(), "{name}: {errors}");
    }
    for name in ["alpha", "c", "x0"] {
        assert!(
            errors[name].as_f64().is_some_and(|e| e > 0.0),
            "{name}: {errors}"
        );
    }
    let (stable, largest) = (
        v["stable_step"].as_f64().unwrap(),
        v["largest_step"].as_f64().unwrap(),
    );
    assert!(
        (stable - 0.1339).abs() < 1e-4 && largest > stable,
        "{stable} {largest}"
    );
    let out = fit_cavatappi(&path, &["--out", "text"], dir.path());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains(
            "(a step of a thousandth along loading, beta_range, a, gain makes the free run diverge"
        ),
        "{text}"
    );
}

/// A fit that validates worse than the first-order ARX model on the same
/// halves says so, on stderr and in `--json`'s `notes`: the classic model on the Cavatappi 200 g record (38.3 %
/// against ARX's 57.5 %: the Bouc-Wen model misses what this muscle does,
/// docs/RESULTS.md). A fit of a record the classic model generated beats
/// ARX and gets none.
#[test]
fn a_fit_below_the_linear_yardstick_is_flagged() {
    let dir = tempfile::tempdir().unwrap();
    let generated = data(dir.path());
    let out = mckibben(
        &["fit", &generated, "--json", "--out", "generated"],
        dir.path(),
    );
    let v = json(&out);
    let (fit, linear) = (
        v["val_fit_percent"].as_f64().unwrap(),
        v["linear_val_fit_percent"].as_f64().unwrap(),
    );
    assert!(fit > linear, "{fit} against {linear}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("first-order ARX"), "{stderr}");

    let Some(path) = common::require_external("cavatappi_muscle/sample1_200g.csv") else {
        return;
    };
    let out = fit_cavatappi(&path, &["--out", "muscle"], dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("warning: the fit validates worse than the first-order ARX model"),
        "{stderr}"
    );
    // A script reads the same lines from the document, in the order
    // printed; the reader's notes on the file (its gaps) stay on stderr.
    let out = fit_cavatappi(&path, &["--json", "--out", "muscle"], dir.path());
    let file = format!("note: {}: ", path.display());
    let printed: Vec<String> = stderr
        .lines()
        .filter_map(|l| l.strip_prefix("mckibben: "))
        .filter(|l| !l.starts_with(&file))
        .map(String::from)
        .collect();
    let notes: Vec<String> = json(&out)["notes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| {
            format!(
                "{}: {}",
                n["level"].as_str().unwrap(),
                n["text"].as_str().unwrap()
            )
        })
        .collect();
    assert_eq!(notes, printed);
}

/// A record whose output stops moving at its second half (a sensor frozen,
/// an end stop) has no fit % there: the measure divides by the output's
/// spread, which the rounding of a mean made 10⁻¹² and the fit −10¹⁶ %
/// (`identify`) or "diverged" (`fit`). Each command says undefined, why,
/// and gives the RMSE.
#[test]
fn a_validation_half_whose_output_is_constant_has_no_fit_percent() {
    let dir = tempfile::tempdir().unwrap();
    let s = Synthetic::new(Family::Classic, 400, 0.05, 21);
    let mut output = s.trace.output.clone();
    output[200..].fill(7.5);
    let frozen = Trace::uniform("frozen.csv", s.trace.dt(), s.trace.input.clone(), output);
    let path = dir.path().join("frozen.csv");
    write_trace(&path, &frozen).unwrap();
    let csv = path.display().to_string();
    let warned = |out: &Output| {
        let stderr = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(
            stderr.contains("warning: the output is constant over the validation half"),
            "{stderr}"
        );
    };

    let out = mckibben(&["identify", &csv], dir.path());
    warned(&out);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("fit, validation half   undefined (the output is constant over it)"),
        "{text}"
    );
    let v = json(&mckibben(&["identify", &csv, "--json"], dir.path()));
    assert!(v["validation_fit_percent"].is_null(), "{v}");
    assert!(v["validation_rmse"].as_f64().unwrap() > 0.0, "{v}");

    let mut args = short_fit(&csv).to_vec();
    args.extend(["--out", "frozen"]);
    let out = mckibben(&args, dir.path());
    warned(&out);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("validation fit       undefined   (RMSE "),
        "{text}"
    );
    assert!(!text.contains("diverged"), "{text}");
    args.push("--json");
    let v = json(&mckibben(&args, dir.path()));
    assert!(v["val_fit_percent"].is_null(), "{v}");
    assert!(v["linear_val_fit_percent"].is_null(), "{v}");
    assert!(v["val_rmse"].as_f64().unwrap() > 0.0, "{v}");

    let model = dir.path().join("frozen/model.json");
    let out = mckibben(
        &[
            "simulate",
            "--from",
            model.to_str().unwrap(),
            "--input",
            &csv,
        ],
        dir.path(),
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("on its second half undefined, the output being constant over it"),
        "{text}"
    );
}

/// `bench` draws from the thesis' box, in MPa and mm: on the same record in
/// Pa and m nearly every candidate diverged and stopped early, and the rate
/// read ten times that of the record in MPa and mm, without a word. It says
/// how many diverged, and warns where nearly all did.
#[test]
fn bench_says_how_many_candidates_diverged() {
    let dir = tempfile::tempdir().unwrap();
    let s = Synthetic::new(Family::Classic, 400, 0.05, 21);
    let t = &s.trace;
    let pascal: Vec<f64> = t.input.iter().map(|p| 1e6 * p).collect();
    let metre: Vec<f64> = t.output.iter().map(|x| 1e-3 * x).collect();
    let mut si = Trace::uniform("si.csv", t.dt(), pascal, metre);
    si.input_name = "pressure_Pa".into();
    si.output_name = "disp_m".into();
    let path = dir.path().join("si.csv");
    write_trace(&path, &si).unwrap();
    let bench = |file: &str, columns: &[&str]| {
        let mut args = vec![
            "bench",
            file,
            "--pop",
            "200",
            "--repeats",
            "1",
            "--backend",
            "cpu",
        ];
        args.extend_from_slice(columns);
        args.push("--json");
        let out = mckibben(&args, dir.path());
        let share = json(&out)["rows"][0]["diverged_share"].as_f64().unwrap();
        (share, String::from_utf8_lossy(&out.stderr).to_string())
    };
    let (share, stderr) = bench(
        path.to_str().unwrap(),
        &["--input", "pressure_Pa", "--output", "disp_m"],
    );
    assert!(share > 0.9, "{share}");
    assert!(
        stderr.contains("of the drawn candidates diverged"),
        "{stderr}"
    );
    let (share, stderr) = bench(&data(dir.path()), &[]);
    assert!(share > 0.0 && share < 0.9, "{share}");
    assert!(!stderr.contains("diverged"), "{stderr}");
}

/// A record whose input repeats (the Bouc-Wen benchmark's multisine, five
/// periods) is validated on the excitation it was fitted on: `fit` says so.
#[test]
fn a_repeated_excitation_is_noted_as_validating_on_itself() {
    let dir = tempfile::tempdir().unwrap();
    let mut rows = String::from("t,pressure,displacement\n");
    let mut y = 0.0;
    for k in 0..400 {
        let u = 0.3 + 0.2 * ((k % 50) as f64 * 0.7).sin() * ((k % 50) as f64 * 0.13).cos();
        y = 0.9 * y + 2.0 * u;
        rows += &format!("{},{u},{y}\n", k as f64 * 0.01);
    }
    std::fs::write(dir.path().join("periodic.csv"), rows).unwrap();
    let out = mckibben(&short_fit("periodic.csv"), dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("periodic.csv: its input repeats every 50 samples (0.5 s)"),
        "{err}"
    );
    let out = mckibben(&short_fit(&data(dir.path())), dir.path());
    assert!(!String::from_utf8_lossy(&out.stderr).contains("repeats every"));
}

/// A fitted loop with no branch that bends (β = γ = 0) has no stable-step
/// limit, and the report says so rather than leave the line out (the
/// Cavatappi 500 g fit ended at a loading of 0 and its report had no such
/// line).
#[test]
fn a_loop_without_saturation_says_its_steps_are_not_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let line = "  stable steps         not bounded";
    let report = |extra: &[&str]| {
        let out = mckibben(&[&short_fit(&csv)[..], extra].concat(), dir.path());
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let flat = report(&["--fix", "beta=0", "--fix", "gamma=0"]);
    assert!(flat.contains(line), "{flat}");
    let saturating = report(&[]);
    assert!(
        saturating.contains("  stable steps         up to") && !saturating.contains(line),
        "{saturating}"
    );
}

/// A `RAYON_NUM_THREADS` rayon ignores is said to be ignored (a run meant
/// for one thread ran on every core without a word).
#[test]
fn a_thread_count_that_is_not_a_number_is_said_to_be_ignored() {
    let run = |threads: &str| {
        let out = Command::new(env!("CARGO_BIN_EXE_mckibben"))
            .args(["identify", "--json"])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .env("RAYON_NUM_THREADS", threads)
            .output()
            .unwrap();
        assert!(out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let err = run("one");
    assert!(
        err.contains("RAYON_NUM_THREADS=one is not a whole number, so it is ignored"),
        "{err}"
    );
    assert!(!run("1").contains("RAYON_NUM_THREADS"));
}

/// bench's text says how far its timed calls spread around the median, and
/// of a population under a hundred compares all of it (`top-100 identical
/// (30 of 100 shared)` read as a miss).
#[test]
fn bench_shows_its_calls_spread_and_a_small_population_whole() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "bench",
        "--synthetic",
        "300",
        "--backend",
        "cpu",
        "--pop",
        "30",
        "--repeats",
        "3",
    ];
    let out = mckibben(&args, dir.path());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("median s (range)"), "{text}");
    assert!(text.contains("(30 of 30 shared)"), "{text}");
    // The Markdown for docs/PERFORMANCE.md shows the same range.
    let markdown = mckibben(&[&args[..], &["--markdown"]].concat(), dir.path());
    let table = String::from_utf8_lossy(&markdown.stdout);
    let cpu_row = table.lines().find(|l| l.starts_with("| classic | 30 |"));
    assert!(
        table.contains("| median s (range) |") && cpu_row.is_some_and(|r| r.contains("–")),
        "{table}"
    );
    let row = json(&mckibben(&[&args[..], &["--json"]].concat(), dir.path()))["rows"][0].clone();
    let (lo, median, hi) = (
        row["min_s"].as_f64().unwrap(),
        row["median_s"].as_f64().unwrap(),
        row["max_s"].as_f64().unwrap(),
    );
    assert!(0.0 < lo && lo <= median && median <= hi, "{row}");
}

/// A population whose candidates need more memory than is free is refused
/// before a row is allocated: under `ulimit -v` the allocation that failed
/// midway aborted the command (exit 134), and in Python the interpreter.
#[cfg(target_os = "linux")]
#[test]
fn a_population_past_the_free_memory_is_refused_before_it_runs() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let fit = format!(
        "ulimit -v 1500000; exec {} fit {csv} --pop 10000000 --gens 1 --backend cpu",
        env!("CARGO_BIN_EXE_mckibben")
    );
    let out = Command::new("bash")
        .args(["-c", &fit])
        .current_dir(dir.path())
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("--pop 10000000: its candidates need at least 3.6 GB")
            && err.contains("are free here"),
        "{err}"
    );
}

/// `static --pressures` is in MPa: 300 (kPa meant) gave 642 kN without a
/// word.
#[test]
fn a_static_pressure_past_any_muscle_s_gets_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let note = |pressures: &str| {
        let out = mckibben(
            &["static", "--pressures", pressures, "--points", "2"],
            dir.path(),
        );
        assert!(out.status.success());
        String::from_utf8_lossy(&out.stderr).contains("the pressures are in MPa")
    };
    assert!(note("0.3,300"));
    assert!(!note("0.3,0.5"));
}

/// A fit with effects has two starts: the search from scratch and the chain
/// built one effect at a time. On the Cavatappi 300 g record with the
/// diagnosis' verdict the search from scratch ends at estimation SSE 6.47
/// and validates at 64 %; the chain ends lower, and is kept.
#[test]
fn a_fit_with_effects_keeps_the_chain_built_one_effect_at_a_time_where_it_fits_better() {
    let Some(path) = common::require_external("cavatappi_muscle/sample1_300g.csv") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = fit_cavatappi(
        &path,
        &[
            "--effects",
            "creep:two-pole,inertia:ringing",
            "--json",
            "--out",
            "out",
        ],
        dir.path(),
    );
    let v = json(&out);
    let built = &v["built"];
    let (scratch, chain) = (
        built["scratch_sse"].as_f64().unwrap(),
        built["chain_sse"].as_f64().unwrap(),
    );
    assert!(chain < scratch, "{built}");
    assert_eq!(built["kept_chain"], serde_json::json!(true));
    assert!(v["sse"].as_f64().unwrap() <= chain);
    let fit = v["val_fit_percent"].as_f64().unwrap();
    assert!(fit > 80.0, "validation fit {fit} %");
}

#[test]
fn bounds_a_user_sets_hold_and_bad_ones_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let fit = |extra: &[&str]| {
        let mut args = vec![
            "fit",
            &csv,
            "--pop",
            "40",
            "--gens",
            "5",
            "--backend",
            "cpu",
            "--out",
            "fitdir",
            "--json",
        ];
        args.extend_from_slice(extra);
        mckibben(&args, dir.path())
    };
    // A fixed value is the value written; a bounded one stays inside; both
    // are named as the user's bounds, and the box is reported in the
    // coordinates searched.
    let out = json(&fit(&["--fix", "alpha=0.45", "--bound", "b=0.5:0.6"]));
    assert_eq!(out["params"]["alpha"], 0.45);
    let b = out["params"]["b"].as_f64().unwrap();
    assert!((0.5..=0.6).contains(&b), "{b}");
    let names = out["search_box"]["names"].as_array().unwrap();
    assert!(
        names.iter().any(|n| n == "b"),
        "b bounded: searched natively"
    );
    assert!(names.iter().any(|n| n == "loading"), "{names:?}");
    // The data want b near 4.6 (docs/JSON.md's fit): it ends on the user's
    // upper bound, and the report names that bound as the user's.
    let edges = out["on_edge"].as_array().unwrap();
    let b_edge = edges
        .iter()
        .find(|e| e["param"] == "b")
        .unwrap_or_else(|| panic!("b is not reported on its edge: {edges:?}"));
    assert_eq!(b_edge["origin"], "user", "{b_edge}");
    assert!(b > 0.59, "{b} {b_edge}");
    // The default box is in the data's own scale.
    let out = json(&fit(&[]));
    let names = out["search_box"]["names"].as_array().unwrap();
    assert!(names.iter().any(|n| n == "gain"), "{names:?}");
    assert_eq!(out["params"]["A"], 1.0, "the gauge");
    let free = json(&fit(&["--loop", "free"]));
    let names = free["search_box"]["names"].as_array().unwrap();
    assert!(names.iter().any(|n| n == "gamma_range"), "{names:?}");

    let cases: [(&[&str], &str); 5] = [
        (
            &["--bound", "zeta=0:1"],
            "--bound zeta=0:1: no parameter `zeta` in the classic model",
        ),
        (&["--bound", "gain=2:1"], "the box is empty"),
        (&["--bound", "gain=0:x"], "`x` is not a number"),
        (
            &["--fix", "alpha=0.1:0.2"],
            "--fix alpha: expected NAME=VALUE",
        ),
        (&["--bound", "alpha"], "expected NAME=LO:HI or NAME=VALUE"),
    ];
    for (extra, needle) in cases {
        let out = fit(extra);
        assert!(!out.status.success(), "{extra:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{extra:?}: {err}");
    }
    // alpha is a share: a box past [0, 1] runs, and the command says what
    // it leaves; one inside says nothing of it.
    for (fix, noted) in [("alpha=2", true), ("alpha=0.45", false)] {
        let args = short_fit(&csv);
        let out = mckibben(
            &[&args[..], &["--out", "alphadir", "--fix", fix]].concat(),
            dir.path(),
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{fix}: {err}");
        assert_eq!(err.contains("reaches past [0, 1]"), noted, "{fix}: {err}");
    }
}

/// The report says what a single try cannot tell, and counts the tries
/// that agree where there are several; the thesis' single search runs no
/// tries and says nothing of them.
#[test]
fn the_report_says_whether_its_tries_agree_or_that_one_cannot_tell() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let text = |extra: &[&str]| {
        let mut args = vec!["fit", &csv, "--gens", "3", "--backend", "cpu"];
        args.extend_from_slice(extra);
        let out = mckibben(&args, dir.path());
        assert!(out.status.success(), "{extra:?}");
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let one = text(&["--pop", "40"]);
    assert!(
        one.contains("tries: 1, which cannot tell whether another try"),
        "{one}"
    );
    let two = text(&["--pop", "2000"]);
    assert!(two.contains("N = 2000 (2 tries of 1000)"), "{two}");
    assert!(two.contains("of 2 tries ended within"), "{two}");
    assert!(!two.contains("tries: 1, which"), "{two}");
    let mixed = text(&["--pop", "3000"]);
    assert!(
        mixed.contains("N = 3000 (2 tries of 1000 and 10 of 100)"),
        "{mixed}"
    );
    assert!(mixed.contains("of 12 tries ended within"), "{mixed}");
    // On the shipped stair three generations leave the tries in several
    // basins: the lowest other one is set beside the fit, its SSE the
    // first other basin's, its run apart from the fit's over the
    // validation half.
    let stair = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv");
    let args = [
        "fit",
        stair,
        "--gens",
        "3",
        "--backend",
        "cpu",
        "--pop",
        "3000",
    ];
    let doc = json(&mckibben(&[&args[..], &["--json"]].concat(), dir.path()));
    let out = mckibben(&args, dir.path());
    let mixed = String::from_utf8_lossy(&out.stdout).into_owned();
    let agreement = &doc["agreement"];
    assert!(agreement["agreeing"].as_u64().unwrap() < 12, "{agreement}");
    let runner_up = &agreement["runner_up"];
    assert_eq!(
        runner_up["sse"], agreement["other_basins"][0],
        "{agreement}"
    );
    let apart = runner_up["apart_rmse"].as_f64().unwrap();
    assert!(apart > 0.0, "{runner_up}");
    assert!(
        mixed.contains("runner-up            estimation SSE ")
            && mixed.contains("from this one over the validation half"),
        "{mixed}"
    );
    // Two of twelve agree: the note that more tries may find a lower SSE
    // says how far the basins found so far differ in what they predict.
    let share = 100.0 * apart / doc["val_rmse"].as_f64().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&format!(
            "the runner-up basin's model strays from this one over the validation half by {share:.0} % \
             of this model's own error there"
        )),
        "{err}"
    );
    let thesis = text(&["--thesis-flow", "--pop", "30"]);
    assert!(!thesis.contains("tries:"), "{thesis}");
}

/// A generalized fit whose last allowed refining round still gained says
/// so, with the flag that lets it go on; the classic family, which is not
/// refined, refuses the flag.
#[test]
fn a_refinement_cut_short_by_its_cap_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let stair = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv");
    let fit = |extra: &[&str]| {
        let mut args = vec!["fit", stair, "--model", "generalized", "--gens", "20"];
        args.extend_from_slice(extra);
        mckibben(&args, dir.path())
    };
    // One round: on this record the first round takes several per cent off.
    let out = fit(&["--refine-rounds", "1", "--json"]);
    let report = json(&out);
    let refining = &report["refining"];
    assert_eq!(refining["rounds"], 1, "{refining}");
    assert_eq!(refining["cut_tries"], 1, "{refining}");
    let gain = refining["largest_last_gain"].as_f64().unwrap();
    assert!(gain > 1e-3, "{refining}");
    let out = fit(&["--refine-rounds", "1"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("refining ran out of rounds: after 1 round the fit still lowered")
            && err.contains("--refine-rounds 4 lets it go on"),
        "{err}"
    );
    // No rounds: nothing to cut short.
    let none = json(&fit(&["--refine-rounds", "0", "--json"]));
    assert_eq!(none["refining"]["cut_tries"], 0, "{}", none["refining"]);
    assert!(none["refining"]["largest_last_gain"].is_null());
    let classic = mckibben(&["fit", stair, "--refine-rounds", "8"], dir.path());
    let err = String::from_utf8_lossy(&classic.stderr);
    assert!(!classic.status.success());
    assert!(
        err.contains("--refine-rounds: only a generalized fit is refined"),
        "{err}"
    );
    let report = json(&mckibben(
        &["fit", stair, "--gens", "5", "--json"],
        dir.path(),
    ));
    assert!(report["refining"].is_null(), "{}", report["refining"]);
}

/// The parameters whose standard error reaches their own size are listed
/// in the JSON, where an infinite error would read as a held one's `null`,
/// and named in the text's note. On the 1 rad/s sine the offset `x0` is
/// such a parameter.
#[test]
fn the_parameters_a_record_does_not_determine_are_listed() {
    let dir = tempfile::tempdir().unwrap();
    let sine = concat!(env!("CARGO_MANIFEST_DIR"), "/data/sine_1rads_4.5kg.csv");
    let report = json(&mckibben(&["fit", sine, "--json"], dir.path()));
    let errors = report["std_errors"].as_object().unwrap();
    let loose: Vec<&str> = report["params"]
        .as_object()
        .unwrap()
        .iter()
        .filter(|(name, v)| {
            errors[name.as_str()]
                .as_f64()
                .is_some_and(|e| e >= v.as_f64().unwrap().abs())
        })
        .map(|(name, _)| name.as_str())
        .collect();
    assert!(!loose.is_empty(), "{errors:?}");
    assert_eq!(report["undetermined"], serde_json::json!(loose));
    let out = mckibben(&["fit", sine], dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    let note = err
        .lines()
        .find(|l| l.contains("the estimation half does not determine"))
        .unwrap_or_else(|| panic!("{err}"));
    for name in loose {
        assert!(note.contains(&format!("{name} (")), "{note}");
    }
}

/// A record in metres: the report writes every parameter, the SSE and the
/// RMSE with their digits (at six decimals `b` read `0.000005`, at four
/// the RMSE `0.0013`), each within its last digit of `result.json`'s.
#[test]
fn the_report_keeps_its_figures_digits_in_any_unit() {
    let dir = tempfile::tempdir().unwrap();
    let s = Synthetic::new(Family::Classic, 400, 0.05, 21);
    let metres = mckibben::data::Trace {
        output_name: "displacement_m".into(),
        output: s.trace.output.iter().map(|x| x * 1e-3).collect(),
        ..s.trace.clone()
    };
    let csv = dir.path().join("metres.csv");
    write_trace(&csv, &metres).unwrap();
    let csv = csv.display().to_string();
    let out = mckibben(
        &[
            "fit",
            &csv,
            "--output",
            "displacement_m",
            "--pop",
            "40",
            "--gens",
            "3",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let result: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("out/fit/result.json")).unwrap(),
    )
    .unwrap();
    let shown = |label: &str| -> f64 {
        let line = text
            .lines()
            .find(|l| l.trim_start().starts_with(label))
            .unwrap_or_else(|| panic!("no `{label}` line in {text}"));
        let value = match line.split_once("(RMSE ") {
            // Its unit follows where the output column states one.
            Some((_, rmse)) => rmse.trim_end_matches(')').split(' ').next().unwrap(),
            None => line.trim_start()[label.len()..]
                .split_whitespace()
                .next()
                .unwrap(),
        };
        value.parse().unwrap_or_else(|_| panic!("{line}"))
    };
    let mut figures: Vec<(String, f64)> = result["params"]
        .as_object()
        .unwrap()
        .iter()
        .map(|(name, v)| (format!("{name} "), v.as_f64().unwrap()))
        .collect();
    figures.push(("SSE (estimation)".into(), result["sse"].as_f64().unwrap()));
    figures.push((
        "validation fit  ".into(),
        result["val_rmse"].as_f64().unwrap(),
    ));
    assert!(figures.iter().any(|(_, v)| v.abs() < 1e-4), "{figures:?}");
    for (label, v) in figures {
        let s = shown(&label);
        assert!(
            (s - v).abs() <= 1e-3 * v.abs(),
            "`{label}` reads {s} for {v:e}: {text}"
        );
    }
}

/// `fit a.csv b.csv` fits one model to both records: the report scores
/// each record's second half on its own, as the written model scores it
/// there (`simulate --from`), pools them in its headline figure, and
/// draws each record's loop and trace.
#[test]
fn a_fit_of_several_records_scores_each_as_its_model_file_does() {
    let dir = tempfile::tempdir().unwrap();
    let records: Vec<String> = [(400, 21), (600, 22)]
        .iter()
        .map(|&(len, seed)| {
            let s = Synthetic::new(Family::Classic, len, 0.05, seed);
            let path = dir.path().join(format!("record{seed}.csv"));
            write_trace(&path, &s.trace).unwrap();
            path.display().to_string()
        })
        .collect();
    let (a, b) = (records[0].as_str(), records[1].as_str());
    let fit = [
        "fit",
        a,
        b,
        "--pop",
        "60",
        "--gens",
        "20",
        "--backend",
        "cpu",
    ];
    let report = json(&mckibben(
        &[&fit[..], &["--json", "--out", "out"]].concat(),
        dir.path(),
    ));
    assert_eq!(report["data"], format!("{a}, {b}"));
    let scored = report["records"].as_array().expect("records");
    assert_eq!(scored.len(), 2);
    for (record, (path, len)) in scored.iter().zip([(a, 400), (b, 600)]) {
        assert_eq!(record["data"], path);
        assert_eq!(record["samples"], len);
        let run = json(&mckibben(
            &[
                "simulate",
                "--from",
                "out/model.json",
                "--input",
                path,
                "--json",
            ],
            dir.path(),
        ));
        let (fit, simulated) = (
            record["val_fit_percent"].as_f64().unwrap(),
            run["val_fit_percent"].as_f64().unwrap(),
        );
        assert!(
            (fit - simulated).abs() < 1e-3,
            "{path}: {fit} against {simulated}"
        );
    }
    for figure in ["loop.svg", "trace.svg", "loop-2.svg", "trace-2.svg"] {
        assert!(dir.path().join("out").join(figure).exists(), "{figure}");
    }
    // A later fit of one record into the same folder leaves no figure of
    // a second record that would pass for its own.
    let one = mckibben(&[&short_fit(a)[..], &["--out", "out"]].concat(), dir.path());
    assert!(one.status.success());
    assert!(dir.path().join("out/loop.svg").exists());
    assert!(
        !dir.path().join("out/loop-2.svg").exists() && !dir.path().join("out/trace-2.svg").exists()
    );
    let text = mckibben(&[&fit[..], &["--out", "text"]].concat(), dir.path());
    let stdout = String::from_utf8_lossy(&text.stdout);
    assert!(
        stdout.contains("the 2 records' second halves pooled") && stdout.contains(b),
        "{stdout}"
    );
    assert!(
        !String::from_utf8_lossy(&text.stderr).contains("does not hold on this record"),
        "both records are one muscle's"
    );
    // A record logged with the opposite sign is another muscle to the one
    // model: it is named, whatever the pooled figure says.
    let s = Synthetic::new(Family::Classic, 600, 0.05, 22);
    let flipped = Trace {
        output: s.trace.output.iter().map(|y| -y).collect(),
        ..s.trace
    };
    write_trace(&dir.path().join("flipped.csv"), &flipped).unwrap();
    let fit = [
        "fit",
        a,
        "flipped.csv",
        "--pop",
        "60",
        "--gens",
        "20",
        "--backend",
        "cpu",
    ];
    let both = mckibben(&[&fit[..], &["--out", "flipped"]].concat(), dir.path());
    let stderr = String::from_utf8_lossy(&both.stderr);
    assert!(
        stderr.contains("its own first-order ARX model")
            && stderr.contains("does not hold on this record"),
        "{stderr}"
    );
}

/// Records sampled at different steps cannot share one model's poles:
/// the fit refuses them and names both.
#[test]
fn a_fit_of_records_at_different_steps_names_them() {
    let dir = tempfile::tempdir().unwrap();
    let s = Synthetic::new(Family::Classic, 400, 0.05, 21);
    let slow = Trace {
        t: s.trace.t.iter().map(|t| 2.0 * t).collect(),
        ..s.trace.clone()
    };
    write_trace(&dir.path().join("fast.csv"), &s.trace).unwrap();
    write_trace(&dir.path().join("slow.csv"), &slow).unwrap();
    let out = mckibben(
        &["fit", "fast.csv", "slow.csv", "--pop", "20", "--gens", "2"],
        dir.path(),
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("slow.csv is sampled every") && err.contains("fast.csv every"),
        "{err}"
    );
    assert!(!dir.path().join("out").exists(), "nothing written");
}

/// A file without a time column fits with `--dt` as the same file with
/// one: the same parameters, bit for bit, and the model file records how
/// it was read. Without `--dt` the error names the flag.
#[test]
fn a_file_without_a_time_column_fits_with_dt() {
    let dir = tempfile::tempdir().unwrap();
    let timed = data(dir.path());
    let text = std::fs::read_to_string(&timed).unwrap();
    let untimed: String = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split_once(',').unwrap().1.to_string() + "\n")
        .collect();
    assert!(untimed.starts_with("pressure,displacement"), "{untimed}");
    std::fs::write(dir.path().join("untimed.csv"), untimed).unwrap();
    let fit = |file: &str, extra: &[&str]| {
        let args = [&short_fit(file)[..], extra, &["--json", "--out", "out"]].concat();
        json(&mckibben(&args, dir.path()))
    };
    let with_column = fit(&timed, &[])["params"].clone();
    let with_dt = fit("untimed.csv", &["--dt", "0.01"]);
    assert_eq!(with_dt["params"], with_column);
    let model: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("out/model.json")).unwrap())
            .unwrap();
    assert_eq!(model["provenance"]["read"]["dt"], 0.01);
    let without = mckibben(&short_fit("untimed.csv"), dir.path());
    let err = String::from_utf8_lossy(&without.stderr);
    assert!(
        !without.status.success() && err.contains("--dt SECONDS"),
        "{err}"
    );
}

/// With `--effects`, the chain built one effect at a time is the fit's
/// second start, a warm start of a fifth of the population and no global
/// stage; where it is kept, the report still gives the population and
/// algorithm the fit was asked for, as the line announcing it did.
#[test]
fn a_kept_chain_start_reports_the_population_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let twin = mckibben(
        &[
            "twin",
            "--experiment",
            "stair",
            "--seed",
            "3",
            "--out",
            "stair.csv",
        ],
        dir.path(),
    );
    assert!(twin.status.success());
    let kept = (1..=4).find_map(|seed| {
        let seed = seed.to_string();
        let report = json(&mckibben(
            &[
                "fit",
                "stair.csv",
                "--effects",
                "creep",
                "--algo",
                "pso",
                "--pop",
                "60",
                "--gens",
                "10",
                "--seed",
                &seed,
                "--backend",
                "cpu",
                "--json",
                "--out",
                "out",
            ],
            dir.path(),
        ));
        assert_eq!(
            (report["population"].as_u64(), report["algo"].as_str()),
            (Some(60), Some("pso"))
        );
        (report["built"]["kept_chain"] == true).then_some(seed)
    });
    assert!(
        kept.is_some(),
        "no seed of 1–4 kept the chain's start: the case tests nothing"
    );
}

/// `fit --out` writes the files `files_written` names, and refuses a folder
/// where one of them would replace a file it reads: a recording named
/// `history.csv` was replaced by the fit's history.
#[test]
fn fit_writes_its_named_files_and_none_over_its_data() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let second = dir.path().join("second.csv");
    let s = Synthetic::new(Family::Classic, 400, 0.05, 22);
    write_trace(&second, &s.trace).unwrap();
    let mut args = short_fit(&csv).to_vec();
    args.extend([second.to_str().unwrap(), "--out", "two"]);
    let out = mckibben(&args, dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut written: Vec<String> = std::fs::read_dir(dir.path().join("two"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    written.sort();
    let mut named = mckibben::fit::report::files_written(2);
    named.sort();
    assert_eq!(written, named);

    let recording = dir.path().join("rec");
    std::fs::create_dir(&recording).unwrap();
    let history = recording.join("history.csv");
    std::fs::copy(&csv, &history).unwrap();
    let before = std::fs::read(&history).unwrap();
    let out = mckibben(
        &[&short_fit("rec/history.csv")[..], &["--out", "rec"]].concat(),
        dir.path(),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("--out rec: the command writes history.csv there, over rec/history.csv that it reads as DATA"),
        "{err}"
    );
    assert_eq!(std::fs::read(&history).unwrap(), before);
    // `diagnose --out` of the folder its --from model lies in, likewise.
    let out = mckibben(
        &["diagnose", &csv, "--from", "two/model.json", "--out", "two"],
        dir.path(),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--out two: the command writes model.json there, over two/model.json that it reads as --from"),
        "{err}"
    );
    // A checkpoint inside the folder under a name the fit writes: the
    // model replaced it, and a resume then found no checkpoint.
    let out = mckibben(
        &[
            &short_fit(&csv)[..],
            &["--out", "two", "--checkpoint", "two/model.json"],
        ]
        .concat(),
        dir.path(),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--out two: the command writes model.json there, over two/model.json that it reads as --checkpoint"),
        "{err}"
    );
}

/// The other commands that write into a folder refuse one where a file
/// they write would replace a record they read, and leave it as it was:
/// `compare --out` (its DATA and `--cross`), `diagnose --report` and
/// `control --csv`/`--plot` (its `--design-data`) replaced them, exit 0.
/// A folder where a file goes is refused before the run too.
#[test]
fn no_output_folder_replaces_a_record_the_command_reads() {
    let dir = tempfile::tempdir().unwrap();
    let stair = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv");
    let seven = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_7kg.csv");
    let placed = |name: &str, record: &str| {
        let path = dir.path().join(name);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::copy(record, &path).unwrap();
        (name.to_string(), std::fs::read(&path).unwrap())
    };
    let refused = |args: &[&str], (name, before): (String, Vec<u8>), wanted: &str| {
        let out = mckibben(args, dir.path());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}: {err}");
        assert!(err.contains(wanted), "{args:?}: {err}");
        assert_eq!(
            std::fs::read(dir.path().join(&name)).unwrap(),
            before,
            "{name}"
        );
    };
    let compare = [
        "compare",
        "--thesis-sizes",
        "4",
        "--sizes",
        "0",
        "--gens",
        "1",
    ];
    let quick = [&compare[..], &["--seeds", "0", "--backend", "cpu"]].concat();
    refused(
        &[&quick[..], &["c/compare.md", "--out", "c"]].concat(),
        placed("c/compare.md", stair),
        "--out c: the command writes compare.md there, over c/compare.md that it reads as DATA",
    );
    refused(
        &[
            &quick[..],
            &[stair, "--cross", "x/compare.json", "--out", "x"],
        ]
        .concat(),
        placed("x/compare.json", seven),
        "over x/compare.json that it reads as --cross",
    );
    refused(
        &[
            "diagnose",
            "d/diagnose_fit.svg",
            "--max-effects",
            "0",
            "--report",
            "d",
        ],
        placed("d/diagnose_fit.svg", stair),
        "--report d: the command writes diagnose_fit.svg there, over d/diagnose_fit.svg that \
         it reads as DATA",
    );
    let twin = [
        "twin",
        "--experiment",
        "multisine",
        "--out",
        "k/control_mpc_4.5kg_1rad.csv",
    ];
    assert!(mckibben(&twin, dir.path()).status.success());
    let record = std::fs::read(dir.path().join("k/control_mpc_4.5kg_1rad.csv")).unwrap();
    let control = [
        "control",
        "--controller",
        "mpc",
        "--freq",
        "1",
        "--load",
        "4.5",
        "--warmup",
        "1",
        "--duration",
        "2",
        "--steady-from",
        "1",
        "--design-data",
        "k/control_mpc_4.5kg_1rad.csv",
    ];
    for flag in ["--csv", "--plot"] {
        let named = match flag {
            "--csv" => "k/control_mpc_4.5kg_1rad.csv",
            _ => "k/control_mpc_4.5kg_1rad.svg",
        };
        if flag == "--plot" {
            std::fs::copy(
                dir.path().join("k/control_mpc_4.5kg_1rad.csv"),
                dir.path().join(named),
            )
            .unwrap();
        }
        let mut args = control.to_vec();
        let last = args.len() - 1;
        args[last] = named;
        args.extend([flag, "k"]);
        let before = std::fs::read(dir.path().join(named)).unwrap();
        refused(
            &args,
            (named.to_string(), before),
            &format!("{flag} k: the command writes"),
        );
    }
    assert_eq!(
        std::fs::read(dir.path().join("k/control_mpc_4.5kg_1rad.csv")).unwrap(),
        record
    );
    // A folder where a file goes is found before the fit, not after it.
    std::fs::create_dir_all(dir.path().join("f/trace.svg")).unwrap();
    let out = mckibben(
        &[&short_fit(stair)[..], &["--out", "f"]].concat(),
        dir.path(),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(
            "--out f: the command writes the file trace.svg there, and f/trace.svg is a folder"
        ),
        "{err}"
    );
    assert!(out.stdout.is_empty(), "the fit ran first");
}

/// A named pipe is read once: the provenance hashed it by opening it again,
/// which waited for a writer that never came (and a shell's `<(…)` gave the
/// hash of nothing). Its `sha256` is null, as a generated trace's.
#[cfg(unix)]
#[test]
fn a_fit_reads_a_named_pipe_once() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("stair.pipe");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    let text = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv")).unwrap();
    let writer = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::write(fifo, text).unwrap())
    };
    let out = mckibben(
        &[&short_fit("stair.pipe")[..], &["--out", "piped"]].concat(),
        dir.path(),
    );
    writer.join().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let source = first_source(&dir.path().join("piped/model.json"));
    assert_eq!(source["file"], "stair.pipe");
    assert!(source["sha256"].is_null(), "{source}");
}

/// The first data file a model file's provenance names.
fn first_source(model: &Path) -> serde_json::Value {
    let model: serde_json::Value = serde_json::from_slice(&std::fs::read(model).unwrap()).unwrap();
    model["provenance"]["data"][0].clone()
}

/// `-` reads standard input, as `cat run.csv | mckibben fit -`: the same fit
/// as of the file, its provenance naming `-` with no checksum.
#[test]
fn a_fit_reads_standard_input_as_its_file() {
    let dir = tempfile::tempdir().unwrap();
    let stair = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv");
    // The JSON a run with `file` on its standard input prints.
    let piped = |args: &[&str], file: &str| -> serde_json::Value {
        use std::io::Write as _;
        let mut child = command(dir.path())
            .args(args)
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let bytes = std::fs::read(file).unwrap();
        child.stdin.take().unwrap().write_all(&bytes).unwrap();
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let piped_fit = piped(
        &[&short_fit("-")[..], &["--out", "piped", "--json"]].concat(),
        stair,
    );
    let file = mckibben(
        &[&short_fit(stair)[..], &["--out", "file", "--json"]].concat(),
        dir.path(),
    );
    let file: serde_json::Value = serde_json::from_slice(&file.stdout).unwrap();
    assert_eq!(piped_fit["params"], file["params"]);
    let source = first_source(&dir.path().join("piped/model.json"));
    assert_eq!(source["file"], "-");
    assert!(source["sha256"].is_null(), "{source}");

    // `simulate --input -` too, as every DATA reads it; but standard input
    // is read once, so not for `--from` as well.
    let piped_run = piped(&["simulate", "--input", "-", "--json"], stair);
    let file = mckibben(&["simulate", "--input", stair, "--json"], dir.path());
    let file: serde_json::Value = serde_json::from_slice(&file.stdout).unwrap();
    assert_eq!(piped_run["val_fit_percent"], file["val_fit_percent"]);
    let twice = mckibben(&["simulate", "--from", "-", "--input", "-"], dir.path());
    let err = String::from_utf8_lossy(&twice.stderr);
    assert!(err.contains("would both read standard input"), "{err}");
}

/// `fit --effects` under a budget the chain's build spends: the build stops
/// at the budget, and the error says the time went there (it said no
/// candidate was scored, after seconds of the build's searches).
#[test]
fn a_budget_spent_building_the_chain_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let out = mckibben(
        &[
            &short_fit(&csv)[..],
            &["--effects", "creep", "--time-budget", "0"],
        ]
        .concat(),
        dir.path(),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("stopped (TimeBudget) while the chain was built (")
            && err.contains("nothing was written to out/fit"),
        "{err}"
    );
}

/// A fit whose files cannot be written prints its report (the minutes of
/// search are not lost) without saying it wrote them, and exits 1: a link
/// to a device stood where the model goes (a folder there is refused
/// before the fit).
#[cfg(unix)]
#[test]
fn a_failed_write_is_not_reported_as_written() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    std::fs::create_dir_all(dir.path().join("od")).unwrap();
    std::os::unix::fs::symlink("/dev/null", dir.path().join("od/model.json")).unwrap();
    for json in [false, true] {
        let mut args = [&short_fit(&csv)[..], &["--out", "od"]].concat();
        if json {
            args.push("--json");
        }
        let out = mckibben(&args, dir.path());
        let (stdout, err) = (
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr),
        );
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains("cannot write --out od"), "{err}");
        if json {
            let doc: serde_json::Value = serde_json::from_str(&stdout).unwrap();
            assert!(doc.get("out").is_none(), "{doc}");
            assert!(doc["sse"].is_number());
        } else {
            assert!(
                stdout.contains("evaluations in") && !stdout.contains("wrote"),
                "{stdout}"
            );
        }
    }
    assert!(!dir.path().join("od/result.json").exists());
}

/// A checkpoint that cannot be written (a full disk, a file where its
/// folder goes) does not throw the fit away: its files are written and a
/// warning says it cannot be resumed (the fit ran to its end and then
/// failed, writing nothing).
#[test]
fn a_checkpoint_that_cannot_be_written_keeps_the_fit() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    std::fs::write(dir.path().join("afile"), "x").unwrap();
    let args = [
        &short_fit(&csv)[..],
        &["--checkpoint", "afile/ck.json", "--out", "kept", "--json"],
    ]
    .concat();
    let out = mckibben(&args, dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(dir.path().join("kept/model.json").exists());
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let warned = doc["notes"].as_array().unwrap().iter().any(|n| {
        n["level"] == "warning"
            && n["text"]
                .as_str()
                .unwrap()
                .starts_with("cannot write checkpoint afile/ck.json")
    });
    assert!(warned, "{}", doc["notes"]);
}

/// Standard output that cannot be written (a full disk) is an error that
/// names it, exit 1: `println!` panicked (exit 101). A file name that is
/// not UTF-8 (from another system) is read and recorded with its odd bytes
/// replaced: recording the command line panicked, after the whole fit.
#[cfg(target_os = "linux")]
#[test]
fn a_full_standard_output_and_a_name_that_is_not_utf8_are_no_panics() {
    use std::os::unix::ffi::OsStrExt;
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    for args in [
        vec!["identify", csv.as_str()],
        [&short_fit(&csv)[..], &["--json", "--out", "full"]].concat(),
    ] {
        let out = command(dir.path())
            .args(&args)
            .stdout(std::fs::File::create("/dev/full").unwrap())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("mckibben: error: standard output: No space left on device"),
            "{args:?}: {err}"
        );
    }

    let odd = dir.path().join(std::ffi::OsStr::from_bytes(b"run\xff.csv"));
    std::fs::copy(&csv, &odd).unwrap();
    let out = command(dir.path())
        .args(["identify", "--out", "arx.json"])
        .arg(&odd)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let model = std::fs::read_to_string(dir.path().join("arx.json")).unwrap();
    assert!(model.contains("run\u{fffd}.csv"), "{model}");
}

/// A model file whose means lie past the f32 range from its data (edited
/// by hand): `fit --from` is refused with the column and the model's mean,
/// where the polish's decomposition of non-finite residuals panicked.
#[test]
fn a_model_whose_means_are_far_from_the_data_is_refused_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let csv = data(dir.path());
    let out = mckibben(
        &[&short_fit(&csv)[..], &["--out", "m"]].concat(),
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.path().join("m/model.json")).unwrap();
    let mut model: serde_json::Value = serde_json::from_str(&text).unwrap();
    model["data"]["output"]["mean"] = serde_json::json!(1e39);
    std::fs::write(dir.path().join("far.json"), model.to_string()).unwrap();
    let out = mckibben(
        &[
            &short_fit(&csv)[..],
            &["--from", "far.json", "--out", "far"],
        ]
        .concat(),
        dir.path(),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("deviations from the model's mean 1e39 must stay below")
            && err.contains("fit afresh"),
        "{err}"
    );
}

/// Every command's `--help` opens with what it does, before its usage: a
/// constant declared between a command's doc comment and its arguments
/// once took `control`'s whole description and examples with it.
#[test]
fn every_command_s_help_says_what_it_does_before_its_usage() {
    for command in [
        "fit", "identify", "simulate", "diagnose", "control", "compare", "sweep", "bench", "twin",
        "static",
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_mckibben"))
            .args([command, "--help"])
            .output()
            .unwrap();
        let help = String::from_utf8_lossy(&out.stdout);
        let before = help.split("Usage:").next().unwrap_or_default();
        assert!(
            before.split_whitespace().count() >= 20,
            "{command} --help says nothing before its usage:\n{help}"
        );
    }
}
