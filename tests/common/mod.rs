//! What the integration tests share: one rule for a test that needs
//! something a checkout may lack — a GPU adapter, or the external data in
//! `../shared` beside the repository.
//!
//! Run locally without it, such a test prints a loud SKIP banner to stderr
//! and returns (it passes: a developer without a GPU or without the data can
//! still run the suite). Under `CI=true` it fails instead: CI installs
//! lavapipe (`.ci/run`) and clones `../shared` beside the repository, so a
//! missing adapter or file there is a broken set-up that must not pass as a
//! green test.
//!
//! It also holds [`InterruptAt`], the observer the engine tests press
//! Ctrl-C with, and [`interrupt_once`], which presses it on a command.
//! Each test file includes this with `mod common;`.

// Every test binary compiles its own copy of this module and uses only the
// helpers it needs; the others would each warn as dead code.
#![allow(dead_code)]

use std::fmt::Display;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Whether the tests run under CI (`CI=true`), where nothing may be skipped.
pub fn under_ci() -> bool {
    std::env::var("CI").as_deref() == Ok("true")
}

/// A requirement of the calling test is missing (`reason` says which):
/// panics under `CI=true`, otherwise prints a SKIP banner to stderr. The
/// caller returns after it.
#[track_caller]
pub fn skip_or_fail(reason: &str) {
    if under_ci() {
        panic!("CI=true, so this test must run, but {reason}");
    }
    // Straight to the process's stderr: the test harness captures what
    // `eprintln!` writes and shows it only for failing tests, which would
    // hide the banner of a test that passes by skipping.
    let _ = writeln!(
        std::io::stderr().lock(),
        "\n********\n*** SKIP: {reason}\n*** (the test returns without checking anything; \
         under CI=true it fails)\n********\n"
    );
}

/// The value of `opened` (a GPU evaluator, a device, an adapter: whatever
/// needs an adapter), or `None` after [`skip_or_fail`] with its error.
#[track_caller]
pub fn require_gpu<T, E: Display>(opened: Result<T, E>) -> Option<T> {
    match opened {
        Ok(v) => Some(v),
        Err(e) => {
            skip_or_fail(&format!("no usable GPU adapter: {e:#}"));
            None
        }
    }
}

/// Whether `info` is lavapipe: Mesa's CPU Vulkan adapter, told by its
/// device type (a CPU), not by its name. There the shaders' guard against
/// fused multiply-adds (`rounded()` in `shaders/prologue.wgsl`) makes them
/// give the CPU's bits; every test that expects bits on lavapipe and a
/// tolerance elsewhere asks this.
pub fn is_lavapipe(info: &wgpu::AdapterInfo) -> bool {
    info.device_type == wgpu::DeviceType::Cpu
}

/// The best adapter present, whatever it is; `None` after [`skip_or_fail`]
/// when there is none.
#[track_caller]
pub fn require_any_adapter() -> Option<wgpu::Adapter> {
    require_gpu(
        mckibben::eval::gpu::adapters()
            .into_iter()
            .next()
            .ok_or("none found (install mesa-vulkan-drivers and libvulkan1)"),
    )
}

/// The lavapipe adapter; `None` after [`skip_or_fail`] when there is none.
#[track_caller]
pub fn require_lavapipe_adapter() -> Option<wgpu::Adapter> {
    let lavapipe = mckibben::eval::gpu::adapters()
        .into_iter()
        .find(|a| is_lavapipe(&a.get_info()));
    if lavapipe.is_none() {
        skip_or_fail("no CPU Vulkan adapter (lavapipe)");
    }
    lavapipe
}

/// A GPU evaluator on lavapipe, with `options`; `None` after
/// [`skip_or_fail`] when there is none.
#[track_caller]
pub fn require_lavapipe(
    options: mckibben::eval::gpu::GpuOptions,
) -> Option<mckibben::eval::gpu::GpuEvaluator> {
    use mckibben::eval::gpu::GpuEvaluator;
    require_gpu(GpuEvaluator::with_adapter(
        require_lavapipe_adapter()?,
        options,
    ))
}

/// The external data folder: `../shared/data/external` beside the
/// repository (see its README.md there).
pub fn external_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/external")
}

/// `path` when it exists, or `None` after [`skip_or_fail`].
#[track_caller]
pub fn require_path(path: PathBuf) -> Option<PathBuf> {
    if path.exists() {
        return Some(path);
    }
    skip_or_fail(&format!(
        "{} is absent (the external data live in ../shared beside the repository; \
         see ../shared/data/external/README.md)",
        path.display()
    ));
    None
}

/// The file or folder `relative` under [`external_dir`], or `None` after
/// [`skip_or_fail`].
#[track_caller]
pub fn require_external(relative: &str) -> Option<PathBuf> {
    require_path(external_dir().join(relative))
}

/// How every command reads a Cavatappi record (../shared/data/external's
/// README): its time, pressure and displacement columns, onto a 10 ms grid
/// across its gaps.
pub const CAVATAPPI_FLAGS: [&str; 8] = [
    "--time",
    "t_s",
    "--input",
    "pressure_psi",
    "--output",
    "disp_mm",
    "--resample",
    "0.01",
];

/// An engine observer that raises the stop flag (Ctrl-C) when the history
/// record numbered `.0` (1-based, any stage) is made.
pub struct InterruptAt<'a>(pub usize, pub &'a std::sync::atomic::AtomicBool);

impl mckibben::optim::engine::Observer for InterruptAt<'_> {
    fn record(&mut self, r: &mckibben::optim::history::GenerationRecord, _: usize) {
        if r.generation == self.0 {
            self.1.store(true, std::sync::atomic::Ordering::SeqCst);
        }
    }
}

/// Runs `command` with its output piped and presses Ctrl-C (SIGINT)
/// `settle` after the first line of its stderr that `ready` accepts: a line
/// the command prints once its handler is in place. Returns its exit status,
/// its stdout, and its stderr after that line.
#[cfg(unix)]
pub fn interrupt_once(
    command: &mut std::process::Command,
    ready: impl Fn(&str) -> bool,
    settle: std::time::Duration,
) -> std::process::Output {
    use std::io::{BufRead, Read};
    use std::process::Stdio;
    let mut child = command
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run mckibben");
    let mut stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    while !ready(&line) {
        line.clear();
        assert!(
            stderr.read_line(&mut line).unwrap() > 0,
            "stderr ended before the line that says the command is ready"
        );
    }
    std::thread::sleep(settle);
    // SAFETY: kill(2) on our own child's pid, with a valid signal.
    assert_eq!(unsafe { libc::kill(child.id() as i32, libc::SIGINT) }, 0);
    let mut out = child.wait_with_output().unwrap();
    stderr.read_to_end(&mut out.stderr).unwrap();
    out
}
