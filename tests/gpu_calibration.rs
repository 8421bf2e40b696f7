//! The calibration kernel (`shaders/calibration.wgsl`, issue 52) on
//! lavapipe: it runs, its mul-add variants give the CPU's evaluation of the
//! same loop bit for bit, its `pow` variant stays finite and near the
//! CPU's, its rates are finite and positive, and `bench --json` reports
//! them. Behaviour only: how fast is the benchmarks' to say.
//!
//! Without lavapipe the test fails when `CI=true` and otherwise prints a
//! loud SKIP message and returns (`common::require_lavapipe`).

mod common;

use std::process::Command;

use mckibben::eval::gpu::GpuOptions;
use mckibben::eval::gpu::calibration::{Sizing, Variant, reference};

const BIN: &str = env!("CARGO_BIN_EXE_mckibben");

#[test]
fn the_calibration_loop_gives_the_cpus_values() {
    let Some(mut gpu) = common::require_lavapipe(GpuOptions::default()) else {
        return;
    };
    // 20 steps: the mul-add chains are still on their way to their fixed
    // points, so every step shows in the bits. 320 invocations: five
    // workgroups, every addend of the 256 an invocation can have.
    let (invocations, steps) = (320, 20);
    for variant in Variant::ALL {
        let (values, seconds) = gpu.calibration_run(variant, invocations, steps).unwrap();
        assert_eq!(values.len(), invocations as usize);
        let seconds = seconds.expect("lavapipe offers timestamp queries");
        assert!(
            seconds.is_finite() && seconds > 0.0,
            "{variant:?}: {seconds}"
        );
        for (i, &got) in values.iter().enumerate() {
            let want = reference(variant, i as u32, steps);
            assert!(got.is_finite(), "{variant:?}, invocation {i}: {got}");
            if variant == Variant::Pow {
                // lavapipe's pow is within an ulp or so of Rust's powf, not equal.
                assert!(
                    ((got - want) / want).abs() < 1e-5,
                    "{variant:?}, invocation {i}: {got} against {want}"
                );
            } else {
                assert_eq!(
                    got.to_bits(),
                    want.to_bits(),
                    "{variant:?}, invocation {i}: {got} against {want}"
                );
            }
        }
    }
    // The ceiling, small: every variant timed, finite positive rates.
    let sizing = Sizing {
        invocations: 4096,
        min_seconds: 2e-3,
        max_steps: 1 << 14,
    };
    let ceiling = gpu.calibrate(sizing).unwrap().expect("timestamps");
    assert_eq!(ceiling.invocations, 4096);
    let names: Vec<Variant> = ceiling.variants.iter().map(|t| t.variant).collect();
    assert_eq!(names, Variant::ALL);
    for t in &ceiling.variants {
        // Passes of s and 4s steps: the longer adds 3s.
        assert!(t.steps % 3 == 0 && t.steps / 3 * 4 <= 1 << 14, "{t:?}");
        assert_eq!(t.ops_per_step, 16);
        assert!(
            t.device_s > 0.0 && t.ops_per_s.is_finite() && t.ops_per_s > 0.0,
            "{t:?}"
        );
    }
    assert_eq!(
        ceiling.ceiling_ops_per_s(),
        ceiling.ops_per_s(Variant::Independent).unwrap()
    );
}

#[test]
fn bench_reports_the_ceiling_and_each_kernels_share() {
    if common::require_lavapipe_adapter().is_none() {
        return;
    }
    let bench = |extra: &[&str]| {
        let out = Command::new(BIN)
            .args([
                "bench",
                "--synthetic",
                "200",
                "--backend",
                "gpu",
                "--pop",
                "64",
            ])
            .args(["--repeats", "1"])
            .args(extra)
            .output()
            .unwrap();
        let (stdout, stderr) = (
            String::from_utf8_lossy(&out.stdout).to_string(),
            String::from_utf8_lossy(&out.stderr),
        );
        assert!(out.status.success(), "{extra:?}: {stderr}");
        stdout
    };
    let v: serde_json::Value = serde_json::from_str(&bench(&["--json"])).unwrap();
    let c = &v["calibration"];
    let variants: Vec<&str> = c["variants"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["variant"].as_str().unwrap())
        .collect();
    assert_eq!(variants, ["dependent", "independent", "pow"]);
    let ceiling = c["ceiling_ops_per_s"].as_f64().unwrap();
    assert_eq!(Some(ceiling), c["variants"][1]["ops_per_s"].as_f64());
    let row = &v["rows"][0];
    assert_eq!(row["ops_per_candidate_sample"], 19, "classic at n = 1");
    let ops = row["kernel_ops_per_s"].as_f64().unwrap();
    let kernel = row["kernel_candidate_samples_per_s"].as_f64().unwrap();
    assert_eq!(ops, kernel * 19.0);
    assert_eq!(row["ceiling_share"].as_f64().unwrap(), ops / ceiling);

    // The text names the ceiling; the markdown adds the share column and
    // the calibration's own table.
    let text = bench(&[]);
    assert!(text.contains("device ceiling"), "{text}");
    assert!(text.contains("of the ceiling"), "{text}");
    let md = bench(&["--markdown"]);
    let tables: Vec<&str> = md.trim_end().split("\n\n").collect();
    assert_eq!(tables.len(), 2, "{md}");
    assert!(
        tables[0]
            .lines()
            .next()
            .unwrap()
            .contains("| share of ceiling |")
    );
    let row: Vec<&str> = tables[0].lines().nth(2).unwrap().split(" | ").collect();
    assert!(row[8].ends_with(" %"), "{row:?}");
    let calibration: Vec<&str> = tables[1].lines().skip(2).collect();
    assert_eq!(calibration.len(), 3, "{md}");
    assert!(calibration[1].starts_with("| classic | independent | 16 | "));
}
