//! `scripts/gpu-check.sh --small` end to end (the CI smoke run of the real-GPU
//! check, issue 31), and the `bench` flags it relies on.
//!
//! The script needs a GPU adapter: without one the test fails when `CI=true`
//! and otherwise prints a loud SKIP message and returns
//! (`common::require_gpu`). On lavapipe (a CPU adapter) the GPU's scores and
//! the staged fit must carry the CPU path's bits.

mod common;

use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_mckibben");

#[test]
fn the_small_gpu_check_prints_every_row() {
    let Some(adapter) = common::require_any_adapter() else {
        return;
    };
    let on_cpu_adapter = common::is_lavapipe(&adapter.get_info());
    let dir = tempfile::tempdir().unwrap();
    let out_file = dir.path().join("check.md");
    let out = Command::new("bash")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/gpu-check.sh"))
        .args(["--small", "--bin", BIN, "--out"])
        .arg(&out_file)
        // The peak memory column asks the default GNU time, as checked below.
        .env_remove("GNU_TIME")
        .output()
        .expect("run bash");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "exit {:?}\n{stdout}\n{stderr}",
        out.status
    );
    assert_eq!(
        std::fs::read_to_string(&out_file).unwrap(),
        stdout,
        "--out holds what was printed"
    );
    let rows: Vec<Vec<&str>> = stdout
        .lines()
        .filter(|l| {
            l.starts_with("| ")
                && !l.starts_with("| model")
                && !l.starts_with("| N ")
                && !l.starts_with("| backend")
        })
        .map(|l| l.trim_matches('|').split(" | ").map(str::trim).collect())
        .collect();
    let row = |cells: &[&str]| {
        rows.iter()
            .find(|r| r.len() >= cells.len() && r[..cells.len()] == *cells)
            .unwrap_or_else(|| panic!("no row starting {cells:?} in\n{stdout}"))
    };
    for model in [
        "classic",
        "generalized",
        "classic + creep, delay, saturation",
    ] {
        for n in ["1000", "4000"] {
            let gpu = row(&[model, n, "gpu"]);
            let cpu = row(&[model, n, "cpu"]);
            assert_eq!(gpu.len(), 12, "{gpu:?}");
            // The CPU has no device clock: no kernel-only figures, no share.
            assert_eq!(
                cpu[6..],
                ["—", "—", "—", "1×", "reference", "reference"],
                "{cpu:?}"
            );
            for r in [gpu, cpu] {
                for cell in &r[3..6] {
                    let v: f64 = median(cell).unwrap_or_else(|| panic!("{r:?}"));
                    assert!(v.is_finite() && v > 0.0, "{r:?}");
                }
            }
            assert!(gpu[9].ends_with('×'), "{gpu:?}");
            if on_cpu_adapter {
                // lavapipe offers timestamps: the kernels alone, within the call.
                let kernel: f64 = gpu[7].parse().unwrap_or_else(|_| panic!("{gpu:?}"));
                let call = median(gpu[5]).unwrap();
                assert!(kernel > 0.0 && kernel <= call, "{gpu:?}");
                assert_eq!(gpu[10..], ["0 (bit-identical)", "yes (100/100)"], "{gpu:?}");
                // The plain families' kernels have an operation count, so a
                // share of the calibrated ceiling; with effects, none.
                let share = gpu[8].strip_suffix(" %").map(str::parse::<f64>);
                if model.contains('+') {
                    assert_eq!(gpu[8], "—", "{gpu:?}");
                } else {
                    assert!(matches!(share, Some(Ok(s)) if s > 0.0), "{gpu:?}");
                }
            }
        }
        if on_cpu_adapter {
            // The calibration of this model's bench call: every variant's rate.
            for variant in ["dependent", "independent", "pow"] {
                let r = row(&[model, variant, "16"]);
                assert_eq!(r.len(), 7, "{r:?}");
                let rate: f64 = r[6].parse().unwrap_or_else(|_| panic!("{r:?}"));
                assert!(rate.is_finite() && rate > 0.0, "{r:?}");
            }
        }
    }
    let gnu_time = std::process::Command::new("/usr/bin/time")
        .args(["-f", "%M", "-o", "/dev/null", "true"])
        .status()
        .is_ok_and(|s| s.success());
    let cpu_fit = row(&["200", "12", "cpu"]);
    let gpu_fit = row(&["200", "12", "gpu"]);
    for r in [cpu_fit, gpu_fit] {
        assert_eq!((r.len(), r[5]), (15, "completed"), "{r:?}");
        let fit: f64 = r[7].parse().unwrap();
        assert!(fit > 50.0 && fit <= 100.0, "validation fit %: {r:?}");
        // The host's time a row of the global stage, outside the evaluator.
        let host: f64 = r[10].parse().unwrap_or_else(|_| panic!("{r:?}"));
        assert!(host > 0.0, "{r:?}");
        // The polish's seconds, a part of the fit's.
        let (polish, whole): (f64, f64) = (r[13].parse().unwrap(), r[4].parse().unwrap());
        assert!(polish > 0.0 && polish <= whole, "{r:?}");
        // The process's peak resident memory, where GNU time can tell it.
        if gnu_time {
            let peak: u64 = r[14].parse().unwrap_or_else(|_| panic!("{r:?}"));
            assert!(peak >= 1, "{r:?}");
        } else {
            assert_eq!(r[14], "—", "{r:?}");
        }
    }
    // The device's time a generation: the GPU's kernels, none on the CPU;
    // and a generation's time over the larger of the host's and the
    // device's, at least 1 (they cannot overlap past full).
    assert_eq!(cpu_fit[11..13], ["—", "—"], "{cpu_fit:?}");
    if on_cpu_adapter {
        let device: f64 = gpu_fit[11]
            .parse()
            .unwrap_or_else(|_| panic!("{gpu_fit:?}"));
        assert!(device > 0.0, "{gpu_fit:?}");
        let ratio: f64 = gpu_fit[12]
            .parse()
            .unwrap_or_else(|_| panic!("{gpu_fit:?}"));
        assert!(ratio >= 0.99, "{gpu_fit:?}");
    }
    if on_cpu_adapter {
        assert_eq!(gpu_fit[9], "yes (bit-identical)", "{gpu_fit:?}");
        assert_eq!(gpu_fit[6..8], cpu_fit[6..8], "same SSE and fit");
    }
    // The sweep on both backends: one case at N = 100, and on lavapipe the
    // same fit as the CPU's.
    let cpu_sweep = row(&["cpu", "classic", "100"]);
    let gpu_sweep = row(&["gpu", "classic", "100"]);
    for r in [cpu_sweep, gpu_sweep] {
        assert_eq!((r.len(), r[3]), (10, "1"), "one try: {r:?}");
        assert!(r[4] == "0/1" || r[4] == "1/1", "{r:?}");
    }
    if on_cpu_adapter {
        assert_eq!(cpu_sweep[4..7], gpu_sweep[4..7], "pass, within 5 %, p");
    }
    // The diagnosis on both backends (its rows are the ones of four cells):
    // the same verdict, and on lavapipe the same JSON to the byte.
    let diagnosis = |backend: &str| {
        rows.iter()
            .find(|r| r.len() == 4 && r[0] == backend)
            .unwrap_or_else(|| panic!("no diagnosis row of {backend} in\n{stdout}"))
    };
    let cpu_diagnosis = diagnosis("cpu");
    let gpu_diagnosis = diagnosis("gpu");
    assert_eq!(cpu_diagnosis[2], gpu_diagnosis[2], "the verdicts");
    assert!(
        cpu_diagnosis[2] == "none"
            || cpu_diagnosis[2]
                .split(", ")
                .all(|name| name.starts_with("delay")),
        "the verdict is the names the run accepted: {cpu_diagnosis:?}"
    );
    if on_cpu_adapter {
        assert_eq!(
            gpu_diagnosis[3], "yes (byte-identical)",
            "{gpu_diagnosis:?}"
        );
    }
    assert!(
        stdout.contains("- adapter (wgpu): ") && stdout.contains("- CPU: "),
        "{stdout}"
    );
}

