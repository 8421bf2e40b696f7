//! The records a fit or a diagnosis works on: each trace split into an
//! estimation and a validation half (the thesis' split, §4.3.1) in one set
//! of deviation coordinates, the ARX prior of the boxes and the effects'
//! constants. `fit` (one record per file) and `diagnose` (one per load) both
//! split here, in their [`FitProblem`](super::problem::FitProblem), so
//! that a model's parameters mean the same to both.

use std::ops::Range;

use crate::data::{Trace, range};
use crate::ident::arx::{Arx, ArxOrders, linear_prior};
use crate::ident::{pooled_fit_percent, rmse};
use crate::model::effects::{Context, ModelDescription};
use crate::model::experiment::halves;
use crate::model::sim::check_f32_range_about;
use crate::model::{Experiment, LinearPrior, Model, check_f32_range};

/// Validation scores of a parameter vector (output units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Validation {
    pub rmse: f64,
    /// MATLAB `compare` fit, percent.
    pub fit_percent: f64,
}

/// Traces split for a fit.
#[derive(Debug, Clone)]
pub struct Records {
    /// Every trace in the coordinates of the first one's estimation half
    /// (or of the model it is read for).
    pub whole: Vec<Experiment>,
    /// Their estimation halves.
    pub est: Vec<Experiment>,
    /// First validation sample of each.
    pub val_start: Vec<usize>,
    /// The effects' constants of each trace (ranges, branch tolerance, the
    /// end stop's side), from its estimation half; a model's chain keeps its
    /// own on the first.
    pub ctx: Vec<Context>,
    /// What the data say about scale, the boxes' reference
    /// ([`linear_prior`]: ARX on the first trace's estimation half, ranges
    /// over every estimation half).
    pub prior: LinearPrior,
}

