//! Arguments shared by the commands that read experiment data: which file,
//! which columns, and what to do with a non-uniform time base. One loader
//! serves both the one-file form ([`DataArgs`]) and the many-file form
//! ([`MultiDataArgs`]).

use std::path::{Path, PathBuf};

use anyhow::Context;

use mckibben::data::Trace;
use mckibben::data::csv::{
    Gaps, ReadOptions, STANDARD_OUTPUT, print_trace_with_comments, read_traces_with_notes,
    trace_text,
};
use mckibben::data::{write_all_atomic, write_atomic};
use mckibben::fit::settings::MAX_POPULATION;
use mckibben::model::file::{ModelFile, Provenance, ReadSettings};
pub use mckibben::names::given_once;
use mckibben::optim::engine::generations_refused;
use mckibben::optim::streams::checked_seed;
use mckibben::report::Figure;

/// The hysteretic families `fit` fits and `diagnose` takes as a baseline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ModelArg {
    Classic,
    Generalized,
}

impl From<ModelArg> for mckibben::model::Family {
    fn from(m: ModelArg) -> Self {
        match m {
            ModelArg::Classic => Self::Classic,
            ModelArg::Generalized => Self::Generalized,
        }
    }
}

/// A population-size flag: a count up to [`MAX_POPULATION`], so that a
/// typo or a wrapped number is an error naming the flag, not an aborted
/// allocation.
pub fn population(s: &str) -> Result<usize, String> {
    let n: usize = s.parse().map_err(|e| format!("{e}"))?;
    if n > MAX_POPULATION {
        return Err(format!(
            "at most {MAX_POPULATION} candidates (a larger population is a typo, or more rows \
             than a machine holds)"
        ));
    }
    Ok(n)
}

/// A number of generations (`fit`, `control` and `compare --gens`,
/// `compare --budget-gens`, `diagnose` and `validate --generations`), as
/// [`generations_refused`] takes it. Zero ran the drawn population alone,
/// or one generation, without a word.
pub fn generations(s: &str) -> Result<usize, String> {
    let g = s.parse::<usize>().map_err(|e| format!("{e}"))?;
    generations_refused(g).map_or(Ok(g), Err)
}

/// `fit --stall`: generations without improvement, at least 1. Zero ended
/// every stage after its first generation.
pub fn stall(s: &str) -> Result<usize, String> {
    match s.parse::<usize>().map_err(|e| format!("{e}"))? {
        0 => Err("at least 1: 0 would end every stage after its first generation".into()),
        g => Ok(g),
    }
}

/// `simulate --piece`: a piece's number, as `--split-gaps` numbers them,
/// from 1.
pub fn piece(s: &str) -> Result<usize, String> {
    match s.parse::<usize>().map_err(|e| format!("{e}"))? {
        0 => Err("pieces are numbered from 1, as `identify FILE --split-gaps` lists them".into()),
        k => Ok(k),
    }
}

/// A seed flag: an integer up to
/// [`MAX_SEED`](mckibben::optim::streams::MAX_SEED).
pub fn seed(s: &str) -> Result<u64, String> {
    let seed: u64 = s.parse().map_err(|e| format!("{e}"))?;
    checked_seed(seed)
}

/// A flag naming a file or folder to write: `-` (standard output to many
/// tools) and an empty name are refused, where they would make a file or
/// folder of that name.
pub fn output_path(s: &str) -> Result<std::path::PathBuf, String> {
    match s {
        "" => Err("an empty name: give the file or folder to write".into()),
        "-" => Err("`-` is not standard output here: give a file or folder to write".into()),
        _ => Ok(s.into()),
    }
}

/// Where a command that writes one CSV trace (`simulate --out`, `twin
/// --out`) writes it: a file, atomically, or standard output for `-`, so
/// that the trace can be piped into another program.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CsvOut {
    File(PathBuf),
    Stdout,
}

