//! Identification of the benchmark oscillator from a training multisine:
//!
//! 1. **Population search** over a wide box, on a prefix of the record,
//!    scored in batches by an [`OscillatorEvaluator`]: the `f32` twin, one
//!    candidate per rayon task, or the WGSL shader. It scores the integrated displacement at the
//!    750 Hz instants without the decimation filter — whose gain is within
//!    1e-3 of one in the 5–150 Hz band — and integrates at 5 × 750 Hz
//!    instead of 20 ×, where Newmark's period error at 150 Hz, (ω·h)²/12,
//!    is 0.5 %: a few µm, below the measurement noise. It only has to rank.
//! 2. **Levenberg–Marquardt** in `f64` on the whole record through the exact
//!    benchmark pipeline (band-limited upsampling, Newmark, `decimate`), with
//!    ν freed (ν ≥ 1).
//!
//! The population stage runs on the fitting engine ([`crate::optim::engine`])
//! with the project's differential evolution, scoring each generation in one
//! batch.

use nalgebra::DVector;

use super::boucwen::Params;
use super::evaluator::{OscillatorEvaluator, OscillatorProblem};
use super::{FS, Record, UPSAMPLE, resample};
use crate::model::Measure;
use crate::optim::Algorithm;
use crate::optim::engine::{Engine, Objective, Plan, Space, StopRules};
use crate::optim::lm::{self, LmError, LmSettings};
use crate::search::{Params as Canonical, Rows};

/// Settings of the identification.
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifySettings {
    /// 750 Hz samples (from the start of the record) the population stage scores.
    pub search_samples: usize,
    /// Integration steps per 750 Hz sample in the population stage.
    pub search_upsample: usize,
    /// 750 Hz samples (from the start) the refinement fits; 0 = all.
    pub refine_samples: usize,
    pub population: usize,
    pub generations: usize,
    pub lm_iterations: usize,
    pub seed: u64,
}

impl Default for IdentifySettings {
    fn default() -> Self {
        IdentifySettings {
            search_samples: 1024,
            search_upsample: 5,
            refine_samples: 2 * super::PERIOD,
            population: 60,
            generations: 200,
            lm_iterations: 30,
            seed: 7,
        }
    }
}

/// What the identification found.
#[derive(Debug, Clone)]
pub struct Identified {
    pub params: Params,
    /// Best population-stage vector and its `f32` SSE.
    pub search_best: Params,
    pub search_sse: f64,
    /// RMSE (m) on the training record after refinement.
    pub train_rmse: f64,
    pub evaluations: usize,
    pub lm_iterations: usize,
    pub scorer: String,
}

/// The training record on the integration grid: upsampled once, simulated
/// many times.
pub struct Training {
    u15: Vec<f64>,
    y: Vec<f64>,
}

impl Training {
    /// Prepares `rec`: a periodic record (whole periods of `period` samples)
    /// is upsampled period-wise and integrated with one extra period, as the
    /// PDF's example does; any other record is upsampled as a transient.
    pub fn new(rec: &Record, period: usize) -> Training {
        let u15 = if super::is_periodic(&rec.u, period) {
            let one = resample::upsample(&rec.u[..period], UPSAMPLE, true);
            let n = rec.u.len() / period + 1;
            (0..n).flat_map(|_| one.iter().copied()).collect()
        } else {
            resample::upsample(&rec.u, UPSAMPLE, false)
        };
        Training {
            u15,
            y: rec.y.clone(),
        }
    }

    /// Simulated output at 750 Hz over the record, `None` if diverged.
    pub fn simulate(&self, p: &Params) -> Option<Vec<f64>> {
        let y15 = super::boucwen::simulate_f64(p, &self.u15, 1.0 / (FS * UPSAMPLE as f64))?;
        let mut y = resample::decimate(&y15);
        y.truncate(self.y.len());
        Some(y)
    }

    fn residuals(&self, p: &Params) -> Option<DVector<f64>> {
        let y = self.simulate(p)?;
        Some(DVector::from_iterator(
            y.len(),
            y.iter().zip(&self.y).map(|(a, b)| a - b),
        ))
    }
}

/// Identifies the oscillator from `rec` (one multisine, `period` samples per
/// period). `evaluator` scores the population stage on the
/// [`search_trace`] of the same record and settings.
pub fn identify(
    rec: &Record,
    period: usize,
    settings: &IdentifySettings,
    evaluator: &mut dyn OscillatorEvaluator,
) -> anyhow::Result<Identified> {
    let (lower, upper) = search_box(rec, period)?;
    let trace = search_trace(rec, period, settings);
    let (best, best_sse, evaluations) =
        population_search(settings, &lower, &upper, &trace, evaluator)?;
    let keep = match settings.refine_samples {
        0 => rec.y.len(),
        n => n.min(rec.y.len()),
    };
    let refine = Record {
        u: rec.u[..keep].to_vec(),
        y: rec.y[..keep].to_vec(),
    };
    let training = Training::new(&refine, period);
    let (params, train_sse, lm_iterations) =
        levenberg_marquardt(&training, best, settings.lm_iterations)?;
    Ok(Identified {
        params,
        search_best: best,
        search_sse: best_sse,
        train_rmse: (train_sse / keep as f64).sqrt(),
        evaluations,
        lm_iterations,
        scorer: evaluator.describe(),
    })
}

