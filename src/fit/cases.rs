//! Seeded identification cases with a known answer: truths drawn from the
//! bounded class on their own priors, simulated in absolute units on a
//! stair, a multisine or a mix of sines and steps, plus Gaussian measurement
//! noise, and recorded in MPa→mm, kPa→m or psi→mm.
//!
//! They check what a user expects of `mckibben fit`: that its defaults reach
//! the noise floor — the truth's own validation error — whatever the truth,
//! its units, the excitation and the algorithm. The truths cover what makes a
//! fit hard: slow poles (`a·α` up to 0.995, time constants of hundreds of
//! samples), a fast linear pole whose slowness is all the loop's (so `b` is
//! many times ARX's), classic loops of both bounded classes (`γ` from
//! `−0.9·β` to `3·β`), narrow and wide loops, 0.02–0.1 mm of noise. Nothing
//! is drawn from, or rejected by, the fit's search box: a truth the box
//! cannot hold is a failure of the box.
//!
//! A generalized truth's sign terms in `x` switch at one of two levels
//! ([`SwitchAt`]): at the estimation half's output mean, where the
//! thesis' model (written in deviation coordinates) switches, or at the
//! sensor's zero (the muscle's rest length), the model's usual form. The
//! first kind is simulated the way [`super::synthetic`] does it:
//! once in absolute units to find the estimation half's means, then again in
//! the deviation coordinates of those means with `x_s` at that mean, iterated
//! until the mean is the output's own. The second is simulated once, in
//! absolute units with `x_s = 0`, the output placed so that zero lies from
//! half-way up its swing to a tenth of it below. The truth is stored in the
//! gauge `A = 1` the fit searches in ([`crate::model::coords::gauge_fixed`]:
//! the same outputs).

use std::ops::Range;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::Serialize;

use super::objective::ModelObjective;
use super::problem::FitProblem;
use super::records::Validation;
use crate::data::Trace;
use crate::eval::Evaluator;
use crate::ident::fit::indistinguishable_up_to;
use crate::model::Measure;
use crate::model::coords::{bounded_betas, gauge_fixed, in_bounded_class};
use crate::model::{Family, Flow, simulate};
use crate::optim::engine::{Engine, Objective, Plan, Polish, Space, StopRules};
use crate::search::Rows;

/// The input that excites a case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Excitation {
    /// Pressure levels held from half to three time constants.
    Stair,
    /// A sum of sines with random phases over two decades of frequency.
    Multisine,
    /// Stretches of sine alternating with short stairs.
    Mixed,
}

impl Excitation {
    pub const ALL: [Excitation; 3] = [Excitation::Stair, Excitation::Multisine, Excitation::Mixed];

    pub fn name(self) -> &'static str {
        match self {
            Excitation::Stair => "stair",
            Excitation::Multisine => "multisine",
            Excitation::Mixed => "mixed",
        }
    }
}

/// Where a generalized truth's sign terms in `x` switch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SwitchAt {
    /// At the estimation half's output mean (`x_s = ȳ`).
    EstimationMean,
    /// At the sensor's zero (`x_s = 0`), the muscle's rest length.
    SensorZero,
    /// At a level drawn inside the output's range (from a tenth to nine
    /// tenths of its swing): neither of the two levels above, so a fit that
    /// assumes either misses it.
    Inside,
}

impl SwitchAt {
    pub fn name(self) -> &'static str {
        match self {
            SwitchAt::EstimationMean => "mean",
            SwitchAt::SensorZero => "zero",
            SwitchAt::Inside => "inside",
        }
    }
}

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CaseSpec {
    pub family: Family,
    /// Where a generalized truth switches (the classic family ignores it).
    pub switch: SwitchAt,
    pub excitation: Excitation,
    pub samples: usize,
    /// Standard deviation of the displacement noise (mm).
    pub noise_mm: f64,
    /// Where the pole sits.
    pub pole: Pole,
    /// The units the record is written in.
    pub units: Units,
    pub seed: u64,
}

/// Where a case's slowness lies. Each half of the record spans at least 20
/// time constants of the effective pole `a·(α + (1 − α)·A)` either way.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Pole {
    /// The effective pole in [0.9, 0.99], `α` anywhere in [0.3, 0.99].
    Effective,
    /// `1 − a·α` in [0.005, 0.02]: the linear part itself is slow.
    Slow,
    /// `a·α` in [0.2, 0.7] and the effective pole in [0.9, 0.99]: the
    /// slowness is all the loop's, so the input gain `b` is several times
    /// what ARX finds.
    FastLinear,
}