/// A `--out FILE.csv` flag that takes `-` for standard output; an empty
/// name is refused.
pub fn csv_output(s: &str) -> Result<CsvOut, String> {
    match s {
        "-" => Ok(CsvOut::Stdout),
        _ => output_path(s).map(CsvOut::File),
    }
}

impl CsvOut {
    /// Writes `trace` with `# ` comment lines first and, where `plot` names
    /// a file, its figure: a trace file and its figure both or neither.
    pub fn write(
        &self,
        trace: &Trace,
        comments: &[String],
        plot: Option<(&Path, &Figure)>,
    ) -> anyhow::Result<()> {
        let svg = plot.map(|(path, figure)| Ok::<_, anyhow::Error>((path, figure.to_svg()?)));
        let svg = svg.transpose()?;
        match self {
            CsvOut::File(path) => {
                let text = trace_text(path, trace, comments)?;
                let mut files: Vec<(&Path, &[u8])> = vec![(path, text.as_bytes())];
                files.extend(svg.as_ref().map(|(p, s)| (*p, s.as_bytes())));
                write_all_atomic(&files).with_context(|| match &svg {
                    Some((plot, _)) => format!(
                        "cannot write --out {} and --plot {}",
                        path.display(),
                        plot.display()
                    ),
                    None => format!("cannot write --out {}", path.display()),
                })?;
            }
            CsvOut::Stdout => {
                // The figure first: a reader that closes the pipe early
                // ends the command.
                if let Some((path, svg)) = &svg {
                    write_atomic(path, svg.as_bytes())
                        .with_context(|| format!("cannot write --plot {}", path.display()))?;
                }
                print_trace_with_comments(trace, comments)?;
            }
        }
        Ok(())
    }

    /// Where a command's summary goes: where the trace does not (standard
    /// error when the trace is on standard output).
    pub fn summary(out: Option<&CsvOut>) -> Box<dyn std::io::Write> {
        match out {
            Some(CsvOut::Stdout) => Box::new(std::io::stderr()),
            _ => Box::new(std::io::stdout()),
        }
    }

    /// The file, or `-`.
    pub fn file(&self) -> Option<&Path> {
        match self {
            CsvOut::File(path) => Some(path),
            CsvOut::Stdout => None,
        }
    }
}

impl std::fmt::Display for CsvOut {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CsvOut::File(path) => write!(f, "{}", path.display()),
            CsvOut::Stdout => f.write_str(STANDARD_OUTPUT),
        }
    }
}

/// Refuses a set of files to write where one would replace a file the
/// command reads, or another of the set: `simulate --input run.csv --out
/// run.csv` would replace the recording by its simulation, and `--out
/// x.csv --plot x.csv` the trace by its figure. Each path comes with the
/// flag that named it; a path is compared as the file it names (`./a.csv`
/// and `a.csv` are one file, and so are two links to it).
pub fn check_distinct(reads: &[(&str, &Path)], writes: &[(&str, &Path)]) -> anyhow::Result<()> {
    for (i, (flag, path)) in writes.iter().enumerate() {
        let clash = reads
            .iter()
            .map(|(what, p)| (*what, *p, "reads"))
            .chain(writes[..i].iter().map(|(what, p)| (*what, *p, "writes")));
        for (what, other, verb) in clash {
            if same_file(path, other) {
                anyhow::bail!(
                    "{flag} {}: the command {verb} that file as {what}; give another name",
                    path.display()
                );
            }
        }
    }
    Ok(())
}

/// Refuses an output folder `dir` (named by `flag`) where the command would
/// write one of `names` over a file it reads (`fit rec/history.csv --out
/// rec` replaced the recording by the fit's history), or where a folder
/// stands in the place of one of them.
pub fn check_folder(
    flag: &str,
    dir: &Path,
    names: &[String],
    reads: &[(&str, &Path)],
) -> anyhow::Result<()> {
    for name in names {
        let written = dir.join(name);
        if let Some((what, read)) = reads.iter().find(|(_, read)| same_file(&written, read)) {
            anyhow::bail!(
                "{flag} {}: the command writes {name} there, over {} that it reads as {what}; \
                 give another folder",
                dir.display(),
                read.display()
            );
        }
        // Found now, not once the run is over and its files cannot go.
        anyhow::ensure!(
            !written.is_dir(),
            "{flag} {}: the command writes the file {name} there, and {} is a folder; give \
             another folder",
            dir.display(),
            written.display()
        );
    }
    Ok(())
}

