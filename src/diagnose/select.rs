//! Which effect: fit the baseline, then every catalogued effect as an
//! addition to it, score each on the validation part, accept by a stated rule
//! and repeat on the remainder (forward selection).
//!
//! **Acceptance rule.** Let `R0` be the validation RMSE of the current model
//! and `R1` the candidate's (each fit keeps the seed with the lowest
//! estimation SSE among those that stay finite on validation); `s0`, `s1` the
//! seed-to-seed spreads of the validation RMSE (`s0` from refitting the
//! current model with the candidates' seeds and budget, so refitting alone is
//! not mistaken for an effect; spread = 1.4826·MAD over the seeds, a robust
//! standard deviation, so one seed stuck in a poor basin does not veto what
//! the others agree on); `N` the validation samples and `k` the candidate's
//! extra parameters. A candidate is accepted only if all three hold:
//! 1. `R0 − R1 > 3·√(s0² + s1²)`: the improvement is clearly beyond seed-to-seed spread;
//! 2. `ΔBIC = N·ln(R1²/R0²) + k·ln N < −10`: it pays for its parameters
//!    ("very strong" evidence on the Kass–Raftery scale);
//! 3. `(R0 − R1)/R0 ≥ 2 %`: an improvement a user would notice.
//!
//! Of the candidates that pass, the one with the lowest validation RMSE is
//! accepted; the next round starts from it.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Uniform};
use rayon::prelude::*;
use serde::Serialize;

use super::effects::{Augmented, Context, Effect, effect_box};
use crate::data::Trace;
use crate::ident::arx::{Arx, ArxOrders};
use crate::model::experiment::halves;
use crate::model::{Experiment, Family, Flow, LinearPrior, SearchSpace};
use crate::optim::de::{De, DeSettings};
use crate::optim::{Bounds, Optimizer};

/// Budget and rule settings of a diagnosis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Settings {
    /// Seeds per fit (the spread over them is the acceptance rule's yardstick).
    pub seeds: usize,
    /// Seeds, population and generations of the baseline fit (from scratch:
    /// more seeds, since a from-scratch fit can end in a poor basin and the
    /// best of the seeds on the estimation part is kept).
    pub baseline_seeds: usize,
    pub baseline_population: usize,
    pub baseline_generations: usize,
    /// Population and generations of each candidate fit (warm-started from
    /// the current model, effect parameters drawn over their whole box).
    pub population: usize,
    pub generations: usize,
    /// At most this many effects are named.
    pub max_effects: usize,
    /// Rule 1: improvement must exceed this many seed standard deviations.
    pub spread_factor: f64,
    /// Rule 2: ΔBIC must be below this.
    pub bic_threshold: f64,
    /// Rule 3: minimum relative improvement of the validation RMSE.
    pub min_relative: f64,
    /// Base seed; seed `i` of a fit uses `seed + i`.
    pub seed: u64,
}

impl Default for Settings {
    /// Sized so that `mckibben diagnose` on the default data (a few thousand
    /// samples) finishes in seconds on two cores. The baseline budget is
    /// measured: on the self-test's control case (stair, 4.5 kg) a seed of
    /// 40 × 600 ends in the true model's basin about two times in three
    /// (one in four at 40 × 300), so the best of 6 seeds misses it rarely.
    fn default() -> Self {
        Settings {
            seeds: 3,
            baseline_seeds: 6,
            baseline_population: 40,
            baseline_generations: 600,
            population: 30,
            generations: 300,
            max_effects: 3,
            spread_factor: 3.0,
            bic_threshold: -10.0,
            min_relative: 0.02,
            seed: 1,
        }
    }
}

/// The data of a diagnosis: each dataset in the deviation coordinates of its
/// estimation half, the estimation part, and where validation starts.
#[derive(Debug, Clone)]
pub struct Data {
    pub whole: Vec<Experiment>,
    pub est: Vec<Experiment>,
    /// First validation sample of each dataset.
    pub val_start: Vec<usize>,
    pub ctx: Vec<Context>,
    /// ARX estimate on the first dataset's estimation half (bounds of the linear part).
    pub prior: LinearPrior,
}

