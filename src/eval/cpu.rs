//! The CPU evaluator: the reference numbers, computed fast.
//!
//! Candidates are advanced [`LANES`] at a time, side by side, each lane in its
//! own slot of plain `f32` arrays, so that the compiler turns the inner loop
//! into SIMD instructions, compiled for AVX-512 or AVX2 where the CPU has
//! them: one candidate at a time would leave the vector unit idle. Every
//! lane calls the very step functions of
//! [`crate::model::sim`] (the single source of truth), in the same order and
//! without fused multiply-adds, so each lane's SSE is bit-identical to
//! [`crate::model::sse`] for that candidate.
//!
//! Divergence: `sse` stops at the first out-of-bounds state and returns `+∞`.
//! A batch cannot stop one lane, so each lane carries a mask that latches at
//! the first out-of-bounds state; a latched lane's SSE is `+∞` whatever it
//! accumulated afterwards. The batch stops early once every lane has latched.
//!
//! Batches are spread over threads with rayon. Each batch is computed by one
//! thread from its own inputs only, so results do not depend on the number of
//! threads.

use rayon::prelude::*;

use super::{Evaluator, Problem, Scores, check_dim, effects, to_f32};
use crate::model::Family;
use crate::model::sim::{
    classic_w, generalized_w, in_bounds, linear_part, linear_step, restart_w, switch_threshold,
};
use crate::search::{Params, Rows};

pub use super::batch::LANES;
use super::batch::block;

/// Samples of a batch's recorded errors gathered into the lanes' residual
/// vectors at a time: 64 samples of 32 lanes are 8 KiB, inside any L1.
const GATHER_SAMPLES: usize = 64;

/// The batched, multi-threaded CPU evaluator. It holds no device and no
/// buffers, so copies of it score side by side.
#[derive(Debug, Default, Clone)]
pub struct CpuEvaluator {
    /// Why the CPU was chosen, when `--backend auto` chose it.
    note: Option<String>,
}

impl CpuEvaluator {
    pub fn new() -> Self {
        CpuEvaluator::default()
    }

    /// A CPU evaluator that says why it was chosen (in [`Evaluator::describe`]).
    pub fn with_note(note: impl Into<String>) -> Self {
        CpuEvaluator {
            note: Some(note.into()),
        }
    }
}

impl Evaluator for CpuEvaluator {
    /// A copy: it holds no device and no buffers.
    fn fork(&self) -> Option<Box<dyn Evaluator + Send>> {
        Some(Box::new(self.clone()))
    }

    fn describe(&self) -> String {
        let threads = match rayon::current_num_threads() {
            1 => "1 thread".to_string(),
            n => format!("{n} threads"),
        };
        let base = format!("cpu ({LANES}-lane batches on {threads})");
        match &self.note {
            Some(note) => format!("{base}; {note}"),
            None => base,
        }
    }

    fn evaluate(
        &mut self,
        problem: &Problem,
        population: Rows<'_, Params>,
    ) -> anyhow::Result<Scores> {
        check_dim(problem, population)?;
        Ok(score_rows(problem, &to_f32(population.as_flat())))
    }

