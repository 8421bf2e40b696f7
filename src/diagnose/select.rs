//! Which effect: fit the baseline, then every catalogued effect as an
//! addition to it, score each on the validation part, accept by a stated rule
//! and repeat on the remainder (forward selection).
//!
//! **Acceptance rule.** Let `R0` be the validation RMSE of the current model
//! and `R1` the candidate's (each fit keeps the seed with the lowest
//! estimation SSE among those that stay finite on validation); `s0`, `s1` the
//! seed-to-seed spreads of the validation RMSE (`s0` from refitting the
//! current model with the candidates' seeds and budget, so refitting alone is
//! not mistaken for an effect; spread = 1.4826·MAD over the seeds that reach
//! the best estimation fit, a robust standard deviation of fits the
//! estimation data cannot tell apart); `N` the validation samples, `k` the
//! candidate's extra parameters and `F` the noise-floor estimate. A candidate
//! is accepted only if all four hold:
//! 1. `R0 − R1 > 3·√(s0² + s1²)`: the improvement is clearly beyond seed-to-seed spread;
//! 2. `ΔBIC = N·ln(R1²/R0²) + k·ln N < −10`: it pays for its parameters
//!    ("very strong" evidence on the Kass–Raftery scale);
//! 3. `(R0 − R1)/R0 ≥ 2 %`: an improvement a user would notice;
//! 4. `R0 > 1.1·F`: there is a gap left to explain (the floor estimate is
//!    good to about 10 %).
//!
//! Of the candidates that pass, the one with the lowest validation RMSE is
//! accepted; the next round starts from it.

use nalgebra::DVector;
use rand::{RngExt, SeedableRng};
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
use crate::optim::lm::{self, LmSettings};
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
    /// From-scratch seeds of each first-round candidate, on top of its warm
    /// seeds (baseline population and generations, through the
    /// multi-step-ahead predictor first; see [`Start::Ahead`]).
    pub scratch_seeds: usize,
    /// At most this many effects are named.
    pub max_effects: usize,
    /// Rule 1: improvement must exceed this many seed standard deviations.
    pub spread_factor: f64,
    /// Rule 2: ΔBIC must be below this.
    pub bic_threshold: f64,
    /// Rule 3: minimum relative improvement of the validation RMSE.
    pub min_relative: f64,
    /// Rule 4: the current model must miss by more than this multiple of the
    /// noise-floor estimate (which is good to about 10 %), else there is no
    /// gap left to explain.
    pub floor_margin: f64,
    /// Base seed; seed `i` of a fit uses `seed + i`.
    pub seed: u64,
}

impl Default for Settings {
    /// Sized so that `mckibben diagnose` on the default data (a few thousand
    /// samples) finishes in seconds on two cores. The baseline gets 12 seeds
    /// because a from-scratch fit of the classic model to the twin's stair
    /// is multimodal: measured on `data/stair_4.5kg.csv`, 2 of 6 seeds of
    /// 40 × 600 leave the linear model's plateau (`A = 0`) for the better
    /// basins (estimation SSE 3000–3600 against 10752).
    fn default() -> Self {
        Settings {
            seeds: 3,
            baseline_seeds: 12,
            baseline_population: 40,
            baseline_generations: 600,
            population: 30,
            generations: 300,
            scratch_seeds: 4,
            max_effects: 3,
            spread_factor: 3.0,
            bic_threshold: -10.0,
            min_relative: 0.02,
            floor_margin: 1.1,
            seed: 1,
        }
    }
}

