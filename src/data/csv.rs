//! Reading and writing experiment CSV files (the format: README.md, "Data format").
//!
//! A file has one header row, optionally preceded by `#` or `%` comment lines; blank
//! lines, and rows whose every cell is empty (a spreadsheet's `,,`), are
//! skipped. One column is the time (s), one the model input and one
//! the output; every other numeric column is carried along in
//! [`Trace::extra`]. Every malformed value is an error naming the file, the
//! 1-based line number and the column, so a user can open the file at the
//! right place.
//!
//! The models are discrete-time, so the time base must be uniform:
//! every step within [`UNIFORM_TOLERANCE`] of the median step. Recorded data
//! that is not (a logger that dropped samples, a paused recording, a logger
//! glitch that sends the clock back) is rejected unless the user asks to
//! resample it ([`Gaps::Resample`], gaps only), to split it at the gaps
//! and backward jumps ([`Gaps::Split`]), or both: to split it where the
//! clock jumps back and resample each piece ([`Gaps::SplitResample`]).

use std::fmt::{self, Write as _};
use std::io::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};

use super::signals::samples_in;
use super::{Trace, write_atomic};

/// How far one time step may stray from the median step and still count as
/// uniform: 10 %. This admits timer jitter and times printed with few
/// digits (a 1 kHz logger writing milliseconds with 4 decimals is exact to
/// 5 %), and rejects a dropped sample (a step of 2·dt).
pub const UNIFORM_TOLERANCE: f64 = 0.10;

/// With [`Gaps::Split`], a step longer than this many median steps ends a
/// segment: at 1.5·dt at least one sample is missing.
pub const GAP_FACTOR: f64 = 1.5;

/// With [`Gaps::Split`], segments with fewer samples than this are dropped
/// (with a note): too short to estimate and validate anything on.
pub const MIN_SEGMENT: usize = 20;

/// What to do when the time base is not uniform.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Gaps {
    /// Report the first bad row as an error (the default: nothing is
    /// changed behind the user's back).
    Reject,
    /// Interpolate every column linearly onto `t0 + k·dt`, `dt` in seconds.
    /// A gap becomes a straight line between its two ends.
    Resample(f64),
    /// Cut the file at every step longer than [`GAP_FACTOR`] median steps
    /// and at every step where time runs back or stands still, one trace
    /// per segment, each cut reported in a note. Each segment must itself
    /// be uniform; segments shorter than [`MIN_SEGMENT`] samples are
    /// dropped, with a note.
    Split,
    /// Cut the file only where time runs back or stands still (which no
    /// interpolation can cross), and interpolate each piece onto its own
    /// `t0 + k·dt`, `dt` in seconds: a gap inside a piece becomes a straight
    /// line, as with [`Gaps::Resample`]. A row that is not a finite number
    /// is dropped, as with [`Gaps::Split`], and interpolated over. Pieces
    /// with fewer than [`MIN_SEGMENT`] samples, read or resampled, are
    /// dropped, with a note.
    SplitResample(f64),
}

impl Gaps {
    /// Whether the file is cut into pieces, each its own experiment.
    fn splits(self) -> bool {
        matches!(self, Gaps::Split | Gaps::SplitResample(_))
    }
}

/// The largest gauge pressure (MPa) a McKibben muscle is driven with, well
/// under which it works: a pressure past it is refused where one is taken
/// in MPa (`control`'s and `static`'s), and a column read as MPa past
/// [`UNUSUAL_MPA`] already gets a note.
pub const IMPLAUSIBLE_MPA: f64 = 10.0;

/// The most gauge pressure (MPa) a column named `pressure` holds without a
/// note when it is read: tap-water and pneumatic muscles are driven under
/// it, and bar, the other unit of such a rig's gauges, reads ten times
/// larger (0.6 MPa is 6 bar).
pub const UNUSUAL_MPA: f64 = 1.0;

/// Which columns to read and how to treat the time base.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadOptions {
    /// Time column (seconds); with `dt`, the name the time takes.
    pub time: String,
    /// A file without a time column: its rows are `dt` seconds apart
    /// (`--dt`). A file that has the column `time` is then an error, not
    /// a choice between two clocks.
    pub dt: Option<f64>,
    /// The rows' spacing where the file has no time column and `dt` is not
    /// given: a model's own `--dt`, carried to the data it is read for
    /// (`simulate --from`, `fit --from`); a file with its clock reads it.
    pub untimed_dt: Option<f64>,
    /// Model input column (default `pressure`, MPa).
    pub input: String,
    /// Model output column (default `displacement`, mm).
    pub output: String,
    pub gaps: Gaps,
}

impl ReadOptions {
    /// The header of a file these options read: its clock's column, unless
    /// its rows are `dt` apart, and the input's and output's.
    fn expected_header(&self) -> String {
        match self.dt {
            Some(_) => format!("{},{}", self.input, self.output),
            None => format!("{},{},{}", self.time, self.input, self.output),
        }
    }
}

impl Default for ReadOptions {
    /// The default column names, those of the shipped data: `t`, `pressure`,
    /// `displacement`.
    fn default() -> Self {
        ReadOptions {
            time: "t".into(),
            dt: None,
            untimed_dt: None,
            input: "pressure".into(),
            output: "displacement".into(),
            gaps: Gaps::Reject,
        }
    }
}

/// Everything that can be wrong with a data file. Messages follow the
/// `file: line N, column "c": what` pattern.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: line {line}: {message}", path.display())]
    Parse {
        path: PathBuf,
        line: u64,
        message: String,
    },
    #[error("{}: the file is empty (expected a header row such as `{expected}`)", path.display())]
    Empty {
        path: PathBuf,
        /// The header the columns asked for make (`t,u_N,y_m` where
        /// `--input u_N --output y_m`).
        expected: String,
    },
    #[error(
        "{}: line {line} holds no numbers ({}), right under the header: a row of units? \
         Make it a comment (`# s,MPa,mm`) or delete it, and state each unit in its column's \
         name (`t_s`, `pressure_MPa`, `stroke_mm`), where the model file records it",
        path.display(), quoted(cells)
    )]
    UnitRow {
        path: PathBuf,
        line: u64,
        cells: Vec<String>,
    },
    #[error(
        "{}: line {line}: a header row but {rows} data row{}{}; a time step needs at least 2",
        path.display(),
        if *rows == 1 { "" } else { "s" },
        match dropped {
            0 => String::new(),
            n => format!(
                " left after {n} whose time, input or output is not a finite number were \
                 dropped"
            ),
        }
    )]
    TooFewRows {
        path: PathBuf,
        line: u64,
        rows: usize,
        /// Rows `--split-gaps` or `--resample` dropped for a value that is
        /// no finite number.
        dropped: usize,
    },
    #[error(
        "{}: line {line}: no {role} column \"{column}\"; the file has columns {}{}; choose another with {flag} COL{}{}",
        path.display(), quoted(available), layout_hint(available),
        likely_column(role, column, available),
        if *role == "time" { " (or, for a file without one, give its rows' spacing in seconds with --dt SECONDS)" } else { "" }
    )]
    MissingColumn {
        path: PathBuf,
        line: u64,
        role: &'static str,
        column: String,
        available: Vec<String>,
        flag: &'static str,
    },
    #[error(
        "{}: line {line} holds only numbers ({}) and no {role} column \"{column}\": if it is \
         data, the file needs a header line that names its columns (for example \
         `t,pressure,displacement`; MATLAB's writetable writes one, csvwrite and writematrix \
         do not); if those are the columns' names, choose them with --time, --input and \
         --output",
        path.display(), quoted(first)
    )]
    NoHeader {
        path: PathBuf,
        line: u64,
        role: &'static str,
        column: String,
        /// The line's first fields.
        first: Vec<String>,
    },
    #[error(
        "{}: line {line}: column \"{column}\" is named as both the time and the {role}: each \
         needs a column of its own",
        path.display()
    )]
    TimeAsData {
        path: PathBuf,
        line: u64,
        column: String,
        role: &'static str,
    },
    #[error(
        "{}: line {line}: --dt gives the rows' spacing for a file without a time column, \
         and this file has one, \"{column}\": read its clock instead (--time={column}, without \
         --dt), and --resample DT to put it on another step",
        path.display()
    )]
    TimeBesideDt {
        path: PathBuf,
        line: u64,
        column: String,
    },
    #[error("{}: line {line}: column \"{column}\" appears twice in the header", path.display())]
    DuplicateColumn {
        path: PathBuf,
        line: u64,
        column: String,
    },
    #[error("{}: line {line}: {found} fields, but the header on line {header_line} has {expected}", path.display())]
    Ragged {
        path: PathBuf,
        line: u64,
        found: usize,
        expected: usize,
        header_line: u64,
    },
    #[error("{}: line {line}, column \"{column}\": \"{}\" is not a number{hint}", path.display(), shown(value))]
    NotANumber {
        path: PathBuf,
        line: u64,
        column: String,
        value: String,
        /// What to do about it, where the cell is a sample's (`MISSED_READING`).
        hint: &'static str,
    },
    #[error("{}: line {line}, column \"{column}\": \"{}\" is not finite{hint}", path.display(), shown(value))]
    NotFinite {
        path: PathBuf,
        line: u64,
        column: String,
        value: String,
        hint: &'static str,
    },
    #[error(
        "{}: line {line}, column \"{column}\": time {} does not increase (previous row: {}){}; {hint}",
        path.display(), super::readable(*value), super::readable(*previous), runs_back(*value, *previous, *per_second)
    )]
    NotIncreasing {
        path: PathBuf,
        line: u64,
        column: String,
        /// The times as the file writes them, in its column's unit.
        value: f64,
        previous: f64,
        /// How many of the column's unit make a second (1 for seconds).
        per_second: f64,
        /// What the user can do, which depends on the flags given.
        hint: &'static str,
    },
    #[error(
        "{}: line {line}, column \"{column}\": non-uniform time base: step {} s, expected {} s (±{}%); {hint}",
        path.display(), seconds(*step), seconds(*expected), UNIFORM_TOLERANCE * 100.0
    )]
    NonUniform {
        path: PathBuf,
        line: u64,
        column: String,
        step: f64,
        expected: f64,
        /// What the user can do, which depends on the flags given.
        hint: &'static str,
    },
    #[error("{}: {message}", path.display())]
    Unusable { path: PathBuf, message: String },
    #[error("{}: {message}", path.display())]
    BadTrace { path: PathBuf, message: String },
}

/// A difference of two time stamps as the rows wrote it: twelve significant
/// digits, so that 0.32 − 0.00 reads `0.32`, not `0.32000000000000006`.
fn seconds(v: f64) -> String {
    let rounded: f64 = format!("{v:.11e}").parse().unwrap_or(v);
    rounded.to_string()
}

impl DataError {
    /// The same error with `hint` as what the user can do about a time
    /// base, for a caller that does not offer `--split-gaps` or
    /// `--resample` (the reader's own hints name them); other errors are
    /// returned as they are.
    pub fn with_time_hint(
        mut self,
        not_increasing: &'static str,
        non_uniform: &'static str,
    ) -> Self {
        match &mut self {
            DataError::NotIncreasing { hint, .. } => *hint = not_increasing,
            DataError::NonUniform { hint, .. } => *hint = non_uniform,
            _ => {}
        }
        self
    }
}

impl DataError {
    /// The same error with `hint` as what the user can do about a sample's
    /// cell that holds no finite number, for a caller that offers neither
    /// `--resample` nor `--split-gaps` (the reader's own hints name them);
    /// other errors are returned as they are.
    pub fn with_cell_hint(mut self, cell: &'static str) -> Self {
        match &mut self {
            DataError::NotANumber { hint, .. } | DataError::NotFinite { hint, .. } => *hint = cell,
            _ => {}
        }
        self
    }
}

/// ": it runs back by D s" when `value` is below `previous` (times in a
/// unit `per_second` of which make a second): a 1 s jump back in a 1 kHz
/// file reads more clearly than two nearby times.
fn runs_back(value: f64, previous: f64, per_second: f64) -> String {
    if value < previous {
        format!(
            ": it runs back by {} s",
            super::readable(rounded((previous - value) / per_second))
        )
    } else {
        String::new()
    }
}

/// `x` to 6 significant digits, so that a difference of two times prints as
/// 1.02 rather than 1.0199999999999996.
fn rounded(x: f64) -> f64 {
    format!("{x:.5e}").parse().unwrap_or(x)
}

/// What a header that is no list of columns most likely is, where a
/// column is not found: a table whose columns spaces separate, read as one
/// name, or a LabVIEW measurement file's header block.
fn layout_hint(names: &[String]) -> &'static str {
    match names {
        [first, ..] if first.starts_with("LabVIEW Measurement") => {
            " (a LabVIEW measurement file: save the data as a spreadsheet file with one header \
             row, or delete the header blocks up to the last `***End_of_Header***`)"
        }
        // Three words at least: `pressure kPa` is one name with its unit.
        [one] if one.split_whitespace().count() > 2 => {
            " (one name with spaces: columns separated by spaces, as MATLAB's `save -ascii` \
             or an aligned table writes them, are not read; separate them by commas, \
             semicolons or tabs)"
        }
        _ => "",
    }
}

/// The columns of `available` that name what `column` names, for the flag
/// that chooses one: a unit after the name (`pressure_psi`,
/// `Displacement [mm]`) for the input and output, a name of time (`time`,
/// `t_s`) for the clock. The default names state no unit, and a lab's
/// export states one more often than not. Named, not taken: which of two
/// pressure sensors drives the muscle is the user's to say.
fn likely_column(role: &str, column: &str, available: &[String]) -> String {
    let word = |name: &str| {
        let name = name.trim().to_lowercase();
        let end = name.find(['_', ' ', '[', '(', '/']).unwrap_or(name.len());
        name[..end].to_string()
    };
    let asked = word(column);
    let likely: Vec<&String> = available
        .iter()
        .filter(|n| match role {
            "time" => crate::data::units::names_a_time(n),
            _ => !asked.is_empty() && word(n) == asked,
        })
        .collect();
    match likely.as_slice() {
        [] => String::new(),
        [one] => format!(", here \"{}\"", shown(one)),
        _ => format!(
            ", here one of {} (in other units, or from other sensors)",
            quoted(&likely.iter().map(|n| n.to_string()).collect::<Vec<_>>()),
        ),
    }
}