/// The units a case's record is written in: the input in MPa, kPa or psi,
/// the output in mm or m.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Units {
    MpaMm,
    KpaM,
    PsiMm,
}

impl Units {
    /// Input and output units per MPa and per mm.
    fn factors(self) -> (f64, f64) {
        match self {
            Units::MpaMm => (1.0, 1.0),
            Units::KpaM => (1000.0, 1e-3),
            Units::PsiMm => (145.037_737_73, 1.0),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Units::MpaMm => "MPa→mm",
            Units::KpaM => "kPa→m",
            Units::PsiMm => "psi→mm",
        }
    }
}

/// A generated case.
#[derive(Debug, Clone)]
pub struct Case {
    pub spec: CaseSpec,
    /// Pressure (MPa) and displacement (mm), sampled at [`CASE_DT`].
    pub trace: Trace,
    /// The truth as a canonical vector in the fit's deviation coordinates
    /// (those of the estimation half of `trace`).
    pub truth: Vec<f64>,
    /// The truth's own validation scores: the floor a fit can reach.
    pub truth_validation: Validation,
}

/// The first case of [`matrix`] whose generalized truth switches inside its
/// output's range: placed after the other kinds, so that the twenty before
/// it draw their truths as if this kind did not exist.
pub const INSIDE_FROM: usize = 20;

/// Sample time of the generated traces (s): the shipped rig data's.
pub const CASE_DT: f64 = 0.01;

/// Pressure range of the inputs (MPa gauge), as the thesis' rig.
const P_MIN: f64 = 0.05;
const P_MAX: f64 = 0.5;

/// The standard matrix: `count` cases of `family`, cycling through the three
/// excitations, the three pole kinds (shifted, so that each excitation meets
/// each) and, every fourth case, other units than MPa→mm; noise spread over
/// 0.02–0.1 mm, 8000–12000 samples; case `i` has seed `seed + i`. Generalized
/// truths switch at the estimation mean in cases 0, 1, 4, 5, 8, 9, … up to
/// case 19 and at the sensor's zero in cases 2, 3, 6, 7, … up to 19 (a case
/// of the first kind draws from its seed as if the second kind did not
/// exist), and inside the output's range from case 20 on
/// ([`INSIDE_FROM`]): a matrix of 30 holds ten of each.
pub fn matrix(family: Family, count: usize, seed: u64) -> Vec<CaseSpec> {
    (0..count)
        .map(|i| {
            let s = seed + i as u64;
            let mut rng = ChaCha8Rng::seed_from_u64(s ^ 0x5eed);
            CaseSpec {
                family,
                switch: if i >= INSIDE_FROM {
                    SwitchAt::Inside
                } else if (i / 2) % 2 == 1 {
                    SwitchAt::SensorZero
                } else {
                    SwitchAt::EstimationMean
                },
                excitation: Excitation::ALL[i % 3],
                samples: rng.random_range(8000..=12000),
                noise_mm: 0.02 + 0.08 * rng.random::<f64>(),
                pole: [Pole::Effective, Pole::Slow, Pole::FastLinear][(i + i / 3) % 3],
                units: match i % 8 {
                    3 => Units::KpaM,
                    7 => Units::PsiMm,
                    _ => Units::MpaMm,
                },
                seed: s,
            }
        })
        .collect()
}

impl Case {
    /// Generates the case `spec` (deterministic in its seed).
    pub fn generate(spec: CaseSpec) -> Case {
        assert!(
            spec.family != Family::Linear,
            "cases are hysteretic: classic or generalized"
        );
        let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
        loop {
            if let Some(case) = attempt(spec, &mut rng) {
                return case;
            }
        }
    }

    /// The fitting problem on this case with the default box.
    pub fn problem(&self) -> FitProblem {
        FitProblem::new(&self.trace, self.spec.family, Flow::Joint, None, false)
            .expect("a generated case identifies")
    }

