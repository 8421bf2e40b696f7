//! Same seed, same result: with any rayon thread count, and across a
//! checkpoint and resume (the JSON round trip of the whole run state).

use mckibben::eval::{Problem, cpu::CpuEvaluator};
use mckibben::model::Family;
use mckibben::optim::history::GenerationRecord;
use mckibben::optim::synthetic::Synthetic;
use mckibben::optim::{AlgoSettings, Algorithm, RunSettings, Runner};

fn setup() -> (Synthetic, Problem) {
    let s = Synthetic::new(Family::Classic, 300, 0.05, 3);
    let p = Problem::new(Family::Classic, vec![s.estimation.clone()]);
    (s, p)
}

/// History without the wall-clock column.
fn fingerprint(r: &Runner) -> Vec<GenerationRecord> {
    r.history
        .records
        .iter()
        .map(|g| GenerationRecord {
            seconds: 0.0,
            ..g.clone()
        })
        .collect()
}

fn settings() -> AlgoSettings {
    let mut s = AlgoSettings::default();
    // Exercise the parallel all-pairs firefly move.
    s.mfa.max_attractors = None;
    // The GA's non-uniform mutation depends on the generation counter,
    // which the checkpoint must carry.
    s.ga.mutation = mckibben::optim::ga::Mutation::NonUniform;
    s
}

fn run(algo: Algorithm, threads: usize) -> Vec<GenerationRecord> {
    let (s, problem) = setup();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut r = Runner::new(algo, &settings(), s.space(), RunSettings::new(64, 12, 9)).unwrap();
        r.run(&problem, &mut CpuEvaluator::new(), &mut [], None, None)
            .unwrap();
        fingerprint(&r)
    })
}

#[test]
fn thread_count_does_not_change_the_result() {
    for algo in Algorithm::ALL {
        let one = run(algo, 1);
        assert_eq!(one.len(), 12);
        assert!(one.last().unwrap().best_sse.is_some(), "{algo}");
        assert_eq!(one, run(algo, 3), "{algo}");
    }
}

#[test]
fn different_seeds_differ() {
    let (s, problem) = setup();
    let mut a = Runner::new(
        Algorithm::De,
        &settings(),
        s.space(),
        RunSettings::new(32, 3, 1),
    )
    .unwrap();
    let mut b = Runner::new(
        Algorithm::De,
        &settings(),
        s.space(),
        RunSettings::new(32, 3, 2),
    )
    .unwrap();
    a.run(&problem, &mut CpuEvaluator::new(), &mut [], None, None)
        .unwrap();
    b.run(&problem, &mut CpuEvaluator::new(), &mut [], None, None)
        .unwrap();
    assert_ne!(fingerprint(&a), fingerprint(&b));
}

#[test]
fn checkpoint_resume_gives_the_identical_result() {
    let dir = tempfile::tempdir().unwrap();
    let (s, problem) = setup();
    for algo in Algorithm::ALL {
        let run_settings = RunSettings::new(40, 10, 5);
        let mut straight = Runner::new(algo, &settings(), s.space(), run_settings.clone()).unwrap();
        let full = straight
            .run(&problem, &mut CpuEvaluator::new(), &mut [], None, None)
            .unwrap();

        let path = dir.path().join(format!("{algo}.json"));
        let mut first = Runner::new(algo, &settings(), s.space(), run_settings).unwrap();
        for _ in 0..4 {
            first.step(&problem, &mut CpuEvaluator::new()).unwrap();
        }
        first.save(&path).unwrap();
        drop(first);
        let mut resumed = Runner::load(&path).unwrap();
        assert_eq!(resumed.generation(), 4);
        let out = resumed
            .run(&problem, &mut CpuEvaluator::new(), &mut [], None, None)
            .unwrap();
        assert_eq!(out.params, full.params, "{algo}");
        assert_eq!(out.sse, full.sse, "{algo}");
        assert_eq!(out.evaluations, full.evaluations, "{algo}");
        assert_eq!(fingerprint(&resumed), fingerprint(&straight), "{algo}");
    }
}