/// The population stage's trace, in `f32`: the first `s.search_samples`
/// samples of `rec` (one multisine with `period` samples per period), the
/// input upsampled by `s.search_upsample` onto its integration grid.
pub fn search_trace(rec: &Record, period: usize, s: &IdentifySettings) -> OscillatorProblem {
    let n = s.search_samples.min(rec.y.len()).max(1);
    let stride = s.search_upsample.max(1);
    let periodic = super::is_periodic(&rec.u, period);
    let up = if periodic {
        resample::upsample(&rec.u[..period], stride, true)
    } else {
        resample::upsample(&rec.u, stride, false)
    };
    let len = (n - 1) * stride + 1;
    let u: Vec<f32> = (0..len).map(|i| up[i % up.len()] as f32).collect();
    OscillatorProblem {
        u,
        y: rec.y[..n].iter().map(|&v| v as f32).collect(),
        stride,
        h: (1.0 / (FS * stride as f64)) as f32,
    }
}

/// The population stage's coordinates `[m, c, ω0, ρ, β·γ, β·δ]` to
/// parameters: ω0 = √((k + α)/m) is the small-amplitude natural frequency
/// (rad/s) and ρ = α/(k + α) the hysteretic share of the stiffness.
///
/// Why: the oscillator is lightly damped (ζ ≈ 1 %), so the output error is a
/// narrow dip in ω0, about ζ wide; in `[m, k, α]` that dip is a thin curved
/// sheet, and a population search settles in the broad false minimum that
/// trades a wrong frequency for large damping. With ω0 an axis, bounded by
/// the best linear approximation ([`bla`]), the dip is easy to find.
pub fn search_to_params(v: &[f64]) -> Params {
    let (m, c, w0, rho) = (v[0], v[1], v[2], v[3]);
    let big_k = m * w0 * w0;
    Params::from_slice(&[m, c, (1.0 - rho) * big_k, rho * big_k, v[4], v[5], 1.0])
}

/// The best linear approximation of a periodic record: `m·ÿ + c·ẏ + K·y = u`
/// fitted in the frequency domain (Levy's linear least squares,
/// `Σ_k |U_k − (K − m·ω_k² + j·c·ω_k)·Y_k|²`) on the DFT lines of the
/// last full period where the input has power. Returns `(m, c, K)`.
pub fn bla(rec: &Record, period: usize) -> Option<(f64, f64, f64)> {
    let periods = rec.u.len() / period;
    if periods == 0 {
        return None;
    }
    // Steady state: the last period (the transient from rest has decayed).
    let off = (periods - 1) * period;
    let u = &rec.u[off..off + period];
    let y = &rec.y[off..off + period];
    let n = period as f64;
    let dft = |x: &[f64], k: usize| -> (f64, f64) {
        let (mut re, mut im) = (0.0, 0.0);
        for (i, &v) in x.iter().enumerate() {
            let ang = -2.0 * std::f64::consts::PI * ((k * i) % period) as f64 / n;
            re += v * ang.cos();
            im += v * ang.sin();
        }
        (re, im)
    };
    let spectrum: Vec<(usize, (f64, f64))> = (1..period / 2).map(|k| (k, dft(u, k))).collect();
    let peak = spectrum
        .iter()
        .map(|(_, (a, b))| a * a + b * b)
        .fold(0.0, f64::max);
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atb = nalgebra::Vector3::<f64>::zeros();
    for (k, (ur, ui)) in spectrum {
        if ur * ur + ui * ui < 1e-6 * peak {
            continue;
        }
        let w = 2.0 * std::f64::consts::PI * FS * k as f64 / n;
        let (yr, yi) = dft(y, k);
        // (K − m·w² + j·c·w)(yr + j·yi): real and imaginary rows in (K, m, c).
        let rows = [
            ([yr, -w * w * yr, -w * yi], ur),
            ([yi, -w * w * yi, w * yr], ui),
        ];
        for (a, b) in rows {
            let a = nalgebra::Vector3::from(a);
            ata += a * a.transpose();
            atb += a * b;
        }
    }
    let x = ata.lu().solve(&atb)?;
    let (big_k, m, c) = (x[0], x[1], x[2]);
    (m > 0.0 && big_k > 0.0).then_some((m, c.max(0.0), big_k))
}

/// Bound on β·γ·max|y| and |β·δ|·max|y| in the population stage.
pub const BETA_STROKES: f64 = 5.0;