    /// A short name for tables: family, excitation, pole, units, where a
    /// generalized truth switches when not at the mean, seed.
    pub fn name(&self) -> String {
        let pole = match self.spec.pole {
            Pole::Effective => "",
            Pole::Slow => " (slow)",
            Pole::FastLinear => " (fast a·α)",
        };
        let units = match self.spec.units {
            Units::MpaMm => String::new(),
            u => format!(" {}", u.name()),
        };
        let switch = match (self.spec.family, self.spec.switch) {
            (Family::Generalized, SwitchAt::SensorZero) => " x_s=0",
            (Family::Generalized, SwitchAt::Inside) => " x_s inside",
            _ => "",
        };
        format!(
            "{} {}{pole}{units}{switch} #{}",
            self.spec.family,
            self.spec.excitation.name(),
            self.spec.seed
        )
    }

    /// The truth polished on the estimation data ([`polished_truth`]).
    pub fn polished_truth(&self, evaluator: &mut dyn Evaluator) -> anyhow::Result<(Vec<f64>, f64)> {
        polished_truth(&self.problem(), &self.truth, evaluator)
    }

    /// Judges a fit of this case: its validation RMSE over the truth's, and
    /// whether it passes. A fit passes when that ratio is at most 1.05; or,
    /// where the truth's own polished optimum validates worse than that
    /// (the estimation data then cannot reach the truth), when its
    /// estimation SSE is within the likelihood-ratio threshold of that
    /// optimum's.
    pub fn judge(
        &self,
        fitted: &[f64],
        evaluator: &mut dyn Evaluator,
    ) -> anyhow::Result<Judgement> {
        let problem = self.problem();
        let ratio = problem.validate(fitted).rmse / self.truth_validation.rmse;
        let mut judgement = Judgement {
            ratio,
            polished_ratio: None,
            passes: ratio <= PASS_RATIO,
        };
        if !judgement.passes {
            let (polished, polished_sse) = self.polished_truth(evaluator)?;
            let polished_ratio = problem.validate(&polished).rmse / self.truth_validation.rmse;
            judgement.polished_ratio = Some(polished_ratio);
            if polished_ratio > PASS_RATIO {
                let mut objective = ModelObjective::for_problem(evaluator, &problem);
                let sse = Objective::costs(&mut objective, Rows::one(fitted), Measure::FreeRun)?[0]
                    as f64;
                let samples = problem.estimation().len().saturating_sub(1);
                judgement.passes = sse <= indistinguishable_up_to(polished_sse, samples);
            }
        }
        Ok(judgement)
    }
}

/// `truth` polished on `problem`'s estimation data (Levenberg–Marquardt on
/// the free run, as the fit's last stage, from the truth itself): the
/// optimum the data make of the truth's basin, and its estimation SSE.
pub fn polished_truth(
    problem: &FitProblem,
    truth: &[f64],
    evaluator: &mut dyn Evaluator,
) -> anyhow::Result<(Vec<f64>, f64)> {
    let plan = Plan::polish(Polish {
        starts: 1,
        longest: problem.estimation().len(),
        ..Polish::default()
    });
    // A box around the truth, which the fit's box need not hold: `A`, `n`
    // and the switching level held (the gauge, n = 1, and the truth's own
    // kind of switching: a level only moves the loss where it passes a
    // sample, so no derivative would move it anyway), `α` over its range,
    // the rest ten times the truth's size either way.
    let names: Vec<String> = problem
        .model
        .family
        .params()
        .iter()
        .map(|p| p.name.into())
        .collect();
    let (mut lower, mut upper): (Vec<f64>, Vec<f64>) = truth
        .iter()
        .map(|&v| (v - 10.0 * v.abs() - 1.0, v + 10.0 * v.abs() + 1.0))
        .unzip();
    let ni = problem.model.family.exponent_index().expect("hysteretic");
    for i in [0, ni]
        .into_iter()
        .chain(problem.model.family.switch_index())
    {
        (lower[i], upper[i]) = (truth[i], truth[i]);
    }
    (lower[1], upper[1]) = (0.0, 1.0);
    let space = Space::new(lower, upper, names);
    let mut engine =
        Engine::new(plan, space, 1, StopRules::default())?.with_initial(Rows::one(truth));
    let mut objective = ModelObjective::for_problem(evaluator, problem);
    let outcome = engine.run(&mut objective, &mut [], None, None)?;
    Ok((outcome.params, outcome.sse))
}

