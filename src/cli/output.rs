//! The commands' writes to standard output and standard error, through
//! macros that stand in for `println!`, `print!` and `eprintln!`, which
//! panic where the stream cannot be written (a full disk, a file system
//! that refuses the write).
//!
//! - `outln!` and `out!` return an error naming standard output, for `?`,
//!   as any other write of the command: `mckibben fit --json > /dev/full`
//!   says so and exits 1.
//! - `errln!` drops a failed write: there is nowhere left to say it.

use std::fmt;
use std::io::Write;

/// The text and a line end on standard output.
pub fn line(text: fmt::Arguments) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_fmt(text)
        .and_then(|()| out.write_all(b"\n"))
        .map_err(failed)
}

/// The text on standard output, as written.
pub fn text(text: fmt::Arguments) -> anyhow::Result<()> {
    std::io::stdout().lock().write_fmt(text).map_err(failed)
}

fn failed(e: std::io::Error) -> anyhow::Error {
    anyhow::anyhow!("standard output: {e}")
}

/// `println!` that returns an error where standard output cannot be written.
macro_rules! outln {
    () => {
        $crate::cli::output::line(format_args!(""))
    };
    ($($arg:tt)*) => {
        $crate::cli::output::line(format_args!($($arg)*))
    };
}

/// `print!` that returns an error where standard output cannot be written.
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::cli::output::text(format_args!($($arg)*))
    };
}

/// `eprintln!` that does not panic where standard error cannot be written.
macro_rules! errln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}
