//! Whether the diagnosed chain belongs to the muscle or to one recording
//! (`diagnose --transfer OTHER …`): the final model's chain is carried to
//! another record as `fit --carry MODEL` carries it (its effects with their
//! dynamics, the poles, delays and how fast steps fall, held at the
//! diagnosed values; the baseline and the effects' sizes fitted on the
//! record's estimation half alone, with `fit`'s defaults and the
//! diagnosis' seed), the plain baseline is fitted as `fit` fits it, and
//! both are scored on that record's second half. No choice of the
//! diagnosis saw that record, so the share of the baseline's gap the chain
//! closes there is the tool's own check that an effect carries over. The
//! chain refitted from its names alone (`fit --effects CHAIN`) is reported
//! beside it. Where the chain collapses, its leading links are carried
//! alone, one link fewer at a time, to name the first link that does not.
//!
//! Why the dynamics are held: another record of the same muscle differs
//! in its load, its history and its offsets, which set the sizes, but a
//! slow state's time constant is the muscle's. An estimation half of two
//! loadings pins a gain and hardly a pole slower than the record: refitted
//! from names alone, a ratchet's walk or a creep's pole runs wherever that
//! half lets it, and the chain validates below the plain fit on records
//! where, carried, it holds (docs/RESULTS.md, "Transfers between
//! loads").

use anyhow::Context as _;
use serde::Serialize;

use super::effects::Effect;
use super::locate::noise_floor;
use super::settings::{Interrupted, Settings};
use super::{Diagnosis, accept::gap_closed, chain::with_chain_start};
use crate::data::{Trace, same_samples, same_step, tidy_step, units};
use crate::fit::edge::{ActiveBound, active_bounds};
use crate::fit::records::Validation;
use crate::fit::run::{FitRun, FitTarget};
use crate::fit::settings::FitSettings;
use crate::model::experiment::halves;
use crate::model::file::check_units;
use crate::model::{Family, UserBound};
use crate::optim::engine::Outcome;

/// The chain and the baseline fitted on one other record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Transfer {
    /// The record.
    pub dataset: String,
    /// The effects fitted there: the final model's, less those one record
    /// cannot hold (`load` needs several).
    pub chain: Vec<Effect>,
    /// The chain's dynamics held there (`fit --carry`).
    pub dynamics_held: Vec<Held>,
    /// Free-run RMSE and fit % on the record's second half: the plain
    /// baseline's (`fit`) and the carried chain's (`fit --carry`).
    pub baseline_val_rmse: f64,
    pub baseline_val_fit_percent: f64,
    pub chain_val_rmse: f64,
    pub chain_val_fit_percent: f64,
    /// Fit % on the second half of the chain refitted from its names alone
    /// (`fit --effects CHAIN`, its dynamics fitted on the record's first
    /// half too): below the carried chain's, the record's first half does
    /// not pin the chain's dynamics.
    pub names_only_val_fit_percent: f64,
    /// The record's noise floor, from its second half.
    pub noise_floor_rmse: f64,
    /// Share of the baseline's gap above that floor the chain closes there.
    pub gap_closed: f64,
    /// Whether the chain collapses there: it validates below the plain
    /// baseline, or its fit has no finite score at all.
    pub collapses: bool,
    /// Where it collapses, the longest leading part of the chain that does
    /// not: the links before the one that holds the diagnosed recording.
    /// `None` where the chain holds, or where even its first link
    /// collapses.
    pub carries: Option<Carried>,
    /// The chain's own parameters that its fit on this record left on or
    /// near an edge of their box: how far the record's first half pushed an
    /// effect (a creep's gain at its limit, a ratchet walking at a steady
    /// rate), where to look first when the chain collapses.
    pub chain_on_edge: Vec<ActiveBound>,
}

/// One parameter held at its diagnosed value, as `--fix param=value`
/// holds it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Held {
    pub param: String,
    pub value: f64,
}

/// The leading links of a chain that carry over to a record, and their fit
/// % on its second half.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Carried {
    pub effects: Vec<Effect>,
    pub val_fit_percent: f64,
}

/// The longest proper leading part of `chain` whose fit % (`score`) does
/// not collapse against the plain baseline's `baseline_fit_percent`,
/// shortest last: a chain that collapses is cut one link at a time from
/// its end, as the diagnosis added them, until what is left holds.
pub fn longest_carried(
    chain: &[Effect],
    baseline_fit_percent: f64,
    mut score: impl FnMut(&[Effect]) -> anyhow::Result<f64>,
) -> anyhow::Result<Option<Carried>> {
    for len in (1..chain.len()).rev() {
        let fit_percent = score(&chain[..len])?;
        if !collapses(fit_percent, baseline_fit_percent) {
            return Ok(Some(Carried {
                effects: chain[..len].to_vec(),
                val_fit_percent: fit_percent,
            }));
        }
    }
    Ok(None)
}

