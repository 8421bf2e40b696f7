//! How much of the gap is explainable at all: a flexible model of the
//! baseline's residual, fitted on the estimation half and scored on the
//! selection part, gives a reference for how far *any* model driven by the
//! same signals could close the gap; the named effects are reported as
//! shares of it, and a large reference that the catalogue closes little of
//! is reported as "not explained by the catalogue".
//!
//! **Why a model of the residual.** Residual analysis asks whether what the
//! model leaves still depends on past inputs (Ljung, *System
//! Identification*, 2nd ed., §16.6 "Residual analysis": a residual that
//! correlates with past inputs means the model has left input-driven
//! dynamics unexplained); fitting that dependence with a flexible model
//! turns the yes/no test into an amount. The model is a NARX-style
//! regression (Billings, *Nonlinear System Identification: NARMAX Methods*,
//! 2013) restricted to what a model could use in **free run**: lags and
//! filters of the input, its rate and branch, and the baseline's own
//! prediction. Never the measured output: with it the regression becomes a
//! one-step-ahead predictor that "explains" noise and drift by copying the
//! last measurement, which no simulation model can do.
//!
//! **What the number means.** The reference is what a ridge regression on
//! these features achieves on selection data it never saw, so it is an
//! estimate, not a theorem: an effect whose mark lies outside the span of the
//! features (a hard nonlinearity deep in the state) can close more, and so
//! can a physical effect refitted jointly with the baseline when the record
//! is short (as on the Cavatappi files: docs/DIAGNOSIS.md, "When not to
//! trust the result"); a share above 100 % says just that. The groups of
//! features and the penalty are chosen by blocked cross-validation on the
//! estimation half ([`ridge`](super::ridge)).

use std::ops::Range;

use serde::Serialize;

use super::Step;
use super::accept::gap_closed;
use super::effects::Effect;
use super::locate::{Band, Share, Where};
use super::ridge::{Problem, Ridge, RidgeSettings};
use super::spectrum::Peak;

/// One dataset's signals over the whole record.
#[derive(Debug, Clone, Copy)]
pub struct Signals<'a> {
    /// Input in absolute units.
    pub input: &'a [f64],
    /// The baseline's free-run prediction from the first sample.
    pub prediction: &'a [f64],
    /// The measured output, in the prediction's coordinates.
    pub measured: &'a [f64],
    /// End of the estimation half, which the flexible model is fitted on.
    pub est_end: usize,
    /// The samples it is scored on (the selection blocks).
    pub scored: &'a [Range<usize>],
}

/// The explainable bound of the baseline's residual `r = y − ŷ`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Bound {
    /// Selection RMSE of `r` (the baseline's).
    pub baseline_rmse: f64,
    /// Selection RMSE of `r − r̂`, `r̂` the flexible model's prediction.
    pub bound_rmse: f64,
    /// The noise floor the gaps are measured against.
    pub floor_rmse: f64,
    /// Share of the baseline's gap above the noise floor that `r̂` closes
    /// (the definition of [`gap_closed`]).
    pub gap_closable: f64,
    /// Penalty chosen by cross-validation, features offered, and the
    /// groups of them selected (the signals that explain the residual).
    pub lambda: f64,
    pub features: usize,
    pub groups: Vec<&'static str>,
}

/// Time constants (samples) of the Laguerre banks on the input, 8 functions
/// each: 3 samples for the fast transients (delay, valve), 10 and 30 for
/// ringing and lag (a 4 Hz ringing at 100 Hz has a 25-sample period).
const LAGUERRE_TAUS: [f64; 3] = [3.0, 10.0, 30.0];
const LAGUERRE_ORDER: usize = 8;
/// Time constants (samples) of first-order low-passes of the input: slow
/// creep and drift during holds, up to tens of seconds at 100 Hz.
const SLOW_TAUS: [f64; 4] = [100.0, 300.0, 1000.0, 3000.0];
/// Plain input lags (samples): a delay or a fast transient.
const LAGS: usize = 64;
/// Lags of the baseline prediction (samples).
const PRED_LAGS: [usize; 5] = [0, 1, 2, 4, 8];
/// Input move, as a share of its range, that switches the branch (as the
/// `asymmetry` effect's).
const BRANCH_TOL: f64 = 0.02;

/// What the features are built from, shared by all datasets.
struct Scales {
    u_ref: f64,
    branch_tol: f64,
    /// Quintile edges of the input and of the prediction on the estimation rows.
    u_knots: [f64; 4],
    y_knots: [f64; 4],
}