/// The validation RMSE ratio (fit over truth) at which a case passes.
pub const PASS_RATIO: f64 = 1.05;

/// How a fit of a case fares ([`Case::judge`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Judgement {
    /// Validation RMSE of the fit over the truth's.
    pub ratio: f64,
    /// The same of the truth polished on the estimation data, where the
    /// fit's ratio is over [`PASS_RATIO`].
    pub polished_ratio: Option<f64>,
    pub passes: bool,
}

/// One draw of a truth and an input; `None` when the draw is rejected (it
/// diverges, barely moves, or its parameters leave the default box).
fn attempt(spec: CaseSpec, rng: &mut ChaCha8Rng) -> Option<Case> {
    // Each half of the record spans at least 20 time constants of the
    // effective pole, or the estimation half cannot tell a slow pole from a
    // drift and the truth is not what the data determine.
    let slowest = 1.0 - 40.0 / spec.samples as f64;
    let pole = draw_pole(spec.pole, slowest, rng)?;
    let shape = draw_shape(spec.family, rng);
    if pole.effective > slowest {
        return None;
    }
    let tau = 1.0 / (1.0 - pole.effective);
    let p = input(spec.excitation, spec.samples, tau, rng);
    let mut draft = scale_to_swing(spec.family, &pole, &shape, tau, p, rng)?;
    let placed = place(spec, &mut draft, rng)?;
    record_case(spec, draft, &placed, rng)
}

/// The linear part of a drawn truth: `a`, `α`, the loop's weight `A` and
/// the output's effective pole `a·(α + (1 − α)·A)` they make.
struct DrawnPole {
    a: f64,
    alpha: f64,
    big_a: f64,
    effective: f64,
}

/// A truth and its input, `b` scaled so that the output swings as drawn,
/// before the output is placed: what placing it needs.
struct Draft {
    family: Family,
    theta: Vec<f64>,
    a: f64,
    alpha: f64,
    /// The input (MPa).
    p: Vec<f64>,
    /// The noiseless output of the scaled truth, switching at zero.
    second: Vec<f64>,
    /// The drawn swing (mm).
    swing: f64,
    /// The range of `second`.
    r1: f64,
}

/// A placed truth's noiseless output, in the coordinates of the output
/// mean `y_mean`.
struct Placed {
    x: Vec<f64>,
    y_mean: f64,
}

/// A value drawn log-uniformly from `lo` to `hi`.
fn log_uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    (lo.ln() + rng.random::<f64>() * (hi / lo).ln()).exp()
}

/// Draws the linear part for `pole`; `None` where the draw leaves the
/// class's range. For small loops `w ≈ A·x`, so the output's effective
/// pole is `a·(α + (1 − α)·A)`: a slow muscle either has `a·α` itself
/// near 1 (the slow cases, up to 0.995) or a fast `a·α` and a slow
/// hysteretic feedback (the thesis' own Table 1: α = 0.5). `slowest` is the
/// slowest effective pole the record's length allows.
fn draw_pole(pole: Pole, slowest: f64, rng: &mut ChaCha8Rng) -> Option<DrawnPole> {
    let (a, alpha, big_a, effective) = match pole {
        Pole::Slow => {
            let a_alpha = 1.0 - log_uniform(rng, 0.005, 0.02);
            let alpha: f64 = rng.random_range(0.93..0.99);
            let a = a_alpha / alpha;
            let big_a_max = ((slowest / a - alpha) / (1.0 - alpha)).min(1.5);
            if a > 1.05 || big_a_max < 0.05 {
                return None;
            }
            let big_a: f64 = rng.random_range(0.05..big_a_max);
            (a, alpha, big_a, a * (alpha + (1.0 - alpha) * big_a))
        }
        Pole::Effective => {
            let effective = 1.0 - log_uniform(rng, 0.01, 0.1);
            let alpha: f64 = rng.random_range(0.3..0.99);
            let a: f64 = rng.random_range(0.6f64.max(effective - 0.2)..1.05);
            let big_a = (effective / a - alpha) / (1.0 - alpha);
            if !(0.05..=2.0).contains(&big_a) {
                return None;
            }
            (a, alpha, big_a, effective)
        }
        Pole::FastLinear => {
            let effective = 1.0 - log_uniform(rng, 0.01, 0.1);
            let a_alpha: f64 = rng.random_range(0.2..0.7);
            let a: f64 = rng.random_range(effective..1.05);
            let alpha = a_alpha / a;
            let big_a = (effective / a - alpha) / (1.0 - alpha);
            if !(0.05..=3.0).contains(&big_a) {
                return None;
            }
            (a, alpha, big_a, effective)
        }
    };
    Some(DrawnPole {
        a,
        alpha,
        big_a,
        effective,
    })
}