/// Whether a chain that validates at `chain_fit_percent` on a record
/// whose plain baseline validates at `baseline_fit_percent` collapses
/// there: below the baseline, or not finite (a fit that diverges on the
/// second half).
pub fn collapses(chain_fit_percent: f64, baseline_fit_percent: f64) -> bool {
    // NaN on either side compares as neither: a collapse.
    chain_fit_percent
        .partial_cmp(&baseline_fit_percent)
        .is_none_or(|o| o.is_lt())
}

/// Whether each record of `others` can take the chain that a diagnosis
/// of `diagnosed` will carry to it, as [`transfer`] will: another record
/// (not one of `diagnosed`'s, which would score the chain on what chose
/// it), sampled at their step (the held poles are per sample), in units
/// of the same kinds as theirs where both name one (the held dynamics are
/// pure numbers, and the rest is fitted on the record in its own units,
/// so kPa carries what psi chose; a valve voltage is another signal), and
/// one on which the baseline of `family` can be fitted (long enough, a
/// response to identify, numbers a fit can take). Checked before the diagnosis, so that a record it cannot use
/// fails at once rather than after the diagnosis' minutes. No search
/// runs.
pub fn check_others(
    family: Family,
    diagnosed: &[Trace],
    others: &[Trace],
    settings: &Settings,
) -> anyhow::Result<()> {
    let Some(first) = diagnosed.first() else {
        return Ok(());
    };
    let dt = first.dt();
    for other in others {
        if let Some(own) = diagnosed.iter().find(|t| same_samples(t, other)) {
            anyhow::bail!(
                "{}: it holds the samples of {}, which the diagnosis reads: a transfer scores \
                 the chain on another record; give one",
                other.source,
                own.source
            );
        }
        anyhow::ensure!(
            same_step(other.dt(), dt),
            "{}: sampled every {} s, the diagnosed record every {} s; the model's poles are \
             per sample, so resample it (--resample {})",
            other.source,
            tidy_step(other.dt()),
            tidy_step(dt),
            tidy_step(dt)
        );
        // A side in another unit of the same kind reads as the diagnosed
        // record's for the check: only another kind is refused.
        let like = |column: &String, diagnosed: &String, size| {
            let convertible = units::between(column, diagnosed, size).is_some();
            if convertible { diagnosed } else { column }.clone()
        };
        check_units(
            "the diagnosed record's",
            &first.input_name,
            &first.output_name,
            &Trace {
                input_name: like(&other.input_name, &first.input_name, units::megapascals_in),
                output_name: like(
                    &other.output_name,
                    &first.output_name,
                    units::millimetres_in,
                ),
                ..other.clone()
            },
        )?;
        FitRun::new(
            std::slice::from_ref(other),
            &FitTarget::chain(family, &[]),
            &FitSettings::staged(settings.seed),
            None,
            None,
            &|_| (),
        )
        .with_context(|| format!("the transfer to {}", other.source))?;
    }
    Ok(())
}

/// The chain of `d`'s final model carried to every record of `others` and
/// its baseline fitted there, each scored on the record's second half; the
/// diagnosis' `settings` give the seed, the backend and the stop flag
/// ([`Interrupted`] once it is raised). A record with another sample time
/// is an error: the held poles are per sample.
pub fn transfer(
    d: &Diagnosis,
    others: &[Trace],
    settings: &Settings,
) -> anyhow::Result<Vec<Transfer>> {
    let chain: Vec<Effect> = d
        .selection
        .final_model
        .effects
        .iter()
        .copied()
        .filter(|e| e.applicable(1))
        .collect();
    let held = |links: &[Effect]| d.final_model.held_dynamics(links);
    let chain_held = held(&chain);
    let dynamics_held: Vec<Held> = chain_held
        .iter()
        .map(|b| Held {
            param: b.name.clone(),
            value: b.lower,
        })
        .collect();
    others
        .iter()
        .map(|trace| {
            d.final_model
                .check_carried_to(trace)
                .with_context(|| format!("the transfer to {}", trace.source))?;
            let (baseline, _) = fit_and_score(trace, d.family, &[], &[], settings)?;
            let (fitted, chain_on_edge, names_only) = if chain.is_empty() {
                (baseline, Vec::new(), baseline.fit_percent)
            } else {
                let (fitted, on_edge) =
                    fit_and_score(trace, d.family, &chain, &chain_held, settings)?;
                let names_only = fit_and_score(trace, d.family, &chain, &[], settings)?.0;
                (fitted, on_edge, names_only.fit_percent)
            };
            let second = halves(trace.len()).1;
            let floor = noise_floor(&[&trace.output[second]]);
            let collapsed = collapses(fitted.fit_percent, baseline.fit_percent);
            let carries = if collapsed {
                longest_carried(&chain, baseline.fit_percent, |links| {
                    Ok(
                        fit_and_score(trace, d.family, links, &held(links), settings)?
                            .0
                            .fit_percent,
                    )
                })?
            } else {
                None
            };
            Ok(Transfer {
                dataset: trace.source.clone(),
                chain: chain.clone(),
                dynamics_held: dynamics_held.clone(),
                baseline_val_rmse: baseline.rmse,
                baseline_val_fit_percent: baseline.fit_percent,
                chain_val_rmse: fitted.rmse,
                chain_val_fit_percent: fitted.fit_percent,
                names_only_val_fit_percent: names_only,
                noise_floor_rmse: floor,
                gap_closed: gap_closed(baseline.rmse, fitted.rmse, floor),
                collapses: collapsed,
                carries,
                chain_on_edge,
            })
        })
        .collect()
}