/// Checks that `dir` (named by `flag`) can be a folder, and one a file can
/// be written in, before a run of minutes, so that a path that cannot fails
/// at once, not after the run (a read-only or immutable folder failed only
/// when the results were written): it creates the folder and a file in it,
/// then removes again the file and the folders it created, so that a run
/// that fails or is interrupted leaves nothing behind. The command creates
/// the folder for good when it writes there.
pub fn check_creatable(flag: &str, dir: &Path) -> anyhow::Result<()> {
    use anyhow::Context as _;
    let missing: Vec<&Path> = dir
        .ancestors()
        .take_while(|a| !a.as_os_str().is_empty() && !a.exists())
        .collect();
    mckibben::data::create_dir_all(dir)
        .with_context(|| format!("cannot create {flag} {}", dir.display()))?;
    // The process and the clock: a probe a killed run left behind under
    // the same process id is no reason to refuse the folder.
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    let probe = dir.join(format!(".mckibben-probe-{}-{nanos}", std::process::id()));
    let written = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe);
    if written.is_ok() {
        let _ = std::fs::remove_file(&probe);
    }
    for folder in missing {
        let _ = std::fs::remove_dir(folder);
    }
    written
        .map(drop)
        .with_context(|| format!("cannot write in {flag} {}", dir.display()))
}

/// Whether `a` and `b` name one file, existing or about to be written: the
/// same canonical path, or the same name in the same canonical folder.
fn same_file(a: &Path, b: &Path) -> bool {
    let canonical = |p: &Path| {
        p.canonicalize().ok().or_else(|| {
            let folder = match p.parent() {
                Some(d) if !d.as_os_str().is_empty() => d,
                _ => Path::new("."),
            };
            Some(folder.canonicalize().ok()?.join(p.file_name()?))
        })
    };
    match (canonical(a), canonical(b)) {
        (Some(x), Some(y)) => x == y,
        _ => a == b,
    }
}

/// The shipped default experiment, relative to the repository root.
pub const DEFAULT_DATA: &str = "data/stair_4.5kg.csv";

/// Column and time-base flags; flattened into [`DataArgs`] and [`MultiDataArgs`].
#[derive(Debug, Clone, clap::Args)]
pub struct ColumnArgs {
    /// Column holding the model input (the muscle pressure, MPa, in the
    /// shipped data). Any numeric column works, e.g. `--input valve_in`.
    /// [default: `pressure`, or the --from model's column where the command
    /// takes --from]
    #[arg(long, value_name = "COL")]
    pub input: Option<String>,
    /// Column holding the measured output (the displacement, mm, in the
    /// shipped data). [default: `displacement`, or the --from model's
    /// column where the command takes --from]
    #[arg(long, value_name = "COL")]
    pub output: Option<String>,
    /// Column holding the time in seconds. It must increase on every row
    /// (with --split-gaps the file is cut where it does not). [default:
    /// `t`, or the --from model's where the command takes --from]
    #[arg(long, value_name = "COL")]
    pub time: Option<String>,
    /// A file without a time column (MATLAB's writetable of u and y, a
    /// logger that counts rows): its rows are SECONDS apart, the first at
    /// 0, as iddata(y, u, Ts) takes them. A file with a time column (`t`,
    /// `time`, or a name with a unit of time, `time_s`) is an error, not a
    /// choice between two clocks.
    #[arg(long = "dt", value_name = "SECONDS", value_parser = positive_seconds,
          allow_negative_numbers = true, conflicts_with = "time")]
    pub dt: Option<f64>,
    /// The `--dt` of the model the data are read for (`--from`,
    /// `--carry`): the rows' spacing of a file that has no time column.
    #[arg(skip)]
    pub model_dt: Option<f64>,
    /// The models are discrete-time and need a uniform time base (every step
    /// within 10% of the median step); a file that is not is an error naming
    /// the first bad row. With this flag every column is instead linearly
    /// interpolated onto t0 + k·DT (DT in seconds, e.g. 0.01 for 100 Hz);
    /// gaps become straight lines. Time that runs back or repeats is still
    /// an error (never interpolated over): add --split-gaps to cut the file
    /// there and resample each piece.
    #[arg(long, value_name = "DT", value_parser = positive_seconds, allow_negative_numbers = true)]
    pub resample: Option<f64>,
    /// Instead of failing on a non-uniform time base, cut the file at every
    /// gap (a step over 1.5 median steps) and at every backward jump of the
    /// time column (time that runs back or repeats, e.g. a logger glitch),
    /// and use each piece as its own experiment (FILE[1], FILE[2], ...). A
    /// row whose time, input or output is not a finite number (a logger's
    /// NaN for a dropped sample, an empty cell) is dropped, and the file is
    /// cut where it was.
    /// Each cut is noted on stderr with its line and times; pieces under 20
    /// samples are dropped with a note. Pieces are never merged or sorted.
    /// With --resample, the file is cut only where time runs back or
    /// stands still, and each piece is interpolated onto its own time base:
    /// a logger whose clock glitches keeps the stretches between glitches
    /// whole, across their gaps.
    #[arg(long)]
    pub split_gaps: bool,
}

