//! What a user asks of a fit, reconciled with a warm start's model file:
//! the one place where `mckibben fit`'s flags and Python's `fit` keywords
//! become a family, its effects and a box.

use anyhow::Context as _;

use super::problem::Overshoot;
use super::run::FitTarget;
use crate::model::effects::Effect;
use crate::model::{Family, Loop, Model, ModelFile, Switching, UserBound};

/// A fit as asked for, before the start model fills in what was not given
/// (`fit --from`, Python's `start=`).
#[derive(Debug, Clone, PartialEq)]
pub struct FitRequest {
    /// The family (`None`: the start model's, else classic).
    pub family: Option<Family>,
    /// The effects after the family (`None`: the start model's, else none).
    pub effects: Option<Vec<Effect>>,
    /// Also fit the Bouc-Wen exponent n.
    pub free_n: bool,
    pub loop_shape: Loop,
    /// `None`: the default (search; a warm start's level held).
    pub switching: Option<Switching>,
    /// `None`: admitted ([`Overshoot`]'s default).
    pub overshoot: Option<Overshoot>,
    /// The user's bounds and fixed values, after the start file's (so that
    /// these win).
    pub bounds: Vec<UserBound>,
    /// The start model is carried, not a warm start (`fit --carry`,
    /// Python's `carry=`): its chain is fitted from scratch with its
    /// effects' dynamics held at its values ([`Model::held_dynamics`]).
    pub carry: bool,
}

/// A request reconciled with its start: what is fitted, and the model the
/// fit starts from, if any, or the model whose chain it carries.
#[derive(Debug, Clone)]
pub struct Resolved {
    pub what: FitTarget,
    pub start: Option<Model>,
    /// The carried model: the data must have its sample time, since the
    /// held poles are per sample ([`Model::check_data`]).
    pub carried: Option<Model>,
}

impl FitRequest {
    /// The fit `self` asks for from `start`: the family, effects and bounds
    /// not given here are the start model's, and the start file's own user
    /// bounds come first. Errors name the start file's part that is wrong.
    pub fn resolve(&self, start: Option<&ModelFile>) -> anyhow::Result<Resolved> {
        let model = start.map(|f| f.model()).transpose()?;
        if let Some(m) = &model {
            let theirs = m.base.family;
            anyhow::ensure!(
                theirs != Family::Linear,
                "the model is linear (`identify`'s), and a fit starts only from a classic or \
                 generalized model: fit without it (the fit's box is built around the same \
                 first-order ARX model)"
            );
            // A warm start's vector is the model's own parameters; the
            // families share no exact map (the classic's γ is a constant
            // weight the generalized sign terms lack). A carried chain is
            // fitted from scratch, so any family may carry it.
            if let Some(asked) = self.family.filter(|f| *f != theirs && !self.carry) {
                anyhow::bail!(
                    "the model is {} and a warm start keeps its family: --model {} would start \
                     from another family's parameters; leave --model out, or fit without a start",
                    theirs.name(),
                    asked.name()
                );
            }
        }
        let family = match (self.family, &model) {
            (Some(f), _) => f,
            (None, Some(m)) => m.base.family,
            (None, None) => Family::Classic,
        };
        let effects = match (&self.effects, &model) {
            (Some(e), _) => e.clone(),
            (None, Some(m)) => m.effects().to_vec(),
            (None, None) => Vec::new(),
        };
        let mut bounds: Vec<UserBound> = match start {
            Some(f) => f
                .user_bounds
                .iter()
                .map(|b| b.parse().map_err(anyhow::Error::msg))
                .collect::<anyhow::Result<_>>()
                .context("its user_bounds")?,
            None => Vec::new(),
        };
        bounds.extend(self.bounds.iter().cloned());
        let (start, carried) = if self.carry {
            let model = model.context("a carried chain needs the model that carries it")?;
            // Held first, so that the user's own bounds win.
            bounds.splice(0..0, model.held_dynamics(&effects));
            (None, Some(model))
        } else {
            (model, None)
        };
        // Later entries win (the user's over the start file's, those over
        // the carried dynamics): only the last of each name is kept, so that
        // the model file written records the bounds that held.
        let mut named = std::collections::HashSet::new();
        bounds.reverse();
        bounds.retain(|b| named.insert(b.name.clone()));
        bounds.reverse();
        anyhow::ensure!(
            start.is_none() || self.switching != Some(Switching::Starts),
            "--switch starts runs two fresh fits, and a warm start is one fit from its model: \
             give search, mean or zero, or fit without a start"
        );
        Ok(Resolved {
            what: FitTarget {
                family,
                effects,
                free_n: self.free_n,
                loop_shape: self.loop_shape,
                switching: self.switching,
                overshoot: self.overshoot,
                bounds,
            },
            start,
            carried,
        })
    }
}