/// On a device lent for minutes, a run must end inside its lease and leave
/// what it measured: past `--deadline` no section starts, the tables say
/// which were skipped, and `--out` holds every table printed.
#[test]
fn past_its_deadline_the_check_starts_no_section_and_names_them() {
    if common::require_any_adapter().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out_file = dir.path().join("check.md");
    let out = Command::new("bash")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/gpu-check.sh"))
        .args(["--small", "--bin", BIN, "--deadline", "0", "--out"])
        .arg(&out_file)
        .output()
        .expect("run bash");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(std::fs::read_to_string(&out_file).unwrap(), stdout);
    assert!(
        stdout.contains(
            "Skipped, the --deadline of 0 s having passed: bench classic; bench generalized; \
             bench classic+effects; fits at N = 200; sweep on cpu; sweep on gpu; diagnose on \
             cpu; diagnose on gpu."
        ),
        "{stdout}"
    );
    // No section ran: no row of any table.
    assert!(
        !stdout.lines().any(|l| l.starts_with("| classic")
            || l.starts_with("| 200 ")
            || l.starts_with("| cpu ")
            || l.starts_with("| gpu ")),
        "{stdout}"
    );
}

#[test]
fn the_check_names_a_bad_flag() {
    let out = Command::new("bash")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/gpu-check.sh"))
        .args(["--small", "--bin", BIN, "--gens", "ten"])
        .output()
        .expect("run bash");
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("--gens") && stderr.contains("'ten'"),
        "{stderr}"
    );
    let out = Command::new("bash")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/gpu-check.sh"))
        .args(["--bin", "/nonexistent/mckibben"])
        .output()
        .expect("run bash");
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--bin"));
    let out = Command::new("bash")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/gpu-check.sh"))
        .args(["--small", "--bin", BIN, "--deadline", "-5"])
        .output()
        .expect("run bash");
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("--deadline") && stderr.contains("'-5'"),
        "{stderr}"
    );
}

