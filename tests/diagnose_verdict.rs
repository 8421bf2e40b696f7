//! What weakens a verdict that names effects is said under it and in the
//! JSON: the acceptance rule judges each effect on the selection part and
//! cannot see a baseline stuck on its box's edge, a size the data leave
//! open, or a chain that collapses on other records.

use mckibben::data::Trace;
use mckibben::diagnose::effects::Effect;
use mckibben::diagnose::report::{DiagnosisJson, to_text, verdict_cautions};
use mckibben::diagnose::transfer::Transfer;
use mckibben::diagnose::{Diagnosis, Settings, diagnose};
use mckibben::model::Family;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A stair through a first-order muscle with a hysteretic state and an
/// output clip, measured with noise: its diagnosis names effects.
fn stair() -> Trace {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let (mut p, mut x, mut w) = (0.0f64, 0.0f64, 0.0f64);
    let (mut u, mut y) = (Vec::new(), Vec::new());
    for k in 0..600 {
        let level = [0.05, 0.2, 0.35, 0.5, 0.3, 0.1][(k / 50) % 6];
        u.push(p);
        y.push(x + noise.sample(&mut rng));
        let xn = (0.93 * (0.6 * x + 0.4 * w) + 18.0 * p - 1.0).min(30.0);
        w += 0.9 * (xn - x) - 0.002 * (xn - x).abs() * w;
        x = xn;
        p = 0.6 * p + 0.4 * level;
    }
    Trace::uniform("stair.csv", 0.1, u, y)
}

fn named_diagnosis() -> Diagnosis {
    let settings = Settings {
        seeds: 2,
        generations: 20,
        scratch_seeds: 0,
        ..Settings::default()
    };
    let effects = [Effect::Delay, Effect::Saturation];
    let d = diagnose(&[stair()], Family::Classic, &effects, &settings).unwrap();
    assert!(
        !d.named().is_empty(),
        "the stair's diagnosis names an effect"
    );
    d
}

#[test]
fn a_verdict_says_what_weakens_it() {
    let mut d = named_diagnosis();
    let verdict_line = |d: &Diagnosis| {
        let text = to_text(d);
        let after = text.split("\nVerdict: ").nth(1).unwrap().to_string();
        after.lines().nth(1).unwrap_or("").to_string()
    };
    // Nothing found: the verdict stands alone.
    for s in &mut d.size_intervals {
        (s.lo_at_edge, s.hi_at_edge) = (false, false);
    }
    d.baseline_on_edge.clear();
    assert!(verdict_cautions(&d).is_empty());
    assert!(!verdict_line(&d).starts_with("Read it with care"));

    // A named effect's size on its box's edge, and a chain that collapses
    // on one of two other records.
    let named = d.named()[0];
    let interval = d
        .size_intervals
        .iter_mut()
        .find(|s| s.effect == named)
        .expect("a named effect has a size interval");
    interval.hi_at_edge = true;
    let transfer = |dataset: &str, collapses: bool| Transfer {
        dataset: dataset.into(),
        chain: d.named().to_vec(),
        dynamics_held: Vec::new(),
        baseline_val_rmse: 1.0,
        baseline_val_fit_percent: 80.0,
        chain_val_rmse: if collapses { 2.0 } else { 0.5 },
        chain_val_fit_percent: if collapses { 60.0 } else { 90.0 },
        names_only_val_fit_percent: 85.0,
        noise_floor_rmse: 0.1,
        gap_closed: if collapses { -0.3 } else { 0.5 },
        collapses,
        carries: None,
        chain_on_edge: Vec::new(),
    };
    d.transfers = vec![transfer("light.csv", true), transfer("heavy.csv", false)];
    let cautions = verdict_cautions(&d);
    assert_eq!(cautions.len(), 2, "{cautions:?}");
    assert!(
        cautions[0].contains(&format!("do not bound {}'s size", named.name())),
        "{cautions:?}"
    );
    assert!(
        cautions[1].contains("collapses on 1 of the 2 other records (TRANSFER: light.csv)"),
        "{cautions:?}"
    );
    assert!(
        verdict_line(&d).starts_with("Read it with care: the data do not bound"),
        "{}",
        to_text(&d)
    );
    let json = serde_json::to_value(DiagnosisJson::of(&d)).unwrap();
    assert_eq!(json["verdict_cautions"].as_array().unwrap().len(), 2);
}

/// A record whose output's second difference follows its noise gets its
/// floor as it is; one whose second difference follows the signal is told
/// the floor is an upper bound, in the text and the JSON.
#[test]
fn a_floor_read_from_motion_at_the_sample_scale_is_called_an_upper_bound() {
    let mut d = named_diagnosis();
    let upper = "The noise floor is an upper bound here";
    assert!(!d.floor_is_upper_bound(), "{}", d.noise_floor_lag1);
    assert!(!to_text(&d).contains(upper));
    d.noise_floor_lag1 = 0.82;
    assert!(to_text(&d).contains(upper), "{}", to_text(&d));
    let json = serde_json::to_value(DiagnosisJson::of(&d)).unwrap();
    assert_eq!(json["noise_floor_upper_bound"], true);
}

/// The report places its parts in the record's time: each block's mean
/// length and the settling gaps in seconds beside their samples (sample
/// counts alone left a reader to find the sample time).
#[test]
fn the_parts_line_says_how_long_its_blocks_and_gaps_are() {
    let d = named_diagnosis();
    let p = &d.parts[0];
    let blocks = p.selection.len() + p.test.len();
    let mean = (p.selection_len() + p.test_len()) as f64 / blocks as f64 * d.dt;
    let gap = (p.test[0].start - p.selection[0].end) as f64 * d.dt;
    let text = to_text(&d);
    let line = text.lines().find(|l| l.starts_with("Parts:")).unwrap();
    let said: Vec<f64> = line
        .split([' ', '(', ')', ',', '-'])
        .filter_map(|w| w.parse().ok())
        .collect();
    // blocks, their seconds, the gap's samples, its seconds
    assert_eq!(said.len(), 4, "{line}");
    assert_eq!(said[0], blocks as f64, "{line}");
    assert!((said[1] - mean).abs() <= 0.05 * mean, "{line}: {mean}");
    assert!(
        (said[3] - gap).abs() <= 0.05 * gap.max(d.dt),
        "{line}: {gap}"
    );
}