/// The population stage's box around the best linear approximation: mass
/// and ω0 within a factor 2 and 1.25 of it, damping up to twice its (which
/// includes the hysteretic dissipation), ρ anywhere in (0, 1), and β·γ,
/// |β·δ| up to [`BETA_STROKES`] / max|y|: beyond that the loop would
/// saturate within a small part of the measured stroke (friction-like).
pub fn search_box(rec: &Record, period: usize) -> anyhow::Result<([f64; 6], [f64; 6])> {
    let (m, c, big_k) = bla(rec, period).ok_or_else(|| {
        anyhow::anyhow!("no best linear approximation: the record needs one full, excited period")
    })?;
    let w0 = (big_k / m).sqrt();
    let y_max = rec.y.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    anyhow::ensure!(y_max > 0.0, "the training output is identically zero");
    let b = BETA_STROKES / y_max;
    Ok((
        [0.5 * m, 0.0, 0.8 * w0, 0.01, 0.0, -b],
        [2.0 * m, 2.0 * c + 1e-9, 1.25 * w0, 0.99, b, b],
    ))
}

/// The population stage's cost, as the fitting engine sees it: rows of
/// search coordinates ([`search_to_params`]) scored as oscillators on the
/// search trace.
struct SearchObjective<'a> {
    evaluator: &'a mut dyn OscillatorEvaluator,
    problem: &'a OscillatorProblem,
}

impl Objective for SearchObjective<'_> {
    fn describe(&self) -> String {
        self.evaluator.describe()
    }

    /// One measure only: the SSE on the search trace.
    fn costs(&mut self, rows: Rows<'_, Canonical>, _: Measure) -> anyhow::Result<Vec<f32>> {
        let params: Vec<f64> = rows
            .iter()
            .flat_map(|x| search_to_params(x).to_vec())
            .collect();
        self.evaluator
            .evaluate(self.problem, Rows::new(&params, super::boucwen::DIM))
    }
}

/// The population stage: the fitting engine's population search with the
/// project's differential evolution ([`crate::optim::de::De`], jDE-adapted
/// current-to-pbest/1/bin), every generation scored in one batch. (The
/// refinement is no engine polish: it fits other coordinates, ν freed, with
/// the exact `f64` pipeline rather than the evaluator.) Returns the best
/// vector, its SSE and the number of evaluations.
fn population_search(
    s: &IdentifySettings,
    lower: &[f64; 6],
    upper: &[f64; 6],
    problem: &OscillatorProblem,
    evaluator: &mut dyn OscillatorEvaluator,
) -> anyhow::Result<(Params, f64, usize)> {
    let space = Space::new(
        lower.to_vec(),
        upper.to_vec(),
        SEARCH_NAMES.iter().map(|n| n.to_string()).collect(),
    );
    let plan = Plan::search(
        Algorithm::De.default_settings(),
        s.population,
        s.generations.max(1),
    );
    let mut engine = Engine::new(plan, space, s.seed, StopRules::default())?;
    let outcome = engine.run(
        &mut SearchObjective { evaluator, problem },
        &mut [],
        None,
        None,
    )?;
    anyhow::ensure!(
        !outcome.params.is_empty(),
        "the population search found no candidate whose simulation stays bounded"
    );
    Ok((
        search_to_params(&outcome.params),
        outcome.sse,
        outcome.evaluations as usize,
    ))
}

/// Names of the population stage's coordinates (see [`search_to_params`]).
pub const SEARCH_NAMES: [&str; 6] = ["m", "c", "omega0", "rho", "beta_gamma", "beta_delta"];

/// Levenberg–Marquardt ([`crate::optim::lm`]) on the residuals of
/// [`Training::simulate`] with ν freed (ν ≥ 1). Returns the parameters,
/// their SSE and the iterations taken.
fn levenberg_marquardt(
    t: &Training,
    start: Params,
    max_iter: usize,
) -> anyhow::Result<(Params, f64, usize)> {
    let inf = f64::INFINITY;
    let mut lower = [-inf; 7];
    (lower[0], lower[6]) = (1e-6, 1.0);
    // Every coordinate's scale is about its size, except ν, which starts at 1.
    let mut floor = [1e-3; 7];
    floor[6] = 1.0;
    let settings = LmSettings {
        max_iterations: max_iter,
        ..LmSettings::default()
    };
    let out = lm::levenberg_marquardt(
        |x| t.residuals(&Params::from_slice(x)),
        &start.to_vec(),
        (&lower, &[inf; 7]),
        &floor,
        &settings,
    )
    .map_err(|e| match e {
        LmError::StartDiverges => {
            anyhow::anyhow!("the population stage's best candidate diverges on the whole record")
        }
        LmError::ProbeDiverges => anyhow::anyhow!("{e}"),
    })?;
    Ok((Params::from_slice(&out.x), out.sse, out.iterations))
}
