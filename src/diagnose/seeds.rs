//! The diagnosis run again from other seeds (`diagnose --repeat K`):
//! whether its verdict is the data's or one seed's. Where the baseline has
//! several basins the estimation data cannot tell apart, the effects named
//! from it can change with the seed; a user who sees an effect named in
//! one run of three reads it as the seed's.

use serde::Serialize;

use super::effects::Effect;
use super::settings::Settings;
use super::{Diagnosis, diagnose_from};
use crate::data::Trace;
use crate::model::Model;

/// One run of `--repeat`: its seed, what it named and how its models
/// scored.
#[derive(Debug, Clone, PartialEq)]
pub struct SeedRun {
    pub seed: u64,
    /// The effects it named ([`Diagnosis::named`]), in order.
    pub named: Vec<Effect>,
    /// `named`, `none`, `not-explained` or `nothing-tried`
    /// ([`Diagnosis::verdict_kind`]).
    pub kind: &'static str,
    /// Its baseline on the selection part, which its choices read.
    pub baseline_selection_fit_percent: f64,
    /// Its baseline and its final model on the test part, which none of
    /// its choices read: before and after on the same samples.
    pub baseline_test_fit_percent: f64,
    pub final_test_fit_percent: f64,
}

impl SeedRun {
    /// The run `d`, the diagnosis from `seed`.
    pub fn of(d: &Diagnosis, seed: u64) -> SeedRun {
        SeedRun {
            seed,
            named: d.named().to_vec(),
            kind: d.verdict_kind(),
            baseline_selection_fit_percent: d.baseline().selection_fit_percent,
            baseline_test_fit_percent: d.baseline().test_fit_percent,
            final_test_fit_percent: d.last().test_fit_percent,
        }
    }
}

/// How many runs named one effect.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct NamedCount {
    /// The effect's name (`saturation:output`), or with `physical` its
    /// physical effect's (`saturation`), named in any realisation.
    pub effect: &'static str,
    pub runs: usize,
}

/// Every run of `--repeat repeats`: `d`, the diagnosis of `traces` that
/// `settings` asked for, then the same diagnosis from seeds `seed + 1` to
/// `seed + repeats − 1`. `progress` hears of each further run before it
/// starts. Fewer than two repeats: nothing to compare, an empty list.
pub fn repeat(
    d: &Diagnosis,
    traces: &[Trace],
    effects: &[Effect],
    settings: &Settings,
    from: Option<&Model>,
    repeats: usize,
    progress: &mut dyn FnMut(u64),
) -> anyhow::Result<Vec<SeedRun>> {
    if repeats < 2 {
        return Ok(Vec::new());
    }
    let mut runs = vec![SeedRun::of(d, settings.seed)];
    for i in 1..repeats as u64 {
        let seed = settings.seed.wrapping_add(i);
        progress(seed);
        let settings = Settings {
            seed,
            ..settings.clone()
        };
        let other = diagnose_from(traces, d.family, effects, &settings, from)?;
        runs.push(SeedRun::of(&other, seed));
    }
    Ok(runs)
}

/// How many of `runs` named each effect (`physical`: each physical effect,
/// in any realisation), most often named first, then by name.
pub fn named_counts(runs: &[SeedRun], physical: bool) -> Vec<NamedCount> {
    let mut counts: Vec<NamedCount> = Vec::new();
    for run in runs {
        let mut names: Vec<&'static str> = run
            .named
            .iter()
            .map(|e| {
                if physical {
                    e.physical().name()
                } else {
                    e.name()
                }
            })
            .collect();
        // A run that names two realisations of one effect counts once.
        names.sort_unstable();
        names.dedup();
        for name in names {
            match counts.iter_mut().find(|n| n.effect == name) {
                Some(n) => n.runs += 1,
                None => counts.push(NamedCount {
                    effect: name,
                    runs: 1,
                }),
            }
        }
    }
    counts.sort_by(|a, b| b.runs.cmp(&a.runs).then(a.effect.cmp(b.effect)));
    counts
}

/// How many of `runs` named `effect` in its realisation, and how many
/// named its physical effect in any realisation.
pub fn runs_naming(runs: &[SeedRun], effect: Effect) -> (usize, usize) {
    let count =
        |same: &dyn Fn(&Effect) -> bool| runs.iter().filter(|r| r.named.iter().any(same)).count();
    (
        count(&|e| *e == effect),
        count(&|e| e.physical() == effect.physical()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(seed: u64, named: &[&str]) -> SeedRun {
        let catalogue = Effect::by_default();
        SeedRun {
            seed,
            named: named
                .iter()
                .map(|n| *catalogue.iter().find(|e| e.name() == *n).unwrap())
                .collect(),
            kind: if named.is_empty() { "none" } else { "named" },
            baseline_selection_fit_percent: 90.0,
            baseline_test_fit_percent: 89.0,
            final_test_fit_percent: 95.0,
        }
    }

    #[test]
    fn effects_are_counted_once_a_run_by_realisation_and_by_physical_effect() {
        let runs = [
            run(1, &["saturation:output", "asymmetry", "deadzone"]),
            run(2, &["saturation:soft", "asymmetry"]),
            run(3, &["saturation:output", "saturation:soft"]),
            run(4, &[]),
        ];
        let by_name = named_counts(&runs, false);
        let count =
            |v: &[NamedCount], name: &str| v.iter().find(|n| n.effect == name).map(|n| n.runs);
        assert_eq!(count(&by_name, "saturation:output"), Some(2));
        assert_eq!(count(&by_name, "saturation:soft"), Some(2));
        assert_eq!(count(&by_name, "asymmetry"), Some(2));
        assert_eq!(count(&by_name, "deadzone"), Some(1));
        let physical = named_counts(&runs, true);
        assert_eq!(
            physical[0],
            NamedCount {
                effect: "saturation",
                runs: 3
            }
        );
        assert_eq!(count(&physical, "asymmetry"), Some(2));
        assert_eq!(count(&physical, "deadzone"), Some(1));
        assert_eq!(physical.len(), 3);
        // Most often first.
        assert!(by_name.windows(2).all(|w| w[0].runs >= w[1].runs));
        // One effect's support, in its realisation and in any.
        let output = runs[0].named[0];
        assert_eq!(runs_naming(&runs, output), (2, 3));
        assert_eq!(runs_naming(&runs, runs[0].named[2]), (1, 1));
    }
}