fn quoted(names: &[String]) -> String {
    const MOST: usize = 12;
    let mut q: Vec<String> = names
        .iter()
        .take(MOST)
        .map(|n| format!("\"{}\"", shown(n)))
        .collect();
    if names.len() > MOST {
        q.push(format!("and {} more", names.len() - MOST));
    }
    q.join(", ")
}

/// A cell as an error quotes it: control characters escaped (a NUL printed
/// raw) and at most 40 characters, the rest counted (a 50 MB line made a
/// 50 MB message).
fn shown(text: &str) -> String {
    const MOST: usize = 40;
    let head: String = text
        .chars()
        .take(MOST)
        .flat_map(|c| match c.is_control() {
            true => c.escape_default().collect::<Vec<char>>(),
            false => vec![c],
        })
        .collect();
    match text.chars().count() {
        n if n > MOST => format!("{head}… ({n} characters)"),
        _ => head,
    }
}

/// Reads the traces in `path`: one, or with [`Gaps::Split`] one per segment.
/// Notes (cuts, dropped segments, ignored text columns) are discarded; use
/// [`read_traces_with_notes`] to show them.
pub fn read_traces(path: &Path, opts: &ReadOptions) -> Result<Vec<Trace>, DataError> {
    read_traces_with_notes(path, opts).map(|(traces, _)| traces)
}

/// As [`read_traces`], and also the notes a user should see: where
/// [`Gaps::Split`] cut the file and why, segments dropped as too short, text
/// columns left out.
pub fn read_traces_with_notes(
    path: &Path,
    opts: &ReadOptions,
) -> Result<(Vec<Trace>, Vec<String>), DataError> {
    let bytes = super::input::read(path).map_err(|source| DataError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse(path, &bytes, opts)
}

/// How a file separates its fields, read off its header: commas; or,
/// where the header holds no comma, semicolons (what a spreadsheet writes
/// in a locale of decimal commas, which then read as points) or tabs.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Dialect {
    Commas,
    Semicolons,
    Tabs,
}

impl Dialect {
    /// The dialect Excel's first line `sep=;` names (it writes one so that
    /// another Excel reads the file right), or why it cannot be read.
    fn of_sep_line(text: &str) -> Option<Result<Dialect, String>> {
        // Quoted where a tool wrote it as a field: `"sep=;"`.
        let line = text.trim_matches('"');
        let sep = line.get(..4).filter(|s| s.eq_ignore_ascii_case("sep="))?;
        let named = line[sep.len()..].trim();
        Some(match named {
            "," => Ok(Dialect::Commas),
            ";" => Ok(Dialect::Semicolons),
            // `sep=` and a tab: the line is read trimmed.
            "\t" | "" => Ok(Dialect::Tabs),
            other if other.chars().count() == 1 => Err(format!(
                "the first line `{text}` asks for fields separated by \"{other}\": only commas, \
                 semicolons and tabs are read; save the file as CSV with commas"
            )),
            // Longer: not Excel's line, but a header that starts so.
            _ => return None,
        })
    }

    fn of_header(text: &str) -> Dialect {
        if text.contains(',') {
            Dialect::Commas
        } else if text.contains(';') {
            Dialect::Semicolons
        } else if text.contains('\t') {
            Dialect::Tabs
        } else {
            Dialect::Commas
        }
    }

    fn separator(self) -> char {
        match self {
            Dialect::Commas => ',',
            Dialect::Semicolons => ';',
            Dialect::Tabs => '\t',
        }
    }

    /// Whether a comma in a cell is a locale's decimal comma: where commas
    /// do not separate the fields.
    fn decimal_comma(self) -> bool {
        self != Dialect::Commas
    }

    /// The note a file in another dialect than commas gets; `commas`:
    /// whether a cell held a decimal comma.
    fn note(self, path: &Path, commas: bool) -> Option<String> {
        let how = match self {
            Dialect::Commas => return None,
            Dialect::Semicolons => "semicolons",
            Dialect::Tabs => "tabs",
        };
        let commas = if commas {
            ", a decimal comma read as a point"
        } else {
            ""
        };
        Some(format!(
            "{}: fields separated by {how}{commas}",
            path.display()
        ))
    }
}

/// The number a cell holds; where `decimal_comma`, its comma is a decimal
/// point (the cell itself is kept as the file has it, for the header's
/// names and for the messages that quote it).
fn number(cell: &str, decimal_comma: bool) -> Result<f64, std::num::ParseFloatError> {
    if decimal_comma && cell.contains(',') {
        cell.replace(',', ".").parse()
    } else {
        cell.parse()
    }
}

/// The trimmed fields of one line (quotes allowed, as RFC 4180).
fn split_fields(text: &str, dialect: Dialect) -> Result<csv::StringRecord, csv::Error> {
    let record: csv::StringRecord = if !text.contains('"') {
        // The common case, without a reader (and its buffer) per line.
        text.split(dialect.separator()).map(str::trim).collect()
    } else {
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .delimiter(dialect.separator() as u8)
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes());
        let mut record = csv::StringRecord::new();
        reader.read_record(&mut record)?;
        record
    };
    Ok(record)
}

/// Why the header line `text` is not a header with one line a row, where
/// its form shows it: lines ended by a lone carriage return (the whole
/// file would read as one line).
fn check_header_form(text: &str) -> Result<(), String> {
    if text.contains('\r') {
        return Err(
            "the lines end in a lone carriage return (CR, an old Mac format), so the \
                    whole file reads as one line: convert its line ends to LF or CRLF"
                .into(),
        );
    }
    Ok(())
}

/// One data row: its line in the file, its place among the data rows
/// (its time where `--dt` gives the spacing) and where its trimmed cells
/// begin among the [`Cells`].
#[derive(Clone, Copy)]
struct Row {
    line: u64,
    index: usize,
    first: usize,
}

/// The data rows' cells, one after another in one buffer, each row
/// `width` of them: a row costs its text and an offset a cell, where a
/// record of its own held three allocations, about 256 bytes for a line of
/// 27 characters (a logger's hour at 1 kHz is 3.6·10⁶ rows).
#[derive(Default)]
struct Cells {
    text: String,
    /// Where each cell ends in `text`; it begins where the one before ends.
    ends: Vec<usize>,
    width: usize,
}

impl Cells {
    /// Appends a row of `width` cells; returns where they begin.
    fn push<'a>(&mut self, cells: impl IntoIterator<Item = &'a str>) -> usize {
        let first = self.ends.len();
        for cell in cells {
            self.text.push_str(cell);
            self.ends.push(self.text.len());
        }
        first
    }

    /// Cell `c` of `row`.
    fn get(&self, row: &Row, c: usize) -> &str {
        let i = row.first + c;
        let start = i.checked_sub(1).map_or(0, |j| self.ends[j]);
        &self.text[start..self.ends[i]]
    }

    /// The cells of `row`, in order.
    fn of<'a>(&'a self, row: &'a Row) -> impl Iterator<Item = &'a str> {
        (0..self.width).map(move |c| self.get(row, c))
    }
}

/// Where a file's time comes from.
#[derive(Clone, Copy)]
enum Clock {
    /// Its column of that index.
    Column(usize),
    /// Its rows, this many seconds apart (`--dt`).
    Rows(f64),
}