    /// A plain family's residuals in the lanes of the scoring loop, as
    /// many candidates side by side as its scores (a polish asks for a
    /// Jacobian's probes at a time, two dozen rows: one batch, computed in
    /// the time the reference simulation takes for one or two); a model
    /// with effect stages one candidate per task through its reference
    /// simulation.
    fn residuals(
        &mut self,
        problem: &Problem,
        population: Rows<'_, Params>,
    ) -> anyhow::Result<Vec<Option<Vec<f32>>>> {
        check_dim(problem, population)?;
        let rows = to_f32(population.as_flat());
        let d = problem.dim();
        if problem.effects.is_empty() {
            let every = problem.measure.restart_every();
            return Ok(rows
                .par_chunks(LANES * d)
                .with_min_len(batches_per_task(problem))
                .flat_map_iter(|chunk| {
                    let params = transpose(chunk, d);
                    let used = chunk.len() / d;
                    let mut lanes: Vec<Option<Vec<f32>>> = (0..used)
                        .map(|_| Some(Vec::with_capacity(problem.samples())))
                        .collect();
                    for e in &problem.experiments {
                        let (errors, ok) = batch_residuals(
                            problem.family,
                            &params,
                            e.y_mean as f32,
                            &e.u,
                            &e.y,
                            every,
                        );
                        for (l, lane) in lanes.iter_mut().enumerate() {
                            if !ok[l] {
                                *lane = None;
                            }
                        }
                        // A block of samples at a time, each lane's errors
                        // gathered from it while it sits in L1: lane by lane
                        // over the whole trace would stream it once a lane.
                        for block in errors.chunks(GATHER_SAMPLES) {
                            for (l, lane) in lanes.iter_mut().enumerate() {
                                if let Some(r) = lane {
                                    r.extend(block.iter().map(|es| es[l]));
                                }
                            }
                        }
                    }
                    lanes
                })
                .collect());
        }
        let model = problem.model();
        Ok(rows
            .par_chunks(LANES * d)
            .with_min_len(batches_per_task(problem))
            .flat_map_iter(|chunk| effects::batch_residuals(problem, &model, chunk))
            .collect())
    }
}

/// Scores `f32` rows (row-major `N × d`) on every experiment of `problem`.
pub fn score_rows(problem: &Problem, rows: &[f32]) -> Scores {
    let family = problem.family;
    let every = problem.measure.restart_every();
    let d = problem.dim();
    let n = rows.len() / d;
    let model = problem.model();
    let batches: Vec<Vec<[f32; LANES]>> = rows
        .par_chunks(LANES * d)
        .with_min_len(batches_per_task(problem))
        .map(|chunk| {
            if !problem.effects.is_empty() {
                return effects::batch_sse(problem, &model, chunk);
            }
            let params = transpose(chunk, d);
            problem
                .experiments
                .iter()
                .map(|e| batch_sse(family, &params, e.y_mean as f32, &e.u, &e.y, every))
                .collect()
        })
        .collect();
    let per_experiment = (0..problem.experiments.len())
        .map(|e| {
            batches
                .iter()
                .flat_map(|b| b[e])
                .take(n)
                .collect::<Vec<f32>>()
        })
        .collect();
    Scores::from_per_experiment(per_experiment)
}

/// Lane-samples (candidates times samples) one rayon task of the scoring
/// loops takes at least: some 0.1 ms of simulation. A batch of the
/// shipped stair (4000 samples) is a task of its own, as before; a short
/// record's batches go several to a task, since handing one to another
/// thread costs tens of microseconds in wake-ups, as much as its
/// simulation. A batch's scores never depend on its task.
const LANE_SAMPLES_PER_TASK: usize = 1 << 17;

/// Batches of [`LANES`] candidates one task of the scoring loops takes.
fn batches_per_task(problem: &Problem) -> usize {
    (LANE_SAMPLES_PER_TASK / (LANES * problem.samples().max(1))).max(1)
}

/// `params[j][l]`: parameter `j` of lane `l`. A short last batch is padded
/// with copies of its first row; the padding lanes' scores are dropped.
fn transpose(chunk: &[f32], d: usize) -> Vec<[f32; LANES]> {
    let mut params = vec![[0.0f32; LANES]; d];
    let used = chunk.len() / d;
    for l in 0..LANES {
        let row = if l < used { l } else { 0 };
        for (j, p) in params.iter_mut().enumerate() {
            p[l] = chunk[row * d + j];
        }
    }
    params
}

/// The SSE of every lane of one batch on one experiment (its output mean
/// `y_mean` removed), as [`crate::model::measured_sse`] with restarts after
/// every `every`-th sample.
fn batch_sse(
    family: Family,
    params: &[[f32; LANES]],
    y_mean: f32,
    u: &[f32],
    y: &[f32],
    every: usize,
) -> [f32; LANES] {
    let (sse, ok, _) = batch_run::<false>(family, params, y_mean, u, y, every);
    std::array::from_fn(|l| if ok[l] { sse[l] } else { f32::INFINITY })
}