/// The longest of the traces (several come from `--split-gaps`; of equal
/// ones the one whose input spans most, then the first). The note names
/// the piece and its share of the samples, and warns where the rest
/// outweighs it: a recording cut at many short gaps (a logger's pauses)
/// leaves pieces of equal length, and a fit of one of them reads a small
/// part of what was measured. `resampled`: the pieces were cut where the
/// clock jumps and resampled across their gaps (`--resample` beside
/// `--split-gaps`), so that `--resample` is no way to keep more.
pub fn one_trace(mut traces: Vec<Trace>, resampled: bool) -> anyhow::Result<Trace> {
    anyhow::ensure!(!traces.is_empty(), "the data file holds no samples");
    // Of pieces of equal length (a logger that pauses every second) the
    // one whose input moves most: a rest before the first cycle is as long
    // as a cycle. Stable: of wholly equal ones the first stays first.
    traces.sort_by(|a, b| {
        b.len()
            .cmp(&a.len())
            .then(mckibben::data::range(&b.input).total_cmp(&mckibben::data::range(&a.input)))
    });
    if traces.len() > 1 {
        let total: usize = traces.iter().map(Trace::len).sum();
        let longest = &traces[0];
        let share = 100.0 * longest.len() as f64 / total as f64;
        errln!(
            "mckibben: note: {} pieces after --split-gaps; fitting the longest, {} ({} of their \
             {total} samples, {share:.0} %)",
            traces.len(),
            longest.source,
            longest.len(),
        );
        if 2 * longest.len() < total {
            let instead = if resampled {
                ""
            } else {
                "; where the cuts are gaps in time, --resample DT beside --split-gaps keeps \
                 each stretch between jumps of the clock as one record, interpolating across \
                 its gaps (where they are short against the muscle's time constant)"
            };
            errln!(
                "mckibben: warning: the fit reads {share:.0} % of the recording{instead}; \
                 `diagnose` fits every piece"
            );
        }
    }
    Ok(traces.swap_remove(0))
}

