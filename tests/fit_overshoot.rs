//! `fit --overshoot refuse` refuses a loop whose discrete update overshoots
//! on the steps its estimation half takes: on the real Cavatappi 400 g
//! record a population of 4000 finds, where it is admitted (the default),
//! one whose unloading branch throws the state past zero on every turn,
//! which fits the estimation half better and describes none of the
//! validation half.

mod common;

use std::process::Command;

use serde_json::Value;

fn fit_400g(extra: &[&str]) -> Option<Value> {
    let csv = common::require_external("cavatappi_muscle/sample1_400g.csv")?;
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_mckibben"))
        .arg("fit")
        .arg(&csv)
        .args(common::CAVATAPPI_FLAGS)
        .args(["--pop", "4000", "--json", "--out"])
        .arg(dir.path())
        .args(extra)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(serde_json::from_slice(&out.stdout).unwrap())
}

fn number(fit: &Value, name: &str) -> f64 {
    fit[name]
        .as_f64()
        .unwrap_or_else(|| panic!("{name} in {fit}"))
}

#[test]
fn a_fit_told_to_refuse_a_loop_that_overshoots_on_its_records_steps() {
    let (Some(allowed), Some(refused)) = (fit_400g(&[]), fit_400g(&["--overshoot", "refuse"]))
    else {
        return;
    };
    assert_eq!(
        (&allowed["overshoot"], &refused["overshoot"]),
        (&Value::from("allow"), &Value::from("refuse"))
    );
    let arx = number(&refused, "linear_val_fit_percent");
    // Admitted, the overshooting loop wins the estimation half: its
    // update settles only within a hundredth of the record's steps.
    assert!(
        number(&allowed, "stable_step") < 0.1 * number(&allowed, "largest_step"),
        "{allowed}"
    );
    assert!(number(&allowed, "val_fit_percent") < arx, "{allowed}");
    assert!(number(&allowed, "sse") < number(&refused, "sse"));
    // Refused, the fit settles on all but the fastest 1 % of the
    // estimation half's steps (0.47 mm a sample) and validates above ARX.
    assert!(number(&refused, "stable_step") >= 0.45, "{refused}");
    assert!(number(&refused, "val_fit_percent") > arx + 1.0, "{refused}");
}
