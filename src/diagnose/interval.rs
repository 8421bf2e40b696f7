//! How well the data pin each named effect's size: a profile-likelihood
//! interval (Venzon & Moolgavkar 1988, "A method for computing
//! profile-likelihood-based confidence intervals", Appl. Statist. 37(1)).
//!
//! The size (the effect's primary parameter) is held at values stepped away
//! from the estimate, every other parameter refitted at each; the interval
//! is where the estimation SSE stays within `χ²₁(95 %)·σ̂²` of its minimum,
//! `σ̂² = SSE/(N − p)`. A Jacobian's standard error is no substitute here:
//! the `f32` simulation's rounding makes the curvature of a flat profile look
//! steep (measured on the self-test: docs/lab/diagnosis.md, "How sure: the
//! size's interval"). The interval assumes white residuals; on real data,
//! where the residual is correlated (see the whiteness test), it is too
//! narrow.

use serde::Serialize;

use super::effects::Effect;
use super::fitting::polish_held;
use super::likelihood::CHI2_1_95;
use crate::fit::problem::FitProblem;
use crate::fit::searches::Searches;

/// The profile interval of one effect's size.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SizeInterval {
    pub effect: Effect,
    /// The parameter profiled (the effect's primary one).
    pub param: String,
    pub value: f64,
    /// 95 % bounds; a bound on the search box's edge means the data do not
    /// bound the size on that side within the box.
    pub lo: f64,
    pub hi: f64,
    pub lo_at_edge: bool,
    pub hi_at_edge: bool,
}

impl SizeInterval {
    /// The interval's ends carried through `size`, a function of the
    /// effect's parameters (`params`, from its offset on) that reads the
    /// primary one as a size in other units, every other parameter held;
    /// low end first.
    pub fn mapped(&self, params: &[f64], size: impl Fn(&[f64]) -> f64) -> (f64, f64) {
        let mut p = params.to_vec();
        let [a, b] = [self.lo, self.hi].map(|v| {
            p[self.effect.primary()] = v;
            size(&p)
        });
        if a.total_cmp(&b).is_le() {
            (a, b)
        } else {
            (b, a)
        }
    }

    /// Whether the search box cuts the interval short on either side.
    pub fn at_edge(&self) -> bool {
        self.lo_at_edge || self.hi_at_edge
    }
}

/// The 95 % profile interval of `effect`'s primary parameter in the
/// problem's model fitted at `theta` on its estimation part.
pub fn size_interval(
    problem: &FitProblem,
    searches: &Searches,
    theta: &[f64],
    effect: Effect,
) -> anyhow::Result<SizeInterval> {
    let at = problem.model.offset_of(effect).expect("effect in model") + effect.primary();
    let (lo, hi) = (&problem.space.lower, &problem.space.upper);
    let sse0 = problem.est_sse(theta);
    let n = problem.est_samples();
    let sigma2 = sse0 / (n.saturating_sub(theta.len()).max(1)) as f64;
    let limit = sse0 + CHI2_1_95 * sigma2;
    // The profile at `v`: every other parameter polished from `start`.
    let profile = |v: f64, start: &[f64]| polish_held(problem, searches, start, (at, v), (lo, hi));
    let value = theta[at];
    let first_step = 0.05 * value.abs().max(1e-2 * (hi[at] - lo[at]));
    let bound = |edge: f64| -> anyhow::Result<(f64, bool)> {
        let dir = (edge - value).signum();
        if dir == 0.0 {
            return Ok((edge, true));
        }
        // Out from the estimate in doubling steps until the profile leaves
        // the limit (each node started from the one before: the rest of the
        // model moves along with the size), then bisect the crossing.
        let (mut inside, mut start) = (value, theta.to_vec());
        let mut step = first_step;
        loop {
            let v = value + dir * step;
            if (v - edge) * dir >= 0.0 {
                let (_, sse) = profile(edge, &start)?;
                if sse <= limit {
                    return Ok((edge, true));
                }
                return Ok((bisect(inside, edge, &start, &profile, limit)?, false));
            }
            let (p, sse) = profile(v, &start)?;
            if sse > limit {
                return Ok((bisect(inside, v, &start, &profile, limit)?, false));
            }
            inside = v;
            start = p;
            step *= 2.0;
        }
    };
    let (lo_v, lo_at_edge) = bound(lo[at])?;
    let (hi_v, hi_at_edge) = bound(hi[at])?;
    Ok(SizeInterval {
        effect,
        param: problem.model.param_names()[at].clone(),
        value,
        lo: lo_v,
        hi: hi_v,
        lo_at_edge,
        hi_at_edge,
    })
}

