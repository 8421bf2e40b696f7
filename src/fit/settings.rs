//! What a fresh fit runs, as `mckibben fit` asks for it: the algorithm's
//! settings with the user's overrides laid over them, checked; the plan
//! and its tries; the stop rules; and where the run starts, fresh, warm
//! from a model or resumed from a checkpoint.
//!
//! The settings carry `fit`'s flags one for one and every error names the
//! flag it is about, so that the command only parses, calls and prints.

use std::path::Path;

use super::chart::ModelChart;
use super::objective::{
    GENERATIONS, POPULATION, SMALL_TRY_POPULATION, TRY_POPULATION, groups_of, staged_plan,
    tries_text, try_population, try_populations,
};
use super::problem::FitProblem;
use crate::model::{Family, Measure};
use crate::optim::engine::generations_refused;
use crate::optim::engine::{Engine, Plan, StopRules};
use crate::optim::ga::{Crossover, Mutation};
use crate::optim::mfa::{self, Distance, Lambda0Schedule, Scale};
use crate::optim::stage::Stage;
use crate::optim::{AlgoSettings, Algorithm, Streams, ThesisModel};

/// The most refining rounds a fit may ask for (`fit --refine-rounds`).
pub const MAX_REFINE_ROUNDS: usize = 100;

/// The largest population a fit takes: 10⁸ candidates of a generalized
/// model are 11 GB of rows before any copy, past what a machine that runs
/// this tool is likely to hold; a larger `--pop` is a typo or a wrap.
pub const MAX_POPULATION: usize = 100_000_000;

/// Settings of one algorithm laid over its base settings (`None`, `false`:
/// keep the base). Each acts on its own algorithm only, but every one given
/// is checked whatever the algorithm.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// GA crossover (`--crossover`).
    pub crossover: Option<Crossover>,
    /// GA: best individuals kept unchanged (`--elitism`).
    pub elitism: Option<usize>,
    /// GA: mutation probability (`--p-mut`).
    pub p_mut: Option<f64>,
    /// GA: mutation operator (`--mutation`).
    pub mutation: Option<Mutation>,
    /// MFA: Λ0 schedule (`--mfa-lambda0`).
    pub mfa_lambda0: Option<Lambda0Schedule>,
    /// MFA: attractiveness against distance (`--mfa-distance`).
    pub mfa_distance: Option<Distance>,
    /// MFA: units of distances and walk (`--mfa-scale`).
    pub mfa_scale: Option<Scale>,
    /// MFA: attractors a firefly moves towards, 0 for all (`--mfa-attractors`).
    pub mfa_attractors: Option<usize>,
    /// MFA: the brightest attractors instead of random ones (`--mfa-brightest`).
    pub mfa_brightest: bool,
    /// MFA: start of the random walk's schedule (`--mfa-rho0`).
    pub mfa_rho0: Option<f64>,
    /// DE: share of the population x_pbest is drawn from (`--de-p-best`).
    pub de_p_best: Option<f64>,
    /// PSO: one random number for the social term (`--pso-scalar-social`).
    pub pso_scalar_social: bool,
}

impl Overrides {
    /// The algorithm-specific flags given, each with the algorithm it tunes.
    fn given(&self) -> Vec<(&'static str, Algorithm)> {
        use Algorithm::{De, Ga, Mfa, Pso};
        [
            (self.crossover.is_some(), "--crossover", Ga),
            (self.elitism.is_some(), "--elitism", Ga),
            (self.p_mut.is_some(), "--p-mut", Ga),
            (self.mutation.is_some(), "--mutation", Ga),
            (self.mfa_lambda0.is_some(), "--mfa-lambda0", Mfa),
            (self.mfa_distance.is_some(), "--mfa-distance", Mfa),
            (self.mfa_scale.is_some(), "--mfa-scale", Mfa),
            (self.mfa_attractors.is_some(), "--mfa-attractors", Mfa),
            (self.mfa_brightest, "--mfa-brightest", Mfa),
            (self.mfa_rho0.is_some(), "--mfa-rho0", Mfa),
            (self.de_p_best.is_some(), "--de-p-best", De),
            (self.pso_scalar_social, "--pso-scalar-social", Pso),
        ]
        .into_iter()
        .filter(|(given, _, _)| *given)
        .map(|(_, flag, algo)| (flag, algo))
        .collect()
    }
}

/// The thesis' model whose settings a fit of `family` takes in the thesis'
/// flow: the generalized model's for the generalized family, the classic
/// model's for the others.
pub fn thesis_model(family: Family) -> ThesisModel {
    match family {
        Family::Generalized => ThesisModel::Generalized,
        Family::Classic | Family::Linear => ThesisModel::Classic,
    }
}