/// The records of several files (`fit`, `identify`): one record each; a file
/// `--split-gaps` cut into pieces gives its longest piece
/// ([`one_trace`], which says so; `resampled` as there).
pub fn records(traces: Vec<Trace>, resampled: bool) -> anyhow::Result<Vec<Trace>> {
    let mut records: Vec<Trace> = Vec::new();
    let mut pieces: Vec<Trace> = Vec::new();
    for trace in traces {
        let same_file = match (pieces.last(), &trace.cut_from) {
            (Some(last), Some(from)) => last.cut_from.as_ref() == Some(from),
            _ => false,
        };
        if !same_file && !pieces.is_empty() {
            records.push(one_trace(std::mem::take(&mut pieces), resampled)?);
        }
        match trace.cut_from {
            Some(_) => pieces.push(trace),
            None => records.push(trace),
        }
    }
    if !pieces.is_empty() {
        records.push(one_trace(pieces, resampled)?);
    }
    anyhow::ensure!(!records.is_empty(), "the data file holds no samples");
    Ok(records)
}

/// One data file (for `compare` and `bench`).
#[derive(Debug, Clone, clap::Args)]
pub struct DataArgs {
    /// Experiment CSV: a header row (after any `#` comment lines) naming the
    /// columns, one row per sample (`-`: standard input). Without it, the
    /// shipped data/stair_4.5kg.csv is used.
    #[arg(value_name = "DATA")]
    pub data: Option<PathBuf>,
    #[command(flatten)]
    pub columns: ColumnArgs,
}

/// Zero or more data files (for `fit`, `identify`, `diagnose`).
#[derive(Debug, Clone, clap::Args)]
pub struct MultiDataArgs {
    /// Experiment CSV files, each with a header row (after any `#` comment
    /// lines) naming the columns, one row per sample (`-`: standard
    /// input). Without any, the shipped data/stair_4.5kg.csv is used.
    #[arg(value_name = "DATA")]
    pub data: Vec<PathBuf>,
    #[command(flatten)]
    pub columns: ColumnArgs,
}

impl DataArgs {
    /// The traces of the file (several with `--split-gaps`).
    pub fn load(&self) -> anyhow::Result<Vec<Trace>> {
        self.columns.load(self.data.as_slice())
    }
}

impl MultiDataArgs {
    /// The traces of all files, in the order given.
    pub fn load(&self) -> anyhow::Result<Vec<Trace>> {
        self.columns.load(&self.data)
    }

    /// The provenance of a model fitted on these files.
    pub fn provenance(&self, seed: Option<u64>) -> anyhow::Result<Provenance> {
        self.columns.provenance(&self.data, seed)
    }
}

impl ColumnArgs {
    /// These flags, with what they leave unsaid read as `model` was read
    /// (its columns, time column and time base): a model refitted or
    /// diagnosed again reads new data as its own, unless told otherwise.
    pub fn or_as_read_for(&self, model: &ModelFile) -> ColumnArgs {
        let read = &model.provenance.read;
        let time_base_given = self.resample.is_some() || self.split_gaps;
        ColumnArgs {
            input: self.input.clone().or(Some(model.data.input.column.clone())),
            output: self
                .output
                .clone()
                .or(Some(model.data.output.column.clone())),
            time: self.time.clone().or(read.time.clone()),
            dt: self.dt,
            // Only for a file without a time column: another may have one.
            model_dt: if self.time.is_some() { None } else { read.dt },
            resample: if time_base_given {
                self.resample
            } else {
                read.resample
            },
            split_gaps: if time_base_given {
                self.split_gaps
            } else {
                read.split_gaps
            },
        }
    }

    /// The reading options these flags ask for.
    pub fn options(&self) -> ReadOptions {
        let defaults = ReadOptions::default();
        ReadOptions {
            time: self.time.clone().unwrap_or(defaults.time),
            dt: self.dt,
            untimed_dt: self.model_dt,
            input: self.input.clone().unwrap_or(defaults.input),
            output: self.output.clone().unwrap_or(defaults.output),
            gaps: match (self.resample, self.split_gaps) {
                (Some(dt), true) => Gaps::SplitResample(dt),
                (Some(dt), false) => Gaps::Resample(dt),
                (None, true) => Gaps::Split,
                (None, false) => Gaps::Reject,
            },
        }
    }

    /// How these flags read a file, for a model file's provenance.
    pub fn read_settings(&self) -> ReadSettings {
        ReadSettings {
            time: Some(self.options().time),
            resample: self.resample,
            split_gaps: self.split_gaps,
            dt: self.dt.or(self.model_dt),
        }
    }