/// The crossing of the profile with `limit` between `inside` (within it) and
/// `outside`, to 1/64 of their distance.
fn bisect(
    mut inside: f64,
    mut outside: f64,
    start: &[f64],
    profile: &impl Fn(f64, &[f64]) -> anyhow::Result<(Vec<f64>, f64)>,
    limit: f64,
) -> anyhow::Result<f64> {
    let mut start = start.to_vec();
    for _ in 0..6 {
        let mid = 0.5 * (inside + outside);
        let (p, sse) = profile(mid, &start)?;
        if sse <= limit {
            inside = mid;
            start = p;
        } else {
            outside = mid;
        }
    }
    Ok(0.5 * (inside + outside))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Trace;
    use crate::diagnose::fitting::polish;
    use crate::model::Family;
    use crate::model::presets::thesis_params;
    use crate::model::simulate;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// A stair through a valve (pole 0.6) and the thesis' classic model with
    /// an asymmetry of `eps`, plus `sigma` of seeded white noise; the model
    /// and the fit nearest the generating parameters.
    fn asymmetric_stair(eps: f64, sigma: f64) -> (FitProblem, Vec<f64>) {
        let levels = [0.05, 0.2, 0.35, 0.5, 0.3, 0.1, 0.25, 0.45, 0.15];
        let mut p = vec![levels[0]; 1080];
        for k in 1..p.len() {
            p[k] = 0.6 * p[k - 1] + 0.4 * levels[(k / 60) % levels.len()];
        }
        let u: Vec<f32> = p.iter().map(|&v| v as f32).collect();
        let thesis = thesis_params(Family::Classic);
        let theta: Vec<f32> = thesis.iter().map(|&v| v as f32).collect();
        let plain = simulate(Family::Classic, &theta, 0.0, &u, 0.0).x;
        let plain: Vec<f64> = plain.iter().map(|&v| v as f64).collect();
        let clean = FitProblem::diagnosis(
            &[Trace::uniform("stair", 0.1, p.clone(), plain)],
            Family::Classic,
            None,
            crate::diagnose::Settings::default().blocks,
        )
        .expect("valid stair");
        // The thesis' model in the data's deviation coordinates: the fit to
        // its own noiseless response nearest its parameters.
        let (lo, hi) = (clean.space.lower.clone(), clean.space.upper.clone());
        let start: Vec<f64> = thesis
            .iter()
            .zip(lo.iter().zip(&hi))
            .map(|(v, (l, h))| v.clamp(*l, *h))
            .collect();
        let sse = clean.est_sse(&start);
        let (mut truth, _) = polish(&clean, &Searches::cpu(), start, sse, (&lo, &hi)).unwrap();
        truth.push(eps);
        let model = clean.model.with(Effect::Asymmetry);
        let theta: Vec<f32> = truth.iter().map(|&v| v as f32).collect();
        let y = model.simulate(&theta, 0, &clean.records.ctx[0], &clean.records.whole[0]);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let noise = Normal::new(0.0, sigma).unwrap();
        let y: Vec<f64> = y
            .iter()
            .map(|&v| v as f64 + clean.records.whole[0].y_mean + noise.sample(&mut rng))
            .collect();
        let data = FitProblem::diagnosis(
            &[Trace::uniform("stair", 0.1, p, y)],
            Family::Classic,
            None,
            crate::diagnose::Settings::default().blocks,
        )
        .expect("valid stair")
        .with_model(&model);
        let (lo, hi) = (data.space.lower.clone(), data.space.upper.clone());
        let sse = data.est_sse(&truth);
        let (fit, _) = polish(&data, &Searches::cpu(), truth, sse, (&lo, &hi)).unwrap();
        (data, fit)
    }

    #[test]
    fn the_interval_holds_the_truth_and_widens_with_the_noise() {
        let eps = 0.1;
        let (data, fit) = asymmetric_stair(eps, 0.05);
        let quiet = size_interval(&data, &Searches::cpu(), &fit, Effect::Asymmetry).unwrap();
        assert!(quiet.lo <= eps && eps <= quiet.hi, "{quiet:?}");
        assert!(
            quiet.lo < quiet.value && quiet.value < quiet.hi,
            "{quiet:?}"
        );
        assert!(!quiet.lo_at_edge && !quiet.hi_at_edge, "{quiet:?}");
        // Four times the noise: the interval scales with σ for a parameter
        // the data pin (the profile is near-parabolic at this size).
        let (data, fit) = asymmetric_stair(eps, 0.2);
        let loud = size_interval(&data, &Searches::cpu(), &fit, Effect::Asymmetry).unwrap();
        assert!(loud.lo <= eps && eps <= loud.hi, "{loud:?}");
        let ratio = (loud.hi - loud.lo) / (quiet.hi - quiet.lo);
        assert!(
            (2.5..6.0).contains(&ratio),
            "width ratio {ratio}: {quiet:?} {loud:?}"
        );
    }

    /// The ends carried through a size that falls as the primary
    /// parameter grows: the low end comes first, and every other
    /// parameter is held.
    #[test]
    fn an_interval_mapped_through_a_size_keeps_the_other_parameters() {
        let iv = SizeInterval {
            effect: Effect::Ratchet,
            param: "set:ratchet.a".into(),
            value: 1.0,
            lo: 0.5,
            hi: 2.0,
            lo_at_edge: false,
            hi_at_edge: true,
        };
        // A size that falls with `a` and reads `q` as it was.
        let ends = iv.mapped(&[1.0, 0.25], |p| p[1] - p[0]);
        assert_eq!(ends, (0.25 - 2.0, 0.25 - 0.5));
        assert!(iv.at_edge());
    }
}