impl Records {
    /// Splits `traces` after checking that each can be fitted: finite, long
    /// enough to halve, an input that moves over the estimation half and
    /// values the `f32` simulation can sum. All take the first trace's
    /// estimation means as their origin, so that one absolute model (one
    /// intercept) describes them all and a difference between them (a load)
    /// is a gap, not a shift of means. With `model`, they take its means
    /// instead and the first its chain's constants: then its parameters
    /// describe the same model on these records, whatever record it was
    /// fitted on (`fit --from`, `diagnose --from`): its intercept `c` is
    /// written for its means (the generalized switching level `x_s` is in
    /// absolute units and does not depend on them).
    pub fn of(traces: &[Trace], model: Option<&Model>) -> anyhow::Result<Records> {
        anyhow::ensure!(!traces.is_empty(), "no data to fit");
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
            anyhow::ensure!(
                t.input.iter().chain(&t.output).all(|v| v.is_finite()),
                "{}: the data contain non-finite values",
                t.source
            );
            let (e, v) = halves(t.len());
            let (lo, hi) = t.input[e.clone()]
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                });
            anyhow::ensure!(
                hi > lo,
                "{}: the input `{}` is constant over the estimation half, so there is no dynamics to fit",
                t.source,
                t.input_name
            );
            check_f32_range(t)?;
            if let Some(m) = model {
                check_f32_range_about(t, Some((m.base.input_mean, m.base.output_mean)))?;
            }
            let w = match (model, whole.first()) {
                (Some(m), _) => Experiment::with_offsets(t, m.base.input_mean, m.base.output_mean),
                (None, None) => Experiment::with_means_of(t, e.clone()),
                (None, Some(first)) => Experiment::with_offsets(t, first.u_mean, first.y_mean),
            };
            est.push(w.segment(e));
            val_start.push(v.start);
            whole.push(w);
        }
        let mut prior = linear_prior(traces)?;
        // The coordinates' own origin: the model's, where one is given.
        prior.output_mean = whole[0].y_mean;
        // The constants come from the estimation half alone, as the prior.
        let mut ctx: Vec<Context> = est.iter().map(|e| Context::of(e, prior.b >= 0.0)).collect();
        if let Some(chain) = model.and_then(|m| m.chain.as_ref()) {
            ctx[0] = chain.context;
        }
        Ok(Records {
            whole,
            est,
            val_start,
            ctx,
            prior,
        })
    }

    /// Validation scores of `model` at `theta`: a free run over each whole
    /// record from its first sample, scored on its validation half, the
    /// records pooled (one record: its own RMSE and fit %). Starting afresh
    /// at the validation half with `w = 0` would throw away the hysteretic
    /// state, which the model never forgets: `w` integrates the motion, so
    /// a wrong start offsets the output for good and even the true
    /// parameters would score badly. Infinite RMSE and −∞ fit where a run
    /// is not finite on its validation half. `fit`, `diagnose` and the
    /// generated cases' judge all score here.
    pub fn validate(&self, model: &ModelDescription, theta: &[f64]) -> Validation {
        self.score_on(model, theta, &self.validation_halves())
    }

    /// [`Records::validate`], and each record's own scores beside it (in
    /// order: where one record of several is missed), from the one run over
    /// each record.
    pub fn validate_each(&self, model: &ModelDescription, theta: &[f64]) -> Scores {
        Scores::of(&self.runs_on(model, theta, &self.validation_halves()))
    }

    /// The step in one sample that the measured output keeps within on a
    /// `share` of its steps over every estimation half (its largest at 1;
    /// 0 without steps).
    pub fn measured_step_within(&self, share: f64) -> f64 {
        let mut steps: Vec<f64> = output_steps(&self.est).collect();
        if steps.is_empty() {
            return 0.0;
        }
        let at = ((steps.len() - 1) as f64 * share.clamp(0.0, 1.0)).round() as usize;
        *steps.select_nth_unstable_by(at, f64::total_cmp).1
    }

    /// The largest step in one sample of the measured output over every
    /// whole record (`None` without steps).
    pub fn largest_measured_step(&self) -> Option<f64> {
        output_steps(&self.whole).reduce(f64::max)
    }

    /// The largest step in one sample of `model`'s free run at `theta`
    /// over every record (`None` without parameters, or where no run is
    /// finite): what its hysteresis update steps on.
    pub fn largest_simulated_step(&self, model: &ModelDescription, theta: &[f64]) -> Option<f64> {
        if theta.is_empty() {
            return None;
        }
        self.free_runs(model, theta)
            .into_iter()
            .flat_map(|run| {
                run.windows(2)
                    .map(|p| f64::from((p[1] - p[0]).abs()))
                    .filter(|s| s.is_finite())
                    .collect::<Vec<_>>()
            })
            .reduce(f64::max)
    }

    /// The RMS of the difference between `model`'s free runs at `a` and
    /// at `b` over each record's validation half, the records pooled
    /// (output units): how far two fits part where neither was fitted, read
    /// from the records' inputs alone. `+∞` where either run is not finite
    /// there.
    pub fn apart_on_validation(&self, model: &ModelDescription, a: &[f64], b: &[f64]) -> f64 {
        if a.is_empty() || b.is_empty() {
            return f64::INFINITY;
        }
        let (mut sum, mut n) = (0.0, 0usize);
        let runs = self
            .free_runs(model, a)
            .into_iter()
            .zip(self.free_runs(model, b));
        for (i, (run_a, run_b)) in runs.enumerate() {
            for k in self.val_start[i]..run_a.len() {
                sum += (f64::from(run_a[k]) - f64::from(run_b[k])).powi(2);
                n += 1;
            }
        }
        let rms = (sum / n.max(1) as f64).sqrt();
        if n > 0 && rms.is_finite() {
            rms
        } else {
            f64::INFINITY
        }
    }

    /// `model`'s free run at `theta` over each whole record, in order.
    fn free_runs(&self, model: &ModelDescription, theta: &[f64]) -> Vec<Vec<f32>> {
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        (self.whole.iter().enumerate())
            .map(|(i, whole)| model.simulate(&t, i, &self.ctx[i], whole))
            .collect()
    }

    /// Each record's validation half, as [`Records::score_on`] takes it.
    fn validation_halves(&self) -> Vec<Vec<Range<usize>>> {
        self.whole
            .iter()
            .zip(&self.val_start)
            .map(|(w, &from)| std::iter::once(from..w.len()).collect())
            .collect()
    }

    /// Scores of `model` at `theta` on the samples `ranges[i]` of each
    /// record `i` (the diagnosis' selection and test parts), from the one
    /// free run over each whole record, as [`Records::validate`] scores the
    /// second halves: the records pooled, infinite RMSE and −∞ fit where the
    /// run is not finite on a scored sample.
    pub fn score_on(
        &self,
        model: &ModelDescription,
        theta: &[f64],
        ranges: &[Vec<Range<usize>>],
    ) -> Validation {
        pooled(&self.runs_on(model, theta, ranges)).unwrap_or(DIVERGED)
    }

    /// The scored samples of each record with any, measured and as the
    /// free run over the whole record simulates them; none for no
    /// parameters (a fit that found nothing).
    fn runs_on(
        &self,
        model: &ModelDescription,
        theta: &[f64],
        ranges: &[Vec<Range<usize>>],
    ) -> Vec<(Vec<f64>, Vec<f64>)> {
        if theta.is_empty() {
            return Vec::new();
        }
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        let mut runs = Vec::new();
        for (i, (whole, scored)) in self.whole.iter().zip(ranges).enumerate() {
            if scored.is_empty() {
                continue;
            }
            let run = model.simulate(&t, i, &self.ctx[i], whole);
            let (mut y, mut x) = (Vec::new(), Vec::new());
            for r in scored {
                y.extend(whole.y[r.clone()].iter().map(|&v| v as f64));
                x.extend(run[r.clone()].iter().map(|&v| v as f64));
            }
            runs.push((y, x));
        }
        runs
    }

    /// The yardstick a fit is read against: on each record, the first-order
    /// ARX model identified on its estimation half, run free over the whole
    /// record from its first sample and scored on its validation half, the
    /// records pooled as a fit's are ([`Records::validate`]), each record's
    /// own beside them; and each record's ARX model's largest pole modulus
    /// ([`Arx::largest_pole`]: at 1 or past it the yardstick drifts or
    /// grows, and scores nothing a fit need clear). A hysteretic fit that
    /// validates worse than this fits the estimation halves in a way the
    /// validation halves do not share. With several records each has its
    /// own linear model, a yardstick that one model for all must clear with
    /// room. (In each estimation half's own means: ARX has no intercept,
    /// and the fit % and RMSE do not change when both outputs shift alike;
    /// the pooled scores are taken in the records' common coordinates.)
    /// `None` if ARX cannot be identified on a record.
    pub fn linear_yardstick(&self) -> Option<(Scores, Vec<f64>)> {
        let (runs, poles) = self.linear_runs()?;
        Some((Scores::of(&runs), poles))
    }

    /// Each record's validation half, measured and as its own first-order
    /// ARX model runs it ([`Records::linear_yardstick`]), and that model's
    /// largest pole modulus.
    fn linear_runs(&self) -> Option<(ValidationRuns, Vec<f64>)> {
        let mean = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>() / v.len().max(1) as f64;
        let mut scores: Vec<(Vec<f64>, Vec<f64>)> = Vec::new();
        let mut poles = Vec::new();
        for ((whole, est), &from) in self.whole.iter().zip(&self.est).zip(&self.val_start) {
            let (mu, my) = (mean(&est.u), mean(&est.y));
            let u: Vec<f64> = whole.u.iter().map(|&v| v as f64 - mu).collect();
            let y: Vec<f64> = whole.y.iter().map(|&v| v as f64 - my).collect();
            let arx =
                Arx::estimate(&whole.name, &u[..from], &y[..from], ArxOrders::default()).ok()?;
            let sim = arx.simulate(&u, &y);
            scores.push((y[from..].to_vec(), sim[from..].to_vec()));
            poles.push(arx.largest_pole());
        }
        Some((scores, poles))
    }
}