/// What a fresh fit runs: the algorithm, its size and seed, the flow, the
/// staged fit's knobs and the stop rules.
#[derive(Debug, Clone, PartialEq)]
pub struct FitSettings {
    /// Update rule of the population search (`--algo`).
    pub algo: Algorithm,
    /// Population of the global stage (`--pop`).
    pub pop: usize,
    /// Generations of the global stage (`--gens`).
    pub gens: usize,
    pub seed: u64,
    /// The thesis' flow: one search on the free run with the thesis'
    /// settings (`--thesis-flow`), instead of the staged fit.
    pub thesis_flow: bool,
    /// Islands of the staged fit's global stage (`--islands`).
    pub islands: Option<usize>,
    /// Prediction horizon of the staged fit's global stage (`--horizon`).
    pub horizon: Option<usize>,
    /// Most refining rounds of a generalized fit (`--refine-rounds`;
    /// default [`crate::optim::engine::Refine::DEFAULT_ROUNDS`]).
    pub refine_rounds: Option<usize>,
    pub overrides: Overrides,
    /// `--target-sse`, `--time-budget`, `--stall`.
    pub stops: StopRules,
}

impl FitSettings {
    /// `mckibben fit`'s defaults: the staged fit with differential
    /// evolution at [`POPULATION`] and [`GENERATIONS`], no overrides, no
    /// early stop.
    pub fn staged(seed: u64) -> FitSettings {
        FitSettings {
            algo: Algorithm::De,
            pop: POPULATION,
            gens: GENERATIONS,
            seed,
            thesis_flow: false,
            islands: None,
            horizon: None,
            refine_rounds: None,
            overrides: Overrides::default(),
            stops: StopRules::default(),
        }
    }

    /// The base settings (the thesis' or the staged fit's) with the
    /// overrides laid over them; `note` hears of a rule applied unasked.
    fn algo_settings(&self, family: Family, note: &dyn Fn(String)) -> anyhow::Result<AlgoSettings> {
        let o = &self.overrides;
        let mut s = if self.thesis_flow {
            self.algo.thesis_settings(thesis_model(family))
        } else {
            self.algo.staged_settings(self.pop)
        };
        // Every override is checked whatever the algorithm; each only acts on its own.
        if let Some(p) = o.p_mut {
            anyhow::ensure!(
                (0.0..=1.0).contains(&p),
                "--p-mut must be a probability in [0, 1] (got {p})"
            );
        }
        if let Some(e) = o.elitism {
            anyhow::ensure!(e < self.pop, "--elitism must be below --pop (got {e})");
        }
        if let Some(r) = o.mfa_rho0 {
            anyhow::ensure!(
                r.is_finite() && r >= 0.0,
                "--mfa-rho0 must be a finite step size ≥ 0 (got {r})"
            );
        }
        if let Some(p) = o.de_p_best {
            anyhow::ensure!(
                p > 0.0 && p <= 1.0,
                "--de-p-best must be in (0, 1] (got {p})"
            );
        }
        // A flag of another algorithm would be ignored: say so rather than
        // run something other than what the user asked for.
        if let Some((flag, algo)) = o.given().into_iter().find(|&(_, a)| a != self.algo) {
            anyhow::bail!(
                "{flag} tunes --algo {algo}, but this fit runs --algo {}: drop {flag} \
                 or add --algo {algo}",
                self.algo
            );
        }
        if let AlgoSettings::Ga(ga) = &mut s {
            if let Some(p) = o.p_mut {
                ga.p_mut = p;
            }
            if let Some(c) = o.crossover {
                ga.crossover = c;
            }
            if let Some(e) = o.elitism {
                ga.elitism = e;
            }
            if let Some(m) = o.mutation {
                ga.mutation = m;
            }
        }
        if let AlgoSettings::Mfa(m) = &mut s {
            if let Some(l) = o.mfa_lambda0 {
                m.lambda0 = l;
            }
            if let Some(d) = o.mfa_distance {
                m.distance = d;
            }
            if let Some(sc) = o.mfa_scale {
                m.scale = sc;
            }
            if let Some(k) = o.mfa_attractors {
                m.max_attractors = (k > 0).then_some(k);
            } else if self.thesis_flow && self.pop > mfa::ALL_PAIRS_MAX {
                m.towards_brightest();
                note(format!(
                    "the MFA's all-pairs move is O(N²·d) and takes over a second a \
                     generation above N = {}; moving each firefly towards the {} \
                     brightest instead (--mfa-attractors 0 for all pairs)",
                    mfa::ALL_PAIRS_MAX,
                    mfa::BRIGHTEST
                ));
            }
            if o.mfa_brightest {
                m.attractors = mfa::Attractors::Brightest;
            }
            if let Some(r) = o.mfa_rho0 {
                m.rho0 = r;
            }
        }
        if let AlgoSettings::Pso(pso) = &mut s
            && o.pso_scalar_social
        {
            pso.scalar_social = true;
        }
        if let (AlgoSettings::De(de), Some(p)) = (&mut s, o.de_p_best) {
            de.p_best = p;
        }
        Ok(s)
    }