/// Why a switching level asked for (`fit --switch`, Python's `switch=`)
/// does not apply to a fit of `family`: only the generalized model's sign
/// terms switch, and a level given to another family would be ignored
/// without a word.
pub fn switching_misapplied(family: Family, asked: Option<Switching>) -> Option<String> {
    let asked = asked.filter(|_| family != Family::Generalized)?;
    Some(format!(
        "{}: the switching level belongs to the generalized model's sign terms, and this fit \
         is {}",
        format!("{asked:?}").to_lowercase(),
        family.name()
    ))
}

/// Why a switching level asked for (`fit --switch`, Python's `switch=`)
/// contradicts the user's own box on that level (`--fix x_s=…`,
/// `--bound x_s=…`, Python's `fix=`/`bounds=`): both say where the level
/// lies, and one would be dropped without a word.
pub fn switching_boxed(asked: Option<Switching>, bounds: &[UserBound]) -> Option<String> {
    let asked = asked?;
    let level = Family::Generalized.params()[Family::Generalized.switch_index()?].name;
    let boxed = bounds.iter().find(|b| b.name == level)?;
    Some(format!(
        "{}: the switching level is searched or held by it, and also boxed by `{boxed}`",
        format!("{asked:?}").to_lowercase()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::problem::FitProblem;
    use crate::fit::synthetic::Synthetic;
    use crate::model::file::Provenance;

    /// A generalized model with a creep, saved with a user bound on α.
    fn saved() -> ModelFile {
        let s = Synthetic::new(Family::Generalized, 600, 0.05, 2);
        let problem = FitProblem::new(
            &s.trace,
            Family::Generalized,
            crate::model::Flow::Joint,
            None,
            false,
        )
        .unwrap()
        .with_effects(&[Effect::Creep], &[])
        .unwrap();
        let theta = problem.neutral_effects(&crate::model::coords::gauge_fixed(
            Family::Generalized,
            &s.truth,
        ));
        let mut file = ModelFile::new(&problem.fitted_model(&theta), None, Provenance::default());
        file.user_bounds = vec!["alpha=0.2:0.6".to_string()];
        file
    }

    fn asked() -> FitRequest {
        FitRequest {
            family: None,
            effects: None,
            free_n: false,
            loop_shape: Loop::Bounded,
            switching: None,
            overshoot: None,
            bounds: Vec::new(),
            carry: false,
        }
    }

    /// A switching level given to a family without sign terms is named;
    /// none given, or the generalized family, is not.
    #[test]
    fn a_switching_level_applies_to_the_generalized_family_only() {
        let why = switching_misapplied(Family::Classic, Some(Switching::Zero)).unwrap();
        assert!(
            why.starts_with("zero: ") && why.ends_with("this fit is classic"),
            "{why}"
        );
        assert_eq!(switching_misapplied(Family::Classic, None), None);
        // A level asked for and boxed by the user is a contradiction; either
        // alone is not.
        let fixed = [UserBound {
            name: "x_s".into(),
            lower: 1.0,
            upper: 1.0,
        }];
        let why = switching_boxed(Some(Switching::Zero), &fixed).unwrap();
        assert!(why.starts_with("zero:") && why.contains("x_s=1"), "{why}");
        assert_eq!(switching_boxed(None, &fixed), None);
        assert_eq!(switching_boxed(Some(Switching::Zero), &[]), None);
        assert_eq!(
            switching_misapplied(Family::Generalized, Some(Switching::Starts)),
            None
        );
    }

    #[test]
    fn a_carried_model_lends_its_chain_and_its_dynamics_not_a_start() {
        let file = saved();
        let mut request = asked();
        request.carry = true;
        request.bounds = vec!["creep.rho=0.99".parse().unwrap()];
        let r = request.resolve(Some(&file)).unwrap();
        assert!(r.start.is_none() && r.carried.is_some());
        assert_eq!(r.what.effects, [Effect::Creep]);
        let rho = file.model().unwrap().named_params()[..]
            .iter()
            .find(|(n, _)| n == "creep.rho")
            .unwrap()
            .1;
        let bounds: Vec<String> = r.what.bounds.iter().map(|b| b.to_string()).collect();
        // The file's and the user's bounds win over the held dynamics: the
        // user's value of `creep.rho` replaces the held one.
        assert_eq!(
            bounds,
            ["alpha=0.2:0.6".to_string(), "creep.rho=0.99".to_string()]
        );
        let mut unasked = request.clone();
        unasked.bounds.clear();
        let held = unasked.resolve(Some(&file)).unwrap().what.bounds;
        assert!(held.contains(&format!("creep.rho={rho}").parse().unwrap()));
        assert!(request.resolve(None).is_err(), "nothing to carry");
    }

    #[test]
    fn what_is_not_asked_for_comes_from_the_start_and_what_is_asked_wins() {
        let file = saved();
        let r = asked().resolve(Some(&file)).unwrap();
        assert_eq!(r.what.family, Family::Generalized);
        assert_eq!(r.what.effects, vec![Effect::Creep]);
        assert_eq!(r.what.bounds, vec!["alpha=0.2:0.6".parse().unwrap()]);
        assert!(r.start.is_some());
        // Given here: the family (its own), no effects, and a bound after
        // the file's.
        let mut request = asked();
        request.family = Some(Family::Generalized);
        request.effects = Some(Vec::new());
        request.bounds = vec!["alpha=0.3".parse().unwrap()];
        let r = request.resolve(Some(&file)).unwrap();
        assert_eq!(
            (r.what.family, r.what.effects.len()),
            (Family::Generalized, 0)
        );
        // The user's `alpha` replaces the file's: one entry, which the model
        // file written records (it kept both).
        assert_eq!(r.what.bounds, vec!["alpha=0.3".parse().unwrap()]);
        // Another family: the start's parameters mean nothing there.
        request.family = Some(Family::Classic);
        let e = format!("{:#}", request.resolve(Some(&file)).unwrap_err());
        assert!(
            e.contains("the model is generalized and a warm start keeps its family"),
            "{e}"
        );
        // Carried, the chain is fitted from scratch: any family.
        request.carry = true;
        let r = request.resolve(Some(&file)).unwrap();
        assert_eq!(r.what.family, Family::Classic);
        // Without a start: classic, no effects, the bounds as given.
        let r = asked().resolve(None).unwrap();
        assert_eq!((r.what.family, r.what.effects.len()), (Family::Classic, 0));
        assert!(r.start.is_none() && r.what.bounds.is_empty());
    }

    #[test]
    fn a_start_file_with_a_broken_bound_is_an_error_that_names_it() {
        let mut file = saved();
        file.user_bounds = vec!["alpha=oops".to_string()];
        let e = format!("{:#}", asked().resolve(Some(&file)).unwrap_err());
        assert!(e.starts_with("its user_bounds: "), "{e}");
    }
}