fn parse(
    path: &Path,
    bytes: &[u8],
    opts: &ReadOptions,
) -> Result<(Vec<Trace>, Vec<String>), DataError> {
    let p = || path.to_path_buf();
    // Lines are numbered here rather than by the `csv` reader, which does not
    // count comment and blank lines; one record per line.
    let mut header: Option<(u64, Vec<String>)> = None;
    let mut dialect: Option<Dialect> = None;
    // The line of Excel's `sep=` line, where the file has one.
    let mut sep_line: Option<u64> = None;
    let mut rows = Vec::new();
    let mut table = Cells::default();
    // Under --dt a row is a sample, and an empty one (a blank line or `,,`)
    // between samples is a missing sample, not nothing: the lines of those
    // not yet followed by a sample (leading and trailing ones are nothing).
    let mut missing: Vec<u64> = Vec::new();
    let by_rows = opts.dt.is_some() || opts.untimed_dt.is_some();
    for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = i as u64 + 1;
        let text = std::str::from_utf8(raw).map_err(|_| DataError::Parse {
            path: p(),
            line,
            // Excel's "Unicode text" and some loggers write UTF-16, whose
            // byte-order mark says so.
            message: match bytes {
                [0xff, 0xfe, ..] | [0xfe, 0xff, ..] => "UTF-16 text, not UTF-8 (Excel's \
                    \"Unicode text\" writes it): save it as \"CSV UTF-8\", or convert it \
                    (`iconv -f UTF-16 -t UTF-8`)"
                    .into(),
                _ => "not UTF-8 text".into(),
            },
        })?;
        let text = text.trim_start_matches('\u{feff}').trim();
        // `#`, and MATLAB's `%` (a header MATLAB's fprintf wrote), start
        // a comment.
        let comment = text.starts_with(['#', '%']);
        // A comment line that holds a lone carriage return is a file of
        // CR line ends that starts with a comment: all of it read as one
        // comment, it would be reported empty.
        if comment && text.contains('\r') && header.is_none() {
            check_header_form(text).map_err(|message| DataError::Parse {
                path: p(),
                line,
                message,
            })?;
        }
        if text.is_empty() && by_rows && !rows.is_empty() {
            missing.push(line);
        }
        if text.is_empty() || comment {
            continue;
        }
        if header.is_none() {
            check_header_form(text).map_err(|message| DataError::Parse {
                path: p(),
                line,
                message,
            })?;
        }
        if header.is_none()
            && dialect.is_none()
            && let Some(named) = Dialect::of_sep_line(text)
        {
            dialect = Some(named.map_err(|message| DataError::Parse {
                path: p(),
                line,
                message,
            })?);
            sep_line = Some(line);
            continue;
        }
        if let (None, Some(named), Some(at)) = (&header, dialect, sep_line)
            && !text.contains(named.separator())
            && text.contains([',', ';', '\t'])
        {
            return Err(DataError::Parse {
                path: p(),
                line,
                message: format!(
                    "line {at} names {:?} as the separator, and this header holds none: the \
                     file is separated otherwise; delete line {at}",
                    named.separator()
                ),
            });
        }
        let dialect = *dialect.get_or_insert_with(|| Dialect::of_header(text));
        let cells = split_fields(text, dialect).map_err(|e| DataError::Parse {
            path: p(),
            line,
            message: e.to_string(),
        })?;
        match &header {
            None => {
                table.width = cells.len();
                header = Some((line, cells.iter().map(String::from).collect()));
            }
            // A row of empty cells (`,,`: a spreadsheet's export of rows
            // it once held) is a blank line.
            Some(_) if cells.iter().all(|c| c.trim().is_empty()) => {
                if by_rows && !rows.is_empty() {
                    missing.push(line);
                }
                continue;
            }
            Some((header_line, names)) => {
                // Kept as rows of empty cells until the clock is known.
                for line in missing.drain(..) {
                    let index = rows.len();
                    let first = table.push(names.iter().map(|_| ""));
                    rows.push(Row { line, index, first });
                }
                if cells.len() != names.len() {
                    return Err(DataError::Ragged {
                        path: p(),
                        line,
                        found: cells.len(),
                        expected: names.len(),
                        header_line: *header_line,
                    });
                }
                let index = rows.len();
                let first = table.push(&cells);
                rows.push(Row { line, index, first });
            }
        }
    }
    let (header_line, names) = header.ok_or_else(|| DataError::Empty {
        path: p(),
        expected: opts.expected_header(),
    })?;
    // A first line of numbers alone is data more often than names (pandas
    // writes `0,1,2` as names): a column missing from it says both, and
    // two equal numbers in it (a record starting at `0,0,0`) are no
    // header's repeated name.
    let decimal_comma = dialect.is_some_and(Dialect::decimal_comma);
    let numbers_only = names
        .iter()
        .all(|n| number(n.trim(), decimal_comma).is_ok());
    // A set, not a scan of the names before each: a header of 10⁵ columns
    // (a wide logger export) is read in milliseconds, not minutes.
    let mut seen = std::collections::HashSet::with_capacity(names.len());
    for n in &names {
        // Unnamed columns (pandas' index, a spreadsheet's empty columns)
        // are left out below, however many there are.
        if !numbers_only && !n.is_empty() && !seen.insert(n.as_str()) {
            return Err(DataError::DuplicateColumn {
                path: p(),
                line: header_line,
                column: n.clone(),
            });
        }
    }
    let mut untimed_note = None;
    let find = |column: &str, role, flag| {
        names.iter().position(|n| n == column).ok_or_else(|| {
            if numbers_only {
                DataError::NoHeader {
                    path: p(),
                    line: header_line,
                    role,
                    column: column.into(),
                    first: names.iter().take(3).cloned().collect(),
                }
            } else {
                DataError::MissingColumn {
                    path: p(),
                    line: header_line,
                    role,
                    column: column.into(),
                    available: names.clone(),
                    flag,
                }
            }
        })
    };
    let clock = match opts.dt {
        None => match (find(&opts.time, "time", "--time"), opts.untimed_dt) {
            (Ok(c), _) => Clock::Column(c),
            (Err(_), Some(dt)) if !names.iter().any(|n| crate::data::units::names_a_time(n)) => {
                untimed_note = Some(format!(
                    "{}: no time column \"{}\": its rows are read {} s apart, as the model's \
                     data were (--dt)",
                    path.display(),
                    opts.time,
                    crate::data::tidy_step(dt)
                ));
                Clock::Rows(dt)
            }
            (Err(e), _) => return Err(e),
        },
        Some(dt) => match names
            .iter()
            .position(|n| n == &opts.time || crate::data::units::names_a_time(n))
        {
            Some(c) => {
                return Err(DataError::TimeBesideDt {
                    path: p(),
                    line: header_line,
                    column: names[c].clone(),
                });
            }
            None => Clock::Rows(dt),
        },
    };
    let it = match clock {
        Clock::Column(c) => Some(c),
        Clock::Rows(_) => None,
    };
    // The empty rows kept in case the rows were the clock.
    let empty = |r: &Row| table.of(r).all(str::is_empty);
    match clock {
        Clock::Column(_) => rows.retain(|r| !empty(r)),
        // Dropped and cut there with --split-gaps, as a row of NaN is;
        // else an error, as a NaN is.
        Clock::Rows(_) if !opts.gaps.splits() => {
            if let Some(r) = rows.iter().find(|r| empty(r)) {
                return Err(DataError::Parse {
                    path: p(),
                    line: r.line,
                    message: "an empty row between samples: with --dt every row is a sample, \
                              and leaving it out would move every later one a step earlier; \
                              fill it or delete it, or pass --split-gaps to cut the file there"
                        .into(),
                });
            }
        }
        Clock::Rows(_) => {}
    }
    // A time column whose name states another unit than seconds (a
    // logger's `t_ms`) is read in that unit and converted below.
    let time_unit = it.and_then(|it| crate::data::units::time_unit_other_than_seconds(&names[it]));
    let per_second = time_unit.map_or(1.0, |(_, per_second)| per_second);
    let ii = find(&opts.input, "input", "--input")?;
    let io = find(&opts.output, "output", "--output")?;
    // The input and the output may share a column: `simulate` reads a file
    // of an input alone so, and the identification names a measured
    // response that copies the input as such.
    for (c, role) in [(ii, "input"), (io, "output")] {
        if Some(c) == it {
            return Err(DataError::TimeAsData {
                path: p(),
                line: header_line,
                column: names[c].clone(),
                role,
            });
        }
    }
    // A spreadsheet's second header row, of units: text in every cell.
    // Before the rows are dropped below, which would drop it as a row
    // of no numbers and lose the units it states.
    if let Some(first) = rows.first()
        && table
            .of(first)
            .all(|c| !c.is_empty() && number(c, decimal_comma).is_err())
    {
        return Err(DataError::UnitRow {
            path: p(),
            line: first.line,
            cells: table.of(first).take(3).map(String::from).collect(),
        });
    }
    // With --split-gaps a row whose time, input or output is not a finite
    // number (a logger's NaN for a dropped sample, an empty cell) is a
    // glitch: it is dropped, and the gap it leaves is cut as any other;
    // with --resample (and a time column, which says where the row was),
    // it is dropped and interpolated across.
    let mut dropped = Vec::new();
    let dropping = match opts.gaps {
        gaps if gaps.splits() => Some("--split-gaps"),
        Gaps::Resample(_) if matches!(clock, Clock::Column(_)) => Some("--resample"),
        _ => None,
    };
    if let Some(flag) = dropping {
        rows.retain(|row| {
            let bad = it
                .into_iter()
                .chain([ii, io])
                .find(|&c| !number(table.get(row, c), decimal_comma).is_ok_and(f64::is_finite));
            if let Some(c) = bad {
                dropped.push(format!(
                    "{}: line {}: {flag} dropped the row: column \"{}\" holds \"{}\", not \
                     a finite number",
                    path.display(),
                    row.line,
                    names[c],
                    table.get(row, c)
                ));
            }
            bad.is_none()
        });
    }
    // A row that repeats the one before it cell for cell (a logger that
    // wrote a sample twice) holds no sample of its own: it is dropped,
    // with one note for all, where it stopped the read as time standing
    // still, or cut the record in two. Only where a time column says when
    // each row was: rows `--dt` apart that are alike are a muscle holding
    // still.
    let not_finite = dropped.len();
    if matches!(clock, Clock::Column(_)) {
        let mut kept: Option<Row> = None;
        let mut copies: Vec<u64> = Vec::new();
        rows.retain(|row| {
            let copy = kept.is_some_and(|k| table.of(&k).eq(table.of(row)));
            match copy {
                true => copies.push(row.line),
                false => kept = Some(*row),
            }
            !copy
        });
        if let (Some(first), Some(last)) = (copies.first(), copies.last()) {
            dropped.push(match copies.len() {
                1 => format!(
                    "{}: line {first}: a copy of the row before it (every cell alike), dropped",
                    path.display()
                ),
                n => format!(
                    "{}: {n} rows that copy the row before them (every cell alike), lines \
                     {first} to {last}, dropped",
                    path.display()
                ),
            });
        }
    }
    if rows.len() < 2 {
        return Err(DataError::TooFewRows {
            path: p(),
            line: header_line,
            rows: rows.len(),
            dropped: not_finite,
        });
    }

    let commas = decimal_comma && rows.iter().any(|r| table.of(r).any(|c| c.contains(',')));
    let mut notes: Vec<String> = dialect
        .and_then(|d| d.note(path, commas))
        .into_iter()
        .collect();
    notes.extend(untimed_note);
    notes.extend(dropped);
    let missed = match clock {
        Clock::Column(_) => MISSED_READING,
        Clock::Rows(_) => MISSED_READING_BY_ROWS,
    };
    let column = |c: usize| -> Result<Vec<f64>, DataError> {
        Ok(numeric_column(
            path,
            (&rows, &table),
            c,
            &names[c],
            Some(missed),
            decimal_comma,
        )?
        .unwrap_or_default())
    };
    // A row dropped above leaves its time out, and `--split-gaps` cuts there.
    let t = match clock {
        Clock::Column(c) => column(c)?,
        Clock::Rows(dt) => rows.iter().map(|r| r.index as f64 * dt).collect(),
    };
    let (input, output) = (column(ii)?, column(io)?);
    let mut extra = Vec::new();
    for (c, name) in names.iter().enumerate() {
        if Some(c) == it || c == ii || c == io {
            continue;
        }
        // No name to keep it under, nor to write it back with.
        if name.is_empty() {
            notes.push(format!(
                "{}: column {} has no name (pandas' index, or a spreadsheet's empty column); \
                 left out",
                path.display(),
                c + 1
            ));
            continue;
        }
        // A column the model does not read (a marker, a note) may have
        // empty or other cells: left out with a note, not a failed file.
        match numeric_column(path, (&rows, &table), c, name, None, decimal_comma) {
            Ok(Some(v)) => extra.push((name.clone(), v)),
            Ok(None) => notes.push(format!(
                "{}: column \"{name}\" holds no numbers; left out",
                path.display()
            )),
            Err(e) => notes.push(format!(
                "{e}; column \"{name}\" left out (only the time, input and output columns \
                 must be numbers throughout)"
            )),
        }
    }

    // Time that runs back or stands still is never interpolated over or
    // reordered: only `--split-gaps` accepts it, by cutting the file there.
    let hint = match opts.gaps {
        Gaps::Split | Gaps::SplitResample(_) => None,
        Gaps::Reject => Some("pass --split-gaps to cut the file there"),
        Gaps::Resample(_) => Some(
            "--resample cannot interpolate across it; add --split-gaps to cut the file there and resample each piece",
        ),
    };
    if let Some(hint) = hint {
        for k in 1..t.len() {
            if t[k] <= t[k - 1] {
                return Err(DataError::NotIncreasing {
                    path: p(),
                    line: rows[k].line,
                    column: opts.time.clone(),
                    value: t[k],
                    previous: t[k - 1],
                    per_second,
                    hint,
                });
            }
        }
    }
    // Converted after that check, which quotes the file's own times.
    let t = match time_unit {
        Some((unit, per_second)) => {
            notes.push(format!(
                "{}: column \"{}\" read in {unit} and converted to seconds (a file written \
                 from it names its time as it did, in {unit})",
                path.display(),
                opts.time
            ));
            t.into_iter().map(|v| v / per_second).collect()
        }
        None => t,
    };

    // `pressure` states no unit and is taken in MPa (README.md, "Data
    // format"); a tap-water or pneumatic muscle's gauge pressure is under
    // 1 MPa, so a larger value is most likely bar, kPa, Pa or psi under
    // the shipped data's name.
    if opts.input == "pressure" {
        let largest = input.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if largest > UNUSUAL_MPA {
            notes.push(format!(
                "{}: column \"pressure\" is taken in MPa (the shipped data's unit), but it \
                 reaches {}; if it is in kPa, Pa, bar or psi, say so in its name \
                 (`pressure_kPa`), so that a model fitted on it records its unit (a \
                 hydraulic muscle's MPa: name it `pressure_MPa`)",
                path.display(),
                super::readable(rounded(largest))
            ));
        }
    }
    // `displacement` is taken in mm the same way: a muscle's stroke in
    // metres stays under 1, and in micrometres passes 1000 (a metre).
    if opts.output == "displacement" {
        let largest = output.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let other = match largest {
            l if l > 0.0 && l < 1.0 => Some(("reaches only", "m", "m")),
            l if l > 1000.0 => Some(("reaches", "µm", "um")),
            _ => None,
        };
        if let Some((reaches, unit, suffix)) = other {
            notes.push(format!(
                "{}: column \"displacement\" is taken in mm (the shipped data's unit), but it \
                 {reaches} {}; if it is in {unit} or another unit, say so in its name \
                 (`displacement_{suffix}`), so that a model fitted on it records its unit",
                path.display(),
                super::readable(rounded(largest)),
            ));
        }
    }
    for (which, column) in [("input", &opts.input), ("output", &opts.output)] {
        if let Some(unit) = super::units::unknown_bracketed_unit(column) {
            notes.push(format!(
                "{}: the {which} column \"{column}\" names the unit `{unit}`, which mckibben \
                 does not know: it is read as stating none, so a model fitted on it records no \
                 unit (convert the column to a unit the README lists, and name it)",
                path.display()
            ));
        }
    }
    let trace = Trace {
        source: path.display().to_string(),
        time_name: opts.time.clone(),
        t,
        input_name: opts.input.clone(),
        input,
        output_name: opts.output.clone(),
        output,
        extra,
        cut_from: None,
    };
    let lines: Vec<u64> = rows.iter().map(|r| r.line).collect();
    // A muscle is sampled many times a second: a step of a second or more
    // is most likely a time column in milliseconds, read as seconds (a
    // 1 kHz logger's steps by 1).
    let step = median_step(&trace.t);
    // A step given with --dt is the user's own, not a column misread.
    if step >= 1.0 && matches!(clock, Clock::Column(_)) {
        notes.push(format!(
            "{}: column \"{}\" steps by {step} s; the time is read in seconds, so if it is in \
             milliseconds, convert it (the poles a model has are per sample, but --resample, \
             the figures and the reports read seconds)",
            path.display(),
            opts.time
        ));
    }
    // Samples made up between measured ones are no measurements: a fit
    // counts each as one, and its ± shrink with their number.
    if let Gaps::Resample(dt) | Gaps::SplitResample(dt) = opts.gaps
        && dt * GAP_FACTOR < step
    {
        notes.push(format!(
            "{}: --resample {dt} makes about {} samples of each measured one (the file steps \
             by {} s): the made-up samples are no measurements, yet a fit counts each as one, \
             so its ± come out about {:.1}× too small; resample near the file's own step",
            path.display(),
            super::readable(rounded(step / dt)),
            super::readable(rounded(step)),
            (step / dt).sqrt()
        ));
    }
    // A coarser grid picks between neighbours and drops the rest: what the
    // rows between held is lost, noise is not averaged down, and motion
    // faster than the new rate's half folds in.
    if let Gaps::Resample(dt) | Gaps::SplitResample(dt) = opts.gaps
        && dt > GAP_FACTOR * step
    {
        let kept = step / dt;
        notes.push(format!(
            "{}: --resample {dt} keeps about one sample in {} (the file steps by {} s), \
             interpolated between neighbours without averaging: the rows between are dropped, \
             so the noise stays what it was a sample (averaging them would cut it about {:.1}×), \
             and motion faster than {} Hz folds into the record; low-pass or average the file \
             first where that matters",
            path.display(),
            super::readable(rounded(1.0 / kept)),
            super::readable(rounded(step)),
            (1.0 / kept).sqrt(),
            super::readable(rounded(0.5 / dt))
        ));
    }
    let traces = match opts.gaps {
        Gaps::Reject => {
            let hint = "pass --resample DT to interpolate onto a uniform step, or --split-gaps to cut the file at gaps";
            check_uniform(path, &opts.time, &trace.t, &lines, step, hint)?;
            vec![trace]
        }
        Gaps::Resample(dt) => {
            let resampled = resample(path, &trace, dt)?;
            notes.extend(widest_gap_filled(&trace, &lines, step, dt));
            vec![resampled]
        }
        Gaps::Split => {
            let mut pieces = Vec::new();
            for (number, rows) in cut(path, &trace, &lines, Cuts::GapsAndJumps, &mut notes)? {
                // Suggesting --split-gaps here would send the user round in a circle.
                let hint = "--split-gaps cuts only where a step is over 1.5 median steps or time runs back or stands still; add --resample DT to interpolate each piece onto a uniform step";
                check_uniform(
                    path,
                    &opts.time,
                    &trace.t[rows.clone()],
                    &lines[rows.clone()],
                    step,
                    hint,
                )?;
                pieces.push(piece(&trace, number, rows));
            }
            pieces
        }
        Gaps::SplitResample(dt) => {
            let mut pieces = Vec::new();
            for (number, rows) in cut(path, &trace, &lines, Cuts::Jumps, &mut notes)? {
                let read = piece(&trace, number, rows.clone());
                // Checked before resampling, which refuses a span under a step.
                let samples = grid_len(read.t[read.len() - 1] - read.t[0], dt);
                if samples < MIN_SEGMENT {
                    notes.push(format!(
                        "{}: lines {} to {}: --split-gaps dropped piece [{number}]: {samples} \
                         samples at --resample {dt}, fewer than {MIN_SEGMENT}",
                        path.display(),
                        lines[rows.start],
                        lines[rows.end - 1],
                    ));
                    continue;
                }
                pieces.push(resample(path, &read, dt)?);
                notes.extend(widest_gap_filled(&read, &lines[rows], step, dt));
            }
            if pieces.is_empty() {
                return Err(DataError::Unusable {
                    path: p(),
                    message: format!(
                        "--split-gaps: every piece is shorter than {MIN_SEGMENT} samples at --resample {dt}"
                    ),
                });
            }
            pieces
        }
    };
    Ok((traces, notes))
}