#[test]
fn bench_scores_a_model_with_effects_and_times_the_cpu_path() {
    let out = Command::new(BIN)
        .args([
            "bench",
            "--synthetic",
            "300",
            "--backend",
            "cpu",
            "--pop",
            "150",
            "--repeats",
            "1",
            "--effects",
            "creep,saturation:output",
            "--time-reference",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let row = &v["rows"][0];
    assert_eq!(row["model"], "classic + creep, saturation:output");
    assert_eq!(row["effects"][1], "saturation:output");
    assert_eq!(row["population"], 150);
    assert_eq!(row["agreement"]["top100_identical"], true);
    assert_eq!(row["agreement"]["top100_overlap"], 100);
    // --time-reference times the CPU path against a GPU's: on the CPU
    // backend there is no speed-up to measure, and none is reported.
    assert!(row["reference"].is_null() && row["speedup"].is_null());
    // The CPU has no device clock: its kernel figures are null.
    assert!(row["kernel_median_s"].is_null() && row["kernel_candidate_samples_per_s"].is_null());

    // One dataset cannot carry the `load` effect; an unknown name is named.
    for (effects, want) in [("load", "needs at least two datasets"), ("bogus", "bogus")] {
        let out = Command::new(BIN)
            .args([
                "bench",
                "--synthetic",
                "100",
                "--backend",
                "cpu",
                "--pop",
                "4",
            ])
            .args(["--effects", effects])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{effects}");
        assert!(
            stderr.contains("--effects") && stderr.contains(want),
            "{stderr}"
        );
    }
}

/// A timing cell's median: the number alone, or with the timed calls'
/// range beside it (`4.358e-3 (4.34e-3–4.36e-3)`), which must hold it.
fn median(cell: &str) -> Option<f64> {
    let Some((median, range)) = cell.split_once(" (") else {
        return cell.parse().ok();
    };
    let median: f64 = median.parse().ok()?;
    let (lo, hi) = range.strip_suffix(')')?.split_once('–')?;
    let (lo, hi): (f64, f64) = (lo.parse().ok()?, hi.parse().ok()?);
    (lo <= median && median <= hi).then_some(median)
}