/// The errors `x(k) − y(k)`, `k ≥ 1`, of every lane of one batch on one
/// experiment, one array of lanes a sample, as [`crate::model::residuals`]
/// gives each candidate's; a lane is valid where its flag holds (false:
/// it diverged, and its errors stop meaning anything).
fn batch_residuals(
    family: Family,
    params: &[[f32; LANES]],
    y_mean: f32,
    u: &[f32],
    y: &[f32],
    every: usize,
) -> (Vec<[f32; LANES]>, [bool; LANES]) {
    let (_, ok, errors) = batch_run::<true>(family, params, y_mean, u, y, every);
    (errors, ok)
}

/// One batch on one experiment: every lane's SSE, whether it stayed in
/// bounds and, with `RECORD`, its error at every sample. Compiled for the
/// widest vector unit the CPU has (chosen at run time; the arithmetic is
/// the same IEEE `f32` on each, and Rust never fuses a·b + c, so the bits
/// do not depend on the choice).
fn batch_run<const RECORD: bool>(
    family: Family,
    params: &[[f32; LANES]],
    y_mean: f32,
    u: &[f32],
    y: &[f32],
    every: usize,
) -> BatchRun {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has AVX-512F.
            return unsafe { batch_run_avx512::<RECORD>(family, params, y_mean, u, y, every) };
        }
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2.
            return unsafe { batch_run_avx2::<RECORD>(family, params, y_mean, u, y, every) };
        }
    }
    batch_run_portable::<RECORD>(family, params, y_mean, u, y, every)
}

/// A batch's SSE per lane, its in-bounds flags and (when recorded) its
/// errors, one array of lanes a sample.
type BatchRun = ([f32; LANES], [bool; LANES], Vec<[f32; LANES]>);

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn batch_run_avx512<const RECORD: bool>(
    family: Family,
    params: &[[f32; LANES]],
    y_mean: f32,
    u: &[f32],
    y: &[f32],
    every: usize,
) -> BatchRun {
    batch_run_portable::<RECORD>(family, params, y_mean, u, y, every)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn batch_run_avx2<const RECORD: bool>(
    family: Family,
    params: &[[f32; LANES]],
    y_mean: f32,
    u: &[f32],
    y: &[f32],
    every: usize,
) -> BatchRun {
    batch_run_portable::<RECORD>(family, params, y_mean, u, y, every)
}

#[inline(always)]
fn batch_run_portable<const RECORD: bool>(
    family: Family,
    params: &[[f32; LANES]],
    y_mean: f32,
    u: &[f32],
    y: &[f32],
    every: usize,
) -> BatchRun {
    assert_eq!(u.len(), y.len(), "input and output lengths differ");
    if u.is_empty() {
        return ([0.0; LANES], [true; LANES], Vec::new());
    }
    let n_is_one = |j: usize| params[j].iter().all(|&n| n == 1.0);
    match family {
        Family::Linear => {
            lanes_run::<_, RECORD>(&LinearLanes(params.try_into().expect("4")), u, y, every)
        }
        Family::Classic => {
            let p = params.try_into().expect("9 parameters");
            if n_is_one(4) {
                lanes_run::<_, RECORD>(&ClassicLanes::<true>(p), u, y, every)
            } else {
                lanes_run::<_, RECORD>(&ClassicLanes::<false>(p), u, y, every)
            }
        }
        Family::Generalized => {
            let p = params.try_into().expect("14 parameters");
            if n_is_one(8) {
                lanes_run::<_, RECORD>(&GeneralizedLanes::<true>::new(p, y_mean), u, y, every)
            } else {
                lanes_run::<_, RECORD>(&GeneralizedLanes::<false>::new(p, y_mean), u, y, every)
            }
        }
    }
}

/// One family's parameters for a batch of [`LANES`] candidates: the step of
/// lane `l`, from `(x(k−1), w(k−1))` and `u(k−1)` to `(x(k), w(k))`, calling
/// the equations of [`crate::model::sim`].
trait LaneModel {
    /// The start offset `x₀` of lane `l` ([`crate::model::sim::Stepper::start`]).
    fn start(&self, l: usize) -> f32;

    fn step(&self, l: usize, x: f32, w: f32, u_prev: f32) -> (f32, f32);

    /// [`crate::model::sim::Stepper::restart`] of lane `l` to the measurement `y`.
    fn restart(&self, l: usize, x: f32, w: f32, y: f32) -> (f32, f32);
}

struct LinearLanes<'a>(&'a [[f32; LANES]; 4]);