    /// The plan of a fresh fit of `problem`.
    fn plan(&self, problem: &FitProblem, note: &dyn Fn(String)) -> anyhow::Result<Plan> {
        let min = self.algo.min_population();
        anyhow::ensure!(
            self.pop >= min,
            "--pop must be at least {min} for --algo {} (got {})",
            self.algo,
            self.pop
        );
        anyhow::ensure!(
            self.pop <= MAX_POPULATION,
            "--pop {}: at most {MAX_POPULATION} candidates (their rows alone would take {:.0} GB \
             here)",
            self.pop,
            self.pop as f64 * problem.model.dim() as f64 * 8.0 / 1e9
        );
        if let Some(why) = generations_refused(self.gens) {
            anyhow::bail!("--gens {}: {why}", self.gens);
        }
        // As `staged_plan` decides; the thesis' flow has no refining.
        let refined = !self.thesis_flow && problem.model.family.switch_index().is_some();
        if let Some(why) = super::memory::too_large(self.pop, refined, self.algo) {
            anyhow::bail!(why);
        }
        let settings = self.algo_settings(problem.model.family, note)?;
        if self.thesis_flow {
            return Ok(Plan::thesis(settings, self.pop, self.gens));
        }
        let populations = try_populations(self.pop);
        let ran: usize = populations.iter().sum();
        if ran != self.pop {
            note(format!(
                "--pop {} runs {ran} candidates ({}): from {} on, a population is whole tries, \
                 in a fixed order of tries of {TRY_POPULATION} and {SMALL_TRY_POPULATION} (the \
                 next one holds {})",
                self.pop,
                tries_text(&groups_of(&populations)),
                2 * TRY_POPULATION,
                try_populations(self.pop + TRY_POPULATION)[populations.len()]
            ));
        }
        let mut plan = staged_plan(problem, settings, self.pop, self.gens);
        if let Some(rounds) = self.refine_rounds {
            let refine = plan.refine.as_mut().ok_or_else(|| {
                anyhow::anyhow!(
                    "--refine-rounds: only a generalized fit is refined (its switching level \
                     makes ledges the polish stops on); the {} model's polish ends in its \
                     valley's floor",
                    problem.model.family
                )
            })?;
            // The plan lists every round's steps up front: a count past
            // any run's needs is a typo, not a longer fit.
            anyhow::ensure!(
                rounds <= MAX_REFINE_ROUNDS,
                "--refine-rounds {rounds}: at most {MAX_REFINE_ROUNDS} (a round takes about a \
                 tenth of the default fit's time)"
            );
            refine.rounds = rounds;
        }
        if let Some(global) = plan.global.as_mut() {
            if let Some(k) = self.islands {
                anyhow::ensure!(k >= 1, "--islands must be at least 1");
                let n = global.population;
                anyhow::ensure!(
                    n / k >= min,
                    "--islands {k} leaves {} individuals an island of a try of {n} (--pop {}); \
                     --algo {} needs at least {min}",
                    n / k,
                    self.pop,
                    self.algo
                );
                global.islands = k;
            }
            if let Some(h) = self.horizon {
                // Beyond the shortest estimation half a prediction is a free
                // run of the whole half: the horizon then means nothing.
                let shortest = problem
                    .records
                    .est
                    .iter()
                    .map(|e| e.len())
                    .min()
                    .unwrap_or(0);
                anyhow::ensure!(
                    (1..shortest).contains(&h),
                    "--horizon {h}: a prediction horizon is 1 to {} samples here (the \
                     shortest estimation half has {shortest})",
                    shortest.saturating_sub(1)
                );
                global.measure = Measure::Ahead { horizon: h };
            }
        }
        Ok(plan)
    }

