//! The diagnosis fits its baseline as `fit` does too, and starts again
//! from that fit where it beats its own baseline on the estimation half
//! and on the selection part: the diagnosis' baseline, searched among the
//! thesis' loop shapes, then missed a basin, and the effects named from it
//! would stand in for the miss.

use mckibben::data::csv::{ReadOptions, read_traces};
use mckibben::data::signals::Stair;
use mckibben::diagnose::report::{
    DiagnosisJson, plain_fit_caution, plain_fit_start, to_text, verdict_cautions,
};
use mckibben::diagnose::{Diagnosis, PLAIN_FIT_START, Settings, diagnose, effects::Effect};
use mckibben::model::Family;
use mckibben::twin::{TwinConfig, TwinExperiment, run};
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_mckibben");

fn diagnosis_of(trace: &mckibben::data::Trace) -> Diagnosis {
    let effects = Effect::by_default();
    diagnose(
        std::slice::from_ref(trace),
        Family::Classic,
        &effects,
        &Settings::default(),
    )
    .unwrap()
}

/// A twin muscle whose braid has three times the documented friction: its
/// loop closes within a fraction of a millimetre, outside the thesis' loop
/// shapes, and `fit`, whose box is in the data's own scale, reaches it.
/// The diagnosis then starts again from `fit`'s fit: its searched baseline
/// scored the selection part at 26.6 %, where effects named from it stood
/// in for the loop (creep driven by the output, which the twin lacks).
#[test]
fn a_baseline_that_misses_fits_basin_starts_again_from_fits() {
    let mut config = TwinConfig::default();
    config.effects.set("friction", 3.0).unwrap();
    let trace = run(&config, 4.5, 1, &TwinExperiment::Stair(Stair::default()));
    let d = diagnosis_of(&trace);
    let plain = d.plain_fit.clone().expect("the plain fit ran");
    assert!(plain.beats_baseline, "{plain:?}");
    assert!(
        plain.est_sse < plain.searched_est_sse
            && plain.selection_rmse < plain.searched_selection_rmse,
        "{plain:?}"
    );
    assert!(plain.started_from, "{plain:?}");
    assert_eq!(d.from.as_deref(), Some(PLAIN_FIT_START));
    assert_eq!(
        plain.restarted_selection_fit_percent,
        Some(d.baseline().selection_fit_percent)
    );
    assert!(plain_fit_caution(&d).is_none());
    // Refitted warm from `fit`'s fit, in a box widened to hold it: its
    // selection error, not the searched baseline's.
    let base = &d.selection.baseline.best;
    assert!(
        base.sel_rmse < 0.5 * plain.searched_selection_rmse,
        "{base:?} against {plain:?}"
    );
    let why = plain_fit_start(&d).expect("the report says why");
    assert!(why.contains("missed a basin `fit` reaches"), "{why}");
    assert!(to_text(&d).contains(&format!("Started from {PLAIN_FIT_START}: {why}")));
    let json = serde_json::to_value(DiagnosisJson::of(&d)).unwrap();
    assert_eq!(json["from"], PLAIN_FIT_START);
    assert_eq!(json["baseline"]["plain_fit"]["beats_baseline"], true);
    assert_eq!(
        json["baseline"]["plain_fit"]["searched_est_sse"],
        plain.searched_est_sse
    );
    assert_eq!(json["baseline"]["est_sse"], base.est_sse);

    // Had the restart's refit lost the gain, the diagnosis would be the
    // searched baseline's, and the report would say so instead.
    let mut lost = d.clone();
    if let Some(p) = lost.plain_fit.as_mut() {
        p.started_from = false;
    }
    assert!(plain_fit_start(&lost).is_none());
    let caution = plain_fit_caution(&lost).expect("a caution");
    assert!(
        caution.contains("kept the searched one")
            && caution.contains(&format!(
                "scored the selection part at {:.1} %",
                d.baseline().selection_fit_percent
            )),
        "{caution}"
    );
    assert!(to_text(&lost).contains(&format!("  CAUTION: {caution}")));
    assert!(!lost.named().is_empty(), "the verdict names effects");
    assert!(
        verdict_cautions(&lost)
            .iter()
            .any(|c| c.contains("better than the diagnosis' baseline"))
    );
    assert!(
        verdict_cautions(&d)
            .iter()
            .all(|c| !c.contains("better than"))
    );
}

/// On the shipped stair `fit`'s fit scores the selection part better but
/// fits the estimation half worse than the diagnosis' baseline: another
/// trade-off between the two halves, not a basin the baseline missed, and
/// the diagnosis keeps its own baseline.
#[test]
fn a_plain_fit_that_only_validates_better_leaves_the_baseline_alone() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv");
    let trace = read_traces(path.as_ref(), &ReadOptions::default())
        .unwrap()
        .remove(0);
    let d = diagnosis_of(&trace);
    let plain = d.plain_fit.clone().expect("the plain fit ran");
    let base = &d.selection.baseline.best;
    assert!(
        plain.selection_rmse < base.sel_rmse,
        "{plain:?} against {base:?}"
    );
    assert!(plain.est_sse > base.est_sse, "{plain:?} against {base:?}");
    assert_eq!(plain.searched_est_sse, base.est_sse);
    assert!(!plain.beats_baseline);
    assert!(!plain.started_from && plain.restarted_selection_fit_percent.is_none());
    assert!(plain_fit_start(&d).is_none() && plain_fit_caution(&d).is_none());
    assert!(d.from.is_none());
    assert!(!to_text(&d).contains("missed a basin"));
}

/// `diagnose --from` the model `fit` wrote starts from it as it is: the
/// diagnosis' box is widened to hold its baseline (a loop far past the
/// thesis' shapes), where it used to clamp the start into the box and end
/// near the baseline searched from scratch.
#[test]
fn a_diagnosis_from_fits_model_starts_from_its_basin() {
    let dir = tempfile::tempdir().unwrap();
    let record = dir.path().join("friction3.csv");
    let out = dir.path().join("fit");
    let run = |args: &[&str]| {
        let o = Command::new(BIN).args(args).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        o.stdout
    };
    let path = |p: &std::path::Path| p.to_str().unwrap().to_string();
    run(&["twin", "--effect", "friction=3", "--out", &path(&record)]);
    run(&["fit", &path(&record), "--out", &path(&out)]);
    let scratch: serde_json::Value =
        serde_json::from_slice(&run(&["diagnose", &path(&record), "--json"])).unwrap();
    let model = path(&out.join("model.json"));
    let from: serde_json::Value = serde_json::from_slice(&run(&[
        "diagnose",
        &path(&record),
        "--from",
        &model,
        "--json",
    ]))
    .unwrap();
    let searched = scratch["baseline"]["plain_fit"]["searched_selection_rmse"]
        .as_f64()
        .unwrap();
    let rmse = from["baseline"]["selection_rmse"].as_f64().unwrap();
    assert!(
        rmse < 0.5 * searched,
        "from fit's model {rmse} against the baseline searched from scratch {searched}"
    );
    // The start's loop shape is kept: β far past the thesis' 0.5 per mm.
    let beta = from["baseline"]["params"]["beta"].as_f64().unwrap();
    assert!(beta > 0.5, "{beta}");
}