impl LaneModel for LinearLanes<'_> {
    #[inline(always)]
    fn start(&self, l: usize) -> f32 {
        let [.., x0] = self.0;
        x0[l]
    }

    #[inline(always)]
    fn step(&self, l: usize, x: f32, _w: f32, u_prev: f32) -> (f32, f32) {
        let [a, b, c, _] = self.0;
        (linear_step(a[l], b[l], c[l], x, u_prev), 0.0)
    }

    #[inline(always)]
    fn restart(&self, _l: usize, _x: f32, _w: f32, y: f32) -> (f32, f32) {
        (y, 0.0)
    }
}

/// `N_ONE`: every lane has `n = 1` (the common case, compiled without `powf`).
struct ClassicLanes<'a, const N_ONE: bool>(&'a [[f32; LANES]; 9]);

impl<const N_ONE: bool> LaneModel for ClassicLanes<'_, N_ONE> {
    #[inline(always)]
    fn start(&self, l: usize) -> f32 {
        let [.., x0] = self.0;
        x0[l]
    }

    #[inline(always)]
    fn step(&self, l: usize, x: f32, w: f32, u_prev: f32) -> (f32, f32) {
        let [big_a, alpha, beta, gamma, n, a, b, c, _] = self.0;
        let nl = if N_ONE { 1.0 } else { n[l] };
        let xn = linear_part(a[l], alpha[l], b[l], c[l], x, w, u_prev);
        (xn, classic_w(big_a[l], beta[l], gamma[l], nl, w, xn - x))
    }

    #[inline(always)]
    fn restart(&self, l: usize, x: f32, w: f32, y: f32) -> (f32, f32) {
        let [big_a, ..] = self.0;
        (y, restart_w(big_a[l], w, x, y))
    }
}

/// The generalized family's lanes with each lane's switching threshold in
/// the experiment's deviation coordinates, formed once per batch
/// ([`crate::model::sim::Stepper::new`]).
struct GeneralizedLanes<'a, const N_ONE: bool> {
    p: &'a [[f32; LANES]; 14],
    threshold: [f32; LANES],
}

impl<'a, const N_ONE: bool> GeneralizedLanes<'a, N_ONE> {
    fn new(p: &'a [[f32; LANES]; 14], y_mean: f32) -> Self {
        let is = Family::Generalized
            .switch_index()
            .expect("the generalized family has a switching level");
        let threshold = p[is].map(|x_s| switch_threshold(x_s, y_mean));
        GeneralizedLanes { p, threshold }
    }
}

impl<const N_ONE: bool> LaneModel for GeneralizedLanes<'_, N_ONE> {
    #[inline(always)]
    fn start(&self, l: usize) -> f32 {
        let [.., x0] = self.p;
        x0[l]
    }

    #[inline(always)]
    fn step(&self, l: usize, x: f32, w: f32, u_prev: f32) -> (f32, f32) {
        let [big_a, alpha, b1, b2, b3, b4, b5, b6, n, _, a, b, c, _] = self.p;
        let nl = if N_ONE { 1.0 } else { n[l] };
        let betas = [b1[l], b2[l], b3[l], b4[l], b5[l], b6[l]];
        let xn = linear_part(a[l], alpha[l], b[l], c[l], x, w, u_prev);
        let wn = generalized_w(big_a[l], &betas, nl, w, xn, xn - x, self.threshold[l]);
        (xn, wn)
    }

    #[inline(always)]
    fn restart(&self, l: usize, x: f32, w: f32, y: f32) -> (f32, f32) {
        let [big_a, ..] = self.p;
        (y, restart_w(big_a[l], w, x, y))
    }
}

