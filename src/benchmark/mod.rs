//! Validation on the Bouc-Wen nonlinear system identification benchmark
//! (Noël & Schoukens, "Hysteretic benchmark with a dynamic nonlinearity",
//! nonlinearbenchmark.org): real, public test data with published results.
//!
//! * [`boucwen`]: the benchmark's oscillator, its Newmark integration in `f64`
//!   and the `f32` twin of `shaders/boucwen_oscillator.wgsl`;
//! * [`resample`]: the 750 Hz ↔ 15 kHz conversions the PDF prescribes;
//! * [`generator`]: benchmark-like training data from the published system,
//!   so that tests run without the external files;
//! * [`evaluator`]: the oscillator as a scored problem and its own
//!   evaluators (the `f32` twin on the CPU, the shader on the project's wgpu
//!   host);
//! * [`identify`]: population search on those evaluators, then a
//!   Levenberg–Marquardt refinement in `f64`.
//!
//! The data files are read from `../shared/data/external/boucwen_benchmark`
//! and never copied into the repository.

pub mod boucwen;
pub mod evaluator;
pub mod generator;
pub mod identify;
pub mod resample;

use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::data::csv::{DataError, ReadOptions, read_traces};
use crate::data::signals::repeats_every;

pub use boucwen::{FS, Params, UPSAMPLE};

/// Samples per period of the benchmark's multisines (PDF §4–5).
pub const PERIOD: usize = 8192;

/// Where the external benchmark files live, relative to the repository root.
pub const DEFAULT_DATA_DIR: &str = "../shared/data/external/boucwen_benchmark";

/// The published simulation RMSE on the multisine test set (metres), as the
/// data README quotes them, best first.
pub const PUBLISHED: [(&str, f64); 8] = [
    ("gr-SS-NN", 7.53e-6),
    ("SS-NN, improved initialisation", 8.91e-6),
    ("PNLSS (2018)", 1.34e-5),
    ("Koopman input-affine", 1.43e-5),
    ("PNLSS (2017)", 1.87e-5),
    ("SS-NN", 2.65e-5),
    ("dynoNet", 4.52e-5),
    ("NFIR", 1.63e-4),
];

/// One benchmark record at 750 Hz: force `u` (N) and displacement `y` (m).
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    pub u: Vec<f64>,
    pub y: Vec<f64>,
}

/// Reads a benchmark CSV: `#` comment lines, a header with columns `u_N` and
/// `y_m`, then numbers, one row per sample at [`FS`]. The project's own
/// reader reads it (a byte-order mark, semicolons, a row with too many
/// fields: as every command's data); errors name the file, line and column.
pub fn read_record(path: &Path) -> anyhow::Result<Record> {
    let opts = ReadOptions {
        dt: Some(1.0 / FS),
        input: "u_N".into(),
        output: "y_m".into(),
        ..ReadOptions::default()
    };
    let mut traces = read_traces(path, &opts).map_err(|e| match e {
        // The reader's own advice names flags `validate` does not have.
        DataError::MissingColumn {
            path,
            line,
            column,
            available,
            ..
        } => anyhow::anyhow!(
            "{}: line {line}: no column \"{column}\" (a benchmark record holds u_N, the force in \
             N, and y_m, the displacement in m); the file has columns {}",
            path.display(),
            available.join(", ")
        ),
        // A published record has every sample.
        other => other
            .with_cell_hint("; the published records hold a number in every cell: is the file one of them, whole?")
            .into(),
    })?;
    let trace = traces.pop().context("no samples")?;
    // The identification runs in f32 too (the evaluators' twin and shader):
    // values whose squared errors leave its range score nothing.
    crate::model::check_f32_range(&trace)?;
    anyhow::ensure!(
        trace.len() >= resample::MIN_RECORD,
        "{}: {} data rows; a record needs at least {} (the decimation filter's reach; the \
         published records hold 8192 and more)",
        path.display(),
        trace.len(),
        resample::MIN_RECORD
    );
    Ok(Record {
        u: trace.input,
        y: trace.output,
    })
}