/// Records' validation halves, `(measured, simulated)` each.
type ValidationRuns = Vec<(Vec<f64>, Vec<f64>)>;

/// The scores of a run that diverged, or of no run at all.
const DIVERGED: Validation = Validation {
    rmse: f64::INFINITY,
    fit_percent: f64::NEG_INFINITY,
};

/// Scores pooled over the records, and each record's alone.
#[derive(Debug, Clone, PartialEq)]
pub struct Scores {
    pub pooled: Validation,
    pub each: Vec<Validation>,
}

impl Scores {
    /// The scores of records' `(measured, simulated)` samples ([`pooled`]),
    /// infinite RMSE and −∞ fit where a run is not finite.
    fn of(runs: &[(Vec<f64>, Vec<f64>)]) -> Scores {
        Scores {
            pooled: pooled(runs).unwrap_or(DIVERGED),
            each: runs
                .iter()
                .map(|run| pooled(std::slice::from_ref(run)).unwrap_or(DIVERGED))
                .collect(),
        }
    }
}

/// Each step in one sample of the measured output of `experiments`.
fn output_steps(experiments: &[Experiment]) -> impl Iterator<Item = f64> + '_ {
    experiments
        .iter()
        .flat_map(|e| e.y.windows(2).map(|p| f64::from((p[1] - p[0]).abs())))
}