impl Data {
    /// Splits every trace in halves (estimation first, as the thesis, §4.3.1)
    /// and checks that the data can be diagnosed at all.
    pub fn new(traces: &[Trace]) -> anyhow::Result<Data> {
        anyhow::ensure!(!traces.is_empty(), "no data to diagnose");
        let mut whole = Vec::new();
        let mut est = Vec::new();
        let mut val_start = Vec::new();
        for t in traces {
            anyhow::ensure!(
                t.len() >= 40,
                "{}: {} samples are too few to split into estimation and validation halves (need at least 40)",
                t.source,
                t.len()
            );
            let (e, v) = halves(t.len());
            let (lo, hi) = t.input[e.clone()]
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                });
            anyhow::ensure!(
                hi > lo,
                "{}: the input `{}` is constant over the estimation half, so there is no dynamics to diagnose",
                t.source,
                t.input_name
            );
            anyhow::ensure!(
                t.input.iter().chain(&t.output).all(|v| v.is_finite()),
                "{}: the data contain non-finite values",
                t.source
            );
            let w = Experiment::with_means_of(t, e.clone());
            est.push(w.segment(e));
            val_start.push(v.start);
            whole.push(w);
        }
        let first = &est[0];
        let u: Vec<f64> = first.u.iter().map(|&v| v as f64).collect();
        let y: Vec<f64> = first.y.iter().map(|&v| v as f64).collect();
        let arx = Arx::estimate(&first.name, &u, &y, ArxOrders::default())?;
        let max_abs = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let prior = LinearPrior {
            a: arx.a[0],
            b: arx.b[0],
            max_abs_input: traces.iter().map(|t| max_abs(&t.input)).fold(0.0, f64::max),
            max_abs_output: traces
                .iter()
                .map(|t| max_abs(&t.output))
                .fold(0.0, f64::max),
        };
        let ctx = whole
            .iter()
            .map(|w| Context::of(w, prior.b >= 0.0))
            .collect();
        Ok(Data {
            whole,
            est,
            val_start,
            ctx,
            prior,
        })
    }

    pub fn datasets(&self) -> usize {
        self.whole.len()
    }

    /// Validation samples over all datasets.
    pub fn val_samples(&self) -> usize {
        self.whole
            .iter()
            .zip(&self.val_start)
            .map(|(w, s)| w.len() - s)
            .sum()
    }

    /// Estimation SSE of `theta` (summed over datasets, `+∞` if any diverged).
    pub fn est_sse(&self, model: &Augmented, theta: &[f64]) -> f64 {
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        self.est
            .iter()
            .zip(&self.ctx)
            .enumerate()
            .map(|(i, (e, c))| model.sse(&t, i, c, e) as f64)
            .sum()
    }

    /// Predicted output (deviation coordinates) over each whole dataset: the
    /// free run from the first sample, so the validation part starts from a
    /// warmed-up state rather than `w = 0`.
    pub fn predict(&self, model: &Augmented, theta: &[f64]) -> Vec<Vec<f32>> {
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        self.whole
            .iter()
            .zip(&self.ctx)
            .enumerate()
            .map(|(i, (e, c))| model.simulate(&t, i, c, e))
            .collect()
    }

    /// Validation residuals `y − ŷ` per dataset.
    pub fn val_residuals(&self, model: &Augmented, theta: &[f64]) -> Vec<Vec<f64>> {
        self.predict(model, theta)
            .iter()
            .zip(&self.whole)
            .zip(&self.val_start)
            .map(|((p, w), &s)| (s..w.len()).map(|k| w.y[k] as f64 - p[k] as f64).collect())
            .collect()
    }

    /// Validation RMSE over all datasets (`+∞` if the simulation diverged).
    pub fn val_rmse(&self, model: &Augmented, theta: &[f64]) -> f64 {
        let r = self.val_residuals(model, theta);
        let sse: f64 = r.iter().flatten().map(|v| v * v).sum();
        let n = self.val_samples().max(1) as f64;
        let v = (sse / n).sqrt();
        if v.is_finite() { v } else { f64::INFINITY }
    }

    /// The search box of `model`: the default joint-flow box of the baseline
    /// (thesis hull, `a`, `b`, `c` around the ARX estimate) plus each
    /// effect's box.
    pub fn space(&self, model: &Augmented) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let mut base = SearchSpace::around(model.family, None, self.prior, Flow::Joint, false);
        // Least squares on hysteretic data underestimates the input gain: the
        // hysteretic model's `b` relates to the ARX static gain
        // `G = b_ARX/(1 − a_ARX)` through `1 − a·α`, not `1 − a`. Widen the
        // box to reach `G` itself.
        let ib = model.family.linear_indices()[1];
        let g = self.prior.b / (1.0 - self.prior.a).abs().max(1e-3);
        if g.abs() > base.upper[ib].abs().max(base.lower[ib].abs()) {
            if g > 0.0 {
                base.upper[ib] = g;
            } else {
                base.lower[ib] = g;
            }
        }
        let mid: Vec<f64> = base
            .lower
            .iter()
            .zip(&base.upper)
            .map(|(l, u)| 0.5 * (l + u))
            .collect();
        let (mut neutral, mut lo, mut hi) = (mid, base.lower, base.upper);
        for &e in &model.effects {
            let (n, l, h) = effect_box(e, &self.ctx[0], self.datasets());
            neutral.extend(n);
            lo.extend(l);
            hi.extend(h);
        }
        (neutral, lo, hi)
    }
}

