//! The `mckibben` command line. It parses arguments and calls the library;
//! every command lives in its own file under `src/cli/`.

mod cli;

use std::io::Write;
use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    restore_default_sigpipe();
    ensure_runtime_dir();
    let args = cli::Cli::parse();
    check_thread_count();
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            let interrupted = cli::interrupted(&err);
            let mut said = err.to_string();
            // Where standard error cannot be written there is nowhere to
            // say it; the status still does.
            let mut stderr = std::io::stderr().lock();
            let _ = match interrupted {
                true => writeln!(stderr, "mckibben: {said}"),
                false => writeln!(stderr, "mckibben: error: {said}"),
            };
            for cause in err.chain().skip(1).map(|c| c.to_string()) {
                // An error that quotes its cause ("file: No such file") has
                // already said it.
                if !said.contains(&cause) {
                    let _ = writeln!(stderr, "  caused by: {cause}");
                }
                said = cause;
            }
            match interrupted {
                // 128 + SIGINT, the status a shell gives a program Ctrl-C killed.
                true => ExitCode::from(130),
                false => ExitCode::FAILURE,
            }
        }
    }
}

/// rayon ignores a `RAYON_NUM_THREADS` that is not a whole number and runs
/// on every core: a timing meant for one thread should not pass for it.
fn check_thread_count() {
    let Some(value) = std::env::var_os("RAYON_NUM_THREADS") else {
        return;
    };
    let value = value.to_string_lossy();
    if value.trim().parse::<usize>().is_err() {
        let _ = writeln!(
            std::io::stderr().lock(),
            "mckibben: note: RAYON_NUM_THREADS={value} is not a whole number, so it is ignored: \
             the CPU path runs on {} threads",
            rayon::current_num_threads()
        );
    }
}

/// `mckibben fit | head` should end quietly when `head` closes the pipe, as
/// other command-line tools do, rather than report a broken pipe as an
/// error.
fn restore_default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first thing in `main`, before any thread exists;
    // restores the default disposition that Rust's runtime replaced.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// The Vulkan loader, probed by `--backend auto|gpu`, prints an error when
/// `XDG_RUNTIME_DIR` is unset although nothing is wrong; give it a private
/// folder so that the user sees only messages that matter.
fn ensure_runtime_dir() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|d| std::path::Path::new(&d).is_dir()) {
        return;
    }
    let dir = std::env::temp_dir().join("mckibben-runtime");
    if std::fs::create_dir_all(&dir).is_err() {
        return;
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let _ = std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700));
    }
    // SAFETY: called in `main` before any thread exists, so nothing reads the
    // environment concurrently.
    unsafe { std::env::set_var("XDG_RUNTIME_DIR", dir) };
}