/// The three benchmark files.
#[derive(Debug, Clone)]
pub struct BenchmarkData {
    pub train: Record,
    pub test_multisine: Record,
    pub test_sinesweep: Record,
}

impl BenchmarkData {
    /// Loads `train_multisine.csv`, `test_multisine.csv`, `test_sinesweep.csv`
    /// from `dir`.
    pub fn load(dir: &Path) -> anyhow::Result<BenchmarkData> {
        anyhow::ensure!(
            dir.is_dir(),
            "Bouc-Wen benchmark data not found: {} is not a directory (it holds \
             train_multisine.csv, test_multisine.csv, test_sinesweep.csv; see \
             ../shared/data/external/README.md, or pass --data DIR)",
            dir.display()
        );
        Ok(BenchmarkData {
            train: read_record(&dir.join("train_multisine.csv"))?,
            test_multisine: read_record(&dir.join("test_multisine.csv"))?,
            test_sinesweep: read_record(&dir.join("test_sinesweep.csv"))?,
        })
    }
}

/// The default data directory: [`DEFAULT_DATA_DIR`] relative to the
/// repository root (where `Cargo.toml` was built from), else to the current
/// directory.
pub fn default_data_dir() -> PathBuf {
    let from_root = Path::new(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_DATA_DIR);
    if from_root.is_dir() {
        from_root
    } else {
        PathBuf::from(DEFAULT_DATA_DIR)
    }
}

/// Simulates `periods` periods of the periodic input whose one period (at
/// 750 Hz) is `u_period`, from rest, the way the PDF's example does: upsample
/// to 15 kHz, integrate one extra period so that the decimation filter's
/// edge falls outside, decimate, drop the extra period. Returns
/// `periods · u_period.len()` samples at 750 Hz, or `None` if it diverged.
pub fn simulate_periodic(p: &Params, u_period: &[f64], periods: usize) -> Option<Vec<f64>> {
    let one = resample::upsample(u_period, UPSAMPLE, true);
    let u: Vec<f64> = (0..periods + 1).flat_map(|_| one.iter().copied()).collect();
    let y = boucwen::simulate_f64(p, &u, 1.0 / (FS * UPSAMPLE as f64))?;
    let mut y = resample::decimate(&y);
    y.truncate(periods * u_period.len());
    Some(y)
}

/// Simulates a non-periodic input from rest (the sine sweep): upsample (zero
/// outside the record), integrate, decimate. `None` if it diverged.
pub fn simulate_transient(p: &Params, u: &[f64]) -> Option<Vec<f64>> {
    let up = resample::upsample(u, UPSAMPLE, false);
    let y = boucwen::simulate_f64(p, &up, 1.0 / (FS * UPSAMPLE as f64))?;
    Some(resample::decimate(&y))
}

/// Periods simulated before the scored one on the multisine test set. The
/// linear modes decay with ζ·ω0 ≈ 2.5 s⁻¹ (PDF Table 2) and a period lasts
/// 10.9 s, so one period already brings the transient below 1e-11 of the
/// response (PDF Fig. 2b); two leave no doubt.
pub const STEADY_STATE_PERIODS: usize = 2;

/// Root-mean-square of the difference (PDF eq. 6).
pub fn rmse(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    (a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>() / a.len() as f64).sqrt()
}

/// Simulation RMSE on the multisine test set: the test input is one
/// steady-state period, so the model runs [`STEADY_STATE_PERIODS`] + 1
/// periods of it from rest and the last period is scored.
pub fn test_multisine_rmse(p: &Params, test: &Record) -> Option<f64> {
    let n = test.u.len();
    let y = simulate_periodic(p, &test.u, STEADY_STATE_PERIODS + 1)?;
    Some(rmse(&y[STEADY_STATE_PERIODS * n..], &test.y))
}