    /// The provenance of a model fitted on `paths` (the default file when
    /// empty) read with these flags.
    pub fn provenance(&self, paths: &[PathBuf], seed: Option<u64>) -> anyhow::Result<Provenance> {
        let files: Vec<String> = if paths.is_empty() {
            vec![default_data()?.display().to_string()]
        } else {
            paths.iter().map(|p| p.display().to_string()).collect()
        };
        Ok(Provenance::here(&files, seed, self.read_settings()))
    }

    /// Reads `paths` (the default file when empty), printing any notes to
    /// stderr so that `--json` output on stdout stays clean.
    pub fn load(&self, paths: &[PathBuf]) -> anyhow::Result<Vec<Trace>> {
        let default;
        let paths = if paths.is_empty() {
            default = [default_data()?];
            &default[..]
        } else {
            paths
        };
        // One file given twice (under one name or two): its pieces after
        // --split-gaps would pass as one record's, which no later check
        // of the samples can tell apart.
        let files: Vec<PathBuf> = paths
            .iter()
            .map(|p| std::fs::canonicalize(p).unwrap_or_else(|_| p.clone()))
            .collect();
        for (k, file) in files.iter().enumerate() {
            if let Some(j) = files[..k].iter().position(|f| f == file) {
                anyhow::bail!(
                    "DATA names one file twice ({} and {}): a record given twice weighs double \
                     and makes every standard error look √2 smaller; give it once",
                    paths[j].display(),
                    paths[k].display()
                );
            }
        }
        let opts = self.options();
        let mut traces = Vec::new();
        for path in paths {
            let (mut read, notes) = read_traces_with_notes(path, &opts)?;
            for note in notes {
                errln!("mckibben: note: {note}");
            }
            traces.append(&mut read);
        }
        Ok(traces)
    }
}

/// The default data file: `data/stair_4.5kg.csv` under the current folder,
/// else under the source tree this binary was built from.
pub fn default_data() -> anyhow::Result<PathBuf> {
    let candidates = [
        PathBuf::from(DEFAULT_DATA),
        Path::new(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_DATA),
    ];
    first_existing(&candidates)
}

fn first_existing(candidates: &[PathBuf]) -> anyhow::Result<PathBuf> {
    candidates
        .iter()
        .find(|p| p.is_file())
        .cloned()
        .with_context(|| {
            let looked: Vec<String> = candidates.iter().map(|p| p.display().to_string()).collect();
            format!(
                "no DATA file given, and the default {DEFAULT_DATA} is missing (looked for {}); \
                 pass a CSV file, or regenerate the default with the command in data/README.md",
                looked.join(" and ")
            )
        })
}