/// Of a fit's bounds still active at its end, those of the chain's own
/// parameters (`names`), not the baseline's.
fn chain_params_on_edge(names: &[String], on_edge: Vec<ActiveBound>) -> Vec<ActiveBound> {
    on_edge
        .into_iter()
        .filter(|b| names.contains(&b.param))
        .collect()
}

/// `family` with `effects` fitted on `trace` as `fit` fits it by default
/// (with effects: also from the chain built one effect at a time), with
/// the parameters in `held` held there as `--fix` holds them, scored on
/// the second half, with the bounds its chain's parameters ended on.
fn fit_and_score(
    trace: &Trace,
    family: Family,
    effects: &[Effect],
    held: &[UserBound],
    settings: &Settings,
) -> anyhow::Result<(Validation, Vec<ActiveBound>)> {
    let fit_settings = FitSettings::staged(settings.seed);
    let what = FitTarget {
        bounds: held.to_vec(),
        ..FitTarget::chain(family, effects)
    };
    let traces = std::slice::from_ref(trace);
    let fit = FitRun::new(traces, &what, &fit_settings, None, None, &|_| ())?;
    let fit = with_chain_start(
        fit,
        traces,
        &fit_settings,
        settings.backend,
        settings.stop.clone(),
    )?;
    let (fit, outcome) = run_stoppable(fit, settings)?;
    let model = &fit.problem.model;
    let on_edge = chain_params_on_edge(
        &model.param_names()[model.family.dim()..],
        active_bounds(&fit.problem, &outcome.params),
    );
    Ok((fit.problem.validate(&outcome.params), on_edge))
}

/// Runs `fit` on the settings' backend, stopping with the diagnosis' stop
/// flag: a fit the diagnosis makes as `mckibben fit` would. Returns the fit
/// as it ended (its box widened by the edge rule) and its outcome.
pub(crate) fn run_stoppable(fit: FitRun, settings: &Settings) -> anyhow::Result<(FitRun, Outcome)> {
    let mut fit = fit;
    let mut evaluator = crate::eval::open(settings.backend)?;
    let (outcome, _) = fit.run(
        evaluator.as_mut(),
        &mut [],
        Some(settings.stop.as_atomic()),
        None,
    )?;
    if settings.stop.raised() {
        return Err(Interrupted.into());
    }
    Ok((fit, outcome))
}

#[cfg(test)]
mod tests {
    use super::{ActiveBound, Effect, chain_params_on_edge, collapses, longest_carried};
    use crate::model::bounds::Origin;
    use crate::search::Side;

    #[test]
    fn only_the_chains_own_parameters_on_an_edge_are_kept() {
        let bound = |param: &str| ActiveBound {
            param: param.into(),
            bound: Side::Lower,
            origin: Origin::Class,
            inside: 0.0,
        };
        let on_edge = vec![
            bound("alpha"),
            bound("creep.kappa"),
            bound("set:ratchet.q"),
            bound("softening.s"),
        ];
        let chain: Vec<String> = [
            "creep.rho",
            "creep.kappa",
            "creep.z0",
            "set:ratchet.a",
            "set:ratchet.q",
        ]
        .map(String::from)
        .to_vec();
        let kept = chain_params_on_edge(&chain, on_edge);
        let names: Vec<&str> = kept.iter().map(|b| b.param.as_str()).collect();
        assert_eq!(names, ["creep.kappa", "set:ratchet.q"]);
    }

    #[test]
    fn a_collapsing_chain_is_cut_from_its_end_until_what_is_left_holds() {
        let chain = [Effect::Creep, Effect::Inertia, Effect::Set];
        // Only the first link holds on this record (plain fit 60 %).
        let mut tried = Vec::new();
        let carried = longest_carried(&chain, 60.0, |links| {
            tried.push(links.len());
            Ok(if links.len() == 1 { 75.0 } else { 10.0 })
        })
        .unwrap()
        .unwrap();
        assert_eq!(carried.effects, [Effect::Creep]);
        assert_eq!(carried.val_fit_percent, 75.0);
        // The longest part first, and the whole chain never again.
        assert_eq!(tried, [2, 1]);
        // Where even the first link collapses, nothing carries over.
        assert_eq!(
            longest_carried(&chain, 60.0, |_| Ok(f64::NAN)).unwrap(),
            None
        );
    }

    #[test]
    fn a_chain_below_the_plain_fit_or_without_a_score_collapses() {
        assert!(!collapses(88.0, 80.0));
        assert!(!collapses(80.0, 80.0));
        assert!(collapses(79.9, 80.0));
        assert!(collapses(-10.0, 86.0));
        assert!(collapses(f64::NAN, 80.0));
    }
}