/// The data of a diagnosis: every dataset in the deviation coordinates of the
/// first one's estimation half, the estimation part, and where validation starts.
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
        let mut whole: Vec<Experiment> = Vec::new();
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
            // All datasets share the first one's coordinates, so that one
            // absolute model (one intercept) describes them all and a
            // difference between them (a load) is a gap, not a shift of means.
            let w = match whole.first() {
                None => Experiment::with_means_of(t, e.clone()),
                Some(first) => Experiment::with_offsets(t, first.u_mean, first.y_mean),
            };
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
            output_range: crate::data::range(
                &traces
                    .iter()
                    .flat_map(|t| t.output.iter().copied())
                    .collect::<Vec<_>>(),
            ),
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
        self.est_sum(theta, |t, i, c, e| model.sse(t, i, c, e))
    }

    /// Estimation SSE of the `horizon`-step-ahead prediction (see
    /// [`Augmented::sse_ahead`]).
    pub fn est_sse_ahead(&self, model: &Augmented, theta: &[f64], horizon: usize) -> f64 {
        self.est_sum(theta, |t, i, c, e| model.sse_ahead(t, i, c, e, horizon))
    }

    /// `cost(θ, dataset, context, estimation part)` summed over the datasets.
    fn est_sum(
        &self,
        theta: &[f64],
        cost: impl Fn(&[f32], usize, &Context, &Experiment) -> f32,
    ) -> f64 {
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        self.est
            .iter()
            .zip(&self.ctx)
            .enumerate()
            .map(|(i, (e, c))| cost(&t, i, c, e) as f64)
            .sum()
    }

    /// Free-run residuals `ŷ − y` of the estimation part, every dataset from
    /// its second sample on; `None` if the simulation diverged.
    pub fn est_residuals(&self, model: &Augmented, theta: &[f64]) -> Option<DVector<f64>> {
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        let mut r = Vec::with_capacity(self.est.iter().map(|e| e.len()).sum());
        for (i, (e, c)) in self.est.iter().zip(&self.ctx).enumerate() {
            let p = model.simulate(&t, i, c, e);
            r.extend(p.iter().zip(&e.y).skip(1).map(|(&a, &b)| (a - b) as f64));
        }
        r.iter()
            .all(|v| v.is_finite())
            .then(|| DVector::from_vec(r))
    }

    /// The prediction horizon of [`Start::Ahead`]: a third of the ARX time
    /// constant `1/(1 − a)` in samples, so that the output error cannot pile
    /// up through the slow pole, yet the prediction depends on the dynamics
    /// rather than on the last measurement alone (measured on the self-test
    /// of `data/stair_4.5kg.csv`, τ = 69 samples: horizons of 10, 20 and 40
    /// brought 2, 4 and 1 of 8 from-scratch fits of the true model of the
    /// `asymmetry (large)` and `load (small)` cases within 10× the true
    /// model's estimation SSE, the plain free-run search none).
    pub fn horizon(&self) -> usize {
        let tau = 1.0 / (1.0 - self.prior.a).max(1e-3);
        let shortest = self.est.iter().map(|e| e.len()).min().unwrap_or(8);
        ((tau / 3.0).round() as usize).clamp(2, (shortest / 4).max(2))
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
        // The classic loop stays bounded for every input only when β ≥ 0 (and
        // β + γ > 0, else w grows without bound and the fit diverges anyway):
        // with β < 0 the loading branch settles at A/(β+γ), above the level
        // A/(γ−β) past which the unloading branch drives w away. A baseline
        // fitted there follows the data but turns wild under any change of
        // input or parameters, so it is no base to attribute effects to.
        if model.family == Family::Classic {
            base.lower[2] = base.lower[2].max(0.0);
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
    /// Their spread: `1.4826·MAD` over the seeds within 1 % of the best
    /// estimation SSE, a robust standard deviation.
    pub spread: f64,
}

/// Where a fit starts.
#[derive(Debug, Clone, Copy)]
pub enum Start<'a> {
    /// From scratch over the whole box (the baseline).
    Scratch,
    /// From scratch in two stages: half the generations on the
    /// `horizon`-step-ahead prediction error ([`Data::est_sse_ahead`]), the
    /// other half on the free run, started around the first stage's best.
    /// The free-run cost of a slow, hysteretic model is a needle along the
    /// pole and the static gain that differential evolution rarely finds
    /// from scratch; the prediction error's is not. Measured on the
    /// self-test's `asymmetry (large)` case (default data): plain
    /// from-scratch fits of the true model ended at 50× the true model's
    /// estimation SSE in 7 of 7 seeds, even at 100 × 1500; with a horizon
    /// of 20 samples 3 of 4 ended at 1.9–7×.
    Ahead { horizon: usize },
    /// From a known model: `params` is the current model with the new
    /// effect's parameters (from `new_from` on) at their neutral values; the
    /// refit of the current model itself has `new_from == params.len()`.
    Warm { params: &'a [f64], new_from: usize },
}

/// Fits `model` on the estimation part with seed `seed`.
///
/// The search is `optim`'s differential evolution (the one `mckibben fit`
/// uses) through its ask/tell interface. From scratch with the narrow
/// `p_best = 0.02` that helped on hard problems (measured on
/// data/stair_4.5kg.csv, 6 seeds of 40 × 600: 2 leave the linear model's
/// plateau with 0.02 or 0.05, none with 0.1);
/// one member is the ARX model, so the fit starts no worse than least squares.
///
/// Warm-started in two stages. First the new effect's parameters alone, the
/// rest held at the start (a search in one or two dimensions that rarely
/// misses); then everything together from there, with `p_best = 0.2` so the
/// population does not collapse onto the start: the baseline had compensated
/// for the missing effect and must move back. The start is a member
/// throughout, so a fit never ends worse than it started.
pub fn fit_candidate(
    data: &Data,
    model: &Augmented,
    start: Start<'_>,
    seed: u64,
    population: usize,
    generations: usize,
) -> Fit {
    let (neutral, lo, hi) = data.space(model);
    let d = lo.len();
    let np = population.max(6);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // Never NaN: a diverged simulation scores +∞.
    let sse = |p: &[f64]| data.est_sse(model, p);
    let (initial, p_best, generations) = match start {
        Start::Scratch => (
            scratch_rows(data, model, (&neutral, &lo, &hi), np, &mut rng),
            0.02,
            generations,
        ),
        Start::Ahead { horizon } => {
            let rows = scratch_rows(data, model, (&neutral, &lo, &hi), np, &mut rng);
            let ahead = |p: &[f64]| data.est_sse_ahead(model, p, horizon);
            let first = generations / 2;
            let (best, _) = evolve(
                (lo.clone(), hi.clone()),
                &rows,
                np,
                first,
                0.02,
                &mut rng,
                ahead,
            );
            let rows = rows_around(&best, &best, d, (&lo, &hi), np, &mut rng);
            (rows, 0.2, generations - first)
        }
        Start::Warm {
            params: s,
            new_from,
        } => {
            let staged = if new_from < d {
                let k = d - new_from;
                let np1 = (10 * k).max(12);
                let (best, _) = evolve(
                    (lo[new_from..].to_vec(), hi[new_from..].to_vec()),
                    &s[new_from..],
                    np1,
                    60,
                    0.2,
                    &mut rng,
                    |e| {
                        let mut p = s[..new_from].to_vec();
                        p.extend_from_slice(e);
                        sse(&p)
                    },
                );
                let mut p = s[..new_from].to_vec();
                p.extend(best);
                p
            } else {
                s.to_vec()
            };
            let rows = rows_around(s, &staged, new_from, (&lo, &hi), np, &mut rng);
            (rows, 0.2, generations)
        }
    };
    let (best, est_sse) = evolve(
        (lo.clone(), hi.clone()),
        &initial,
        np,
        generations,
        p_best,
        &mut rng,
        sse,
    );
    let (best, est_sse) = polish(data, model, best, est_sse, (&lo, &hi));
    Fit {
        val_rmse: data.val_rmse(model, &best),
        est_sse,
        params: best,
    }
}

/// Levenberg–Marquardt from the search's best on the free-run residuals;
/// the polished point is kept only if its estimation SSE is lower. The
/// free-run cost of a slow, hysteretic model is a narrow curved valley (1 %
/// in α moves the SSE 1000-fold on the default data), along which
/// differential evolution creeps while Gauss–Newton steps follow it.
/// Forward differences in the `f32` simulation: steps of 1e-4 of the
/// coordinate's size (taken as at least 1 % of its box width, so that a
/// coordinate near zero is still probed) stay well above its rounding.
pub(super) fn polish(
    data: &Data,
    model: &Augmented,
    best: Vec<f64>,
    est_sse: f64,
    (lo, hi): (&[f64], &[f64]),
) -> (Vec<f64>, f64) {
    let floor: Vec<f64> = lo.iter().zip(hi).map(|(l, h)| 1e-2 * (h - l)).collect();
    let settings = LmSettings {
        max_iterations: 30,
        rel_step: 1e-4,
        tolerance: 1e-9,
        central: false,
    };
    let residuals = |p: &[f64]| data.est_residuals(model, p);
    match lm::levenberg_marquardt(residuals, &best, (lo, hi), &floor, &settings) {
        Ok(out) => {
            let sse = data.est_sse(model, &out.x);
            if sse < est_sse {
                (out.x, sse)
            } else {
                (best, est_sse)
            }
        }
        // The search's best sits where a probe step diverges: keep it.
        Err(_) => (best, est_sse),
    }
}

/// Nodes of the size profile on each side of neutral: the box's edge times
/// `2^-k`, `k < PROFILE_NODES`.
const PROFILE_NODES: i32 = 6;

/// The profile of a candidate's new effect along its size: from the best fit,
/// the effect's primary parameter (index `at`) is stepped away from neutral
/// toward each edge of its box over a geometric ladder ([`PROFILE_NODES`]
/// nodes a side, so that small sizes are probed as finely as large ones),
/// the rest polished at each node from the node before; the best node is
/// then polished with everything free, and kept if it beats the fit on the
/// estimation part. Why: when the current model has absorbed part of an
/// effect, the fits warm-started from it find the effect small, and the
/// model with the effect at its true size lies along a valley in which the
/// rest of the model must move back with it: measured on the self-test's
/// `inertia (small)` case, Levenberg–Marquardt from the true parameters ends
/// at an estimation SSE of 101.7 with the extra pole 0.6 % off, while every
/// seed's fit ended above 109 with it half as large.
fn profile(data: &Data, model: &Augmented, fit: Fit, at: usize) -> Fit {
    let (neutral, lo, hi) = data.space(model);
    let centre = neutral[at].clamp(lo[at], hi[at]);
    let (mut best, mut best_sse) = (fit.params.clone(), fit.est_sse);
    for edge in [lo[at], hi[at]] {
        if edge == centre {
            continue;
        }
        let mut start = fit.params.clone();
        for k in (0..PROFILE_NODES).rev() {
            let v = centre + (edge - centre) * 0.5f64.powi(k);
            let (node, node_sse) = polish_held(data, model, &start, (at, v), (&lo, &hi));
            if node_sse < best_sse {
                (best, best_sse) = (node.clone(), node_sse);
            }
            start = node;
        }
    }
    if best_sse >= fit.est_sse {
        return fit;
    }
    let (params, est_sse) = polish(data, model, best, best_sse, (&lo, &hi));
    let val_rmse = data.val_rmse(model, &params);
    if val_rmse.is_finite() {
        Fit {
            params,
            est_sse,
            val_rmse,
        }
    } else {
        fit
    }
}

/// [`polish`] from `start` with coordinate `at` held at `v`: one point of
/// the profile along that coordinate.
pub(super) fn polish_held(
    data: &Data,
    model: &Augmented,
    start: &[f64],
    (at, v): (usize, f64),
    (lo, hi): (&[f64], &[f64]),
) -> (Vec<f64>, f64) {
    let (mut l, mut h) = (lo.to_vec(), hi.to_vec());
    (l[at], h[at]) = (v, v);
    let mut p = start.to_vec();
    p[at] = v;
    let sse = data.est_sse(model, &p);
    polish(data, model, p, sse, (&l, &h))
}

/// The initial population of a from-scratch fit: one member at the ARX
/// model (loop closed: `α` at its top, `β = γ = 0`), the rest uniform over
/// the box, except that every other member draws the loop-shape parameters
/// (β, γ or β1…β6) log-uniformly in magnitude over four decades: fits of the
/// muscle often need them near zero, a sliver of the box that a uniform draw
/// and DE's differences of uniform draws rarely visit. Measured with 6 seeds
/// of 40 × 600 on data/stair_4.5kg.csv: 1 seed left the linear model's
/// plateau (A = 0) with uniform draws, 2 with these; on the self-test's
/// control case (4 seeds) none with uniform draws, all four with these at
/// p_best = 0.1.
fn scratch_rows(
    data: &Data,
    model: &Augmented,
    (neutral, lo, hi): (&[f64], &[f64], &[f64]),
    np: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<f64> {
    let d = lo.len();
    let mut v = neutral.to_vec();
    if model.family != Family::Linear {
        v[1] = hi[1];
        v[2] = 0.0f64.clamp(lo[2], hi[2]);
        v[3] = 0.0f64.clamp(lo[3], hi[3]);
    }
    let [ia, ib, ic] = model.family.linear_indices();
    v[ia] = data.prior.a.clamp(lo[ia], hi[ia]);
    v[ib] = data.prior.b.clamp(lo[ib], hi[ib]);
    v[ic] = 0.0f64.clamp(lo[ic], hi[ic]);
    let mut rows = v;
    let shape = 2..model.family.exponent_index().unwrap_or(2);
    for i in 1..np {
        for j in 0..d {
            let uniform = Uniform::new_inclusive(lo[j], hi[j]).map_or(lo[j], |u| u.sample(rng));
            let v = if i % 2 == 1 && shape.contains(&j) {
                let decades = Uniform::new(-4.0, 0.0).map_or(0.0, |u| u.sample(rng));
                let sign = if lo[j] < 0.0 && rng.random::<bool>() {
                    -1.0
                } else {
                    1.0
                };
                (sign * 10f64.powf(decades) * hi[j].abs().max(lo[j].abs())).clamp(lo[j], hi[j])
            } else {
                uniform
            };
            rows.push(v);
        }
    }
    rows
}

/// The initial population of a warm-started fit: the start, the staged
/// model, then members around the staged model: the parameters before
/// `new_from` close (half) or farther (half), the rest near the staged value
/// (half) or anywhere in the box.
fn rows_around(
    start: &[f64],
    staged: &[f64],
    new_from: usize,
    (lo, hi): (&[f64], &[f64]),
    np: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<f64> {
    let d = lo.len();
    (0..np)
        .flat_map(|i| {
            (0..d)
                .map(|j| {
                    let around = |sd: f64, rng: &mut ChaCha8Rng| {
                        let v = staged[j]
                            + Normal::new(0.0, sd * (hi[j] - lo[j])).map_or(0.0, |n| n.sample(rng));
                        v.clamp(lo[j], hi[j])
                    };
                    match i {
                        0 => start[j],
                        1 => staged[j],
                        _ if j < new_from => around(if i % 2 == 0 { 0.1 } else { 0.02 }, rng),
                        _ if i % 2 == 0 => around(0.05, rng),
                        _ => Uniform::new_inclusive(lo[j], hi[j]).map_or(lo[j], |u| u.sample(rng)),
                    }
                })
                .collect::<Vec<f64>>()
        })
        .collect()
}

/// Differential evolution over the box `lo..hi` from the `initial` rows
/// (the rest of the population drawn uniformly), costs from `cost` in
/// parallel; returns the best point seen and its cost.
fn evolve(
    (lo, hi): (Vec<f64>, Vec<f64>),
    initial: &[f64],
    population: usize,
    generations: usize,
    p_best: f64,
    rng: &mut ChaCha8Rng,
    cost: impl Fn(&[f64]) -> f64 + Sync,
) -> (Vec<f64>, f64) {
    let d = lo.len();
    let bounds = Bounds {
        names: (0..d).map(|j| format!("p{j}")).collect(),
        lower: lo,
        upper: hi,
    };
    let settings = DeSettings {
        p_best,
        ..DeSettings::default()
    };
    let mut de = De::new(settings, bounds, population).with_initial(initial);
    let (mut best, mut best_cost) = (initial[..d].to_vec(), f64::INFINITY);
    for _ in 0..=generations {
        let rows = de.ask(rng);
        let costs: Vec<f64> = rows.par_chunks(d).map(&cost).collect();
        for (row, &c) in rows.chunks(d).zip(&costs) {
            if c < best_cost {
                best_cost = c;
                best = row.to_vec();
            }
        }
        de.tell(&costs.iter().map(|&c| c as f32).collect::<Vec<_>>());
    }
    (best, best_cost)
}

/// Fits `model` with `settings.seeds` seeds (from scratch: `baseline_seeds`
/// of the baseline budget); `start` as in [`fit_candidate`].
pub fn fit_seeds(
    data: &Data,
    model: &Augmented,
    start: Start<'_>,
    settings: &Settings,
    salt: u64,
) -> SeededFit {
    summarize(seed_fits(data, model, start, settings, salt))
}

/// [`fit_seeds`] with the fits from scratch `scratch` ([`scratch_fits`])
/// among the seeds: the first round's fits. A from-scratch baseline fitted
/// to data with an unmodelled effect ends where it compensates the effect
/// best, often far from where the model with the effect fits (on the
/// self-test's `asymmetry (large)` case the baseline's β is 0.34 against the
/// true 0.0002), and a warm start cannot walk back; a search from scratch
/// can.
fn fit_seeds_with(
    data: &Data,
    model: &Augmented,
    start: Start<'_>,
    settings: &Settings,
    salt: u64,
    scratch: &[Fit],
) -> SeededFit {
    let mut fits = seed_fits(data, model, start, settings, salt);
    fits.extend_from_slice(scratch);
    summarize(fits)
}

/// The fits of [`fit_seeds`], one per seed.
fn seed_fits(
    data: &Data,
    model: &Augmented,
    start: Start<'_>,
    settings: &Settings,
    salt: u64,
) -> Vec<Fit> {
    let (seeds, pop, gens) = match start {
        Start::Scratch | Start::Ahead { .. } => (
            settings.baseline_seeds,
            settings.baseline_population,
            settings.baseline_generations,
        ),
        Start::Warm { .. } => (settings.seeds, settings.population, settings.generations),
    };
    (0..seeds.max(1) as u64)
        .map(|i| {
            let seed = settings.seed + 1000 * salt + i;
            fit_candidate(data, model, start, seed, pop, gens)
        })
        .collect()
}

/// `settings.scratch_seeds` fits of `model` from scratch through the
/// multi-step-ahead predictor ([`Start::Ahead`]) with the baseline's
/// population and generations. They do not depend on the current model, so
/// a round that is judged again after a rebase reuses them.
fn scratch_fits(data: &Data, model: &Augmented, settings: &Settings, salt: u64) -> Vec<Fit> {
    let ahead = Start::Ahead {
        horizon: data.horizon(),
    };
    (0..settings.scratch_seeds as u64)
        .map(|i| {
            let seed = settings.seed + 1000 * salt + 500 + i;
            fit_candidate(
                data,
                model,
                ahead,
                seed,
                settings.baseline_population,
                settings.baseline_generations,
            )
        })
        .collect()
}

/// The best fit of several seeds and their spread.
fn summarize(fits: Vec<Fit>) -> SeededFit {
    let seed_val_rmse: Vec<f64> = fits.iter().map(|f| f.val_rmse).collect();
    // The spread among the seeds that reached the best estimation fit (within
    // 1 % of its SSE): how much validation moves between fits the estimation
    // data cannot tell apart. A seed stuck in a worse basin is a failed fit,
    // not a competing answer, and does not widen it.
    let best_sse = fits.iter().map(|f| f.est_sse).fold(f64::INFINITY, f64::min);
    let converged: Vec<f64> = fits
        .iter()
        .filter(|f| f.est_sse <= best_sse * 1.01)
        .map(|f| f.val_rmse)
        .collect();
    let spread = std_dev(&converged);
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

/// How many times a round may replace the current model by a better refit
/// found through a candidate (see [`select`]).
pub const MAX_REBASES: usize = 2;

/// What a candidate is judged against: the current model's validation RMSE
/// `r0` and seed spread `s0`, and the noise-floor estimate.
#[derive(Debug, Clone, Copy)]
struct Yardstick {
    r0: f64,
    s0: f64,
    floor: f64,
}

/// Judges every candidate fit against the yardstick, best
/// validation RMSE first.
fn judge_all(
    fits: &[(Effect, Augmented, SeededFit)],
    yardstick: Yardstick,
    n: f64,
    settings: &Settings,
) -> Vec<Candidate> {
    let mut candidates: Vec<Candidate> = fits
        .iter()
        .map(|(e, m, f)| Candidate::judge(*e, m.clone(), f.clone(), yardstick, n, settings))
        .collect();
    candidates.sort_by(|a, b| a.fit.best.val_rmse.total_cmp(&b.fit.best.val_rmse));
    candidates
}

/// One round of forward selection.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Round {
    /// The current model refitted with the candidates' budget.
    pub current: SeededFit,
    /// Fits of the current model (without the new effect) that beat it on
    /// the estimation part and replaced it, in order: `current` itself when
    /// its seeds found a better fit, then refits started from a passing
    /// candidate's parameters; the candidates are judged against the last.
    pub rebased: Vec<SeededFit>,
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

impl Candidate {
    /// Scores `fit` of `model` (the current model plus `effect`) against the
    /// current model's validation RMSE `r0` and seed spread `s0` by the
    /// acceptance rule; `n` validation samples.
    fn judge(
        effect: Effect,
        model: Augmented,
        fit: SeededFit,
        Yardstick { r0, s0, floor }: Yardstick,
        n: f64,
        settings: &Settings,
    ) -> Candidate {
        let datasets = model.datasets;
        let r1 = fit.best.val_rmse;
        let k = effect.dim(datasets) as f64;
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
        let rule4 = r0 > settings.floor_margin * floor;
        let passes = rule1 && rule2 && rule3 && rule4 && r1.is_finite();
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
        if !rule4 {
            why.push(format!(
                "the current model ({r0:.3}) is within {:.0} % of the noise floor {floor:.3}",
                100.0 * (settings.floor_margin - 1.0)
            ));
        }
        let reason = if !r1.is_finite() {
            "the best fit on the estimation part diverges on the validation part".to_string()
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
            .params(datasets)
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
    }
}

/// Fits the baseline, then runs forward selection over `effects`.
///
/// **Ablation.** Before the best passing candidate is accepted, the current
/// model is refitted without the effect, started from the candidate's own
/// parameters. A misspecified fit can end in a basin it cannot leave alone,
/// and a candidate's refit (warm-started, with one more parameter to move
/// along) may find a better one: then most of the candidate's gain is the
/// current model's, reached from a new start. If that refit is better on the
/// estimation part than the current model, it becomes the current model
/// (`Round::rebased`) and the round is judged again against it; the effect
/// is credited only with what the model without it cannot reach from the
/// same place. At most [`MAX_REBASES`] times a round.
pub fn select(
    data: &Data,
    family: Family,
    effects: &[Effect],
    settings: &Settings,
    floor: f64,
) -> Selection {
    let baseline_model = Augmented::new(family, Vec::new(), data.datasets());
    let mut baseline = fit_seeds(data, &baseline_model, Start::Scratch, settings, 0);
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
        let remaining_models: Vec<Augmented> =
            remaining.iter().map(|&e| current_model.with(e)).collect();
        let salt = 100 * (round as u64 + 1);
        let refit = Start::Warm {
            params: &current_params,
            new_from: current_params.len(),
        };
        // The first round adds fits from scratch, computed once per model.
        let first_round = current_model.effects.is_empty();
        let scratch: Vec<Vec<Fit>> = if first_round {
            std::iter::once(&current_model)
                .chain(&remaining_models)
                .enumerate()
                .map(|(i, m)| scratch_fits(data, m, settings, salt + 50 + i as u64))
                .collect()
        } else {
            Vec::new()
        };
        let scratch_of = |i: usize| scratch.get(i).map_or(&[][..], Vec::as_slice);
        let current = fit_seeds_with(data, &current_model, refit, settings, salt, scratch_of(0));
        let mut rebased: Vec<SeededFit> = Vec::new();
        // The refit gives the seed spread of "no new effect". Its seeds (and
        // in the first round its fits from scratch) may also reach a better
        // estimation fit of the current model than the one accepted: then
        // that is the current model, as after an ablation below. Measured on
        // the self-test's `inertia (small)` case: the second round's refit
        // of baseline + inertia reached an estimation SSE of 104.8 against
        // the accepted candidate's 109.5.
        if current.best.est_sse < final_fit.est_sse && current.best.val_rmse.is_finite() {
            current_params = current.best.params.clone();
            final_fit = current.best.clone();
            if first_round {
                baseline = current.clone();
            }
            rebased.push(current.clone());
        }
        let mut yardstick = Yardstick {
            r0: final_fit.val_rmse,
            s0: current.spread,
            floor,
        };
        let mut ablations = 0;
        let candidates = loop {
            let salt = salt + 10 * ablations as u64;
            let fits: Vec<(Effect, Augmented, SeededFit)> = remaining
                .iter()
                .enumerate()
                .zip(&remaining_models)
                .map(|((i, &effect), model)| {
                    let model = model.clone();
                    let (neutral, _, _) = data.space(&model);
                    let mut start = current_params.clone();
                    start.extend_from_slice(&neutral[current_params.len()..]);
                    let start = Start::Warm {
                        params: &start,
                        new_from: current_params.len(),
                    };
                    let salt = salt + 1 + i as u64;
                    let mut fit =
                        fit_seeds_with(data, &model, start, settings, salt, scratch_of(i + 1));
                    let at = current_params.len() + effect.primary();
                    fit.best = profile(data, &model, fit.best, at);
                    (effect, model, fit)
                })
                .collect();
            let candidates = judge_all(&fits, yardstick, n, settings);
            let Some(best) = candidates.iter().find(|c| c.passes) else {
                break candidates;
            };
            if ablations >= MAX_REBASES {
                break candidates;
            }
            let ablated = fit_seeds(
                data,
                &current_model,
                Start::Warm {
                    params: &best.fit.best.params[..current_params.len()],
                    new_from: current_params.len(),
                },
                settings,
                salt + 10,
            );
            if !(ablated.best.est_sse < final_fit.est_sse && ablated.best.val_rmse.is_finite()) {
                break candidates;
            }
            // A better fit of the current model: judge the round again
            // from it, candidates refitted from there.
            current_params = ablated.best.params.clone();
            final_fit = ablated.best.clone();
            if current_model.effects.is_empty() {
                baseline = ablated.clone();
            }
            yardstick = Yardstick {
                r0: ablated.best.val_rmse,
                s0: ablated.spread,
                floor,
            };
            rebased.push(ablated);
            ablations += 1;
        };
        let accepted = candidates.iter().find(|c| c.passes).map(|c| c.effect);
        if let Some(c) = candidates.iter().find(|c| c.passes) {
            current_model = c.model.clone();
            current_params = c.fit.best.params.clone();
            final_fit = c.fit.best.clone();
            verdict.push(c.effect);
        }
        rounds.push(Round {
            current,
            rebased,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::presets::thesis_params;
    use crate::model::simulate;

    /// A stair of pressures through a valve (pole 0.6) and the thesis'
    /// classic model's response (Table 1), plus 0.1 mm of seeded noise.
    fn stair_data() -> Data {
        let levels = [0.05, 0.2, 0.35, 0.5, 0.3, 0.1, 0.25, 0.45, 0.15];
        let mut p = vec![levels[0]; 1080];
        for k in 1..p.len() {
            p[k] = 0.6 * p[k - 1] + 0.4 * levels[(k / 60) % levels.len()];
        }
        let theta: Vec<f32> = thesis_params(Family::Classic)
            .iter()
            .map(|&v| v as f32)
            .collect();
        let u: Vec<f32> = p.iter().map(|&v| v as f32).collect();
        let x = simulate(Family::Classic, &theta, &u, 0.0).x;
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let noise = Normal::new(0.0, 0.1).unwrap();
        let y = x
            .iter()
            .map(|&v| v as f64 + noise.sample(&mut rng))
            .collect();
        Data::new(&[Trace::uniform("stair", 0.1, p, y)]).unwrap()
    }

    #[test]
    fn the_polish_walks_back_along_the_slow_poles_valley() {
        let data = stair_data();
        let model = Augmented::new(Family::Classic, Vec::new(), 1);
        let (_, lo, hi) = data.space(&model);
        let clamp = |p: Vec<f64>| -> Vec<f64> {
            p.iter()
                .zip(lo.iter().zip(&hi))
                .map(|(v, (l, h))| v.clamp(*l, *h))
                .collect()
        };
        // The least-squares fit nearest the generating model is the reference
        // (the data's own coordinates shift the intercept).
        let start = clamp(thesis_params(Family::Classic));
        let start_sse = data.est_sse(&model, &start);
        let (reference, reference_sse) = polish(&data, &model, start, start_sse, (&lo, &hi));
        assert!(reference_sse < start_sse);
        // One percent off in α, a needle's width across the valley.
        let mut off = reference.clone();
        off[1] *= 0.99;
        let off_sse = data.est_sse(&model, &off);
        assert!(
            off_sse > 10.0 * reference_sse,
            "{off_sse} vs {reference_sse}"
        );
        let (back, back_sse) = polish(&data, &model, off, off_sse, (&lo, &hi));
        assert!(
            back_sse < 1.01 * reference_sse,
            "{back_sse} vs {reference_sse}"
        );
        assert!(
            (back[1] - reference[1]).abs() < 1e-3 * reference[1],
            "α {} vs {}",
            back[1],
            reference[1]
        );
    }

    #[test]
    fn the_polish_never_leaves_a_fit_worse_than_the_search_did() {
        let data = stair_data();
        let model = Augmented::new(Family::Classic, Vec::new(), 1);
        let (neutral, lo, hi) = data.space(&model);
        let sse = data.est_sse(&model, &neutral);
        let (p, polished) = polish(&data, &model, neutral.clone(), sse, (&lo, &hi));
        assert!(polished <= sse);
        assert_eq!(polished, data.est_sse(&model, &p));
        assert!(
            p.iter()
                .zip(lo.iter().zip(&hi))
                .all(|(v, (l, h))| l <= v && v <= h)
        );
    }
}