#[test]
fn a_damaged_checkpoint_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.json");
    std::fs::write(&path, b"{\"settings\": 3}").unwrap();
    let err = Runner::load(&path).unwrap_err().to_string();
    assert!(err.contains("not a mckibben checkpoint"), "{err}");
}

/// The same run scored on the GPU backend (lavapipe here): bit-identical on
/// lavapipe, which never fuses multiply-adds (docs/ARCHITECTURE.md); on a
/// hardware GPU, which may, the final SSE agrees to 1e-3. Skipped with a
/// note when no Vulkan adapter is present.
#[test]
fn cpu_and_gpu_backends_give_the_same_run() {
    use mckibben::eval::Evaluator;
    use mckibben::eval::gpu::GpuEvaluator;
    let mut gpu = match GpuEvaluator::open(Default::default()) {
        Ok(g) => g,
        Err(e) => {
            eprintln!("skipped: no GPU adapter ({e})");
            return;
        }
    };
    let software = gpu.describe().contains("llvmpipe");
    let (s, problem) = setup();
    for algo in [Algorithm::De, Algorithm::Mfa] {
        let run = RunSettings::new(48, 6, 13);
        let mut on_cpu = Runner::new(algo, &settings(), s.space(), run.clone()).unwrap();
        let mut on_gpu = Runner::new(algo, &settings(), s.space(), run).unwrap();
        let a = on_cpu
            .run(&problem, &mut CpuEvaluator::new(), &mut [], None, None)
            .unwrap();
        let b = on_gpu.run(&problem, &mut gpu, &mut [], None, None).unwrap();
        if software {
            assert_eq!(fingerprint(&on_cpu), fingerprint(&on_gpu), "{algo}");
        } else {
            assert!(
                (a.sse - b.sse).abs() <= 1e-3 * a.sse,
                "{algo}: {} vs {}",
                a.sse,
                b.sse
            );
        }
    }
}

/// Ctrl-C raises the interrupt flag: the loop finishes the current
/// generation, stops with `Interrupted` and writes the best so far to the
/// checkpoint, from which the run resumes to the uninterrupted result.
#[test]
fn an_interrupt_stops_cleanly_with_the_best_so_far_saved() {
    use mckibben::optim::{Observer, StopReason};
    use std::sync::atomic::{AtomicBool, Ordering};

    struct InterruptAt<'a>(usize, &'a AtomicBool);
    impl Observer for InterruptAt<'_> {
        fn generation(&mut self, r: &GenerationRecord, _: &RunSettings) {
            if r.generation == self.0 {
                self.1.store(true, Ordering::SeqCst);
            }
        }
    }

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ck.json");
    let (s, problem) = setup();
    let run = RunSettings::new(40, 9, 8);
    let flag = AtomicBool::new(false);
    let mut r = Runner::new(Algorithm::Pso, &settings(), s.space(), run.clone()).unwrap();
    let out = r
        .run(
            &problem,
            &mut CpuEvaluator::new(),
            &mut [&mut InterruptAt(3, &flag)],
            Some(&flag),
            Some(&path),
        )
        .unwrap();
    assert_eq!(out.stop, StopReason::Interrupted);
    assert_eq!(out.generations, 3);
    assert!(out.sse.is_finite() && !out.params.is_empty());
    let mut resumed = Runner::load(&path).unwrap();
    assert_eq!(resumed.best().unwrap().1, out.sse);
    let done = resumed
        .run(&problem, &mut CpuEvaluator::new(), &mut [], None, None)
        .unwrap();
    let mut straight = Runner::new(Algorithm::Pso, &settings(), s.space(), run).unwrap();
    let full = straight
        .run(&problem, &mut CpuEvaluator::new(), &mut [], None, None)
        .unwrap();
    assert_eq!((done.params, done.sse), (full.params, full.sse));
}