/// The one scoring loop of every family: all lanes advance sample by sample,
/// each accumulating its squared error (and, with `RECORD`, keeping each
/// sample's error); the output state restarts from the measurement after
/// every `every`-th sample. A lane whose state leaves the bounds latches
/// its flag (its SSE is then `+∞`); the loop stops once every lane has.
/// Blocks end at divergence checks and at restarts, so that neither costs
/// a test per sample.
#[inline(always)]
fn lanes_run<M: LaneModel, const RECORD: bool>(
    m: &M,
    u: &[f32],
    y: &[f32],
    every: usize,
) -> BatchRun {
    let mut x: [f32; LANES] = std::array::from_fn(|l| y[0] + m.start(l));
    let mut w = [0.0f32; LANES];
    let mut acc = [0.0f32; LANES];
    let mut ok = [true; LANES];
    let mut errors = Vec::with_capacity(if RECORD { u.len() - 1 } else { 0 });
    let mut start = 1;
    while start < u.len() {
        let (end, restarts) = block(start, u.len(), every);
        for k in start..end {
            let (up, yk) = (u[k - 1], y[k]);
            let mut es = [0.0f32; LANES];
            for l in 0..LANES {
                let (xn, wn) = m.step(l, x[l], w[l], up);
                ok[l] &= in_bounds(xn) & in_bounds(wn);
                let e = xn - yk;
                es[l] = e;
                acc[l] += e * e;
                x[l] = xn;
                w[l] = wn;
            }
            if RECORD {
                errors.push(es);
            }
        }
        if restarts {
            let yk = y[end - 1];
            for l in 0..LANES {
                (x[l], w[l]) = m.restart(l, x[l], w[l], yk);
            }
        }
        if !any_ok(&ok) {
            break;
        }
        start = end;
    }
    (acc, ok, errors)
}