/// Draws the loop shape from the bounded class: classic β ≥ 0 with γ from
/// −0.9·β (class I) to 3·β (class II); generalized loading slopes
/// log-uniform and (β2, β4) anywhere in the class's diamond.
fn draw_shape(family: Family, rng: &mut ChaCha8Rng) -> Vec<f64> {
    match family {
        Family::Classic => {
            let beta = log_uniform(rng, 1e-3, 0.1);
            let gamma = beta * rng.random_range(-0.9..3.0);
            vec![beta, gamma]
        }
        _ => {
            let loading = [(); 4].map(|_| log_uniform(rng, 2e-3, 0.1));
            let u = rng.random_range(-1.0..1.0);
            let v = rng.random_range(-1.0..1.0);
            bounded_betas(loading, u, v).to_vec()
        }
    }
}

/// A free run of `family`'s `theta` from `x0` in the coordinates of the
/// output mean `y_mean`, in the simulator's single precision; `None` where
/// it diverges.
fn free_run(family: Family, theta: &[f64], y_mean: f64, u: &[f64], x0: f64) -> Option<Vec<f64>> {
    let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
    let u: Vec<f32> = u.iter().map(|&v| v as f32).collect();
    let sim = simulate(family, &t, y_mean as f32, &u, x0 as f32);
    sim.diverged_at
        .is_none()
        .then(|| sim.x.iter().map(|&v| v as f64).collect())
}

/// The range of `v`: its largest value less its smallest.
fn range(v: &[f64]) -> f64 {
    v.iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x))
        - v.iter().fold(f64::INFINITY, |m, &x| m.min(x))
}

/// The mean of `v`.
fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Builds the truth from its drawn parts and scales `b` so that the output
/// to input `p` swings a drawn 10–40 mm; `None` where the output diverges,
/// stays flat or misses the swing by more than a factor of two.
fn scale_to_swing(
    family: Family,
    pole: &DrawnPole,
    shape: &[f64],
    tau: f64,
    p: Vec<f64>,
    rng: &mut ChaCha8Rng,
) -> Option<Draft> {
    // A first guess at b: a static gain of 60 mm/MPa through the effective
    // pole; a generalized loop switching at the first passes' zero.
    let mut theta = vec![pole.big_a, pole.alpha];
    theta.extend(shape);
    theta.push(1.0);
    if family.switch_index().is_some() {
        theta.push(0.0);
    }
    theta.extend([pole.a, 60.0 / tau, 0.0, 0.0]);
    let [_, ib, _] = family.linear_indices();
    let first = free_run(family, &theta, 0.0, &p, 0.0)?;
    let swing = rng.random_range(10.0..40.0);
    let r0 = range(&first);
    // A flat (or NaN) response cannot be scaled to a swing.
    let moves = r0 > 1e-6;
    if !moves {
        return None;
    }
    theta[ib] *= swing / r0;
    let second = free_run(family, &theta, 0.0, &p, 0.0)?;
    let r1 = range(&second);
    if !(0.5 * swing..2.0 * swing).contains(&r1) {
        return None;
    }
    Some(Draft {
        family,
        theta,
        a: pole.a,
        alpha: pole.alpha,
        p,
        second,
        swing,
        r1,
    })
}

/// Places the draft's output as `spec` says its loop switches, and sets
/// the intercept (and the switching level) to match; `None` where the
/// placed output misses its swing or its level.
fn place(spec: CaseSpec, draft: &mut Draft, rng: &mut ChaCha8Rng) -> Option<Placed> {
    let min = draft.second.iter().fold(f64::INFINITY, |m, &x| m.min(x));
    let (est, _) = crate::model::experiment::halves(spec.samples);
    let u_mean = mean(&draft.p[est.clone()]);
    match (draft.family.switch_index(), spec.switch) {
        (Some(_), SwitchAt::SensorZero) => place_at_zero(draft, min, u_mean, rng),
        (Some(is), SwitchAt::Inside) => place_inside(draft, is, min, u_mean, &est, rng),
        _ => place_at_mean(draft, min, u_mean, &est, rng),
    }
}