fn quintile_knots(mut v: Vec<f64>) -> [f64; 4] {
    v.sort_by(f64::total_cmp);
    let at = |f: f64| v[((f * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)];
    [at(0.2), at(0.4), at(0.6), at(0.8)]
}

/// First-order low-pass `z(k) = p·z(k−1) + (1−p)·x(k)`, started at rest at `x(0)`.
fn low_pass(x: &[f64], tau: f64) -> Vec<f64> {
    let p = (-1.0 / tau).exp();
    let mut z = x.first().copied().unwrap_or(0.0);
    x.iter()
        .map(|&v| {
            z = p * z + (1.0 - p) * v;
            z
        })
        .collect()
}

/// The first `order` Laguerre filters of `x` with pole `exp(−1/τ)`
/// (Wahlberg 1991): a low-pass followed by all-pass sections. Together they
/// are an orthonormal basis of stable impulse responses, so a few of them
/// represent a long or oscillating response that plain lags would need a
/// hundred terms for. Started in steady state at `x(0)`.
fn laguerre(x: &[f64], tau: f64, order: usize) -> Vec<Vec<f64>> {
    let p = (-1.0 / tau).exp();
    let g = (1.0 - p * p).sqrt();
    let x0 = x.first().copied().unwrap_or(0.0);
    // All-pass sections have unit DC gain, so every state starts at the first one's.
    let mut state = vec![g / (1.0 - p) * x0; order];
    // Each all-pass section's input at the step before (section i−1's output).
    let mut prev_in = state.clone();
    let mut out = vec![Vec::with_capacity(x.len()); order];
    for &v in x {
        state[0] = p * state[0] + g * v;
        out[0].push(state[0]);
        for i in 1..order {
            let input = state[i - 1];
            state[i] = p * state[i] + prev_in[i] - p * input;
            prev_in[i] = input;
            out[i].push(state[i]);
        }
    }
    out
}

/// The feature groups, in the order [`features`] lays them out: the
/// selection in [`bound`] adds whole groups, so that one kind of signal
/// that does not generalise does not force a large penalty on the rest.
fn groups(datasets: usize) -> Vec<(&'static str, usize)> {
    let mut g = vec![
        ("input lags", LAGS + 1),
        ("input fast filters", LAGUERRE_ORDER),
        ("input mid filters", LAGUERRE_ORDER),
        ("input slow filters", LAGUERRE_ORDER),
        ("input drift filters", SLOW_TAUS.len()),
        ("input rate", 4),
        ("branch", 4),
        ("prediction lags", PRED_LAGS.len()),
        ("level", 3 + 4 + 4),
    ];
    if datasets > 1 {
        g.push(("dataset", 3 * (datasets - 1)));
    }
    g
}

/// The feature rows of one dataset (one row per sample), grouped as [`groups`].
fn features(s: &Signals, dataset: usize, datasets: usize, sc: &Scales) -> Vec<Vec<f64>> {
    let n = s.input.len();
    let u: Vec<f64> = s.input.iter().map(|v| v - sc.u_ref).collect();
    let lag = |x: &[f64], k: usize, j: usize| x[k.saturating_sub(j)];
    let banks: Vec<Vec<f64>> = LAGUERRE_TAUS
        .iter()
        .flat_map(|&t| laguerre(&u, t, LAGUERRE_ORDER))
        .chain(SLOW_TAUS.iter().map(|&t| low_pass(&u, t)))
        .collect();
    let du: Vec<f64> = (0..n).map(|k| u[k] - lag(&u, k, 1)).collect();
    let abs_du: Vec<f64> = du.iter().map(|v| v.abs()).collect();
    let rate_memory = [low_pass(&abs_du, 10.0), low_pass(&abs_du, 100.0)];
    // Branch: +1 loading, −1 unloading, switching after a reversal of
    // BRANCH_TOL of the range.
    let (mut dir, mut extreme) = (1.0, u.first().copied().unwrap_or(0.0));
    let branch: Vec<f64> = u
        .iter()
        .map(|&v| {
            if dir > 0.0 {
                extreme = extreme.max(v);
                if v < extreme - sc.branch_tol {
                    (dir, extreme) = (-1.0, v);
                }
            } else {
                extreme = extreme.min(v);
                if v > extreme + sc.branch_tol {
                    (dir, extreme) = (1.0, v);
                }
            }
            dir
        })
        .collect();
    let (u10, u100) = (low_pass(&u, 10.0), low_pass(&u, 100.0));
    let y = s.prediction;
    (0..n)
        .map(|k| {
            let mut row: Vec<f64> = (0..=LAGS).map(|j| lag(&u, k, j)).collect();
            row.extend(banks.iter().map(|b| b[k]));
            row.extend([du[k], abs_du[k], rate_memory[0][k], rate_memory[1][k]]);
            let d = branch[k];
            row.extend([d, d * u[k], d * u10[k], d * u100[k]]);
            row.extend(PRED_LAGS.iter().map(|&j| lag(y, k, j)));
            row.extend([y[k] * y[k], y[k] * u[k], u[k] * u[k]]);
            // Hinges at the quintiles: a gain that changes with level
            // (dead zone, end stop) as a piecewise-linear function.
            row.extend(sc.u_knots.iter().map(|q| (s.input[k] - q).max(0.0)));
            row.extend(sc.y_knots.iter().map(|q| (y[k] - q).max(0.0)));
            // Per dataset (e.g. per load): an offset and a gain of its own.
            for e in 1..datasets {
                let on = f64::from(u8::from(e == dataset));
                row.extend([on, on * u[k], on * y[k]]);
            }
            row
        })
        .collect()
}

/// A group joins the model only if it lowers the cross-validated error by
/// at least this share: a smaller gain is within what the choice among
/// groups gains by chance.
const MIN_GROUP_GAIN: f64 = 0.01;

/// Forward selection of whole groups (Hastie, Tibshirani & Friedman, *The
/// Elements of Statistical Learning*, §3.3): from the intercept alone, add
/// the group whose ridge fit (penalty by blocked cross-validation) has the
/// lowest cross-validated error, while it improves by [`MIN_GROUP_GAIN`].
fn select_groups(
    problem: &Problem,
    layout: &[(&'static str, usize)],
) -> Option<(Ridge, Vec<&'static str>)> {
    let mut ranges = Vec::new();
    let mut at = 0;
    for &(name, len) in layout {
        ranges.push((name, at..at + len));
        at += len;
    }
    let mut cols: Vec<usize> = Vec::new();
    let mut chosen = Vec::new();
    let mut best = problem.fit(&cols)?;
    loop {
        let trial = ranges
            .iter()
            .filter(|(name, _)| !chosen.contains(name))
            .filter_map(|(name, r)| {
                let with: Vec<usize> = cols.iter().copied().chain(r.clone()).collect();
                problem.fit(&with).map(|f| (*name, with, f))
            })
            .min_by(|a, b| a.2.cv_mse.total_cmp(&b.2.cv_mse));
        match trial {
            Some((name, with, fit)) if fit.cv_mse < (1.0 - MIN_GROUP_GAIN) * best.cv_mse => {
                chosen.push(name);
                cols = with;
                best = fit;
            }
            _ => break,
        }
    }
    Some((best, chosen))
}

/// Fits the flexible model of `r = measured − prediction` on the estimation
/// part of every dataset and scores it on the selection part.
pub fn bound(sets: &[Signals], floor: f64, settings: &RidgeSettings) -> anyhow::Result<Bound> {
    anyhow::ensure!(!sets.is_empty(), "no data for the explainable bound");
    let est_u: Vec<f64> = sets
        .iter()
        .flat_map(|s| s.input[..s.est_end].iter().copied())
        .collect();
    let est_y: Vec<f64> = sets
        .iter()
        .flat_map(|s| s.prediction[..s.est_end].iter().copied())
        .collect();
    anyhow::ensure!(!est_u.is_empty(), "no estimation samples");
    let (lo, hi) = est_u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let sc = Scales {
        u_ref: est_u.iter().sum::<f64>() / est_u.len() as f64,
        branch_tol: BRANCH_TOL * (hi - lo),
        u_knots: quintile_knots(est_u),
        y_knots: quintile_knots(est_y),
    };
    let (mut x_est, mut r_est, mut x_val, mut r_val) = (vec![], vec![], vec![], vec![]);
    for (i, s) in sets.iter().enumerate() {
        let rows = features(s, i, sets.len(), &sc);
        for (k, row) in rows.into_iter().enumerate() {
            let r = s.measured[k] - s.prediction[k];
            // The first sample is the simulation's initial condition.
            if k == 0 {
                continue;
            }
            if k < s.est_end {
                x_est.push(row);
                r_est.push(r);
            } else if s.scored.iter().any(|b| b.contains(&k)) {
                x_val.push(row);
                r_val.push(r);
            }
        }
    }
    anyhow::ensure!(!r_val.is_empty(), "no selection samples");
    let layout = groups(sets.len());
    debug_assert_eq!(
        layout.iter().map(|g| g.1).sum::<usize>(),
        x_est.first().map_or(0, Vec::len)
    );
    let problem = Problem::new(&x_est, &r_est, settings)?;
    let (fit, chosen) = select_groups(&problem, &layout)
        .ok_or_else(|| anyhow::anyhow!("explainable bound: no penalty gives a finite fit"))?;
    let n = r_val.len() as f64;
    let baseline_rmse = (r_val.iter().map(|r| r * r).sum::<f64>() / n).sqrt();
    let bound_rmse = (x_val
        .iter()
        .zip(&r_val)
        .map(|(x, r)| (r - fit.predict(x)).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    Ok(Bound {
        baseline_rmse,
        bound_rmse,
        floor_rmse: floor,
        gap_closable: gap_closed(baseline_rmse, bound_rmse, floor),
        lambda: fit.lambda,
        features: x_est.first().map_or(0, Vec::len),
        groups: chosen,
    })
}

/// Below this closable share the bound is too small to share out: the
/// flexible model finds next to nothing to explain.
pub const MIN_BOUND: f64 = 0.05;
/// The bound counts as large when the flexible model closes at least this
/// share of the gap above the noise floor: on white residuals it closes
/// less than 1 % (`pure_noise_leaves_nothing_to_close`), so 30 % is far
/// beyond chance, and a third of the gap is worth a person's look.
pub const LARGE_BOUND: f64 = 0.3;
/// "Not explained by the catalogue" when the named effects close less than
/// this share of the bound (most of what is explainable is something
/// else), or when the flexible model leaves less than this share of what
/// the final model leaves above the floor (the catalogue fitted most of
/// the gap with effects that are not its shape, as a band-pass two-pole
/// creep fits the independent self-test's sensor cross-talk; on the
/// self-test's catalogued effects the second condition adds no flag to
/// the first: docs/lab/diagnosis.md, "How much is explainable at all").
pub const SMALL_SHARE: f64 = 0.5;

/// One named effect's share of the bound.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EffectShare {
    pub effect: Effect,
    /// Gap closed by adding this effect to the model before it.
    pub gap_closed: f64,
    /// That, over the bound's closable share; `None` when the bound is below [`MIN_BOUND`].
    pub share: Option<f64>,
}

/// Where the residual that the catalogue leaves lies: the most
/// over-represented class of each breakdown of [`locate`](super::locate).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Signature {
    /// Input-level band with the highest energy per sample.
    pub level: Band,
    /// Branch (rising, falling, steady) with the highest energy per sample.
    pub branch: &'static str,
    pub branch_share: Share,
    /// Frequency band holding the most energy.
    pub band: Band,
    /// The largest spectral peak of that residual, if any.
    pub peak: Option<Peak>,
}

/// The bound shared out among the named effects, and the verdict.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Explainable {
    pub bound: Bound,
    pub effect_shares: Vec<EffectShare>,
    /// The final model's gap closed over the bound's (`None` below [`MIN_BOUND`]).
    pub catalogue_share: Option<f64>,
    /// The verdict: the bound is large and the catalogue closes little of it.
    pub not_explained: bool,
    /// Where the final model's residual lies: the pointer for a person.
    pub signature: Option<Signature>,
}

fn ratio(s: &Share) -> f64 {
    if s.samples > 0.0 {
        s.energy / s.samples
    } else {
        0.0
    }
}

/// The signature of a residual broken down by `place`, with its largest peak.
pub fn signature(place: &Where, peak: Option<Peak>) -> Option<Signature> {
    let by_ratio = |a: &&Band, b: &&Band| ratio(&a.share).total_cmp(&ratio(&b.share));
    let level = *place.input_band.iter().max_by(by_ratio)?;
    let band = *place
        .frequency
        .iter()
        .max_by(|a, b| a.share.energy.total_cmp(&b.share.energy))?;
    let b = &place.branch;
    let (branch, branch_share) = [
        ("rising", b.rising),
        ("falling", b.falling),
        ("steady", b.steady),
    ]
    .into_iter()
    .max_by(|x, y| ratio(&x.1).total_cmp(&ratio(&y.1)))?;
    Some(Signature {
        level,
        branch,
        branch_share,
        band,
        peak,
    })
}

/// Shares `bound` out among the effects accepted along `steps` (baseline
/// first); `remaining` is the signature of the final model's residual, the
/// pointer that goes with a "not explained by the catalogue" verdict. The
/// second condition of that verdict ([`SMALL_SHARE`]) holds only while the
/// final model still misses the floor by `floor_margin`, the selection's
/// own margin (a model at the floor has nothing left to explain).
pub fn judge(
    bound: Bound,
    steps: &[Step],
    remaining: Option<Signature>,
    floor_margin: f64,
) -> Explainable {
    let sized = bound.gap_closable >= MIN_BOUND;
    let of_bound = |g: f64| sized.then(|| g / bound.gap_closable);
    let effect_shares = steps
        .windows(2)
        // A step that adds one effect credits it; the chain a selection
        // started from (`diagnose --from`) is credited to none of its own.
        .filter(|w| w[1].effects.len() == w[0].effects.len() + 1)
        .filter_map(|w| {
            let effect = *w[1].effects.last()?;
            let gap = w[1].gap_closed - w[0].gap_closed;
            Some(EffectShare {
                effect,
                gap_closed: gap,
                share: of_bound(gap),
            })
        })
        .collect();
    let closed = steps.last().map_or(0.0, |s| s.gap_closed);
    let catalogue_share = of_bound(closed);
    let closes_little = catalogue_share.is_some_and(|s| s < SMALL_SHARE);
    let final_rmse = steps
        .last()
        .map_or(bound.baseline_rmse, |s| s.selection_rmse);
    let leaves_more = (1.0 - bound.gap_closable) < SMALL_SHARE * (1.0 - closed)
        && final_rmse > floor_margin * bound.floor_rmse;
    let not_explained = bound.gap_closable >= LARGE_BOUND && (closes_little || leaves_more);
    Explainable {
        bound,
        effect_shares,
        catalogue_share,
        not_explained,
        signature: remaining,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal, Uniform};

    const N: usize = 2000;

    fn noise(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let d = Normal::new(0.0, sigma).unwrap();
        (0..n).map(|_| d.sample(&mut rng)).collect()
    }

    /// A stair of random pressure levels held 50–150 samples each.
    fn stair(seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (level, hold) = (
            Uniform::new(0.0, 0.5).unwrap(),
            Uniform::new(50, 150).unwrap(),
        );
        let mut u = Vec::with_capacity(N);
        while u.len() < N {
            let v = level.sample(&mut rng);
            let h = hold.sample(&mut rng);
            u.extend(std::iter::repeat_n(v, h));
        }
        u.truncate(N);
        u
    }

    /// The bound when the measured output is a baseline's prediction plus `residual`.
    fn bound_of(u: &[f64], residual: &[f64], floor: f64) -> Bound {
        let prediction: Vec<f64> = low_pass(u, 5.0).iter().map(|v| 20.0 * v).collect();
        let measured: Vec<f64> = prediction
            .iter()
            .zip(residual)
            .map(|(a, b)| a + b)
            .collect();
        let scored: Vec<_> = std::iter::once(N / 2..N).collect();
        let s = Signals {
            input: u,
            prediction: &prediction,
            measured: &measured,
            est_end: N / 2,
            scored: &scored,
        };
        bound(&[s], floor, &RidgeSettings::default()).unwrap()
    }

    fn plus(a: &[f64], b: &[f64]) -> Vec<f64> {
        a.iter().zip(b).map(|(x, y)| x + y).collect()
    }

    #[test]
    fn a_residual_that_is_a_filter_of_the_input_is_nearly_all_closable() {
        let u = stair(1);
        let sigma = 0.02;
        // A lag the baseline lacks, and a slow creep during holds.
        for (name, tau, gain) in [("lag", 40.0, 2.0), ("creep", 500.0, 3.0)] {
            let r: Vec<f64> = low_pass(&u, tau)
                .iter()
                .zip(&u)
                .map(|(f, v)| gain * (f - v))
                .collect();
            let b = bound_of(&u, &plus(&r, &noise(N, sigma, 2)), sigma);
            assert!(b.gap_closable > 0.9, "{name}: {b:?}");
            assert!(b.groups.iter().any(|g| g.starts_with("input")), "{b:?}");
        }
    }

    #[test]
    fn ringing_after_steps_is_closable() {
        // A damped 4 Hz mode at 100 Hz driven by the input steps.
        let u = stair(3);
        let (w, z) = (2.0 * std::f64::consts::PI * 4.0 * 0.01, 0.08);
        let (a1, a2) = (2.0 * (-z * w).exp() * w.cos(), -(-2.0 * z * w).exp());
        let mut r = vec![0.0; N];
        for k in 2..N {
            r[k] = a1 * r[k - 1] + a2 * r[k - 2] + 0.5 * (u[k] - u[k - 1]);
        }
        let sigma = 0.01;
        let b = bound_of(&u, &plus(&r, &noise(N, sigma, 4)), sigma);
        assert!(b.gap_closable > 0.8, "{b:?}");
    }

    #[test]
    fn pure_noise_leaves_nothing_to_close() {
        let u = stair(5);
        for seed in 6..9 {
            let b = bound_of(&u, &noise(N, 0.1, seed), 0.0);
            assert!(b.gap_closable.abs() < 0.05, "{b:?}");
            assert!(b.groups.is_empty(), "no group helps on noise: {b:?}");
            assert!((b.baseline_rmse - 0.1).abs() < 0.01, "{b:?}");
        }
    }

    #[test]
    fn laguerre_filters_start_in_steady_state_and_are_orthonormal() {
        // Impulse responses: unit energy, mutually orthogonal.
        let mut imp = vec![0.0; 2000];
        imp[1] = 1.0; // from rest
        let l = laguerre(&imp, 10.0, 4);
        for i in 0..4 {
            for j in 0..4 {
                let dot: f64 = l[i].iter().zip(&l[j]).map(|(a, b)| a * b).sum();
                let want = f64::from(u8::from(i == j));
                assert!((dot - want).abs() < 1e-9, "<L{i}, L{j}> = {dot}");
            }
        }
        let flat = laguerre(&[2.0; 50], 10.0, 4);
        for f in &flat {
            assert!(
                (f[49] - f[0]).abs() < 1e-12,
                "not at rest: {} vs {}",
                f[0],
                f[49]
            );
        }
    }

    fn step(gap: f64, effects: Vec<Effect>) -> Step {
        Step {
            effects,
            gap_closed: gap,
            ..Step::default()
        }
    }

    fn bound_closing(share: f64) -> Bound {
        Bound {
            baseline_rmse: 1.0,
            bound_rmse: 0.5,
            floor_rmse: 0.1,
            gap_closable: share,
            lambda: 1.0,
            features: 10,
            groups: vec!["level"],
        }
    }

    #[test]
    fn the_bound_is_shared_out_and_the_verdict_follows_the_thresholds() {
        let steps = vec![
            step(0.0, vec![]),
            step(0.2, vec![Effect::Saturation]),
            step(0.3, vec![Effect::Saturation, Effect::Creep]),
        ];
        let e = judge(bound_closing(0.8), &steps, None, 1.1);
        let shares: Vec<f64> = e.effect_shares.iter().map(|s| s.share.unwrap()).collect();
        assert!((shares[0] - 0.25).abs() < 1e-12 && (shares[1] - 0.125).abs() < 1e-12);
        assert_eq!(e.effect_shares[1].effect, Effect::Creep);
        assert!((e.catalogue_share.unwrap() - 0.375).abs() < 1e-12);
        assert!(e.not_explained, "a large bound, 38 % of it closed");
        // The effects close most of the bound: explained.
        assert!(!judge(bound_closing(0.4), &steps, None, 1.1).not_explained);
        // A small bound: nothing to share out, no verdict.
        let small = judge(bound_closing(0.02), &steps, None, 1.1);
        assert!(small.catalogue_share.is_none() && !small.not_explained);
        assert!(small.effect_shares.iter().all(|s| s.share.is_none()));
    }

    #[test]
    fn a_bound_that_leaves_half_as_much_is_not_explained_while_the_floor_is_missed() {
        // The catalogue closes 96 % of the gap, the flexible model 98 %:
        // it leaves half as much. The final model at 1.0, ten times the floor.
        let mut last = step(0.96, vec![Effect::TwoPoleCreep]);
        last.selection_rmse = 1.0;
        let steps = vec![step(0.0, vec![]), last.clone()];
        let e = judge(bound_closing(0.981), &steps, None, 1.1);
        assert!(e.catalogue_share.unwrap() > 0.9);
        assert!(e.not_explained, "leaves 0.019 of the gap against 0.04");
        // Leaving more than half as much: explained.
        assert!(!judge(bound_closing(0.975), &steps, None, 1.1).not_explained);
        // The final model within the floor's margin: nothing left to explain.
        last.selection_rmse = 0.105;
        let at_floor = vec![step(0.0, vec![]), last];
        assert!(!judge(bound_closing(0.981), &at_floor, None, 1.1).not_explained);
    }
}