/// The note `--resample` owes where it interpolated across a gap (a step
/// over 1.5 median steps, as `--split-gaps` cuts): the widest, with its
/// line, how many of the new samples fall inside it and their share.
/// `None` where the trace (a file, or a piece of one) had no gap.
fn widest_gap_filled(trace: &Trace, lines: &[u64], median: f64, dt: f64) -> Option<String> {
    let steps = trace.t.windows(2).map(|w| w[1] - w[0]);
    let gaps = steps.clone().filter(|&s| s > GAP_FACTOR * median).count();
    let (k, widest) = steps
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .filter(|&(_, s)| s > GAP_FACTOR * median)?;
    // Grid points strictly inside the gap: its ends are measured.
    // Less a billionth, as the grid's own count: a gap of 0.07 s at 0.01 s
    // is 7.000000000000001 steps, and holds 6 points, not 7.
    let made_up = ((widest / dt - 1e-9).ceil() as usize).saturating_sub(1);
    // The resampled record's own count ([`grid_len`]): a plain floor of a
    // span of 1.19 s at 0.01 s counted 119 of its 120.
    let total = grid_len(trace.t[trace.len() - 1] - trace.t[0], dt);
    let others = match gaps {
        1 => String::new(),
        n => format!(", the widest of {n}"),
    };
    Some(format!(
        "{}: line {}: --resample {dt} interpolated across a gap of {} s (from {} s to {} s){others}: \
         {made_up} of the record's {total} samples are made up there ({:.0} %); use it where \
         such gaps are short against the muscle's time constant",
        trace.source,
        lines[k + 1],
        rounded(widest),
        trace.t[k],
        trace.t[k + 1],
        100.0 * made_up as f64 / total as f64,
    ))
}

/// The way out of a sample's cell that holds no number, as a logger writes
/// a missed reading, in a file with a time column ...
const MISSED_READING: &str = "; a missed reading? --resample DT drops such a row and \
                              interpolates across it, --split-gaps cuts the record there";

/// ... and in one read with `--dt`, where a row left out would move every
/// later one a step earlier, so only a cut will do.
const MISSED_READING_BY_ROWS: &str =
    "; a missed reading? --split-gaps drops such a row and cuts the record there";

/// Parses column `c` of every row (`decimal_comma`: as [`number`]), erring
/// at the first bad cell, with `hint` where the column is a sample's (the
/// time, input or output). A column that is not (`None`: not selected)
/// and holds no number at all is a text column: `Ok(None)`, left out of
/// the trace.
fn numeric_column(
    path: &Path,
    (rows, table): (&[Row], &Cells),
    c: usize,
    name: &str,
    hint: Option<&'static str>,
    decimal_comma: bool,
) -> Result<Option<Vec<f64>>, DataError> {
    let required = hint.is_some();
    let mut values = Vec::with_capacity(rows.len());
    let mut first_bad = None;
    for row in rows {
        let cell = table.get(row, c);
        match number(cell, decimal_comma) {
            Ok(v) if v.is_finite() => values.push(v),
            Ok(_) => {
                return Err(DataError::NotFinite {
                    path: path.to_path_buf(),
                    line: row.line,
                    column: name.into(),
                    value: cell.into(),
                    hint: hint.unwrap_or_default(),
                });
            }
            Err(_) => {
                first_bad.get_or_insert((row.line, cell.to_string()));
            }
        }
    }
    match first_bad {
        None => Ok(Some(values)),
        Some(_) if values.is_empty() && !required => Ok(None),
        Some((line, value)) => Err(DataError::NotANumber {
            path: path.to_path_buf(),
            line,
            column: name.into(),
            value,
            hint: hint.unwrap_or_default(),
        }),
    }
}

/// The median time step: robust to a few gaps. Only forward steps count,
/// so that with [`Gaps::Split`] repeated times cannot drag it to zero.
fn median_step(t: &[f64]) -> f64 {
    let mut steps: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|&s| s > 0.0)
        .collect();
    if steps.is_empty() {
        return f64::NAN;
    }
    steps.sort_by(f64::total_cmp);
    steps[steps.len() / 2]
}

/// Errors at the first step outside [`UNIFORM_TOLERANCE`] of `expected`.
fn check_uniform(
    path: &Path,
    column: &str,
    t: &[f64],
    lines: &[u64],
    expected: f64,
    hint: &'static str,
) -> Result<(), DataError> {
    for k in 1..t.len() {
        let step = t[k] - t[k - 1];
        // The times' own rounding, so that a step of exactly 10 % more
        // (0.011 s against 0.01 s, a logger's milliseconds at 100 Hz) is
        // within, as the error's "±10 %" says, whether the times are near
        // 0 or an epoch's 1.7·10⁹ s: a few units in the last place of the
        // larger time.
        let slack = 4.0 * f64::EPSILON * t[k].abs().max(t[k - 1].abs()) + 1e-9 * expected;
        if (step - expected).abs() > UNIFORM_TOLERANCE * expected + slack {
            return Err(DataError::NonUniform {
                path: path.to_path_buf(),
                line: lines[k],
                column: column.into(),
                step,
                expected,
                hint,
            });
        }
    }
    Ok(())
}

/// How many points of a grid `dt` apart fit in `span` seconds, both ends
/// counted; the small slack keeps the last when `span / dt` is an integer
/// up to rounding.
fn grid_len(span: f64, dt: f64) -> usize {
    (span / dt + 1e-9).floor() as usize + 1
}

/// Linear interpolation of every column onto `t0 + k·dt`.
fn resample(path: &Path, trace: &Trace, dt: f64) -> Result<Trace, DataError> {
    let unusable = |message: String| DataError::Unusable {
        path: path.to_path_buf(),
        message,
    };
    if !(dt.is_finite() && dt > 0.0) {
        return Err(unusable(format!(
            "--resample {dt}: the step must be a positive number of seconds"
        )));
    }
    let t0 = trace.t[0];
    let span = trace.t[trace.len() - 1] - t0;
    samples_in(span, dt).map_err(|why| unusable(format!("--resample {dt}: {why}")))?;
    let n = grid_len(span, dt);
    if n < 2 {
        return Err(unusable(format!(
            "--resample {dt}: the file spans only {span} s, less than one step"
        )));
    }
    let grid: Vec<f64> = (0..n).map(|k| t0 + k as f64 * dt).collect();
    // For each grid time: the interval [j, j+1] holding it and the weight of j+1.
    let mut at = Vec::with_capacity(n);
    let mut j = 0;
    for &tg in &grid {
        while j + 2 < trace.len() && trace.t[j + 1] <= tg {
            j += 1;
        }
        let w = ((tg - trace.t[j]) / (trace.t[j + 1] - trace.t[j])).clamp(0.0, 1.0);
        at.push((j, w));
    }
    let interp = |v: &[f64]| -> Vec<f64> {
        at.iter()
            .map(|&(j, w)| v[j] + w * (v[j + 1] - v[j]))
            .collect()
    };
    Ok(Trace {
        source: trace.source.clone(),
        time_name: trace.time_name.clone(),
        input_name: trace.input_name.clone(),
        input: interp(&trace.input),
        output_name: trace.output_name.clone(),
        output: interp(&trace.output),
        extra: trace
            .extra
            .iter()
            .map(|(name, v)| (name.clone(), interp(v)))
            .collect(),
        cut_from: trace.cut_from.clone(),
        t: grid,
    })
}

/// Why [`Gaps::Split`] cut between two rows.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Jump {
    /// A step over [`GAP_FACTOR`] median steps (s): samples are missing.
    Gap(f64),
    /// Time went back by this many seconds (a logger glitch, a clock reset).
    Back(f64),
    /// The same time twice.
    Stall,
}

impl fmt::Display for Jump {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Jump::Gap(step) => write!(f, "gap of {} s", rounded(step)),
            Jump::Back(d) => write!(f, "time runs back by {} s", rounded(d)),
            Jump::Stall => write!(f, "time does not advance"),
        }
    }
}

/// Where a file is cut into pieces.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Cuts {
    /// At every gap (a step over [`GAP_FACTOR`] median steps) and every
    /// jump of the clock ([`Gaps::Split`]).
    GapsAndJumps,
    /// Only where time runs back or stands still ([`Gaps::SplitResample`]:
    /// the resampling fills the gaps).
    Jumps,
}

/// The pieces of `trace` between its cuts, each its number (from 1,
/// counting the dropped ones) and its rows, so that each has an increasing
/// time base of its own. Pieces are never merged or reordered: after a
/// jump back they may overlap earlier times, and each stays a separate
/// experiment. Every cut and every piece dropped as shorter than
/// [`MIN_SEGMENT`] samples is a note naming its line, so the user can find
/// it in the file; an error where every piece is.
fn cut(
    path: &Path,
    trace: &Trace,
    lines: &[u64],
    cuts: Cuts,
    notes: &mut Vec<String>,
) -> Result<Vec<(usize, Range<usize>)>, DataError> {
    let dt = median_step(&trace.t);
    let mut bounds = vec![0];
    let mut jumps = Vec::new();
    for k in 1..trace.len() {
        let step = trace.t[k] - trace.t[k - 1];
        let jump = if step < 0.0 {
            Jump::Back(-step)
        } else if step == 0.0 {
            Jump::Stall
        } else if cuts == Cuts::GapsAndJumps && step > GAP_FACTOR * dt {
            Jump::Gap(step)
        } else {
            continue;
        };
        bounds.push(k);
        jumps.push(jump);
    }
    bounds.push(trace.len());
    let segments = bounds.len() - 1;
    let mut kept = Vec::new();
    for (s, w) in bounds.windows(2).enumerate() {
        let (a, b) = (w[0], w[1]);
        if s > 0 {
            notes.push(format!(
                "{}: line {}: --split-gaps cut here: {} (from {} s on line {} to {} s); piece [{}] starts here",
                path.display(),
                lines[a],
                jumps[s - 1],
                trace.t[a - 1],
                lines[a - 1],
                trace.t[a],
                s + 1
            ));
        }
        if b - a < MIN_SEGMENT {
            let at = if b - a == 1 {
                format!("line {}", lines[a])
            } else {
                format!("lines {} to {}", lines[a], lines[b - 1])
            };
            notes.push(format!(
                "{}: {at}: --split-gaps dropped piece [{}]: {} samples, fewer than {MIN_SEGMENT}",
                path.display(),
                s + 1,
                b - a
            ));
            continue;
        }
        kept.push((s + 1, a..b));
    }
    if kept.is_empty() {
        return Err(DataError::Unusable {
            path: path.to_path_buf(),
            message: format!(
                "--split-gaps: all {segments} segments are shorter than {MIN_SEGMENT} samples"
            ),
        });
    }
    Ok(kept)
}

/// Rows `rows` of `trace` as piece `number`: named `FILE[number]` and
/// knowing the file it was cut from, unless it is the whole file.
fn piece(trace: &Trace, number: usize, rows: Range<usize>) -> Trace {
    let whole = rows.len() == trace.len();
    let mut piece = trace.slice(rows);
    if !whole {
        piece.source = format!("{}[{number}]", trace.source);
        piece.cut_from = Some(trace.source.clone());
    }
    piece
}

/// Writes `trace` as CSV: header `t,<input_name>,<output_name>,<extra...>`,
/// values in Rust's shortest round-trip form, so the same trace always gives
/// the same bytes and reads back bit for bit. Atomic.
pub fn write_trace(path: &Path, trace: &Trace) -> Result<(), DataError> {
    write_trace_with_comments(path, trace, &[])
}

/// As [`write_trace`], with `# ` comment lines first (for example the
/// command that made the file).
pub fn write_trace_with_comments(
    path: &Path,
    trace: &Trace,
    comments: &[String],
) -> Result<(), DataError> {
    write_columns(path, trace, comments, Missing::Refused)
}

/// As [`write_trace_with_comments`], on standard output (`--out -`): the
/// same bytes a file would get, for a pipe into another program. An error
/// names "standard output" where a file's would name the file.
pub fn print_trace_with_comments(trace: &Trace, comments: &[String]) -> Result<(), DataError> {
    let label = Path::new(STANDARD_OUTPUT);
    let text = format_columns(label, trace, comments, Missing::Refused)?;
    let mut stdout = std::io::stdout().lock();
    stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush())
        .map_err(|source| DataError::Io {
            path: label.to_path_buf(),
            source,
        })
}

/// The text [`write_trace_with_comments`] writes to `path` (which errors
/// name), for a caller that writes it with other files at once.
pub fn trace_text(path: &Path, trace: &Trace, comments: &[String]) -> Result<String, DataError> {
    format_columns(path, trace, comments, Missing::Refused)
}

/// What an error about a trace written to standard output names as its file.
pub const STANDARD_OUTPUT: &str = "standard output";

/// As [`write_trace_with_comments`] for a log whose measurements may be
/// missing (a control run's dropped sample): a value that is not finite is
/// written as an empty cell, which [`read_traces`] reports with its line
/// and column if the log is read as data.
pub fn write_log_with_comments(
    path: &Path,
    trace: &Trace,
    comments: &[String],
) -> Result<(), DataError> {
    write_columns(path, trace, comments, Missing::EmptyCell)
}

/// What a writer does with a value that is not finite.
#[derive(Clone, Copy, PartialEq)]
enum Missing {
    /// An error naming its line and column: a trace is data to fit.
    Refused,
    /// An empty cell: a log says what was and was not measured.
    EmptyCell,
}

