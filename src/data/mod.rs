//! Experiment data: the in-memory [`Trace`], CSV input and output, and the
//! signal generators of the thesis' appendix A.

pub mod atomic;
pub mod csv;
pub mod input;
pub mod signals;
pub mod units;

pub use atomic::{create_dir_all, write_all_atomic, write_atomic};

use serde::{Deserialize, Serialize};

/// One recorded (or simulated) experiment: a uniform time base, the model's
/// input and output columns, and any other columns the file carried.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trace {
    /// Where the trace came from (a file path or a generator name), for messages.
    pub source: String,
    /// Name of the time column (default `t`): a file written from the
    /// trace names its time as the file it was read from did.
    pub time_name: String,
    /// Time in seconds, strictly increasing and uniform (see [`Trace::dt`]).
    pub t: Vec<f64>,
    /// Name of the input column (default `pressure`, MPa).
    pub input_name: String,
    /// The model input, one value per sample.
    pub input: Vec<f64>,
    /// Name of the output column (default `displacement`, mm).
    pub output_name: String,
    /// The measured output, one value per sample.
    pub output: Vec<f64>,
    /// Further columns (`valve_in`, `valve_out`, `load_kg`, `reference`, ...), in file order.
    pub extra: Vec<(String, Vec<f64>)>,
    /// The recording this trace is a piece of, where `--split-gaps` cut a
    /// file into several (`None` for a whole file or a generated trace):
    /// pieces of one recording share its muscle, its load and its history.
    pub cut_from: Option<String>,
}

/// A number as a person reads it, and as every parser here reads it back:
/// `1e300`, not 301 digits; `1e-300`, not 300 zeros; `4.5` as `4.5`.
pub fn readable(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e9).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// `max − min` of finite values (0 for none).
pub fn range(v: &[f64]) -> f64 {
    let (lo, hi) = v
        .iter()
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    if hi >= lo { hi - lo } else { 0.0 }
}

/// A column a figure in data units is in: its name and the unit the name
/// states ([`units::unit_of`]; `null` where it states none), so that a
/// script reading an RMSE knows it is in mm, or in psi.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NamedColumn {
    pub column: String,
    pub unit: Option<String>,
}

impl NamedColumn {
    /// What follows a figure in this column's unit: ` mm` where its name
    /// states the unit, nothing where it states none.
    pub fn unit_tail(&self) -> String {
        self.unit
            .as_ref()
            .map_or(String::new(), |u| format!(" {u}"))
    }
}

/// A record's input and output columns, as JSON outputs name them.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Columns {
    pub input: NamedColumn,
    pub output: NamedColumn,
}

impl Columns {
    /// The columns `input` and `output`, each with the unit its name states.
    pub fn of(input: &str, output: &str) -> Columns {
        let named = |column: &str| NamedColumn {
            column: column.to_string(),
            unit: units::unit_of(column),
        };
        Columns {
            input: named(input),
            output: named(output),
        }
    }
}

impl Trace {
    /// Its input and output columns, with their units.
    pub fn columns(&self) -> Columns {
        Columns::of(&self.input_name, &self.output_name)
    }

    /// A trace on the uniform time base `t(k) = k·dt`.
    pub fn uniform(source: impl Into<String>, dt: f64, input: Vec<f64>, output: Vec<f64>) -> Self {
        assert_eq!(input.len(), output.len(), "input and output lengths differ");
        let t = (0..input.len()).map(|k| k as f64 * dt).collect();
        Trace {
            source: source.into(),
            time_name: "t".into(),
            t,
            input_name: "pressure".into(),
            input,
            output_name: "displacement".into(),
            output,
            extra: Vec::new(),
            cut_from: None,
        }
    }

    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Keeps the first `len` samples of every column.
    pub fn truncate(&mut self, len: usize) {
        self.t.truncate(len);
        self.input.truncate(len);
        self.output.truncate(len);
        for (_, column) in &mut self.extra {
            column.truncate(len);
        }
    }

    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// The sample time: the mean step of the (uniform) time base.
    pub fn dt(&self) -> f64 {
        match self.t.len() {
            0 | 1 => f64::NAN,
            n => (self.t[n - 1] - self.t[0]) / (n - 1) as f64,
        }
    }

