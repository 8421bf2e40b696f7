//! The withheld-effect check on a small synthetic rig trace: a
//! representative subset of the self-test cases (the full table is
//! `mckibben diagnose --self-test`).

use std::sync::OnceLock;

use mckibben::data::Trace;
use mckibben::diagnose::selftest::{
    Case, MARKS, Nominal, SizeCheck, cases, mark, noise_sigma, run_case,
};
use mckibben::diagnose::{Effect, Settings};
use mckibben::model::presets::thesis_params;
use mckibben::model::{Family, simulate};

/// A stair of gauge pressures up and down (MPa), the valve smoothing each
/// step with a pole of 0.6, and the thesis' classic model's response (mm).
fn rig_trace(len: usize) -> Trace {
    let levels = [0.05, 0.2, 0.35, 0.5, 0.3, 0.1, 0.25, 0.45, 0.15];
    let mut p = vec![levels[0]; len];
    for k in 1..len {
        let target = levels[(k / 60) % levels.len()];
        p[k] = 0.6 * p[k - 1] + 0.4 * target;
    }
    let mut theta: Vec<f32> = thesis_params(Family::Classic)
        .iter()
        .map(|&v| v as f32)
        .collect();
    theta[7] = 0.5;
    let u: Vec<f32> = p.iter().map(|&v| v as f32).collect();
    let x = simulate(Family::Classic, &theta, 0.0, &u, 0.0).x;
    Trace::uniform("rig", 0.1, p, x.iter().map(|&v| v as f64).collect())
}

fn fast() -> Settings {
    Settings {
        seeds: 2,
        ..Settings::default()
    }
}

/// The nominal model, fitted once for all tests of this file.
fn nominal() -> &'static Nominal {
    static NOMINAL: OnceLock<Nominal> = OnceLock::new();
    NOMINAL.get_or_init(|| Nominal::fit(&rig_trace(1080), Family::Classic, &fast()).unwrap())
}

fn case_of(nominal: &Nominal, name: &str) -> Case {
    cases(nominal, &Effect::ALL)
        .into_iter()
        .find(|c| c.name == name)
        .unwrap_or_else(|| panic!("no case {name}"))
}

fn check(name: &str) {
    let nom = nominal();
    let case = case_of(nom, name);
    let o = run_case(nom, &case, &Effect::ALL, &fast(), 7).unwrap();
    assert!(o.pass, "{name}: {o:?}");
    // The planted realisation itself, its size pinned by the data and so
    // judged against the truth.
    assert_eq!(
        o.size_check,
        SizeCheck::Judged,
        "{name}: its size was not judged: {o:?}"
    );
}

#[test]
fn control_names_nothing() {
    let nom = nominal();
    let o = run_case(nom, &case_of(nom, "control"), &Effect::ALL, &fast(), 7).unwrap();
    assert!(o.named.is_empty(), "{o:?}");
    // The baseline reaches the noise it was generated with.
    assert!(o.baseline_rmse < 1.2 * o.noise_floor, "{o:?}");
}

#[test]
fn a_withheld_delay_is_named_first_sized_and_closes_the_gap() {
    check("delay (large)");
}

#[test]
fn a_withheld_end_stop_is_named_first_sized_and_closes_the_gap() {
    check("saturation (small)");
}

#[test]
fn a_load_dependent_gain_is_found_across_two_datasets() {
    check("load (small)");
}

#[test]
fn two_withheld_effects_are_both_named() {
    let nom = nominal();
    let case = case_of(nom, "delay + saturation");
    let o = run_case(nom, &case, &Effect::ALL, &fast(), 7).unwrap();
    // Both physical effects, in any of their realisations.
    let named = |e: Effect| o.named.iter().any(|n| n.physical() == e);
    assert!(named(Effect::Delay) && named(Effect::Saturation), "{o:?}");
    assert!(o.gap_closed > 0.5, "{o:?}");
}

#[test]
fn every_case_leaves_the_mark_it_was_calibrated_to() {
    let nom = nominal();
    let sigma = noise_sigma(nom);
    let all = cases(nom, &Effect::ALL);
    // The check plants the physical effects' own equations only.
    for e in Effect::PHYSICAL {
        let marks: Vec<f64> = MARKS
            .iter()
            .map(|(k, label)| {
                let case = all
                    .iter()
                    .find(|c| c.name == format!("{e} ({label})"))
                    .unwrap();
                let m = mark(nom, &case.effects);
                // The target, or short of it only where the effect's box ends.
                assert!(
                    m <= 1.01 * k * sigma,
                    "{}: mark {m} above {}",
                    case.name,
                    k * sigma
                );
                m
            })
            .collect();
        assert!(
            marks[0] >= 0.9 * MARKS[0].0 * sigma,
            "{e} (small): mark {} is not {}",
            marks[0],
            MARKS[0].0 * sigma
        );
        assert!(
            marks[1] > marks[0],
            "{e}: the large case leaves no larger mark: {marks:?}"
        );
    }
}

/// The independent self-test's harness on a handful of its cases (the full
/// table is `mckibben diagnose --self-test`): its generator shares no code
/// with the catalogue.
mod independent {
    use super::{fast, nominal};
    use mckibben::diagnose::Effect;
    use mckibben::diagnose::blind::{BlindCase, Setup, cases, run_case};

    fn case(setup: &Setup, name: &str) -> BlindCase {
        cases(setup, 1)
            .into_iter()
            .find(|c| c.name == name)
            .unwrap_or_else(|| panic!("no case {name}"))
    }