/// One fitted model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Fit {
    pub params: Vec<f64>,
    pub est_sse: f64,
    pub val_rmse: f64,
}

/// The fits of one model over several seeds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SeededFit {
    /// The seed with the lowest estimation SSE (among those finite on validation).
    pub best: Fit,
    /// Validation RMSE of every seed.
    pub seed_val_rmse: Vec<f64>,
    /// Their spread: `1.4826·MAD`, a robust standard deviation.
    pub spread: f64,
}

/// Fits `model` on the estimation part with seed `seed`: from scratch when
/// `start` is `None`, else warm-started (`start` is then a member of the
/// initial population, so the fit never ends worse than it started).
///
/// The search is `optim`'s differential evolution (the one `mckibben fit`
/// uses) through its ask/tell interface. From scratch with the narrow
/// `p_best = 0.02` that helped on hard problems (measured: more seeds reach
/// the true model's basin on the self-test's control case than with 0.1);
/// warm-started with `p_best = 0.2`, so the population does not collapse
/// onto the start before the effect's parameter has been explored.
pub fn fit_candidate(
    data: &Data,
    model: &Augmented,
    start: Option<&[f64]>,
    seed: u64,
    population: usize,
    generations: usize,
) -> Fit {
    let (neutral, lo, hi) = data.space(model);
    let d = lo.len();
    let np = population.max(6);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let base_dim = model.family.dim();
    let initial: Vec<f64> = match start {
        // From scratch, one member is the ARX model (α at its largest, no
        // hysteresis), so the fit starts no worse than least squares; the
        // rest is drawn uniformly by the optimizer.
        None => {
            let mut v = neutral;
            if model.family != Family::Linear {
                v[1] = hi[1];
                v[2] = 0.0f64.clamp(lo[2], hi[2]);
                v[3] = 0.0f64.clamp(lo[3], hi[3]);
            }
            let [ia, ib, ic] = model.family.linear_indices();
            v[ia] = data.prior.a.clamp(lo[ia], hi[ia]);
            v[ib] = data.prior.b.clamp(lo[ib], hi[ib]);
            v[ic] = 0.0f64.clamp(lo[ic], hi[ic]);
            v
        }
        // Warm: the start itself, then baseline parameters near it (half the
        // members close, half farther: the baseline compensated for the
        // missing effect and must move) with effect parameters anywhere.
        Some(s) => (0..np)
            .flat_map(|i| {
                let row: Vec<f64> = (0..d)
                    .map(|j| {
                        if i == 0 {
                            s[j]
                        } else if j < base_dim {
                            let sd = if i % 2 == 0 { 0.1 } else { 0.02 } * (hi[j] - lo[j]);
                            let v = s[j] + Normal::new(0.0, sd).map_or(0.0, |n| n.sample(&mut rng));
                            v.clamp(lo[j], hi[j])
                        } else {
                            Uniform::new_inclusive(lo[j], hi[j])
                                .map_or(lo[j], |u| u.sample(&mut rng))
                        }
                    })
                    .collect();
                row
            })
            .collect(),
    };
    let bounds = Bounds {
        names: (0..d).map(|j| format!("p{j}")).collect(),
        lower: lo,
        upper: hi,
    };
    let settings = DeSettings {
        p_best: if start.is_some() { 0.2 } else { 0.02 },
        ..DeSettings::default()
    };
    let mut de = De::new(settings, bounds, np).with_initial(&initial);
    let (mut best, mut best_sse) = (initial[..d].to_vec(), f64::INFINITY);
    for _ in 0..=generations {
        let rows = de.ask(&mut rng);
        let costs: Vec<f64> = rows
            .par_chunks(d)
            .map(|p| {
                let s = data.est_sse(model, p);
                if s.is_nan() { f64::INFINITY } else { s }
            })
            .collect();
        for (row, &c) in rows.chunks(d).zip(&costs) {
            if c < best_sse {
                best_sse = c;
                best = row.to_vec();
            }
        }
        de.tell(&costs.iter().map(|&c| c as f32).collect::<Vec<_>>());
    }
    Fit {
        val_rmse: data.val_rmse(model, &best),
        est_sse: best_sse,
        params: best,
    }
}