/// True while some lane is in bounds.
#[inline(always)]
fn any_ok(ok: &[bool; LANES]) -> bool {
    let mut any = false;
    for &o in ok {
        any |= o;
    }
    any
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::workload::{mixed_population, search_space, stair_experiment};
    use crate::model::{Measure, measured_sse};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// The compiled variants this CPU cannot run, by the feature each needs.
    fn variants_this_cpu_cannot_run() -> Vec<&'static str> {
        #[cfg(target_arch = "x86_64")]
        {
            [
                (
                    "AVX2 (batch_run_avx2)",
                    std::is_x86_feature_detected!("avx2"),
                ),
                (
                    "AVX-512F (batch_run_avx512)",
                    std::is_x86_feature_detected!("avx512f"),
                ),
            ]
            .into_iter()
            .filter(|&(_, has)| !has)
            .map(|(name, _)| name)
            .collect()
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            vec!["AVX2 and AVX-512F (not an x86_64 build)"]
        }
    }

    /// Every compiled variant the CPU can run gives the reference's bits
    /// under every measure, its scores and its residuals, a diverging lane
    /// included (the evaluator tests only see the variant this CPU picks).
    /// A variant this CPU cannot run is not checked, and the test says so
    /// on stderr rather than passing as if it were.
    #[test]
    fn every_instruction_set_variant_is_bit_identical() {
        let unchecked = variants_this_cpu_cannot_run();
        if !unchecked.is_empty() {
            use std::io::Write;
            // Straight to the process's stderr: the harness shows what
            // `eprintln!` writes only for failing tests.
            let _ = writeln!(
                std::io::stderr().lock(),
                "\n********\n*** NOT CHECKED: this CPU lacks {}; those variants' bits were not \
                 compared (run this test on a CPU that has them)\n********\n",
                unchecked.join(" and ")
            );
        }
        let exp = stair_experiment(700, 21);
        let measures = [
            Measure::FreeRun,
            Measure::Ahead { horizon: 1 },
            Measure::Ahead { horizon: 37 },
            Measure::Ahead { horizon: 128 },
        ];
        type Variant<const R: bool> =
            fn(Family, &[[f32; LANES]], f32, &[f32], &[f32], usize) -> BatchRun;
        let mut variants: Vec<(&str, Variant<false>, Variant<true>)> = vec![(
            "portable",
            batch_run_portable::<false>,
            batch_run_portable::<true>,
        )];
        #[cfg(target_arch = "x86_64")]
        {
            // SAFETY (both): called only where the CPU has the feature.
            if std::is_x86_feature_detected!("avx2") {
                variants.push((
                    "avx2",
                    |f, p, m, u, y, e| unsafe { batch_run_avx2::<false>(f, p, m, u, y, e) },
                    |f, p, m, u, y, e| unsafe { batch_run_avx2::<true>(f, p, m, u, y, e) },
                ));
            }
            if std::is_x86_feature_detected!("avx512f") {
                variants.push((
                    "avx512",
                    |f, p, m, u, y, e| unsafe { batch_run_avx512::<false>(f, p, m, u, y, e) },
                    |f, p, m, u, y, e| unsafe { batch_run_avx512::<true>(f, p, m, u, y, e) },
                ));
            }
        }
        for (family, free_n) in [
            (Family::Linear, false),
            (Family::Classic, false),
            (Family::Classic, true),
            (Family::Generalized, false),
            (Family::Generalized, true),
        ] {
            let d = family.dim();
            let space = search_space(family, &exp, free_n);
            let mut pop = mixed_population(&space, LANES, &mut ChaCha8Rng::seed_from_u64(2));
            // One lane that leaves the bounds where it runs free for more
            // than a few samples: a pole far outside the unit circle.
            let ia = family.linear_indices()[0];
            pop[3 * d + ia] = 3.0;
            let rows = to_f32(&pop);
            let params = transpose(&rows, d);
            let y_mean = exp.y_mean as f32;
            for measure in measures {
                let every = measure.restart_every();
                let want_sse: Vec<u32> = rows
                    .chunks_exact(d)
                    .map(|t| measured_sse(family, t, y_mean, &exp.u, &exp.y, measure).to_bits())
                    .collect();
                if every > 20 {
                    assert_eq!(
                        want_sse[3],
                        f32::INFINITY.to_bits(),
                        "{family}: lane 3 diverges"
                    );
                }
                let want_residuals: Vec<Option<Vec<u32>>> = rows
                    .chunks_exact(d)
                    .map(|t| {
                        crate::model::residuals(family, t, y_mean, &exp.u, &exp.y, measure)
                            .map(|r| r.iter().map(|v| v.to_bits()).collect())
                    })
                    .collect();
                for (name, sse, recorded) in &variants {
                    let what = format!("{family}, {measure}, {name}");
                    let (acc, ok, none) = sse(family, &params, y_mean, &exp.u, &exp.y, every);
                    assert!(none.is_empty(), "{what}: errors kept unasked");
                    let got: Vec<u32> = (0..LANES)
                        .map(|l| if ok[l] { acc[l] } else { f32::INFINITY }.to_bits())
                        .collect();
                    assert_eq!(got, want_sse, "{what}: scores");
                    let (_, ok, errors) = recorded(family, &params, y_mean, &exp.u, &exp.y, every);
                    let got: Vec<Option<Vec<u32>>> = (0..LANES)
                        .map(|l| ok[l].then(|| errors.iter().map(|es| es[l].to_bits()).collect()))
                        .collect();
                    assert_eq!(got, want_residuals, "{what}: residuals");
                }
            }
        }
    }
}