    #[test]
    fn the_cases_cover_every_realisation_on_both_excitations() {
        let setup = Setup::new(nominal(), 1).unwrap();
        let all = cases(&setup, 1);
        // 18 catalogued realisations × 2 sizes × 2 excitations, 2 controls,
        // 2 pairs, and the cross-talk outside the catalogue × 2 × 2; then
        // the softening and the set, 2 realisations × 2 sizes on each of
        // the two pulse trains, a control on each, and a creep on equal
        // pulses.
        assert_eq!(all.len(), 80 + 11);
        for exc in &setup.excitations[1..] {
            assert_eq!(exc.input.len(), nominal().trace.len(), "{}", exc.name);
        }
    }

    #[test]
    fn the_control_names_nothing_and_a_pure_delay_is_named_a_lag() {
        let setup = Setup::new(nominal(), 1).unwrap();
        let o = run_case(
            &setup,
            &case(&setup, "control (stair)"),
            &Effect::ALL,
            &fast(),
        )
        .unwrap();
        assert!(o.pass && o.named.is_empty(), "{o:?}");
        let o = run_case(
            &setup,
            &case(&setup, "lag: pure delay (large on stair)"),
            &Effect::ALL,
            &fast(),
        )
        .unwrap();
        assert!(o.pass, "{o:?}");
    }
}

/// The report a person reads when the catalogue cannot explain the gap: a
/// sensor's cross-talk on the shipped stair's input (the independent
/// generator's), diagnosed through the library and printed as text.
#[test]
fn the_report_says_not_explained_and_names_no_cause() {
    use mckibben::data::csv::{ReadOptions, read_traces};
    use mckibben::diagnose::blind::{Setup, cases, synthesize};
    use mckibben::diagnose::diagnose;
    use mckibben::diagnose::report::{DiagnosisJson, to_text};

    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/stair_4.5kg.csv");
    let stair = read_traces(&path, &ReadOptions::default())
        .unwrap()
        .remove(0);
    let settings = Settings::default();
    let nominal = Nominal::fit(&stair, Family::Classic, &settings).unwrap();
    let setup = Setup::new(&nominal, settings.seed).unwrap();
    let case = cases(&setup, settings.seed)
        .into_iter()
        .find(|c| c.name == "outside the catalogue: sensor cross-talk (large on stair)")
        .unwrap();
    let d = diagnose(
        &synthesize(&setup, &case),
        Family::Classic,
        &Effect::ALL,
        &settings,
    )
    .unwrap();
    assert!(d.named().is_empty() && d.explainable.not_explained);
    let text = to_text(&d);
    assert!(
        text.contains("Verdict: not explained by the catalogue."),
        "{text}"
    );
    let json = DiagnosisJson::of(&d);
    assert_eq!(json.verdict_kind, "not-explained");
    assert!(json.verdict.is_empty());
    assert_eq!(json.asked.len(), Effect::ALL.len());

    // Asked to try fewer effects than the catalogue holds, the verdict
    // speaks of those alone.
    let mut d = d;
    d.asked = vec![Effect::Delay, Effect::Creep];
    let text = to_text(&d);
    assert!(
        text.contains("Verdict: not explained by the effects tried (delay, creep).")
            && text.contains("their best model closes"),
        "{text}"
    );
    assert!(
        !text.contains("by the catalogue") && !text.contains("the catalogue's best model"),
        "{text}"
    );
    // Stopped by --max-effects while a round still accepted: the verdict
    // says so itself, since one more round may change it.
    d.selection.capped = true;
    let rounds = d.selection.rounds.len();
    let text = to_text(&d);
    assert!(
        text.contains(&format!(
            "Verdict: not explained by the effects tried (delay, creep) within --max-effects \
             {rounds} (the last round still accepted one)."
        )),
        "{text}"
    );
    assert_eq!(DiagnosisJson::of(&d).asked, ["delay", "creep"]);
}

/// Under a "not explained" verdict the effects the final model holds are
/// fits to part of the gap, and the report calls them so, by name.
#[test]
fn fitted_effects_under_a_not_explained_verdict_are_called_fits() {
    use mckibben::diagnose::diagnose;
    use mckibben::diagnose::report::{DiagnosisJson, to_text};
    use mckibben::diagnose::selftest::synthesize;

    let nom = nominal();
    let case = case_of(nom, "saturation (large)");
    let mut d = diagnose(
        &synthesize(nom, &case, 7),
        Family::Classic,
        &Effect::ALL,
        &fast(),
    )
    .unwrap();
    let fitted: Vec<&str> = d.selection.verdict.iter().map(|e| e.name()).collect();
    assert!(!fitted.is_empty(), "the end stop was not fitted");
    // The same diagnosis read as if a flexible model had found the gap to
    // be something else.
    d.explainable.not_explained = true;
    assert!(DiagnosisJson::of(&d).verdict.is_empty());
    let text = to_text(&d);
    let line = text
        .lines()
        .find(|l| l.contains("are fits to part of the gap, not its cause"))
        .unwrap_or_else(|| panic!("no line calls the effects fits:\n{text}"));
    for e in &fitted {
        assert!(line.contains(e), "{e} is not named in {line:?}");
    }
}

/// A raised stop flag (Ctrl-C in the command, a signal in Python) ends the
/// diagnosis with `Interrupted` instead of a verdict of searches cut short.
#[test]
fn a_raised_stop_flag_interrupts_the_diagnosis() {
    use mckibben::diagnose::{Interrupted, diagnose};

    let settings = fast();
    settings.stop.raise();
    let stopped = diagnose(
        &[rig_trace(1080)],
        Family::Classic,
        &[Effect::Delay],
        &settings,
    );
    let error = stopped.expect_err("a stopped diagnosis gave a verdict");
    assert!(error.downcast_ref::<Interrupted>().is_some(), "{error:#}");
}