fn write_columns(
    path: &Path,
    trace: &Trace,
    comments: &[String],
    missing: Missing,
) -> Result<(), DataError> {
    let text = format_columns(path, trace, comments, missing)?;
    write_atomic(path, text.as_bytes()).map_err(|source| DataError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// The CSV text of `trace`; an error names `path`, where it goes.
fn format_columns(
    path: &Path,
    trace: &Trace,
    comments: &[String],
    missing: Missing,
) -> Result<String, DataError> {
    let bad = |message: String| DataError::BadTrace {
        path: path.to_path_buf(),
        message,
    };
    // A time read in another unit than seconds is written back in it.
    let time: std::borrow::Cow<[f64]> =
        match crate::data::units::time_unit_other_than_seconds(&trace.time_name) {
            Some((_, per_second)) => trace.t.iter().map(|v| v * per_second).collect(),
            None => (&trace.t[..]).into(),
        };
    let mut columns: Vec<(&str, &[f64])> = vec![
        (&trace.time_name, &time),
        (&trace.input_name, &trace.input),
        (&trace.output_name, &trace.output),
    ];
    columns.extend(trace.extra.iter().map(|(n, v)| (n.as_str(), v.as_slice())));
    let mut out = String::new();
    for c in comments {
        for l in c.lines() {
            let _ = writeln!(out, "# {l}");
        }
    }
    let header_line = out.lines().count() as u64 + 1;
    for (i, (name, values)) in columns.iter().enumerate() {
        if name.is_empty() || name.contains(['\n', '\r']) || *name != name.trim() {
            return Err(bad(format!(
                "column name \"{name}\" cannot be written (empty, padded, or holds a newline)"
            )));
        }
        if values.len() != trace.len() {
            return Err(bad(format!(
                "column \"{name}\" has {} values but the time base has {}",
                values.len(),
                trace.len()
            )));
        }
        if let Some(k) = values.iter().position(|v| !v.is_finite())
            && missing == Missing::Refused
        {
            return Err(DataError::NotFinite {
                path: path.to_path_buf(),
                line: header_line + 1 + k as u64,
                column: name.to_string(),
                value: values[k].to_string(),
                hint: "",
            });
        }
        out.push_str(if i == 0 { "" } else { "," });
        // A name with a comma or a quote is quoted as RFC 4180 quotes it,
        // as the reader reads it back (a record's column "a,b").
        if name.contains([',', '"']) {
            let _ = write!(out, "\"{}\"", name.replace('"', "\"\""));
        } else {
            out.push_str(name);
        }
    }
    out.push('\n');
    for k in 0..trace.len() {
        for (i, (_, values)) in columns.iter().enumerate() {
            if i > 0 {
                out.push(',');
            }
            if values[k].is_finite() {
                let _ = write!(out, "{}", values[k]);
            }
        }
        out.push('\n');
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str, gaps: Gaps) -> Result<(Vec<Trace>, Vec<String>), DataError> {
        let opts = ReadOptions {
            gaps,
            ..ReadOptions::default()
        };
        parse(Path::new("x.csv"), text.as_bytes(), &opts)
    }

    /// `notes` less those that doubt a column's unit: the fixtures below
    /// step by seconds and hold pressures of a few units, for numbers that
    /// are easy to follow.
    fn but_unit_doubts(notes: &[String]) -> Vec<String> {
        notes
            .iter()
            .filter(|n| !n.contains("column \"t\" steps by") && !n.contains("is taken in MPa"))
            .cloned()
            .collect()
    }

    fn err(text: &str) -> String {
        read(text, Gaps::Reject).unwrap_err().to_string()
    }

    /// An empty file's error names the header of the columns asked for,
    /// not the default one: `validate boucwen` reads `u_N` and `y_m`.
    #[test]
    fn an_empty_file_names_the_header_asked_for() {
        let opts = ReadOptions {
            input: "u_N".into(),
            output: "y_m".into(),
            ..ReadOptions::default()
        };
        let e = parse(Path::new("x.csv"), b"", &opts).unwrap_err();
        assert!(e.to_string().contains("such as `t,u_N,y_m`"), "{e}");
        let untimed = ReadOptions {
            dt: Some(0.01),
            ..opts
        };
        let e = parse(Path::new("x.csv"), b"", &untimed).unwrap_err();
        assert!(e.to_string().contains("such as `u_N,y_m`"), "{e}");
    }

    /// A file of UTF-16 (Excel's "Unicode text") is named as such, with
    /// the way out; other bytes that are no UTF-8 stay "not UTF-8 text".
    #[test]
    fn a_utf16_file_is_named_as_such() {
        let text = "t,pressure,displacement\n0,0.1,1\n";
        let mut utf16 = vec![0xff, 0xfe];
        utf16.extend(text.encode_utf16().flat_map(|c| c.to_le_bytes()));
        let e = parse(Path::new("x.csv"), &utf16, &ReadOptions::default()).unwrap_err();
        assert!(e.to_string().contains("UTF-16 text, not UTF-8"), "{e}");
        let latin1 = b"t,pressure,displacement\n0,0.1,1\xb5\n";
        let e = parse(Path::new("x.csv"), latin1, &ReadOptions::default()).unwrap_err();
        assert!(
            e.to_string().contains("not UTF-8 text") && !e.to_string().contains("16"),
            "{e}"
        );
    }

    /// A column named with a comma or a quote is written quoted and reads
    /// back under its name (it could not be written: `simulate --out` of
    /// a record with such a column failed).
    #[test]
    fn a_name_with_a_comma_or_a_quote_is_written_quoted_and_reads_back() {
        let mut trace = Trace::uniform("x.csv", 0.01, vec![0.1, 0.2, 0.3], vec![1.0, 2.0, 3.0]);
        trace.extra.push(("a,b".into(), vec![4.0, 5.0, 6.0]));
        trace.extra.push(("say \"hi\"".into(), vec![7.0, 8.0, 9.0]));
        let text = format_columns(Path::new("x.csv"), &trace, &[], Missing::Refused).unwrap();
        assert!(
            text.starts_with("t,pressure,displacement,\"a,b\",\"say \"\"hi\"\"\"\n"),
            "{text}"
        );
        let (back, _) = read(&text, Gaps::Reject).unwrap();
        let names: Vec<&str> = back[0].extra.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["a,b", "say \"hi\""]);
        assert_eq!(back[0].extra[0].1, [4.0, 5.0, 6.0]);
    }

    /// An error quotes at most 40 characters of a cell, with control
    /// characters escaped, and at most 12 column names: a 50 MB line made
    /// a 50 MB message, and a NUL printed raw.
    #[test]
    fn errors_quote_cells_and_columns_briefly() {
        let long = "x".repeat(5000);
        let e = err(&format!(
            "t,pressure,displacement\n0,{long},1\n0.01,0.2,2\n"
        ));
        assert!(
            e.contains(&format!(
                "\"{}… (5000 characters)\" is not a number;",
                "x".repeat(40)
            )),
            "{e}"
        );
        let e = err("t,pressure,displacement\n0,\u{0}1,1\n0.01,0.2,2\n");
        assert!(e.contains("\"\\u{0}1\" is not a number"), "{e}");
        let names: Vec<String> = (0..100).map(|k| format!("c{k}")).collect();
        let e = err(&format!(
            "{}\n{}\n",
            names.join(","),
            vec!["1"; 100].join(",")
        ));
        assert!(
            e.contains("\"c11\", and 88 more") && !e.contains("c12"),
            "{e}"
        );
    }

    /// A column the model does not read, filled only here and there (an
    /// event marker) or with a number among text, is left out with a note
    /// that names its first bad cell; the same cell in the input is an
    /// error.
    #[test]
    fn a_sparse_extra_column_is_left_out_and_a_sparse_input_is_an_error() {
        let text = "t,pressure,displacement,marker,note,load_kg\n0,0.1,1,,ok,3\n\
                    0.01,0.2,2,1,ok,inf\n0.02,0.3,3,,7,3\n";
        let (traces, notes) = read(text, Gaps::Reject).unwrap();
        assert!(traces[0].extra.is_empty(), "{:?}", traces[0].extra);
        assert_eq!(notes.len(), 3, "{notes:?}");
        assert!(
            notes[0].starts_with("x.csv: line 2, column \"marker\": \"\" is not a number")
                && notes[0].ends_with("column \"marker\" left out (only the time, input and output columns must be numbers throughout)"),
            "{notes:?}"
        );
        assert!(
            notes[1].contains("line 2, column \"note\": \"ok\""),
            "{notes:?}"
        );
        // A time column in milliseconds: a note.
        let ms = "t,pressure,displacement\n0,0.1,1\n10,0.2,2\n20,0.3,3\n";
        let (_, notes) = read(ms, Gaps::Reject).unwrap();
        assert!(
            notes.len() == 1 && notes[0].contains("column \"t\" steps by 10 s"),
            "{notes:?}"
        );
        // A 1 kHz logger's milliseconds step by 1.
        let khz = "t,pressure,displacement\n0,0.1,1\n1,0.2,2\n2,0.3,3\n";
        let (_, notes) = read(khz, Gaps::Reject).unwrap();
        assert!(
            notes.len() == 1 && notes[0].contains("column \"t\" steps by 1 s"),
            "{notes:?}"
        );
        // A `pressure` column in kPa, or in bar, under the shipped data's
        // name: a note; a tap-water muscle's MPa: none.
        for (largest, noted) in [("250", true), ("6", true), ("0.6", false)] {
            let text = format!("t,pressure,displacement\n0,0.1,1\n0.01,{largest},2\n");
            let (_, notes) = read(&text, Gaps::Reject).unwrap();
            let reach =
                format!("is taken in MPa (the shipped data's unit), but it reaches {largest}");
            assert_eq!(
                notes.len() == 1
                    && notes[0].contains(&reach)
                    && notes[0].contains("`pressure_MPa`"),
                noted,
                "{notes:?}"
            );
            assert_eq!(notes.is_empty(), !noted, "{notes:?}");
        }
        // A hydraulic muscle's MPa under a name that states it: no note.
        let hydraulic = "t,pressure_MPa,displacement\n0,0.1,1\n0.01,6,2\n";
        let opts = ReadOptions {
            input: "pressure_MPa".into(),
            ..ReadOptions::default()
        };
        let (_, notes) = parse(Path::new("x.csv"), hydraulic.as_bytes(), &opts).unwrap();
        assert!(notes.is_empty(), "{notes:?}");
        // A `displacement` column in metres or micrometres: a note; in mm,
        // however little it moves, none.
        for (column, noted) in [
            ("0.012,0.042", Some("reaches only 0.042; if it is in m")),
            ("12000,42000", Some("reaches 42000; if it is in µm")),
            ("23.4,23.5", None),
        ] {
            let (a, b) = column.split_once(',').unwrap();
            let text = format!("t,pressure,displacement\n0,0.1,{a}\n0.01,0.2,{b}\n");
            let (_, notes) = read(&text, Gaps::Reject).unwrap();
            match noted {
                Some(why) => assert!(notes.len() == 1 && notes[0].contains(why), "{notes:?}"),
                None => assert!(notes.is_empty(), "{notes:?}"),
            }
        }
        // A unit in brackets that no table holds: a note.
        let opts = ReadOptions {
            input: "p [kgf/mm2]".into(),
            ..ReadOptions::default()
        };
        let text = "t,p [kgf/mm2],displacement\n0,0.1,1\n0.01,0.2,2\n";
        let (_, notes) = parse(Path::new("x.csv"), text.as_bytes(), &opts).unwrap();
        assert!(
            notes.len() == 1 && notes[0].contains("names the unit `kgf/mm2`, which mckibben"),
            "{notes:?}"
        );
        let bad_input = "t,pressure,displacement\n0,0.1,1\n0.01,,2\n";
        assert!(
            err(bad_input).contains("line 3, column \"pressure\""),
            "{}",
            err(bad_input)
        );
    }

    /// `n` rows at `dt`, pressure = k, displacement = 2k.
    fn uniform_text(n: usize, dt: f64) -> String {
        let mut s = String::from("t,pressure,displacement\n");
        for k in 0..n {
            // The input in thousandths of the row (MPa, as `pressure` is
            // taken), the output twice the row.
            s += &format!("{},{}e-3,{}\n", k as f64 * dt, k, 2 * k);
        }
        s
    }

    #[test]
    fn reads_comments_blank_lines_and_extra_columns() {
        let text = "\u{feff}# made by a test\n#second\r\n\n\"t\", valve_in ,pressure,displacement,label\n\
                    0,1,0.1,5,a\n \n0.5,2,0.2,6,b\n1.0,3,0.3,7,c";
        let (traces, notes) = read(text, Gaps::Reject).unwrap();
        let tr = &traces[0];
        assert_eq!(tr.t, [0.0, 0.5, 1.0]);
        assert_eq!(tr.input, [0.1, 0.2, 0.3]);
        assert_eq!(tr.output, [5.0, 6.0, 7.0]);
        assert_eq!(tr.extra, [("valve_in".to_string(), vec![1.0, 2.0, 3.0])]);
        assert_eq!(tr.source, "x.csv");
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(notes[0].contains("\"label\""));
        // A spreadsheet's rows of empty cells, after the data and quoted.
        let (again, _) = read(&format!("{text}\n,,,,\n , ,,,\n\"\",,,,\n"), Gaps::Reject).unwrap();
        assert_eq!(again[0].t, tr.t);
        let msg = err("# a\n\nt,pressure,displacement\n\n0,1,2\r\n\n# b\n1,x,3\n");
        assert!(
            msg.starts_with("x.csv: line 8, column \"pressure\""),
            "{msg}"
        );
    }

    #[test]
    fn selects_columns_by_name() {
        let text = "time,a,b\n0,1,2\n1,3,4\n";
        let opts = ReadOptions {
            time: "time".into(),
            input: "b".into(),
            output: "a".into(),
            gaps: Gaps::Reject,
            ..ReadOptions::default()
        };
        let tr = &parse(Path::new("y.csv"), text.as_bytes(), &opts).unwrap().0[0];
        assert_eq!(
            (tr.input_name.as_str(), tr.output_name.as_str()),
            ("b", "a")
        );
        assert_eq!(
            (tr.input.clone(), tr.output.clone()),
            (vec![2.0, 4.0], vec![1.0, 3.0])
        );
    }

    #[test]
    fn every_malformed_input_names_file_line_and_column() {
        let cases: &[(&str, &[&str])] = &[
            (
                "# c\nt,pressure,disp\n0,1,2\n1,1,2\n",
                &[
                    "x.csv: line 2",
                    "no output column \"displacement\"",
                    "\"t\", \"pressure\", \"disp\"",
                    "--output COL",
                ],
            ),
            // A unit after the default name: the column is named, not taken.
            (
                "t,pressure [psi],displacement [mm]\n0,1,2\n1,1,2\n",
                &[
                    "no input column \"pressure\"",
                    "choose another with --input COL, here \"pressure [psi]\"",
                ],
            ),
            (
                "time_s,p1_kPa,Pressure_kPa,pressure_bar,x\n0,1,2,3,4\n1,1,2,3,4\n",
                &[
                    "no time column \"t\"",
                    "--time COL, here \"time_s\" (or, for a file without one",
                ],
            ),
            (
                "t,p1_kPa,Pressure_kPa,pressure_bar,x\n0,1,2,3,4\n1,1,2,3,4\n",
                &["--input COL, here one of \"Pressure_kPa\", \"pressure_bar\" (in other units"],
            ),
            (
                "t,pressure,displacement\n0,1,2\n1,abc,2\n",
                &["x.csv: line 3, column \"pressure\": \"abc\" is not a number"],
            ),
            (
                "t,pressure,displacement\n0,1,2\n1,2,\n",
                &["x.csv: line 3, column \"displacement\": \"\" is not a number"],
            ),
            (
                "t,pressure,displacement\n0,1,2\n1,2,NaN\n",
                &["x.csv: line 3, column \"displacement\": \"NaN\" is not finite"],
            ),
            // (A further column's bad cell is a note: the sparse test below.)
            (
                "t,pressure,displacement,load_kg\n0,1,2,3\n1,inf,2,3\n",
                &["x.csv: line 3, column \"pressure\": \"inf\" is not finite"],
            ),
            (
                "t,pressure,displacement,load_kg\n0,1,2,3\n1,x,2,3\n",
                &["x.csv: line 3, column \"pressure\": \"x\" is not a number"],
            ),
            ("", &["x.csv: the file is empty"]),
            ("# only a comment\n\n", &["x.csv: the file is empty"]),
            (
                "# c\nt,pressure,displacement\n",
                &["x.csv: line 2: a header row but 0 data rows"],
            ),
            (
                "t,pressure,displacement\n0,1,2\n",
                &["x.csv: line 1: a header row but 1 data row; a time step"],
            ),
            (
                "t,pressure,displacement\n0,1,2\n1,2\n",
                &["x.csv: line 3: 2 fields, but the header on line 1 has 3"],
            ),
            (
                "t,pressure,displacement\n0,1,2\n1,1,2\n1,1,3\n",
                &["x.csv: line 4, column \"t\": time 1 does not increase (previous row: 1)"],
            ),
            (
                "t,pressure,displacement\n0,1,2\n1,1,2\n2,1,2\n5,1,2\n6,1,2\n",
                &[
                    "x.csv: line 5, column \"t\": non-uniform time base: step 3 s, expected 1 s",
                    "--resample DT",
                    "--split-gaps",
                ],
            ),
            (
                "t,t,displacement\n0,1,2\n",
                &["x.csv: line 1: column \"t\" appears twice"],
            ),
        ];
        for (text, wanted) in cases {
            let msg = err(text);
            for w in *wanted {
                assert!(msg.contains(w), "input {text:?}\nmessage {msg}\nlacks {w}");
            }
        }
    }

    /// A header of names separated by spaces, or a LabVIEW file's first
    /// line, is named for what it is where a column is not found.
    #[test]
    fn a_header_that_is_no_list_of_columns_says_what_it_looks_like() {
        let e = err("t pressure displacement\n0 0.1 1\n0.01 0.2 2\n");
        assert!(
            e.contains("(one name with spaces: columns separated by spaces"),
            "{e}"
        );
        let e = err("LabVIEW Measurement\t\nWriter_Version\t2\n");
        assert!(e.contains("(a LabVIEW measurement file:"), "{e}");
        for other in [
            "time,pressure,displacement\n0,0.1,1\n0.01,0.2,2\n",
            // One column named with its unit, the README's `disp mm` form.
            "pressure kPa\n1\n2\n",
        ] {
            let e = err(other);
            assert!(!e.contains("(one name") && !e.contains("LabVIEW"), "{e}");
        }
    }

    /// A units row under the header is refused whatever the flags: the
    /// rows `--resample` and `--split-gaps` drop for holding no number
    /// would take it, and the units it states, with them.
    #[test]
    fn a_units_row_is_refused_before_rows_are_dropped() {
        let text = "t,pressure,displacement\ns,kPa,mm\n0,100,1\n0.01,200,2\n0.02,300,3\n";
        for gaps in [
            Gaps::Reject,
            Gaps::Resample(0.01),
            Gaps::Split,
            Gaps::SplitResample(0.01),
        ] {
            let e = read(text, gaps).unwrap_err().to_string();
            assert!(e.contains("line 2 holds no numbers"), "{gaps:?}: {e}");
        }
    }

    /// A row that repeats the one before it cell for cell is dropped with a
    /// note, not read as time standing still; a repeated time with other
    /// values stays an error, and rows `--dt` apart that are alike are
    /// samples.
    #[test]
    fn a_row_copied_cell_for_cell_is_dropped() {
        let text = "t,pressure,displacement\n0,0.1,1\n0.01,0.2,2\n0.01,0.2,2\n0.02,0.3,3\n";
        let (traces, notes) = read(text, Gaps::Reject).unwrap();
        assert_eq!(traces[0].output, [1.0, 2.0, 3.0]);
        assert_eq!(
            notes,
            ["x.csv: line 4: a copy of the row before it (every cell alike), dropped"]
        );
        // A logger that wrote every sample twice: one note for all.
        let twice: String = (0..40)
            .map(|k| format!("{},0.{k},{k}\n", f64::from(k) * 0.01).repeat(2))
            .collect();
        let (traces, notes) =
            read(&format!("t,pressure,displacement\n{twice}"), Gaps::Reject).unwrap();
        assert_eq!(traces[0].len(), 40);
        assert_eq!(
            notes,
            [
                "x.csv: 40 rows that copy the row before them (every cell alike), lines 3 to 81, \
              dropped"
            ]
        );
        let other = "t,pressure,displacement\n0,0.1,1\n0.01,0.2,2\n0.01,0.2,2.5\n0.02,0.3,3\n";
        assert!(err(other).contains("line 4, column \"t\": time 0.01 does not increase"));
        let untimed = ReadOptions {
            dt: Some(0.01),
            ..ReadOptions::default()
        };
        let text = "pressure,displacement\n0.1,1\n0.1,1\n0.1,1\n0.2,2\n";
        let (traces, _) = parse(Path::new("x.csv"), text.as_bytes(), &untimed).unwrap();
        assert_eq!(traces[0].len(), 4);
        // There a missed reading can only be cut out: --resample needs the
        // time a row was taken at.
        let text = "pressure,displacement\n0.1,1\nNaN,1\n0.1,1\n0.2,2\n";
        let e = parse(Path::new("x.csv"), text.as_bytes(), &untimed)
            .unwrap_err()
            .to_string();
        assert!(
            e.ends_with(
                "a missed reading? --split-gaps drops such a row and cuts the record there"
            ),
            "{e}"
        );
    }

    /// MATLAB's `%` starts a comment as `#` does, before the header or
    /// between rows: such lines read as a header of one column before.
    #[test]
    fn matlab_comments_are_comments() {
        let text = "% rig 2, 4.5 kg\n# run 3\nt,pressure,displacement\n0,0.1,1\n% valve reset\n\
                    0.01,0.2,2\n0.02,0.3,3\n";
        let (traces, notes) = read(text, Gaps::Reject).unwrap();
        assert_eq!(traces[0].output, [1.0, 2.0, 3.0], "{notes:?}");
    }

    /// `--resample` finer than the file's step makes up most samples: a
    /// note says how many, and what that does to the ±; near the file's
    /// own step or coarser, none.
    #[test]
    fn resampling_finer_than_measured_is_noted() {
        let text = uniform_text(100, 0.01);
        for (dt, noted) in [(0.001, true), (0.01, false), (0.008, false), (0.05, false)] {
            for gaps in [Gaps::Resample(dt), Gaps::SplitResample(dt)] {
                let (_, notes) = read(&text, gaps).unwrap();
                let finer = notes
                    .iter()
                    .any(|n| n.contains("makes about 10 samples of each"));
                assert_eq!(finer, noted, "{gaps:?}: {notes:?}");
            }
        }
    }

    /// `--resample` coarser than the file's step drops the rows between:
    /// a note says how many and what that does; near the file's own step
    /// or finer, none.
    #[test]
    fn resampling_coarser_than_measured_is_noted() {
        let text = uniform_text(1000, 0.001);
        for (dt, noted) in [
            (0.01, true),
            (0.001, false),
            (0.0014, false),
            (0.0005, false),
        ] {
            for gaps in [Gaps::Resample(dt), Gaps::SplitResample(dt)] {
                let (_, notes) = read(&text, gaps).unwrap();
                let coarser = notes
                    .iter()
                    .find(|n| n.contains("keeps about one sample in"));
                assert_eq!(coarser.is_some(), noted, "{gaps:?}: {notes:?}");
                if let Some(note) = coarser {
                    assert!(
                        note.contains("one sample in 10 (the file steps by 0.001 s)")
                            && note.contains("about 3.2×")
                            && note.contains("faster than 50 Hz"),
                        "{note}"
                    );
                }
            }
        }
    }

    #[test]
    fn jitter_within_tolerance_is_uniform() {
        let text = "t,pressure,displacement\n0,0,0\n0.0105,1,1\n0.0198,2,2\n0.03,3,3\n0.04,4,4\n";
        assert_eq!(read(text, Gaps::Reject).unwrap().0[0].len(), 5);
        let text = "t,pressure,displacement\n0,0,0\n0.0115,1,1\n0.02,2,2\n0.03,3,3\n";
        assert!(err(text).contains("line 3"));
        // Milliseconds at about 100 Hz: steps of 10 and 11 ms, 11 exactly
        // the 10 % the rule admits, however the differences round.
        // From 0, and from an epoch's seconds, where the differences
        // round at 10⁻⁷ s.
        for epoch in [0.0, 1.7e9] {
            let ms: String = (0..200)
                .scan(0u32, |t, k| {
                    let time = epoch + f64::from(*t) / 1000.0;
                    let row = format!("{time},{},{}\n", k % 7, k % 5);
                    *t += if k % 3 == 0 { 11 } else { 10 };
                    Some(row)
                })
                .collect();
            let text = format!("t,pressure,displacement\n{ms}");
            assert_eq!(
                read(&text, Gaps::Reject).unwrap().0[0].len(),
                200,
                "{epoch}"
            );
        }
    }

    /// MATLAB's csvwrite and writematrix write no header: the first row of
    /// numbers is named as such, not listed as columns "0", "0.1", "1".
    #[test]
    fn a_file_without_a_header_says_so() {
        let e = err("0,0,0\n0.01,0.2,2\n0.02,0.3,3\n");
        assert!(e.contains("line 1 holds only numbers"), "{e}");
        let e = err("0,0.1,1\n0.01,0.2,2\n0.02,0.3,3\n");
        assert!(
            e.contains("line 1 holds only numbers (\"0\", \"0.1\", \"1\") and no time column")
                && e.contains("the file needs a header line"),
            "{e}"
        );
        // A header with a number among its names is still a header.
        let e = err("t,pressure,2\n0,0.1,1\n0.01,0.2,2\n");
        assert!(e.contains("no output column \"displacement\""), "{e}");
        // pandas names the columns of an unnamed frame 0, 1, 2: they can
        // be chosen by those names.
        let opts = ReadOptions {
            time: "0".into(),
            input: "1".into(),
            output: "2".into(),
            gaps: Gaps::Reject,
            ..ReadOptions::default()
        };
        let text = "0,1,2\n0,0.1,1\n0.01,0.2,2\n0.02,0.3,3\n";
        let (traces, _) = parse(Path::new("x.csv"), text.as_bytes(), &opts).unwrap();
        assert_eq!(traces[0].output, [1.0, 2.0, 3.0]);
    }

    /// Columns without a name (pandas' `to_csv` index, a spreadsheet's
    /// empty columns at the end) are left out with a note, however many:
    /// two were "column \"\" appears twice", one was kept under the name
    /// "" that no file can be written with.
    #[test]
    fn unnamed_columns_are_left_out() {
        let (plain, _) = read(
            "t,pressure,displacement\n0,0.1,1\n0.01,0.2,2\n",
            Gaps::Reject,
        )
        .unwrap();
        for (text, columns) in [
            (
                ",t,pressure,displacement\n0,0,0.1,1\n1,0.01,0.2,2\n",
                vec![1],
            ),
            (
                "t,pressure,displacement,,\n0,0.1,1,,\n0.01,0.2,2,,\n",
                vec![4, 5],
            ),
        ] {
            let (traces, notes) = read(text, Gaps::Reject).unwrap();
            assert_eq!(
                (&traces[0].t, &traces[0].input, &traces[0].output),
                (&plain[0].t, &plain[0].input, &plain[0].output),
                "{text:?}"
            );
            assert!(traces[0].extra.is_empty(), "{text:?}");
            let expected: Vec<String> = columns
                .iter()
                .map(|c| format!("x.csv: column {c} has no name (pandas' index, or a spreadsheet's empty column); left out"))
                .collect();
            assert_eq!(notes, expected, "{text:?}");
        }
    }

    /// One column named for two roles (`--input t`) would fit the time as
    /// the pressure.
    #[test]
    fn one_column_in_two_roles_is_an_error() {
        let text = "t,pressure,displacement\n0,0.1,1\n0.01,0.2,2\n0.02,0.3,3\n";
        for (time, input, output, roles) in [
            ("t", "t", "displacement", "both the time and the input"),
            ("t", "pressure", "t", "both the time and the output"),
        ] {
            let opts = ReadOptions {
                time: time.into(),
                input: input.into(),
                output: output.into(),
                gaps: Gaps::Reject,
                ..ReadOptions::default()
            };
            let e = parse(Path::new("x.csv"), text.as_bytes(), &opts)
                .unwrap_err()
                .to_string();
            assert!(e.contains(roles), "{e}");
        }
    }

    #[test]
    fn a_header_in_another_form_says_which() {
        for (text, expect) in [
            (
                "# logged by hand\rt,pressure,displacement\r0,0.1,1\r0.01,0.2,2\r",
                "lone carriage return",
            ),
            (
                "t,pressure,displacement\r0,0.1,1\r0.01,0.2,2\r",
                "lone carriage return",
            ),
        ] {
            let err = read(text, Gaps::Reject).unwrap_err().to_string();
            assert!(err.contains(expect), "{text:?}: {err}");
        }
        // CRLF is read as it should be.
        let crlf = "t,pressure,displacement\r\n0,0.1,1\r\n0.01,0.2,2\r\n";
        assert_eq!(read(crlf, Gaps::Reject).unwrap().0[0].len(), 2);
        // A spreadsheet's semicolons with decimal commas (a quoted cell
        // too), and tabs, read as the same numbers, and say how.
        let (commas, _) = read(
            "t,pressure,displacement\n0,0.1,1\n0.01,0.25,2\n",
            Gaps::Reject,
        )
        .unwrap();
        for (text, how) in [
            (
                "t;pressure;displacement\n0;0,1;1\n0,01;\"0,25\";2\n",
                "semicolons, a decimal comma read as a point",
            ),
            (
                "t;pressure;displacement\n0;0.1;1\n0.01;0.25;2\n",
                "semicolons",
            ),
            (
                "t\tpressure\tdisplacement\n0\t0.1\t1\n0.01\t0.25\t2\n",
                "tabs",
            ),
        ] {
            let (traces, notes) = read(text, Gaps::Reject).unwrap();
            assert_eq!(
                (&traces[0].t, &traces[0].input, &traces[0].output),
                (&commas[0].t, &commas[0].input, &commas[0].output),
                "{text:?}"
            );
            assert_eq!(
                notes,
                [format!("x.csv: fields separated by {how}")],
                "{text:?}"
            );
        }
        let err = read(
            "t;pressure;displacement\n0;0,1;1\n0,01;1.234,5;2\n",
            Gaps::Reject,
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.starts_with("x.csv: line 3, column \"pressure\": \"1.234,5\" is not"),
            "the cell as the file has it: {err}"
        );
        // A name's comma is the name's: Excel keeps it in a header of
        // semicolons.
        let named = ReadOptions {
            input: "pressure (MPa, gauge)".into(),
            ..ReadOptions::default()
        };
        let text = "sep=;\nt;pressure (MPa, gauge);displacement\n0;0,1;1\n0,01;0,25;2\n";
        let (traces, _) = parse(Path::new("x.csv"), text.as_bytes(), &named).unwrap();
        assert_eq!(traces[0].input, commas[0].input);
        assert_eq!(traces[0].input_name, "pressure (MPa, gauge)");
    }

    #[test]
    fn resample_interpolates_every_column_onto_the_grid() {
        // A gap between t = 2 and t = 4; values linear in t, so interpolation is exact.
        let text = "t,pressure,displacement,valve_in\n0,0,0,0\n1,1,10,5\n2,2,20,10\n4,4,40,20\n5,5,50,25\n";
        let tr = &read(text, Gaps::Resample(0.5)).unwrap().0[0];
        let want: Vec<f64> = (0..=10).map(|k| k as f64 * 0.5).collect();
        assert_eq!(tr.t, want);
        assert_eq!(tr.input, want);
        let ten: Vec<f64> = want.iter().map(|v| v * 10.0).collect();
        assert_eq!(tr.output, ten);
        assert_eq!(tr.column("valve_in").unwrap()[9], 22.5);
        // The gap is said: its line, its width, the samples made up in it
        // (after a note that 0.5 s is finer than the file's 1 s).
        let (_, notes) = read(text, Gaps::Resample(0.5)).unwrap();
        let notes = but_unit_doubts(&notes);
        assert!(
            notes[0].contains("makes about 2 samples of each measured one"),
            "{notes:?}"
        );
        assert_eq!(
            notes[1..],
            [
                "x.csv: line 5: --resample 0.5 interpolated across a gap of 2 s (from 2 s to 4 s): \
              3 of the record's 11 samples are made up there (27 %); use it where such gaps are \
              short against the muscle's time constant"
            ]
        );
        // 50 rows 10 ms apart from 0 s, then 50 from `resume` s on.
        let gapped = |resume: f64| {
            let mut text = String::from("t,pressure,displacement\n");
            for k in 0..100 {
                let t = match k < 50 {
                    true => 0.01 * k as f64,
                    false => resume + 0.01 * (k - 50) as f64,
                };
                text += &format!("{t},{k},{k}\n");
            }
            text
        };
        // The note counts the samples the record has: 1.19 s at 0.01 s
        // is 120 of them, which a floor of 118.99… counted as 119.
        let (traces, notes) = read(&gapped(0.70), Gaps::Resample(0.01)).unwrap();
        assert_eq!(traces[0].len(), 120);
        assert!(
            notes
                .iter()
                .any(|n| n.contains("of the record's 120 samples")),
            "{notes:?}"
        );
        // And the points inside a gap: 0.49 s to 0.56 s holds 0.50 … 0.55.
        let (_, notes) = read(&gapped(0.56), Gaps::Resample(0.01)).unwrap();
        assert!(
            notes.iter().any(|n| n.contains(": 6 of the record's")),
            "{notes:?}"
        );
        let (_, notes) = read(
            "t,pressure,displacement\n0,0,0\n1,1,1\n2,2,2\n",
            Gaps::Resample(0.5),
        )
        .unwrap();
        // No gap, no gap note.
        assert!(
            !notes.iter().any(|n| n.contains("across a gap")),
            "{notes:?}"
        );
        assert!(read(text, Gaps::Resample(0.0)).is_err());
        assert!(
            read(text, Gaps::Resample(10.0))
                .unwrap_err()
                .to_string()
                .contains("less than one step")
        );
    }

    /// A logger's file of NaN rows alone: the error says that --split-gaps
    /// dropped them (it read as a file with no data rows at all).
    #[test]
    fn a_file_split_gaps_empties_says_what_it_dropped() {
        let mut s = String::from("t,pressure,displacement\n");
        for k in 0..10 {
            s += &format!("{k},nan,1\n");
        }
        let e = read(&s, Gaps::Split).unwrap_err().to_string();
        assert!(
            e.contains(
                "0 data rows left after 10 whose time, input or output is not a finite \
                 number were dropped"
            ),
            "{e}"
        );
        let e = read("t,pressure,displacement\n", Gaps::Split)
            .unwrap_err()
            .to_string();
        assert!(!e.contains("dropped"), "{e}");
    }

    #[test]
    fn split_cuts_at_gaps_and_drops_short_segments() {
        // 30 samples, a gap, 5 samples (dropped), a gap, 25 samples.
        let mut s = String::from("t,pressure,displacement\n");
        let times = (0..30)
            .map(|k| k as f64)
            .chain((0..5).map(|k| 100.0 + k as f64))
            .chain((0..25).map(|k| 200.0 + k as f64));
        for (k, t) in times.enumerate() {
            s += &format!("{t},{k}e-3,0\n");
        }
        let (traces, notes) = read(&s, Gaps::Split).unwrap();
        assert_eq!(traces.len(), 2);
        assert_eq!((traces[0].len(), traces[1].len()), (30, 25));
        assert_eq!(
            (traces[0].source.as_str(), traces[1].source.as_str()),
            ("x.csv[1]", "x.csv[3]")
        );
        assert_eq!((traces[1].t[0], traces[1].input[0]), (200.0, 0.035));
        assert_eq!(
            but_unit_doubts(&notes),
            [
                "x.csv: line 32: --split-gaps cut here: gap of 71 s (from 29 s on line 31 to 100 s); piece [2] starts here",
                "x.csv: lines 32 to 36: --split-gaps dropped piece [2]: 5 samples, fewer than 20",
                "x.csv: line 37: --split-gaps cut here: gap of 96 s (from 104 s on line 36 to 200 s); piece [3] starts here",
            ]
        );
        // No gap: one trace under the file's own name.
        let one = read(&uniform_text(30, 0.01), Gaps::Split).unwrap().0;
        assert_eq!((one.len(), one[0].source.as_str()), (1, "x.csv"));
        // A segment that is non-uniform inside is still an error.
        let mut bad = uniform_text(30, 1.0);
        bad += "29.7,0,0\n";
        let bad = bad.replace("29,29e-3,58\n", "29.3,29e-3,58\n");
        let msg = read(&bad, Gaps::Split).unwrap_err().to_string();
        assert!(
            msg.starts_with("x.csv: line 31, column \"t\": non-uniform time base: step 1.3")
                && msg.ends_with("--split-gaps cuts only where a step is over 1.5 median steps or time runs back or stands still; add --resample DT to interpolate each piece onto a uniform step"),
            "{msg}"
        );
        // Nothing long enough: an error.
        let short = read(&uniform_text(5, 1.0), Gaps::Split)
            .unwrap_err()
            .to_string();
        assert!(
            short.contains("all 1 segments are shorter than 20"),
            "{short}"
        );
    }

    /// 100 Hz from t = 10 s after a comment line (row k on line k + 3); at
    /// row `back` a logger glitch sends the clock back by 1.02 s, and it
    /// ticks on from there.
    fn runs_back_text(n: usize, back: usize) -> String {
        let mut s = String::from("# logger\nt,pressure,displacement\n");
        for k in 0..n {
            let t = 10.0 + k as f64 * 0.01 - if k >= back { 1.03 } else { 0.0 };
            s += &format!("{t:.2},{k}e-3,0\n");
        }
        s
    }

    #[test]
    fn split_cuts_where_time_runs_back_and_says_where() {
        let text = runs_back_text(150, 100);
        let (traces, notes) = read(&text, Gaps::Split).unwrap();
        assert_eq!(
            (traces.len(), traces[0].len(), traces[1].len()),
            (2, 100, 50)
        );
        assert_eq!(
            (traces[0].source.as_str(), traces[1].source.as_str()),
            ("x.csv[1]", "x.csv[2]")
        );
        // Both know the recording they were cut from.
        for tr in &traces {
            assert_eq!(tr.cut_from.as_deref(), Some("x.csv"), "{}", tr.source);
        }
        // Each piece keeps its own rows in file order; the second overlaps
        // the first in time and is neither merged with it nor sorted.
        assert_eq!((traces[0].t[0], traces[0].t[99]), (10.0, 10.99));
        assert_eq!((traces[1].t[0], traces[1].input[0]), (9.97, 0.1));
        for tr in &traces {
            assert!((tr.dt() - 0.01).abs() < 1e-9, "{}: {}", tr.source, tr.dt());
        }
        assert_eq!(
            notes,
            [
                "x.csv: line 103: --split-gaps cut here: time runs back by 1.02 s (from 10.99 s on line 102 to 9.97 s); piece [2] starts here"
            ]
        );

        // Without --split-gaps: the same line, what happened, and the way out.
        let msg = err(&text);
        assert_eq!(
            msg,
            "x.csv: line 103, column \"t\": time 9.97 does not increase (previous row: 10.99): it runs back by 1.02 s; pass --split-gaps to cut the file there"
        );
        // --resample does not interpolate over it either.
        let msg = read(&text, Gaps::Resample(0.01)).unwrap_err().to_string();
        assert!(
            msg.starts_with("x.csv: line 103, column \"t\": time 9.97 does not increase"),
            "{msg}"
        );
        assert!(
            msg.contains(
                "--resample cannot interpolate across it; add --split-gaps to cut the file there \
                 and resample each piece"
            ),
            "{msg}"
        );
    }

    /// Both flags: the file is cut only where its clock runs back, each
    /// piece interpolated onto its own grid across its gaps, a row that is
    /// not a number dropped and interpolated over; a piece too short at the
    /// step is dropped with a note, and a file with none left is an error.
    #[test]
    fn split_and_resample_cut_only_where_the_clock_jumps() {
        // Rows 40 to 44 missing (a gap of 0.06 s; row k is on line k − 2
        // after them) and row 120 a NaN.
        let text: String = runs_back_text(150, 100)
            .lines()
            .enumerate()
            .filter(|&(line, _)| !(42..47).contains(&line))
            .map(|(line, row)| match line {
                122 => "10.17,NaN,0\n".to_string(),
                _ => format!("{row}\n"),
            })
            .collect();
        let (traces, notes) = read(&text, Gaps::SplitResample(0.01)).unwrap();
        let lengths: Vec<usize> = traces.iter().map(Trace::len).collect();
        assert_eq!(lengths, [100, 50], "{notes:?}");
        assert_eq!(
            (traces[0].source.as_str(), traces[1].source.as_str()),
            ("x.csv[1]", "x.csv[2]")
        );
        assert_eq!((traces[0].t[0], traces[1].t[0]), (10.0, 9.97));
        // The input rises by 1e-3 a row, so the straight line across a
        // gap is the rise itself.
        for (tr, first) in traces.iter().zip([0, 100]) {
            assert!((tr.dt() - 0.01).abs() < 1e-9, "{}", tr.source);
            for (k, &u) in tr.input.iter().enumerate() {
                let want = (first + k) as f64 * 1e-3;
                assert!(
                    (u - want).abs() < 1e-9,
                    "{}[{k}]: {u} against {want}",
                    tr.source
                );
            }
        }
        assert_eq!(notes.len(), 4, "{notes:?}");
        assert_eq!(
            notes[..2],
            [
                "x.csv: line 118: --split-gaps dropped the row: column \"pressure\" holds \"NaN\", not a finite number",
                "x.csv: line 98: --split-gaps cut here: time runs back by 1.02 s (from 10.99 s on line 97 to 9.97 s); piece [2] starts here",
            ]
        );
        assert!(
            notes[2].starts_with("x.csv[1]: line 43: --resample 0.01 interpolated across a gap of 0.06 s (from 10.39 s to 10.45 s)")
                && notes[3].starts_with("x.csv[2]: line 119: --resample 0.01 interpolated across a gap of 0.02 s"),
            "{notes:?}"
        );

        // At 0.05 s the first piece keeps 20 samples, the second 10.
        let (traces, notes) = read(&text, Gaps::SplitResample(0.05)).unwrap();
        assert_eq!((traces.len(), traces[0].len()), (1, 20), "{notes:?}");
        assert!(
            notes.contains(&"x.csv: lines 98 to 147: --split-gaps dropped piece [2]: 10 samples at --resample 0.05, fewer than 20".to_string()),
            "{notes:?}"
        );
        let msg = read(&text, Gaps::SplitResample(0.1))
            .unwrap_err()
            .to_string();
        assert_eq!(
            msg,
            "x.csv: --split-gaps: every piece is shorter than 20 samples at --resample 0.1"
        );
    }

    #[test]
    fn split_drops_a_short_piece_before_a_jump_back_with_a_note() {
        // The clock runs back after 5 rows: those 5 are too few to keep.
        let (traces, notes) = read(&runs_back_text(40, 5), Gaps::Split).unwrap();
        assert_eq!(traces.len(), 1);
        assert_eq!(
            (traces[0].source.as_str(), traces[0].len()),
            ("x.csv[2]", 35)
        );
        assert_eq!(traces[0].t[0], 9.02);
        assert_eq!(
            notes,
            [
                "x.csv: lines 3 to 7: --split-gaps dropped piece [1]: 5 samples, fewer than 20",
                "x.csv: line 8: --split-gaps cut here: time runs back by 1.02 s (from 10.04 s on line 7 to 9.02 s); piece [2] starts here",
            ]
        );
    }

    #[test]
    fn split_cuts_where_time_stands_still() {
        // Row 30 repeats the time of row 29 (a logger writing one sample twice).
        let mut text = uniform_text(30, 1.0);
        for k in 29..60 {
            text += &format!("{k},{k}e-3,0\n");
        }
        let (traces, notes) = read(&text, Gaps::Split).unwrap();
        assert_eq!((traces[0].len(), traces[1].len()), (30, 31));
        assert_eq!(traces[1].t[0], 29.0);
        assert_eq!(
            but_unit_doubts(&notes),
            [
                "x.csv: line 32: --split-gaps cut here: time does not advance (from 29 s on line 31 to 29 s); piece [2] starts here"
            ]
        );
        assert!(err(&text).ends_with(
            "line 32, column \"t\": time 29 does not increase (previous row: 29); pass --split-gaps to cut the file there"
        ));
    }

    #[test]
    fn split_drops_a_row_that_is_not_a_number_and_cuts_there() {
        // Row 30 a logger's NaN, row 60 an empty output, the last a NaN time.
        let rows: Vec<String> = uniform_text(100, 1.0).lines().map(String::from).collect();
        let mut text = String::new();
        for (k, row) in rows.iter().enumerate() {
            let row = match k {
                31 => "30,NaN,60".to_string(),
                61 => "60,60e-3,".to_string(),
                100 => "nan,99e-3,198".to_string(),
                _ => row.clone(),
            };
            text += &row;
            text += "\n";
        }
        let (traces, notes) = read(&text, Gaps::Split).unwrap();
        let lengths: Vec<usize> = traces.iter().map(Trace::len).collect();
        assert_eq!(lengths, [30, 29, 38], "{notes:?}");
        assert_eq!((traces[1].t[0], traces[2].t[0]), (31.0, 61.0));
        assert_eq!(
            but_unit_doubts(&notes),
            [
                "x.csv: line 32: --split-gaps dropped the row: column \"pressure\" holds \"NaN\", not a finite number",
                "x.csv: line 62: --split-gaps dropped the row: column \"displacement\" holds \"\", not a finite number",
                "x.csv: line 101: --split-gaps dropped the row: column \"t\" holds \"nan\", not a finite number",
                "x.csv: line 33: --split-gaps cut here: gap of 2 s (from 29 s on line 31 to 31 s); piece [2] starts here",
                "x.csv: line 63: --split-gaps cut here: gap of 2 s (from 59 s on line 61 to 61 s); piece [3] starts here",
            ]
        );
        // Without --split-gaps or --resample each is the error it was
        // (the time column is read first), with the ways out.
        let msg = err(&text);
        assert!(
            msg.contains(
                "line 101, column \"t\": \"nan\" is not finite; a missed reading? \
                 --resample DT drops such a row"
            ),
            "{msg}"
        );
        // --resample drops them too, and interpolates across: one record.
        let (traces, notes) = read(&text, Gaps::Resample(1.0)).unwrap();
        assert_eq!(traces.len(), 1);
        assert_eq!(traces[0].len(), 99, "{notes:?}");
        assert!(
            notes[0].starts_with("x.csv: line 32: --resample dropped the row: column \"pressure\""),
            "{notes:?}"
        );
        assert!(
            notes
                .iter()
                .any(|n| n.contains("--resample 1 interpolated across a gap of 2 s")),
            "{notes:?}"
        );
    }

    /// A file without a time column reads with `--dt` as rows that far
    /// apart, the first at 0; a row `--split-gaps` drops keeps its time out,
    /// so the file is cut there; a file that has the time column refuses
    /// `--dt`, and one without it names `--dt` in its error.
    #[test]
    fn rows_dt_apart_where_the_file_has_no_time_column() {
        let mut text = String::from("pressure,displacement\n");
        for k in 0..60 {
            match k {
                25 => text += "NaN,50\n",
                _ => text += &format!("{},{}\n", k as f64 * 1e-3, 2 * k),
            }
        }
        let at = |gaps| ReadOptions {
            dt: Some(0.5),
            gaps,
            ..ReadOptions::default()
        };
        let missing = err(&text);
        assert!(missing.contains("no time column \"t\"") && missing.contains("--dt SECONDS"));
        let nan = parse(Path::new("x.csv"), text.as_bytes(), &at(Gaps::Reject)).unwrap_err();
        assert!(nan.to_string().contains("line 27"), "{nan}");
        let (traces, _) = parse(Path::new("x.csv"), text.as_bytes(), &at(Gaps::Split)).unwrap();
        let lengths: Vec<usize> = traces.iter().map(Trace::len).collect();
        assert_eq!(lengths, [25, 34]);
        assert_eq!((traces[0].t[1], traces[1].t[0]), (0.5, 13.0));
        assert_eq!(
            (traces[1].output[0], traces[0].time_name.as_str()),
            (52.0, "t")
        );
        let timed = uniform_text(40, 0.01);
        let both = parse(Path::new("x.csv"), timed.as_bytes(), &at(Gaps::Reject)).unwrap_err();
        assert!(
            matches!(&both, DataError::TimeBesideDt { column, .. } if column == "t"),
            "{both}"
        );
        // A clock under another name is a clock too.
        let logged = timed.replacen("t,", "time_s,", 1);
        let both = parse(Path::new("x.csv"), logged.as_bytes(), &at(Gaps::Reject)).unwrap_err();
        assert!(both.to_string().contains("--time=time_s"), "{both}");
        // An empty row between samples is a missing sample: an error, or a
        // cut with --split-gaps; trailing empty rows are nothing.
        let rows = |hole: &str| {
            let mut s = String::from("pressure,displacement\n");
            for k in 0..50 {
                s += &match k {
                    25 => format!("{hole}\n"),
                    _ => format!("{},{k}\n", k as f64 * 1e-3),
                };
            }
            s.replacen("\n", "\n\n,\n", 1) + "\n,\n"
        };
        for hole in [",", ""] {
            let e = parse(Path::new("x.csv"), rows(hole).as_bytes(), &at(Gaps::Reject));
            let e = e.unwrap_err().to_string();
            assert!(e.contains("line 29: an empty row between samples"), "{e}");
        }
        let (cut, _) = parse(Path::new("x.csv"), rows(",").as_bytes(), &at(Gaps::Split)).unwrap();
        let starts: Vec<(usize, f64)> = cut.iter().map(|t| (t.len(), t.t[0])).collect();
        assert_eq!(starts, [(25, 0.0), (24, 13.0)]);
        // A model's own spacing reads a file without a clock, and says so;
        // a file with its clock reads that.
        let carried = ReadOptions {
            untimed_dt: Some(0.5),
            ..ReadOptions::default()
        };
        let e = parse(Path::new("x.csv"), rows(",").as_bytes(), &carried).unwrap_err();
        assert!(e.to_string().contains("line 29: an empty row"), "{e}");
        let clean = rows("1,1");
        let (read, notes) = parse(Path::new("x.csv"), clean.as_bytes(), &carried).unwrap();
        assert_eq!(read[0].t[2], 1.0);
        assert!(
            notes[0].contains("read 0.5 s apart, as the model's data were"),
            "{notes:?}"
        );
        let (own, _) = parse(Path::new("x.csv"), timed.as_bytes(), &carried).unwrap();
        assert_eq!(own[0].t[1], 0.01);
    }

    /// A row of units under the header is named for what it likely is,
    /// with the fix; a first row with a number in it is data, read as such.
    #[test]
    fn a_row_of_units_under_the_header_says_so() {
        let e = err("t,pressure,displacement\ns,MPa,mm\n0,0.1,1\n0.01,0.2,2\n");
        assert!(
            e.contains("line 2 holds no numbers (\"s\", \"MPa\", \"mm\")")
                && e.contains("a row of units?"),
            "{e}"
        );
        let e = err("t,pressure,displacement\ns,0.1,mm\n0,0.1,1\n0.01,0.2,2\n");
        assert!(e.contains("\"s\" is not a number"), "{e}");
    }

    /// Excel's `sep=;` first line names the separator and is no header;
    /// a separator that is not read is an error naming the line.
    #[test]
    fn an_excel_sep_line_names_the_separator() {
        let body = "t;pressure;displacement\n0;0,1;1\n0,01;0,2;2\n0,02;0,3;3\n";
        let (traces, notes) = read(&format!("sep=;\n{body}"), Gaps::Reject).unwrap();
        assert_eq!(traces[0].input, [0.1, 0.2, 0.3]);
        assert!(notes[0].contains("semicolons"), "{notes:?}");
        let commas = "SEP=,\nt,pressure,displacement\n0,0.1,1\n0.01,0.2,2\n";
        assert_eq!(read(commas, Gaps::Reject).unwrap().0[0].output, [1.0, 2.0]);
        let tabs = "sep=\t\nt\tpressure\tdisplacement\n0\t0,1\t1\n0,01\t0,2\t2\n";
        assert_eq!(read(tabs, Gaps::Reject).unwrap().0[0].output, [1.0, 2.0]);
        let quoted = "\"sep=;\"\nt;pressure;displacement\n0;0,1;1\n0,01;0,2;2\n";
        assert_eq!(read(quoted, Gaps::Reject).unwrap().0[0].input, [0.1, 0.2]);
        let other = err("sep=;\nt,pressure,displacement\n0,0.1,1\n0.01,0.2,2\n");
        assert!(
            other.contains("line 1 names ';'") && other.contains("line 2"),
            "{other}"
        );
        let pipes = err("sep=|\nt|pressure|displacement\n0|0.1|1\n");
        assert!(
            pipes.contains("line 1") && pipes.contains("\"|\""),
            "{pipes}"
        );
    }

    #[test]
    fn write_then_read_round_trips_bit_for_bit() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out/trace.csv");
        let mut tr = Trace::uniform(
            "gen",
            0.01,
            vec![0.1, 1.0 / 3.0, -2.5e-7],
            vec![1e12, 0.0, -0.0],
        );
        tr.extra
            .push(("valve_in".into(), vec![f64::MIN_POSITIVE, 7.0, 0.3]));
        write_trace_with_comments(&p, &tr, &["mckibben simulate\nsecond line".into()]).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert!(bytes.starts_with(
            b"# mckibben simulate\n# second line\nt,pressure,displacement,valve_in\n0,0.1,"
        ));
        let back = &read_traces(&p, &ReadOptions::default()).unwrap()[0];
        assert_eq!(
            (&back.t, &back.input, &back.output, &back.extra),
            (&tr.t, &tr.input, &tr.output, &tr.extra)
        );
        write_trace_with_comments(&p, &tr, &["mckibben simulate\nsecond line".into()]).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), bytes, "same trace, same bytes");
    }

    #[test]
    fn writing_refuses_what_could_not_be_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.csv");
        let tr = Trace::uniform("gen", 1.0, vec![0.0, f64::NAN], vec![0.0, 1.0]);
        let msg = write_trace(&p, &tr).unwrap_err().to_string();
        assert!(
            msg.contains("line 3, column \"pressure\": \"NaN\" is not finite"),
            "{msg}"
        );
        let mut tr = Trace::uniform("gen", 1.0, vec![0.0, 1.0], vec![0.0, 1.0]);
        // A newline in a name would split the header (a comma is quoted).
        tr.extra.push(("a\nb".into(), vec![0.0, 0.0]));
        assert!(write_trace(&p, &tr).is_err());
        tr.extra[0] = ("short".into(), vec![0.0]);
        assert!(
            write_trace(&p, &tr)
                .unwrap_err()
                .to_string()
                .contains("\"short\" has 1 values")
        );
        assert!(!p.exists());
    }

    #[test]
    fn missing_file_names_the_path() {
        let msg = read_traces(Path::new("no/such.csv"), &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(msg.starts_with("no/such.csv: "), "{msg}");
    }
}