/// Fits `model` with `settings.seeds` seeds; `start` as in [`fit_candidate`].
pub fn fit_seeds(
    data: &Data,
    model: &Augmented,
    start: Option<&[f64]>,
    settings: &Settings,
    salt: u64,
) -> SeededFit {
    let (seeds, pop, gens) = match start {
        None => (
            settings.baseline_seeds,
            settings.baseline_population,
            settings.baseline_generations,
        ),
        Some(_) => (settings.seeds, settings.population, settings.generations),
    };
    let fits: Vec<Fit> = (0..seeds.max(1) as u64)
        .map(|i| {
            fit_candidate(
                data,
                model,
                start,
                settings.seed + 1000 * salt + i,
                pop,
                gens,
            )
        })
        .collect();
    let seed_val_rmse: Vec<f64> = fits.iter().map(|f| f.val_rmse).collect();
    let spread = std_dev(&seed_val_rmse);
    // The seed with the lowest estimation SSE among those that stay finite on
    // the validation part: a fit that diverges there is not a model (the
    // validation part is used for nothing else in this choice).
    let any_finite = fits.iter().any(|f| f.val_rmse.is_finite());
    let best = fits
        .into_iter()
        .filter(|f| f.val_rmse.is_finite() || !any_finite)
        .min_by(|a, b| a.est_sse.total_cmp(&b.est_sse))
        .expect("at least one seed");
    SeededFit {
        best,
        seed_val_rmse,
        spread,
    }
}

/// The seed-to-seed spread: a robust standard deviation, `1.4826·MAD` of the
/// seeds' validation RMSEs (non-finite ones count as +∞). A seed stuck in a
/// poor basin is a failed fit, not spread, and the median ignores it while
/// seeds that agree give a small spread.
fn std_dev(v: &[f64]) -> f64 {
    if v.len() < 2 {
        return 0.0;
    }
    let median = |x: &mut Vec<f64>| {
        x.sort_by(f64::total_cmp);
        let m = x.len() / 2;
        if x.len() % 2 == 0 {
            0.5 * (x[m - 1] + x[m])
        } else {
            x[m]
        }
    };
    let mut w: Vec<f64> = v
        .iter()
        .map(|&x| if x.is_nan() { f64::INFINITY } else { x })
        .collect();
    let med = median(&mut w);
    let mut dev: Vec<f64> = w.iter().map(|x| (x - med).abs()).collect();
    let mad = median(&mut dev);
    if mad.is_finite() {
        1.4826 * mad
    } else {
        f64::INFINITY
    }
}

/// Share of the baseline's gap above the noise floor that `rmse` closes, in
/// residual energy: `(R_b² − R²) / (R_b² − F²)`; 0 when the baseline is
/// already at the floor.
pub fn gap_closed(baseline_rmse: f64, rmse: f64, floor: f64) -> f64 {
    let gap = baseline_rmse.powi(2) - floor.powi(2);
    if gap.is_nan() || gap <= 0.0 || !rmse.is_finite() {
        return 0.0;
    }
    (baseline_rmse.powi(2) - rmse.powi(2)) / gap
}

/// One candidate of one round.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Candidate {
    pub effect: Effect,
    /// The model the candidate is (current effects plus this one).
    pub model: Augmented,
    pub fit: SeededFit,
    /// The candidate's own parameters, by name.
    pub effect_params: Vec<(String, f64)>,
    /// ΔBIC against the current model on the validation part.
    pub delta_bic: f64,
    /// Relative improvement of the validation RMSE against the current model.
    pub relative: f64,
    /// Improvement in units of the combined seed spread.
    pub spread_ratio: f64,
    pub passes: bool,
    /// Why it passes or fails, in words.
    pub reason: String,
}

/// One round of forward selection.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Round {
    /// The current model refitted with the candidates' budget.
    pub current: SeededFit,
    /// Candidates by validation RMSE, best first.
    pub candidates: Vec<Candidate>,
    pub accepted: Option<Effect>,
}

/// The result of the selection.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Selection {
    pub baseline_model: Augmented,
    pub baseline: SeededFit,
    pub rounds: Vec<Round>,
    /// Accepted effects in the order accepted.
    pub verdict: Vec<Effect>,
    pub final_model: Augmented,
    pub final_fit: Fit,
}