/// Simulation RMSE on the sine-sweep test set, simulated from rest as it was
/// recorded.
pub fn test_sinesweep_rmse(p: &Params, test: &Record) -> Option<f64> {
    let y = simulate_transient(p, &test.u)?;
    Some(rmse(&y, &test.y))
}

/// True when `u` repeats with period `n` (to rounding of the file's digits).
pub fn is_periodic(u: &[f64], n: usize) -> bool {
    n > 0 && u.len().is_multiple_of(n) && (u.len() == n || repeats_every(u, n))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A record too short for the decimation filter is an error naming the
    /// file (simulating it read past its ends).
    #[test]
    fn a_record_shorter_than_the_filter_reach_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("test_sinesweep.csv");
        std::fs::write(&path, "u_N,y_m\n1,0\n2,0\n3,0\n").unwrap();
        let err = read_record(&path).unwrap_err().to_string();
        assert!(
            err.contains("test_sinesweep.csv: 3 data rows; a record needs at least 16"),
            "{err}"
        );
    }

    /// A benchmark file is read as every command's data: a byte-order
    /// mark and semicolons read as the plain file; a row with a field too
    /// many, or a missing column, is an error naming the line.
    #[test]
    fn a_record_reads_as_every_command_s_data() {
        let dir = tempfile::tempdir().unwrap();
        let rows: String = (0..40).map(|k| format!("{k},{}e-4\n", k % 5)).collect();
        let plain = dir.path().join("plain.csv");
        std::fs::write(&plain, format!("# fs=750 Hz\nu_N,y_m\n{rows}")).unwrap();
        let want = read_record(&plain).unwrap();
        assert_eq!((want.u.len(), want.u[3], want.y[3]), (40, 3.0, 3e-4));
        let bom = dir.path().join("bom.csv");
        std::fs::write(&bom, format!("\u{feff}# fs=750 Hz\nu_N,y_m\n{rows}")).unwrap();
        assert_eq!(read_record(&bom).unwrap(), want);
        let semicolons = dir.path().join("semicolons.csv");
        std::fs::write(&semicolons, format!("u_N;y_m\n{}", rows.replace(',', ";"))).unwrap();
        assert_eq!(read_record(&semicolons).unwrap(), want);

        let extra = dir.path().join("extra.csv");
        let mut text = format!("u_N,y_m\n{rows}");
        text = text.replacen("7,2e-4\n", "7,2e-4,1,2\n", 1);
        std::fs::write(&extra, text).unwrap();
        let err = read_record(&extra).unwrap_err().to_string();
        assert!(err.contains("extra.csv: line 9"), "{err}");
        let huge = dir.path().join("huge.csv");
        std::fs::write(&huge, format!("u_N,y_m\n{}", rows.replace("e-4", "e300"))).unwrap();
        let err = read_record(&huge).unwrap_err().to_string();
        assert!(
            err.contains("column `y_m` of") && err.contains("overflow the f32 arithmetic"),
            "{err}"
        );
        // A missed reading: `validate` has neither --resample nor
        // --split-gaps, and its error names neither.
        let missed = dir.path().join("missed.csv");
        std::fs::write(
            &missed,
            format!("u_N,y_m\n{}", rows.replacen("7,", "NaN,", 1)),
        )
        .unwrap();
        let err = read_record(&missed).unwrap_err().to_string();
        assert!(
            err.contains("missed.csv: line 9, column \"u_N\"")
                && err.contains("the published records hold a number in every cell")
                && !err.contains("--split-gaps"),
            "{err}"
        );
        let renamed = dir.path().join("renamed.csv");
        std::fs::write(&renamed, format!("force,y_m\n{rows}")).unwrap();
        let err = read_record(&renamed).unwrap_err().to_string();
        assert!(
            err.contains("renamed.csv: line 1: no column \"u_N\" (a benchmark record holds u_N"),
            "{err}"
        );
    }
}