/// The draft's free run in absolute units from its first sample moved by
/// `shift`; `None` where it diverges or misses its swing by more than a
/// factor of two.
fn shifted_run(draft: &Draft, shift: f64) -> Option<Vec<f64>> {
    let x = free_run(
        draft.family,
        &draft.theta,
        0.0,
        &draft.p,
        draft.second[0] + shift,
    )?;
    (0.5 * draft.swing..2.0 * draft.swing)
        .contains(&range(&x))
        .then_some(x)
}

/// The change of the intercept `c` that moves the model's output by
/// `shift` for good, its hysteretic state unchanged (the output's own pole
/// is `a·α`): `(1 − a·α)·shift`.
fn intercept_for_shift(a: f64, alpha: f64, shift: f64) -> f64 {
    (1.0 - a * alpha) * shift
}

/// Switching at the sensor's zero: simulated once, in absolute units
/// (x_s = 0), its lowest point (`min` before placing) placed from half its
/// swing below zero to a tenth of it above (x ↦ x + s is the same loop
/// with c + (1 − a·α)·s only for a loop that switches with it, so the
/// placement moves the switching and the swing a little).
fn place_at_zero(draft: &mut Draft, min: f64, u_mean: f64, rng: &mut ChaCha8Rng) -> Option<Placed> {
    let [_, ib, ic] = draft.family.linear_indices();
    let (a, alpha) = (draft.a, draft.alpha);
    let floor = rng.random_range(-0.5..0.1) * draft.r1;
    let shift = floor - min;
    draft.theta[ic] = intercept_for_shift(a, alpha, shift);
    let x = shifted_run(draft, shift)?;
    // The intercept for the input less its estimation mean.
    draft.theta[ic] += draft.theta[ib] * u_mean;
    Some(Placed { x, y_mean: 0.0 })
}

/// Switching inside the output's range: placed 2–10 mm above zero as a
/// truth at the mean, its loop switching (parameter `is`) at a level drawn
/// inside the swing; simulated once in absolute units, as a truth at zero.
/// The level must be crossed in the estimation half `est`, or that half
/// cannot place it.
fn place_inside(
    draft: &mut Draft,
    is: usize,
    min: f64,
    u_mean: f64,
    est: &Range<usize>,
    rng: &mut ChaCha8Rng,
) -> Option<Placed> {
    let [_, ib, ic] = draft.family.linear_indices();
    let (a, alpha) = (draft.a, draft.alpha);
    let shift = rng.random_range(2.0..10.0) - min;
    draft.theta[ic] = intercept_for_shift(a, alpha, shift);
    draft.theta[is] = min + shift + rng.random_range(0.1..0.9) * draft.r1;
    let x = shifted_run(draft, shift)?;
    let level = draft.theta[is];
    let crossed = x[est.clone()]
        .windows(2)
        .any(|w| (w[0] - level) * (w[1] - level) < 0.0);
    if !crossed {
        return None;
    }
    draft.theta[ic] += draft.theta[ib] * u_mean;
    Some(Placed { x, y_mean: 0.0 })
}