    /// A warm start from the canonical `start`: the free-run stage from
    /// `start` and a cloud around it ([`crate::optim::engine::space::Space::cloud`]), then the polish;
    /// no global search, so the fit refines the basin it is given (a global
    /// search finds other basins, and where the estimation data do not
    /// settle the model some of those fit the estimation half better and
    /// validate worse: docs/ARCHITECTURE.md, "Warm starts").
    pub fn start_warm(
        &self,
        problem: &FitProblem,
        start: &[f64],
    ) -> anyhow::Result<Engine<ModelChart>> {
        let plan = self.plan(problem, &|_| ())?.from_point();
        let space = problem.engine_space();
        let n = plan.free_run.as_ref().map_or(1, |f| f.population);
        // The cloud is the free-run stage's first population: its draws
        // before the first generation.
        let streams = Streams::new(self.seed, Stage::FreeRun, 0);
        let rows = space.cloud(start, n, &streams);
        Ok(Engine::new(plan, space, self.seed, self.stops()?)?.with_initial(rows.rows()))
    }

    /// The stop rules, checked.
    fn stops(&self) -> anyhow::Result<StopRules> {
        if let Some(t) = self.stops.time_budget_s {
            anyhow::ensure!(
                t >= 0.0,
                "--time-budget must be at least 0 seconds (got {t})"
            );
        }
        if let Some(sse) = self.stops.target_sse {
            anyhow::ensure!(
                sse.is_finite() && sse >= 0.0,
                "--target-sse must be a finite SSE of 0 or more (got {sse})"
            );
        }
        Ok(self.stops.clone())
    }

    /// What of this command's N, G, seed and update rule a checkpoint's
    /// `plan` and `seed` override, as `N = 200 (not 500)`: a loop over seeds
    /// that reuses one checkpoint resumes one fit each time.
    fn overridden_by(&self, plan: &Plan, seed: u64) -> Vec<String> {
        let mut out = Vec::new();
        let n: usize = (0..plan.tries).map(|t| try_population(plan, t)).sum();
        let asked: usize = match self.thesis_flow {
            true => self.pop,
            false => try_populations(self.pop).iter().sum(),
        };
        if n != asked {
            out.push(format!("N = {n} (not {asked})"));
        }
        if let Some(global) = &plan.global {
            if global.generations != self.gens {
                out.push(format!("G = {} (not {})", global.generations, self.gens));
            }
            let algo = global.settings.algorithm();
            if algo != self.algo {
                out.push(format!("--algo {algo} (not {})", self.algo));
            }
        }
        if seed != self.seed {
            out.push(format!("seed {seed} (not {})", self.seed));
        }
        out
    }

    /// The engine to run on `problem`: resumed from `checkpoint` when that file
    /// exists, else fresh. A checkpoint holds the whole future of its run,
    /// so its plan, N, G, seed and settings win over these and it resumes to
    /// the identical result; only the stop rules are taken from here, since
    /// when to stop is the caller's to choose again. `note` hears of the
    /// resumption and of rules applied unasked.
    pub fn start(
        &self,
        problem: &FitProblem,
        checkpoint: Option<&Path>,
        note: &dyn Fn(String),
    ) -> anyhow::Result<Engine<ModelChart>> {
        let space = problem.engine_space();
        if let Some(path) = checkpoint.filter(|p| p.exists()) {
            let mut engine = Engine::load(path)?;
            anyhow::ensure!(
                engine.space.names == space.names,
                "checkpoint {} fits the parameters {:?}, not those of a {} model: pass the --model it was made with",
                path.display(),
                engine.space.names,
                problem.model.family
            );
            if let Some(subject) = &engine.subject {
                anyhow::ensure!(
                    *subject == problem.data_digest(),
                    "checkpoint {} was made by a fit of other data (another file, other columns, \
                     another --resample or --dt): resuming it would report that fit as this \
                     one's; delete it or name another --checkpoint",
                    path.display()
                );
            }
            // The box, held values included: a checkpoint resumes its own
            // box, so another --bound or --fix would be reported as applied
            // and not be.
            let differs: Vec<String> = (0..space.dim())
                .filter(|&i| {
                    engine.space.lower[i].to_bits() != space.lower[i].to_bits()
                        || engine.space.upper[i].to_bits() != space.upper[i].to_bits()
                })
                .map(|i| space.names[i].clone())
                .collect();
            anyhow::ensure!(
                differs.is_empty(),
                "checkpoint {} searched another box for {} (made with other --bound, --fix, \
                 --loop or --free-n): resuming it would not apply this command's; give the \
                 flags it was made with, or name another --checkpoint",
                path.display(),
                differs.join(", ")
            );
            engine.stops = self.stops()?;
            let overridden = self.overridden_by(&engine.plan, engine.seed);
            note(format!(
                "resuming at generation {} of {} from {} (its plan, N, G, seed and settings \
                 win{})",
                engine.generation(),
                engine.plan.generations(),
                path.display(),
                match overridden.is_empty() {
                    true => String::new(),
                    false => format!(": {}", overridden.join(", ")),
                }
            ));
            return Ok(engine);
        }
        let mut engine = Engine::new(self.plan(problem, note)?, space, self.seed, self.stops()?)?;
        engine.subject = Some(problem.data_digest());
        Ok(engine)
    }
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;