/// Parses a step in seconds that must be positive and finite.
fn positive_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) => mckibben::data::sample_time(v),
        Err(_) => Err(format!(
            "\"{s}\" is not a positive number of seconds (e.g. 0.01 for 100 Hz)"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;
    use mckibben::optim::engine::MAX_GENERATIONS;

    #[derive(Debug, Parser)]
    struct One {
        #[command(flatten)]
        data: DataArgs,
    }

    #[derive(Debug, Parser)]
    struct Many {
        #[command(flatten)]
        data: MultiDataArgs,
    }

    #[test]
    fn flags_map_to_read_options() {
        let one = One::try_parse_from(["x", "f.csv", "--input", "valve_in", "--resample", "0.01"])
            .unwrap();
        assert_eq!(one.data.data, Some(PathBuf::from("f.csv")));
        let o = one.data.columns.options();
        assert_eq!(
            (o.input.as_str(), o.output.as_str(), o.time.as_str()),
            ("valve_in", "displacement", "t")
        );
        assert_eq!(o.gaps, Gaps::Resample(0.01));
        let many = Many::try_parse_from(["x", "a.csv", "b.csv", "--split-gaps"]).unwrap();
        assert_eq!(many.data.data.len(), 2);
        assert_eq!(many.data.columns.options().gaps, Gaps::Split);
        let both = One::try_parse_from(["x", "--resample", "0.01", "--split-gaps"]).unwrap();
        assert_eq!(both.data.columns.options().gaps, Gaps::SplitResample(0.01));
        assert_eq!(
            One::try_parse_from(["x"]).unwrap().data.columns.options(),
            ReadOptions::default()
        );
    }

    #[test]
    fn bad_flags_are_refused_by_name() {
        let e = One::try_parse_from(["x", "--resample", "-1"]).unwrap_err();
        assert!(
            e.to_string().contains("not a positive number of seconds"),
            "{e}"
        );
    }

    /// A count past a word less one wrapped once the initial population
    /// was added: `diagnose --generations 18446744073709551615` said "need
    /// at least one generation".
    #[test]
    fn generation_counts_are_bounded_on_both_sides() {
        assert!(generations("0").is_err());
        assert_eq!(generations("300"), Ok(300));
        assert_eq!(
            generations(&MAX_GENERATIONS.to_string()),
            Ok(MAX_GENERATIONS)
        );
        for wrapping in [MAX_GENERATIONS + 1, usize::MAX] {
            let e = generations(&wrapping.to_string()).unwrap_err();
            assert!(e.starts_with("at most 1000000000"), "{e}");
        }
    }

    #[test]
    fn loads_every_file_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.csv");
        let b = dir.path().join("b.csv");
        std::fs::write(&a, "t,pressure,displacement\n0,1,2\n1,3,4\n").unwrap();
        std::fs::write(&b, "# b\nt,pressure,displacement\n0,5,6\n1,7,8\n2,9,10\n").unwrap();
        let many = Many::try_parse_from(["x", b.to_str().unwrap(), a.to_str().unwrap()]).unwrap();
        let traces = many.data.load().unwrap();
        assert_eq!((traces[0].len(), traces[1].len()), (3, 2));
        let one = One::try_parse_from(["x", a.to_str().unwrap(), "--output", "nope"]).unwrap();
        let e = one.data.load().unwrap_err().to_string();
        assert!(
            e.contains("a.csv: line 1: no output column \"nope\""),
            "{e}"
        );
    }

    #[test]
    fn missing_default_says_how_to_regenerate() {
        let e = first_existing(&[PathBuf::from("no/such/stair.csv")])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("no/such/stair.csv") && e.contains("data/README.md"),
            "{e}"
        );
    }

    /// A folder a file cannot be written in fails the check, before a run
    /// (it failed once the fit was done), and the check leaves a folder it
    /// made, and its probe, behind in none. Made unwritable by its mode,
    /// or, for root, whom modes do not stop, by `chattr +i` where the file
    /// system has it.
    #[test]
    fn an_output_folder_that_takes_no_file_fails_the_check() {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = tempfile::tempdir().unwrap();
        let fresh = dir.path().join("a/b");
        check_creatable("--out", &fresh).unwrap();
        assert!(!dir.path().join("a").exists());
        let locked = dir.path().join("locked");
        std::fs::create_dir(&locked).unwrap();
        std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o555)).unwrap();
        let writable = std::fs::write(locked.join("x"), "").is_ok();
        let immutable = writable
            && std::fs::remove_file(locked.join("x")).is_ok()
            && std::process::Command::new("chattr")
                .arg("+i")
                .arg(&locked)
                .status()
                .is_ok_and(|s| s.success());
        if writable && !immutable {
            eprintln!("no way to make a folder unwritable here (root, no chattr): not checked");
            return;
        }
        let err = check_creatable("--out", &locked).unwrap_err();
        assert!(
            format!("{err:#}").contains("cannot write in --out"),
            "{err:#}"
        );
        if immutable {
            let _ = std::process::Command::new("chattr")
                .arg("-i")
                .arg(&locked)
                .status();
        }
        std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o755)).unwrap();
        assert_eq!(std::fs::read_dir(&locked).unwrap().count(), 0);
    }
}