/// Switching at the estimation half's mean (and every classic truth):
/// placed 2–10 mm above zero (contraction positive): x ↦ x + s is the
/// model with c + (1 − a·α)·s for the classic model; for both families it
/// is the absolute trace the second pass re-expresses. `None` where the
/// second pass does not settle on its mean.
fn place_at_mean(
    draft: &mut Draft,
    min: f64,
    u_mean: f64,
    est: &Range<usize>,
    rng: &mut ChaCha8Rng,
) -> Option<Placed> {
    let [_, ib, ic] = draft.family.linear_indices();
    let (a, alpha, swing) = (draft.a, draft.alpha, draft.swing);
    let second = &draft.second;
    let floor = rng.random_range(2.0..10.0);
    let absolute: Vec<f64> = second.iter().map(|&x| x + floor - min).collect();
    // Second pass: the truth in the deviation coordinates of the
    // estimation half. Its origin `o` must be the mean of the output
    // it produces over that half (a generalized truth switches there),
    // so iterate to the fixed point.
    let u: Vec<f64> = draft.p.iter().map(|v| v - u_mean).collect();
    let level = absolute[0] - second[0];
    let mut origin = mean(&absolute[est.clone()]);
    let mut x = Vec::new();
    for _ in 0..20 {
        // The intercept that keeps the absolute level with this origin.
        draft.theta[ic] = intercept_for_shift(a, alpha, level - origin) + draft.theta[ib] * u_mean;
        if let Some(is) = draft.family.switch_index() {
            draft.theta[is] = origin;
        }
        x = free_run(draft.family, &draft.theta, origin, &u, absolute[0] - origin)?;
        let off = mean(&x[est.clone()]);
        origin += off;
        if off.abs() < 1e-9 * swing {
            break;
        }
    }
    if mean(&x[est.clone()]).abs() > 1e-6 * swing {
        return None;
    }
    Some(Placed { x, y_mean: origin })
}

/// The case of a placed truth: its output with measurement noise, the
/// truth moved to the noisy record's coordinates and both written in the
/// spec's units, in the gauge the fit searches in; `None` where the record
/// does not identify or the truth does not validate.
fn record_case(
    spec: CaseSpec,
    draft: Draft,
    placed: &Placed,
    rng: &mut ChaCha8Rng,
) -> Option<Case> {
    let family = spec.family;
    let [_, ib, ic] = family.linear_indices();
    let switch = family.switch_index();
    let Draft {
        mut theta,
        a,
        alpha,
        p,
        ..
    } = draft;
    let (x, y_mean) = (&placed.x, placed.y_mean);
    let noise = spec.noise_mm;
    let l: Vec<f64> = x
        .iter()
        .map(|&x| {
            let e: f64 = rng.sample(StandardNormal);
            x + y_mean + noise * e
        })
        .collect();
    let name = format!("{} {} case #{}", family, spec.excitation.name(), spec.seed);
    let trace = Trace::uniform(name, CASE_DT, p, l);
    let problem = FitProblem::new(&trace, family, Flow::Joint, None, false).ok()?;
    // The coordinates the fit uses are the noisy record's (the noise moves
    // the output mean by about noise/√N): a shift of ȳ moves c only (the
    // switching level is absolute).
    let dy = problem.estimation().y_mean - y_mean;
    theta[ic] -= intercept_for_shift(a, alpha, dy);
    // The true state starts at the noiseless first sample: the measured one
    // less its noise.
    theta[family.start_index()] = x[0] + y_mean - trace.output[0];
    // In the record's units: the input scaled by `ku`, the output by `ky`;
    // `b` by ky/ku, the intercept, start and switching level by ky, the
    // loop shape (1/output units, n = 1) by 1/ky.
    let (ku, ky) = spec.units.factors();
    let trace = Trace::uniform(
        trace.source.clone(),
        CASE_DT,
        trace.input.iter().map(|v| v * ku).collect(),
        trace.output.iter().map(|v| v * ky).collect(),
    );
    theta[ib] *= ky / ku;
    theta[ic] *= ky;
    theta[family.start_index()] *= ky;
    if let Some(is) = switch {
        theta[is] *= ky;
    }
    for v in &mut theta[2..family.exponent_index().expect("hysteretic")] {
        *v /= ky;
    }
    let theta = gauge_fixed(family, &theta);
    debug_assert!(in_bounded_class(family, &theta));
    let problem = FitProblem::new(&trace, family, Flow::Joint, None, false).ok()?;
    let truth_validation = problem.validate(&theta);
    truth_validation.rmse.is_finite().then_some(Case {
        spec,
        trace,
        truth: theta,
        truth_validation,
    })
}

/// The input of `excitation`: `len` samples of pressure in
/// [[`P_MIN`], [`P_MAX`]] MPa, paced by the truth's time constant `tau`
/// (samples), so that a slow muscle is given time to move.
fn input(excitation: Excitation, len: usize, tau: f64, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let tau = tau.clamp(5.0, len as f64 / 20.0);
    let mut p = Vec::with_capacity(len);
    match excitation {
        Excitation::Stair => {
            while p.len() < len {
                stair_step(&mut p, tau, rng);
            }
        }
        Excitation::Multisine => multisine(&mut p, len, tau, len as f64 / 8.0, rng),
        Excitation::Mixed => {
            while p.len() < len {
                let stretch = (rng.random_range(3.0..8.0) * tau) as usize;
                let mut sine = Vec::new();
                multisine(&mut sine, stretch.max(10), tau, stretch as f64 / 2.0, rng);
                p.extend(sine);
                for _ in 0..rng.random_range(2..5) {
                    stair_step(&mut p, tau, rng);
                }
            }
        }
    }
    p.truncate(len);
    p
}