    use super::*;
    use crate::fit::synthetic::Synthetic;
    use crate::model::Flow;

    fn settings(algo: Algorithm, pop: usize) -> FitSettings {
        FitSettings {
            algo,
            pop,
            gens: 10,
            ..FitSettings::staged(1)
        }
    }

    #[test]
    fn every_override_is_checked_whatever_the_algorithm_and_errors_name_the_flag() {
        let mut s = settings(Algorithm::De, 40);
        s.overrides.p_mut = Some(2.0);
        let e = s.algo_settings(Family::Classic, &|_| ()).unwrap_err();
        assert!(e.to_string().starts_with("--p-mut"), "{e}");
        let mut s = settings(Algorithm::Ga, 40);
        s.stops.time_budget_s = Some(-1.0);
        assert!(
            s.stops()
                .unwrap_err()
                .to_string()
                .starts_with("--time-budget")
        );
    }

    #[test]
    fn a_flag_of_another_algorithm_is_an_error_that_names_both() {
        let mut s = settings(Algorithm::Pso, 40);
        s.overrides.p_mut = Some(0.3);
        let e = s.algo_settings(Family::Classic, &|_| ()).unwrap_err();
        let e = e.to_string();
        assert!(e.starts_with("--p-mut tunes --algo ga"), "{e}");
        assert!(e.contains("runs --algo pso"), "{e}");
        let mut s = settings(Algorithm::Ga, 40);
        s.overrides.p_mut = Some(0.3);
        s.overrides.mfa_brightest = true;
        let e = s.algo_settings(Family::Classic, &|_| ()).unwrap_err();
        assert!(e.to_string().starts_with("--mfa-brightest"), "{e}");
        s.overrides.mfa_brightest = false;
        let Ok(AlgoSettings::Ga(ga)) = s.algo_settings(Family::Classic, &|_| ()) else {
            panic!("a GA with its own flag");
        };
        assert_eq!(ga.p_mut, 0.3);
    }

    #[test]
    fn the_thesis_flow_caps_a_large_swarm_and_says_so() {
        let data = Synthetic::new(Family::Classic, 600, 0.05, 1);
        let problem =
            FitProblem::new(&data.trace, Family::Classic, Flow::Thesis, None, false).unwrap();
        let mut s = settings(Algorithm::Mfa, mfa::ALL_PAIRS_MAX + 1);
        s.thesis_flow = true;
        let notes = RefCell::new(Vec::new());
        let plan = s.plan(&problem, &|n| notes.borrow_mut().push(n)).unwrap();
        let Some(AlgoSettings::Mfa(m)) = plan.global.map(|g| g.settings) else {
            panic!("an MFA plan");
        };
        assert_eq!(m.max_attractors, Some(mfa::BRIGHTEST));
        assert_eq!(notes.borrow().len(), 1);
        s.overrides.mfa_attractors = Some(0);
        notes.borrow_mut().clear();
        s.plan(&problem, &|n| notes.borrow_mut().push(n)).unwrap();
        assert!(notes.borrow().is_empty());
    }

    /// Python's `pop` reaches the plan without the CLI's parser: a
    /// population past any machine is an error there too, before a row is
    /// allocated.
    #[test]
    fn a_population_past_any_machine_is_an_error() {
        let data = Synthetic::new(Family::Classic, 600, 0.05, 1);
        let problem =
            FitProblem::new(&data.trace, Family::Classic, Flow::Joint, None, false).unwrap();
        let e = settings(Algorithm::De, MAX_POPULATION + 1)
            .plan(&problem, &|_| ())
            .unwrap_err();
        assert!(
            e.to_string().contains("at most 100000000 candidates"),
            "{e}"
        );
        // At the cap it plans, where the machine's memory holds it.
        let at_cap = settings(Algorithm::De, MAX_POPULATION).plan(&problem, &|_| ());
        if let Err(e) = at_cap {
            assert!(e.to_string().contains("are free here"), "{e}");
        }
    }
}
