//! The run log of a loop on a rig, written as the run goes: one CSV row per
//! measured sample, flushed at once, so that a rig (or a controller) that
//! dies mid-run leaves everything up to its last sample on disk. Events —
//! a missing, late or bad measurement, the valve closed — are `#` comment
//! lines between the rows, which the project's CSV reader skips.
//!
//! Unlike the project's result files this one is not written atomically: a
//! log that appears only when the run ends would lose exactly the runs it is
//! for.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// A CSV log open for appending.
pub struct RunLog {
    path: PathBuf,
    out: Option<BufWriter<File>>,
}

impl RunLog {
    /// A log that writes nothing.
    pub fn none() -> RunLog {
        RunLog {
            path: PathBuf::new(),
            out: None,
        }
    }

    /// Creates (truncates) `path` and writes the comment lines `header`
    /// and the column names.
    pub fn create(path: &Path, header: &[String]) -> io::Result<RunLog> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            crate::data::create_dir_all(dir)?;
        }
        let mut log = RunLog {
            path: path.to_path_buf(),
            out: Some(BufWriter::new(File::create(path)?)),
        };
        for line in header {
            log.write(&format!("# {line}"))?;
        }
        log.write("t,reference,pressure,displacement,valve_in")?;
        Ok(log)
    }

    /// Where the log is.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn write(&mut self, line: &str) -> io::Result<()> {
        if let Some(out) = &mut self.out {
            out.write_all(line.as_bytes())?;
            out.write_all(b"\n")?;
            out.flush()?;
        }
        Ok(())
    }

    /// One measured sample and the command computed from it.
    pub fn row(
        &mut self,
        t: f64,
        reference: f64,
        pressure: f64,
        displacement: f64,
        valve: f64,
    ) -> io::Result<()> {
        self.write(&format!(
            "{t},{reference},{pressure},{displacement},{valve}"
        ))
    }

    /// An event, as a comment line.
    pub fn event(&mut self, text: &str) -> io::Result<()> {
        self.write(&format!("# {text}"))
    }
}