/// One stair level, held from half to three time constants.
fn stair_step(p: &mut Vec<f64>, tau: f64, rng: &mut ChaCha8Rng) {
    let level = rng.random_range(P_MIN..P_MAX);
    let hold = rng.random_range(0.5 * tau..3.0 * tau).max(5.0) as usize;
    p.extend(std::iter::repeat_n(level, hold));
}

/// `len` samples of eight sines with periods log-spread from `tau / 2` to
/// `40·tau` samples (at most `longest`, so that each half of the record
/// sees whole periods of every component and validation does not
/// extrapolate) and random phases, scaled into the pressure range (a random
/// part of it, at least half).
fn multisine(p: &mut Vec<f64>, len: usize, tau: f64, longest: f64, rng: &mut ChaCha8Rng) {
    let shortest = 0.5 * tau;
    let ratio = (80.0f64).min(longest / shortest).max(1.0);
    let components: Vec<(f64, f64)> = (0..8)
        .map(|i| {
            let period = shortest * ratio.powf(i as f64 / 7.0);
            let phase = std::f64::consts::TAU * rng.random::<f64>();
            (std::f64::consts::TAU / period, phase)
        })
        .collect();
    let raw: Vec<f64> = (0..len)
        .map(|k| {
            components
                .iter()
                .map(|(w, ph)| (w * k as f64 + ph).sin())
                .sum()
        })
        .collect();
    let (lo, hi) = raw
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let span = rng.random_range(0.5..1.0) * (P_MAX - P_MIN);
    let base = P_MIN + rng.random::<f64>() * (P_MAX - P_MIN - span);
    p.extend(raw.iter().map(|v| base + span * (v - lo) / (hi - lo)));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cases_are_reproducible_and_the_truth_reaches_the_noise() {
        for family in [Family::Classic, Family::Generalized] {
            // Every kind of switching level (the generalized truths switch
            // inside their range from case 20 on), every unit.
            for spec in matrix(family, 24, 11)
                .into_iter()
                .filter(|s| s.units != Units::MpaMm || s.seed % 3 == 0)
                .filter(|s| s.seed < 19 || family == Family::Generalized)
            {
                let spec = CaseSpec {
                    samples: 3000,
                    ..spec
                };
                let case = Case::generate(spec);
                let again = Case::generate(spec);
                assert_eq!(case.trace.output, again.trace.output);
                assert_eq!(case.truth, again.truth);
                // The truth validates at about the noise: its error is the
                // noise plus what the noisy first sample leaves in the state.
                let v = case.truth_validation;
                let (_, ky) = spec.units.factors();
                let noise = spec.noise_mm * ky;
                assert!(
                    v.rmse < 1.5 * noise && v.rmse > 0.8 * noise,
                    "{}: truth RMSE {} for noise {noise}",
                    case.name(),
                    v.rmse,
                );
                assert!(in_bounded_class(family, &case.truth), "{}", case.name());
                if let (Some(is), SwitchAt::Inside) = (family.switch_index(), spec.switch) {
                    // Inside the output's range, in the record's units.
                    let (lo, hi) = case
                        .trace
                        .output
                        .iter()
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                            (a.min(v), b.max(v))
                        });
                    let x_s = case.truth[is];
                    assert!(lo < x_s && x_s < hi, "{}: x_s {x_s}", case.name());
                }
                assert_eq!(case.truth[0], 1.0, "the truth is in the gauge A = 1");
                let range = case.trace.output.iter().fold(0.0f64, |m, &v| m.max(v))
                    - case
                        .trace
                        .output
                        .iter()
                        .fold(f64::INFINITY, |m, &v| m.min(v));
                assert!(range > 4.0 * ky, "{}: output range {range}", case.name());
            }
        }
    }
}