/// Fits the baseline, then runs forward selection over `effects`.
pub fn select(data: &Data, family: Family, effects: &[Effect], settings: &Settings) -> Selection {
    let baseline_model = Augmented::new(family, Vec::new(), data.datasets());
    let baseline = fit_seeds(data, &baseline_model, None, settings, 0);
    let mut current_model = baseline_model.clone();
    let mut current_params = baseline.best.params.clone();
    let mut final_fit = baseline.best.clone();
    let mut rounds = Vec::new();
    let mut verdict = Vec::new();
    let n = data.val_samples().max(2) as f64;
    for round in 0..settings.max_effects {
        let remaining: Vec<Effect> = effects
            .iter()
            .copied()
            .filter(|e| !current_model.effects.contains(e) && e.applicable(data.datasets()))
            .collect();
        if remaining.is_empty() {
            break;
        }
        let salt = 100 * (round as u64 + 1);
        let current = fit_seeds(data, &current_model, Some(&current_params), settings, salt);
        // The refit gives the seed spread of "no new effect"; the yardstick
        // is the model as accepted.
        let (r0, s0) = (final_fit.val_rmse, current.spread);
        let mut candidates: Vec<Candidate> = remaining
            .iter()
            .enumerate()
            .map(|(i, &effect)| {
                let model = current_model.with(effect);
                let (neutral, _, _) = data.space(&model);
                let mut start = current_params.clone();
                start.extend_from_slice(&neutral[current_params.len()..]);
                let fit = fit_seeds(data, &model, Some(&start), settings, salt + 1 + i as u64);
                let r1 = fit.best.val_rmse;
                let k = effect.dim(data.datasets()) as f64;
                let (delta_bic, relative) = if r1.is_finite() {
                    (n * (r1 * r1 / (r0 * r0)).ln() + k * n.ln(), (r0 - r1) / r0)
                } else {
                    (f64::INFINITY, f64::NEG_INFINITY)
                };
                let spread = (s0 * s0 + fit.spread * fit.spread).sqrt();
                let spread_ratio = if spread > 0.0 {
                    (r0 - r1) / spread
                } else if r1 < r0 {
                    f64::INFINITY
                } else {
                    0.0
                };
                let rule1 = r0 - r1 > settings.spread_factor * spread;
                let rule2 = delta_bic < settings.bic_threshold;
                let rule3 = relative >= settings.min_relative;
                let passes = rule1 && rule2 && rule3 && r1.is_finite();
                let mut why = Vec::new();
                if !rule1 {
                    why.push(format!(
                        "improvement {:.3} is within {}× the seed spread {:.3}",
                        r0 - r1,
                        settings.spread_factor,
                        spread
                    ));
                }
                if !rule2 {
                    why.push(format!(
                        "ΔBIC {delta_bic:.1} does not pay for {k} parameter(s)"
                    ));
                }
                if !rule3 {
                    why.push(format!(
                        "relative improvement {:.1} % is below {:.1} %",
                        100.0 * relative,
                        100.0 * settings.min_relative
                    ));
                }
                let reason = if !r1.is_finite() {
                    "the best fit on the estimation part diverges on the validation part"
                        .to_string()
                } else if passes {
                    format!(
                        "improves validation RMSE by {:.1} % ({:.1}× the seed spread, ΔBIC {:.0})",
                        100.0 * relative,
                        spread_ratio,
                        delta_bic
                    )
                } else {
                    why.join("; ")
                };
                let at = model.offset_of(effect).expect("effect in model");
                let effect_params = effect
                    .params(data.datasets())
                    .into_iter()
                    .zip(&fit.best.params[at..])
                    .map(|(p, &v)| (p.name, v))
                    .collect();
                Candidate {
                    effect,
                    model,
                    fit,
                    effect_params,
                    delta_bic,
                    relative,
                    spread_ratio,
                    passes,
                    reason,
                }
            })
            .collect();
        candidates.sort_by(|a, b| a.fit.best.val_rmse.total_cmp(&b.fit.best.val_rmse));
        let accepted = candidates.iter().find(|c| c.passes).map(|c| c.effect);
        if let Some(c) = candidates.iter().find(|c| c.passes) {
            current_model = c.model.clone();
            current_params = c.fit.best.params.clone();
            final_fit = c.fit.best.clone();
            verdict.push(c.effect);
        }
        rounds.push(Round {
            current,
            candidates,
            accepted,
        });
        if accepted.is_none() {
            break;
        }
    }
    Selection {
        baseline_model,
        baseline,
        rounds,
        verdict,
        final_model: current_model,
        final_fit,
    }
}