/// The scores of records' `(measured, simulated)` samples pooled: the RMSE
/// over all of them, and the fit with each record's deviations from its own
/// mean ([`pooled_fit_percent`]); `None` where there is no sample or a
/// simulated one is not finite.
fn pooled(scores: &[(Vec<f64>, Vec<f64>)]) -> Option<Validation> {
    let y: Vec<f64> = scores.iter().flat_map(|(y, _)| y.iter().copied()).collect();
    let x: Vec<f64> = scores.iter().flat_map(|(_, x)| x.iter().copied()).collect();
    if y.is_empty() || x.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let records: Vec<(&[f64], &[f64])> = scores
        .iter()
        .map(|(y, x)| (y.as_slice(), x.as_slice()))
        .collect();
    Some(Validation {
        rmse: rmse(&y, &x),
        fit_percent: pooled_fit_percent(&records),
    })
}

/// How many times its swing the output's level may sit from zero before
/// [`offset_note`] speaks.
const FAR_LEVEL: f64 = 10.0;

/// A note where the estimation half's output sits more than `FAR_LEVEL`
/// times its swing (largest less smallest) away from zero, as an encoder's
/// counts or an absolute position do. The fit works in deviations from the
/// mean, but the intercept's search box is sized from the largest absolute
/// input and output, up to [`crate::model::bounds::LEVEL_REACH`] times their
/// span (`ident::arx::linear_prior`), so such a level gives a wider box
/// than the record near its zero: the shipped stair with 1000 mm added
/// validates at 92.05 % instead of 92.39 % (docs/GUIDE.md, "When not to
/// trust it").
pub fn offset_note(trace: &Trace) -> Option<String> {
    let est = &trace.output[halves(trace.len()).0];
    let mean = est.iter().sum::<f64>() / est.len().max(1) as f64;
    let swing = range(est);
    (swing > 0.0 && mean.abs() > FAR_LEVEL * swing).then(|| {
        format!(
            "the output `{}` sits at {mean:.6e} on average, {:.0} times its swing of \
             {swing:.3e}: the intercept's search box, sized from absolute values up to {} \
             swings, is then wider than a record near zero gets, so this fit may differ a \
             little from that one; subtract the level from the column to get that fit",
            trace.output_name,
            mean.abs() / swing,
            crate::model::bounds::LEVEL_REACH
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::synthetic::Synthetic;
    use crate::model::Family;

    #[test]
    fn records_pool_their_validation_halves_and_a_runaway_scores_minus_infinity() {
        let (a, b) = (
            Synthetic::new(Family::Classic, 600, 0.05, 1),
            Synthetic::new(Family::Classic, 800, 0.05, 2),
        );
        let both = Records::of(&[a.trace.clone(), b.trace.clone()], None).unwrap();
        let model = ModelDescription::new(Family::Classic, Vec::new(), 2);
        let pooled = both.validate(&model, &a.truth);
        assert!(pooled.fit_percent > 90.0, "{pooled:?}");
        // The pooled RMSE² is the sample-weighted mean of each record's,
        // each record scored in the same coordinates.
        let mut sum = 0.0;
        let mut samples = 0;
        for i in 0..2 {
            let one = Records {
                whole: vec![both.whole[i].clone()],
                est: vec![both.est[i].clone()],
                val_start: vec![both.val_start[i]],
                ctx: vec![both.ctx[i]],
                prior: both.prior,
            };
            let n = both.whole[i].len() - both.val_start[i];
            let single = ModelDescription::new(Family::Classic, Vec::new(), 1);
            let alone = one.validate(&single, &a.truth);
            // Each record's own score, as `fit` reports it beside the pool.
            let scores = both.validate_each(&model, &a.truth);
            assert_eq!((scores.each[i], scores.pooled), (alone, pooled));
            sum += alone.rmse.powi(2) * n as f64;
            samples += n;
        }
        let expected = (sum / samples as f64).sqrt();
        assert!(
            (pooled.rmse - expected).abs() < 1e-9 * expected,
            "{pooled:?} {expected}"
        );
        // β + γ < 0 with a large A: the state runs away.
        let mut runaway = a.truth.clone();
        runaway[0] = 1e6;
        runaway[3] = -runaway[2] - 10.0;
        let v = both.validate(&model, &runaway);
        assert!(
            v.rmse.is_infinite() && v.fit_percent == f64::NEG_INFINITY,
            "{v:?}"
        );
        assert_eq!(both.validate(&model, &[]).rmse, f64::INFINITY);
    }

    /// Two fits part by the RMS of their free runs' difference over the
    /// validation halves, pooled over the records: none for a fit beside
    /// itself, and what the runs themselves give for two others; a run
    /// that diverges parts infinitely.
    #[test]
    fn fits_part_by_their_runs_over_the_validation_halves() {
        let (a, b) = (
            Synthetic::new(Family::Classic, 600, 0.05, 1),
            Synthetic::new(Family::Classic, 800, 0.05, 2),
        );
        let both = Records::of(&[a.trace.clone(), b.trace.clone()], None).unwrap();
        let model = ModelDescription::new(Family::Classic, Vec::new(), 2);
        assert_eq!(both.apart_on_validation(&model, &a.truth, &a.truth), 0.0);
        let mut other = a.truth.clone();
        other[6] *= 1.1;
        let (mut sum, mut n) = (0.0, 0);
        for (i, whole) in both.whole.iter().enumerate() {
            let run = |theta: &[f64]| {
                let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
                model.simulate(&t, i, &both.ctx[i], whole)
            };
            let (p, q) = (run(&a.truth), run(&other));
            for k in both.val_start[i]..whole.len() {
                sum += (p[k] as f64 - q[k] as f64).powi(2);
                n += 1;
            }
        }
        let expected = (sum / n as f64).sqrt();
        let apart = both.apart_on_validation(&model, &other, &a.truth);
        assert!(
            expected > 0.0 && (apart - expected).abs() < 1e-12 * expected,
            "{apart} {expected}"
        );
        let mut runaway = a.truth.clone();
        runaway[0] = 1e6;
        runaway[3] = -runaway[2] - 10.0;
        assert_eq!(
            both.apart_on_validation(&model, &runaway, &a.truth),
            f64::INFINITY
        );
    }

    /// An output far from zero for its swing gets the note; the shipped
    /// data's kind of level (about half its swing) does not.
    #[test]
    fn an_output_far_from_zero_for_its_swing_is_noted() {
        let s = Synthetic::new(Family::Classic, 400, 0.05, 3);
        assert!(offset_note(&s.trace).is_none());
        let swing = range(&s.trace.output[..200]);
        let far = Trace {
            output: s.trace.output.iter().map(|y| y + 20.0 * swing).collect(),
            ..s.trace.clone()
        };
        let note = offset_note(&far).expect("a note");
        assert!(
            note.contains("times its swing") && note.contains("subtract the level"),
            "{note}"
        );
    }

    /// The yardstick carries each record's ARX pole: inside the unit circle
    /// on a muscle-like record, past it on the shipped stair's first 25 s
    /// (its estimation half rises and falls once).
    #[test]
    fn the_yardstick_carries_each_record_s_arx_pole() {
        let s = Synthetic::new(Family::Classic, 600, 0.05, 1);
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/stair_4.5kg.csv");
        let stair = crate::data::csv::read_traces(
            std::path::Path::new(path),
            &crate::data::csv::ReadOptions::default(),
        )
        .unwrap()
        .remove(0);
        let first = Trace::uniform(
            "first.csv",
            stair.dt(),
            stair.input[..2500].to_vec(),
            stair.output[..2500].to_vec(),
        );
        let both = Records::of(&[s.trace.clone(), first], None).unwrap();
        let (scores, poles) = both.linear_yardstick().unwrap();
        assert_eq!((scores.each.len(), poles.len()), (2, 2));
        assert!((0.0..1.0).contains(&poles[0]), "{poles:?}");
        assert!(poles[1] > 1.0, "{poles:?}");
    }
}