    /// A further column by name, if the trace carries it.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.extra
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }

    /// The samples `range` of this trace, every column cut alike.
    pub fn slice(&self, range: std::ops::Range<usize>) -> Trace {
        Trace {
            source: self.source.clone(),
            time_name: self.time_name.clone(),
            t: self.t[range.clone()].to_vec(),
            input_name: self.input_name.clone(),
            input: self.input[range.clone()].to_vec(),
            output_name: self.output_name.clone(),
            output: self.output[range.clone()].to_vec(),
            extra: self
                .extra
                .iter()
                .map(|(n, v)| (n.clone(), v[range.clone()].to_vec()))
                .collect(),
            cut_from: self.cut_from.clone(),
        }
    }
}

/// Whether sample time `dt` is `reference`'s, within 1 %: what one
/// discrete-time model, whose poles are per sample, can run on.
pub fn same_step(dt: f64, reference: f64) -> bool {
    (dt - reference).abs() <= 0.01 * reference
}

/// Where `traces` are not all sampled at the first one's step (within
/// [`same_step`]'s 1 %), the sentence that says which and why one model
/// cannot take them: its poles are per sample.
pub fn mixed_steps(traces: &[Trace]) -> Option<String> {
    let first = traces.first()?;
    let other = traces.iter().find(|t| !same_step(t.dt(), first.dt()))?;
    Some(format!(
        "{} is sampled every {} s, {} every {} s: one model's poles are per sample, so \
         resample the records onto one step",
        other.source,
        tidy_step(other.dt()),
        first.source,
        tidy_step(first.dt())
    ))
}

/// Why one model cannot take `traces` as they are, if it cannot: columns
/// of other names (another quantity, or another unit), or one record given
/// twice, which would weigh it double and shrink every standard error by
/// √2 without a sample more.
pub fn unlike_records(traces: &[Trace]) -> Option<String> {
    let first = traces.first()?;
    for (k, t) in traces.iter().enumerate() {
        if (&t.input_name, &t.output_name) != (&first.input_name, &first.output_name) {
            return Some(format!(
                "{} has the input `{}` and output `{}`, {} `{}` and `{}`: one model takes one \
                 input and one output, in one unit; give the records the same columns",
                t.source,
                t.input_name,
                t.output_name,
                first.source,
                first.input_name,
                first.output_name
            ));
        }
        if let Some(twin) = traces[..k].iter().find(|o| same_samples(o, t)) {
            return Some(format!(
                "{} and {} hold the same samples: a record given twice weighs double and \
                 makes every standard error look √2 smaller; give it once",
                twin.source, t.source
            ));
        }
    }
    None
}

/// Whether two traces hold the same samples: one record, given twice or
/// under two names.
pub fn same_samples(a: &Trace, b: &Trace) -> bool {
    a.input == b.input && a.output == b.output && a.t == b.t
}

/// The sample times a record may have: a nanosecond to a day. Past either,
/// a step is a typo, and the times `k·dt` lose their digits or overflow.
pub const SAMPLE_TIMES: std::ops::RangeInclusive<f64> = 1e-9..=86_400.0;

/// `dt` where it is a sample time ([`SAMPLE_TIMES`]), else why it is not.
pub fn sample_time(dt: f64) -> Result<f64, String> {
    if SAMPLE_TIMES.contains(&dt) {
        Ok(dt)
    } else if dt.is_finite() && dt > 0.0 {
        Err(format!(
            "{dt:e} s is outside a nanosecond to a day (1e-9 to 86400): not a sample time"
        ))
    } else {
        Err(format!(
            "{dt} is not a positive number of seconds (e.g. 0.01 for 100 Hz)"
        ))
    }
}

/// The traces' sources as a message names them: `a.csv, b.csv`.
pub fn sources(traces: &[Trace]) -> String {
    traces
        .iter()
        .map(|t| t.source.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// `v` rounded to 10 significant digits, for a time step computed from a
/// record (a span over a count): 0.09999999999999999 s reads as 0.1 s, in
/// a message and in the flag it suggests.
pub fn tidy_step(v: f64) -> f64 {
    format!("{v:.9e}").parse().unwrap_or(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_computed_time_step_reads_as_the_step_it_is() {
        let dt = (39.9 - 0.0) / 399.0;
        assert_ne!(dt, 0.1);
        assert_eq!(tidy_step(dt), 0.1);
        assert_eq!(tidy_step(0.012345678912), 0.01234567891);
        assert!(tidy_step(f64::NAN).is_nan());
    }
}
