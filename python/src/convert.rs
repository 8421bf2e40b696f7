//! Conversions between Python's values and the library's: arrays of any
//! float dtype and layout (or lists) to `f64` vectors, checked; names to the
//! library's enums; serialisable values to Python objects; errors to
//! Python's exceptions.

use std::path::Path;

use clap::ValueEnum;
use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{
    PyException, PyFileExistsError, PyFileNotFoundError, PyIsADirectoryError, PyMemoryError,
    PyNotADirectoryError, PyOSError, PyPermissionError, PyTypeError, PyValueError,
};
use pyo3::prelude::*;
use serde::Serialize;

use mckibben::eval::Backend;
use mckibben::fit::problem::Overshoot;
use mckibben::model::{Family, Loop, Switching};
use mckibben::names::UnknownName;
use mckibben::optim::Algorithm;

/// A value as a message shows it: its type and repr (`str '0.1'`,
/// `bool True`), a long repr cut short.
pub fn given(obj: &Bound<'_, PyAny>) -> String {
    if obj.is_none() {
        return "None".into();
    }
    let ty = obj
        .get_type()
        .name()
        .map_or_else(|_| "object".into(), |n| n.to_string());
    let repr = obj.repr().map_or_else(|_| "?".into(), |r| r.to_string());
    let repr = match repr.char_indices().nth(60) {
        Some((at, _)) => format!("{}...", &repr[..at]),
        None => repr,
    };
    format!("{ty} {repr}")
}

/// Whether `e`, raised while an argument was read, must reach the caller as
/// it is: an interrupt (`KeyboardInterrupt`, `SystemExit`: no `Exception`)
/// or a `MemoryError`, which a message on the argument would turn into a
/// wrong value (Ctrl-C during a pandas column's `__array__` read as "not an
/// array of numbers").
pub fn must_pass(e: &PyErr, py: Python<'_>) -> bool {
    !e.is_instance_of::<PyException>(py) || e.is_instance_of::<PyMemoryError>(py)
}

/// The values of a numeric array in C order, with its shape.
pub struct Floats {
    pub values: Vec<f64>,
    pub shape: Vec<usize>,
}

/// `obj` (a NumPy array of any real dtype and layout, a list, a scalar) as
/// a C-contiguous `float64` array: `obj` itself when it is one, else a
/// copy. Complex numbers, booleans, text, `None` and objects are a
/// `TypeError`; a ragged list or a single number a `ValueError`. `what`
/// names the argument in messages.
pub fn contiguous<'py>(
    obj: &Bound<'py, PyAny>,
    what: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let np = obj.py().import("numpy")?;
    refuse_masked(&np, obj, what)?;
    let array = np
        .call_method1("asarray", (obj,))
        .map_err(|e| match must_pass(&e, obj.py()) {
            true => e,
            false => PyValueError::new_err(format!("{what}: not an array of numbers ({e})")),
        })?;
    let ndim: usize = array.getattr("ndim")?.extract()?;
    let dtype = array.getattr("dtype")?;
    let kind: String = dtype.getattr("kind")?.extract()?;
    let real = matches!(kind.as_str(), "f" | "i" | "u");
    // A str, `None` or another object NumPy makes a 0-d array of: not an
    // array at all.
    if ndim == 0 && !real {
        return Err(PyTypeError::new_err(format!(
            "{what} must be an array of numbers (a NumPy array or a list), got {}",
            given(obj)
        )));
    }
    // `ascontiguousarray` makes a single number a one-sample array: a
    // scalar passed for a series would then run as one.
    if ndim == 0 {
        return Err(PyValueError::new_err(format!(
            "{what}: a single number, not an array of samples"
        )));
    }
    if !real {
        let name: String = dtype.getattr("name")?.extract()?;
        return Err(PyTypeError::new_err(format!(
            "{what}: expected real numbers (a float or integer array or list), got dtype {name}"
        )));
    }
    let contiguous = np.call_method1("ascontiguousarray", (array, "float64"))?;
    Ok(contiguous.cast_into::<PyArrayDyn<f64>>()?)
}

/// A NumPy masked array with a masked value is an error naming the first:
/// `asarray` would hand on the number under the mask, and a free run needs
/// a number at every sample. One with nothing masked is its data.
fn refuse_masked(np: &Bound<'_, PyModule>, obj: &Bound<'_, PyAny>, what: &str) -> PyResult<()> {
    let ma = np.getattr("ma")?;
    if !obj.is_instance(&ma.getattr("MaskedArray")?)? {
        return Ok(());
    }
    let mask = ma.call_method1("getmaskarray", (obj,))?;
    if !mask.call_method0("any")?.extract::<bool>()? {
        return Ok(());
    }
    let first: usize = mask
        .call_method0("ravel")?
        .call_method0("argmax")?
        .extract()?;
    let shape: Vec<usize> = mask.getattr("shape")?.extract()?;
    Err(PyValueError::new_err(format!(
        "{what}{} is masked: a free run needs a number at every sample; fill the masked \
         values (`.filled(...)`) or cut the record before them",
        index_text(first, &shape)
    )))
}

/// The index of the `i`-th value of a row-major array of `shape`, as
/// Python writes it: `[i]`, or `[row, column]`.
fn index_text(i: usize, shape: &[usize]) -> String {
    if shape.len() == 2 {
        format!("[{}, {}]", i / shape[1].max(1), i % shape[1].max(1))
    } else {
        format!("[{i}]")
    }
}

/// [`contiguous`]'s values, copied.
pub fn floats(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Floats> {
    let array = contiguous(obj, what)?;
    let shape = array.shape().to_vec();
    let values = array.readonly().as_slice()?.to_vec();
    Ok(Floats { values, shape })
}

/// The first NaN or infinite value, as an error naming its index.
fn check_finite(values: &[f64], shape: &[usize], what: &str) -> PyResult<()> {
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "{what}{} is {}: every value must be a finite number",
            index_text(i, shape),
            values[i]
        )));
    }
    Ok(())
}

/// A one-dimensional, non-empty, finite series (`u`, `y`).
pub fn series(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
    let Floats { values, shape } = floats(obj, what)?;
    if shape.len() != 1 {
        return Err(PyValueError::new_err(format!(
            "{what} must be one-dimensional (one value per sample), got shape {}",
            shape_text(&shape)
        )));
    }
    if values.is_empty() {
        return Err(PyValueError::new_err(format!("{what} is empty")));
    }
    check_finite(&values, &shape, what)?;
    Ok(values)
}

/// Candidates as rows of `d` values: an `(N, d)` array (N ≥ 1), or one
/// vector of `d`; returns the rows (row-major), N, and whether a single
/// vector was given. `names` name the `d` columns in messages.
pub fn rows(
    obj: &Bound<'_, PyAny>,
    names: &[String],
    what: &str,
) -> PyResult<(Vec<f64>, usize, bool)> {
    let (view, n, single) = rows_view(obj, names, what)?;
    Ok((view.as_slice()?.to_vec(), n, single))
}

/// As [`rows`], without copying an array that is already C-contiguous
/// `float64`: a read-only view of it.
pub fn rows_view<'py>(
    obj: &Bound<'py, PyAny>,
    names: &[String],
    what: &str,
) -> PyResult<(PyReadonlyArrayDyn<'py, f64>, usize, bool)> {
    let d = names.len();
    let array = contiguous(obj, what)?;
    let shape = array.shape().to_vec();
    let (n, single) = match shape.as_slice() {
        [k] if *k == d => (1, true),
        [_, k] if *k == d => (shape[0], false),
        _ => {
            return Err(PyValueError::new_err(format!(
                "{what} must be an (N, {d}) array of candidates, one column per parameter ({}), \
                 or one vector of {d}; got shape {}",
                names.join(", "),
                shape_text(&shape)
            )));
        }
    };
    if n == 0 {
        return Err(PyValueError::new_err(format!(
            "{what} holds no candidate (N = 0)"
        )));
    }
    let view = array.readonly();
    check_finite(view.as_slice()?, &shape, what)?;
    Ok((view, n, single))
}

/// A shape as Python prints it: `(3,)`, `(2, 4)`.
pub fn shape_text(shape: &[usize]) -> String {
    match shape {
        [k] => format!("({k},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|k| k.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// A sample time (`what` names it): finite and positive.
pub fn sample_time(dt: f64, what: &str) -> PyResult<f64> {
    if dt.is_finite() && dt > 0.0 {
        // As the commands' --dt and --resample: a nanosecond to a day.
        mckibben::data::sample_time(dt)
            .map_err(|why| PyValueError::new_err(format!("{what}: {why}")))
    } else {
        Err(PyValueError::new_err(format!(
            "{what} must be a positive number of seconds, got {dt}"
        )))
    }
}

/// A hysteretic family by name (`classic`, `generalized`), given as the
/// argument `what`.
pub fn family(name: &str, what: &str) -> PyResult<Family> {
    match name
        .parse::<Family>()
        .map_err(|e| PyValueError::new_err(e.to_string()))?
    {
        Family::Linear => Err(PyValueError::new_err(format!(
            "{what} must be a hysteresis model, classic or generalized \
             (the linear model is fitted by least squares: `mckibben identify`)"
        ))),
        f => Ok(f),
    }
}

/// An update rule by name (`ga`, `mfa`, `pso`, `de`).
pub fn algorithm(name: &str) -> PyResult<Algorithm> {
    name.parse()
        .map_err(|e: UnknownName| PyValueError::new_err(e.to_string()))
}

/// A clap value (`--backend`, `--loop`) by name, its error listing the choices.
fn choice<T: ValueEnum>(name: &str, what: &str) -> PyResult<T> {
    T::from_str(name, true).map_err(|_| {
        let names: Vec<String> = T::value_variants()
            .iter()
            .filter_map(|v| v.to_possible_value().map(|p| p.get_name().to_string()))
            .collect();
        PyValueError::new_err(format!(
            "unknown {what} `{name}`: expected one of {}",
            names.join(", ")
        ))
    })
}

/// A backend by name (`auto`, `cpu`, `gpu`).
pub fn backend(name: &str) -> PyResult<Backend> {
    choice(name, "backend")
}

/// A loop class by name (`bounded`, `free`).
pub fn loop_shape(name: &str) -> PyResult<Loop> {
    choice(name, "loop")
}

/// Whether a fit admits a loop whose update overshoots (`refuse`,
/// `allow`), as `fit --overshoot`.
pub fn overshoot(name: &str) -> PyResult<Overshoot> {
    choice(name, "overshoot")
}

/// Where a generalized fit's sign terms switch (`starts`, `search`,
/// `mean`, `zero`), as `fit --switch`.
pub fn switching(name: &str) -> PyResult<Switching> {
    choice(name, "switch")
}

/// `value` as the Python objects `json.loads` makes of its JSON (what
/// `--json` prints): dicts, lists, floats, ints, strings, None.
pub fn to_python<'py>(py: Python<'py>, value: &impl Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| PyValueError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A library error about the caller's input: `ValueError`, its causes
/// joined as the command prints them.
pub fn value_error(e: anyhow::Error) -> PyErr {
    PyValueError::new_err(in_python_terms(&format!("{e:#}")))
}

/// A library error while computing: `RuntimeError`.
pub fn runtime_error(e: anyhow::Error) -> PyErr {
    pyo3::exceptions::PyRuntimeError::new_err(in_python_terms(&format!("{e:#}")))
}

/// A library error reading a file: the `OSError` of its cause when an I/O
/// error is its cause ([`os_error`]), else `ValueError` (the file's content).
fn file_error(e: anyhow::Error) -> PyErr {
    let message = in_python_terms(&format!("{e:#}"));
    match e.chain().find_map(|c| c.downcast_ref::<std::io::Error>()) {
        Some(io) => os_error(io, message),
        None => PyValueError::new_err(message),
    }
}

/// A library error reading or writing the file at `path`: where an error the
/// OS gave with an errno is its cause, what Python's `open` raises
/// ([`open_error`]); else [`file_error`].
pub fn file_error_at(e: anyhow::Error, path: &Path) -> PyErr {
    e.chain()
        .find_map(|c| c.downcast_ref::<std::io::Error>())
        .and_then(|io| open_error(io, path))
        .unwrap_or_else(|| file_error(e))
}

/// `io`, an error the OS gave reading or writing `path`, exactly as
/// Python's `open` raises it: the errno's `OSError` subclass with `errno`,
/// `strerror` (the OS's words) and `filename` set, `[Errno 2] No such file
/// or directory: 'x.csv'` (a script's `except OSError as e: e.filename`
/// read `None`); `None` where the OS gave no errno.
pub fn open_error(io: &std::io::Error, path: &Path) -> Option<PyErr> {
    let errno = io.raw_os_error()?;
    let words = io.to_string();
    // Rust's text of an OS error ends in " (os error N)".
    let words = words
        .strip_suffix(&format!(" (os error {errno})"))
        .unwrap_or(&words)
        .to_string();
    let filename = path.to_string_lossy().into_owned();
    Some(PyOSError::new_err((errno, words, filename)))
}

/// The I/O error `io` as Python's `open` raises it: the `OSError` subclass
/// of its errno (`FileNotFoundError`, `PermissionError`,
/// `IsADirectoryError`, …, with `errno` set), or of its kind where the OS
/// gave none; `message` (the library's: the file and the cause) its text.
/// A folder read as a file was a plain `OSError`, which an `except
/// IsADirectoryError` missed.
pub fn os_error(io: &std::io::Error, message: String) -> PyErr {
    use std::io::ErrorKind;
    if let Some(errno) = io.raw_os_error() {
        // OSError(errno, text) makes the errno's subclass itself.
        return PyOSError::new_err((errno, message));
    }
    match io.kind() {
        ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
        ErrorKind::PermissionDenied => PyPermissionError::new_err(message),
        ErrorKind::IsADirectory => PyIsADirectoryError::new_err(message),
        ErrorKind::NotADirectory => PyNotADirectoryError::new_err(message),
        ErrorKind::AlreadyExists => PyFileExistsError::new_err(message),
        _ => PyOSError::new_err(message),
    }
}

/// The library's messages name the command's flags (`--time-budget must be
/// at least 0 seconds`); a flag that stands for one of the package's
/// keyword arguments is named as that argument instead: `` `time_budget` ``,
/// and a flag with its value's placeholder as `` `input=COL` ``. Flags the
/// package has no argument for stay as they are.
pub fn in_python_terms(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(at) = rest.find("--") {
        out.push_str(&rest[..at]);
        let after = &rest[at + 2..];
        // A flag starts a word: `--` inside one is a path's or a name's
        // (`run--seed.json`), left as it is; so is one inside a code span,
        // which quotes a command (`diagnose --effects`).
        let starts_word = out
            .chars()
            .next_back()
            .is_none_or(|c| c.is_whitespace() || "(`'\",;:[".contains(c));
        let quoted = out.matches('`').count() % 2 == 1;
        // A code span of the flag alone (`` `--pop` ``) is the keyword's
        // own: it takes no second pair of backticks.
        let alone = quoted && out.ends_with('`');
        if !starts_word || (quoted && !alone) {
            out.push_str("--");
            rest = after;
            continue;
        }
        let len = after
            .find(|c: char| !(c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-'))
            .unwrap_or(after.len());
        let flag = &after[..len];
        let Some(keyword) = keyword_of(flag) else {
            out.push_str("--");
            rest = after;
            continue;
        };
        rest = &after[len..];
        let code = |text: String| match alone {
            true => text,
            false => format!("`{text}`"),
        };
        // A value after `=` (`--time=t`, `--loop=free`) is the argument's:
        // `time="t"`, a number bare.
        if let Some(given) = rest.strip_prefix('=') {
            let end = given
                .find(|c: char| c.is_whitespace() || matches!(c, ',' | ';' | ')'))
                .unwrap_or(given.len());
            let value = &given[..end];
            match value.parse::<f64>() {
                Ok(_) => out.push_str(&code(format!("{keyword}={value}"))),
                Err(_) => out.push_str(&code(format!("{keyword}=\"{value}\""))),
            }
            rest = &given[end..];
            continue;
        }
        // A placeholder (`--input COL`) or a number (`--refine-rounds 8`)
        // joins the keyword as its value.
        let placeholder = rest.strip_prefix(' ').and_then(|r| {
            let upper = r.find(|c: char| !c.is_ascii_uppercase()).unwrap_or(r.len());
            let number = r
                .find(|c: char| !(c.is_ascii_digit() || c == '.'))
                .unwrap_or(r.len());
            let whole = |n: usize| !r[n..].starts_with(|c: char| c.is_alphanumeric());
            if upper >= 2 {
                Some(&r[..upper])
            } else if number >= 1 && r.starts_with(|c: char| c.is_ascii_digit()) && whole(number) {
                Some(r[..number].trim_end_matches('.'))
            } else {
                None
            }
        });
        // One of the flag's named values (`--switch starts`) is a string.
        let named = rest.strip_prefix(' ').and_then(|r| {
            let end = r
                .find(|c: char| !(c.is_ascii_lowercase() || c == '-'))
                .unwrap_or(r.len());
            named_values(flag).contains(&&r[..end]).then(|| &r[..end])
        });
        match (placeholder, named) {
            (Some(value), _) => {
                out.push_str(&code(format!("{keyword}={value}")));
                rest = &rest[1 + value.len()..];
            }
            (None, Some(value)) => {
                out.push_str(&code(format!("{keyword}=\"{value}\"")));
                rest = &rest[1 + value.len()..];
            }
            (None, None) => out.push_str(&code(keyword)),
        }
    }
    out.push_str(rest);
    one_keyword_once(out)
}

/// `text` with a keyword named twice in a row (`` `bounds` or `bounds` ``,
/// `` `bounds`, `bounds` ``, `` `bounds` and `bounds` ``, where `--bound`
/// and `--fix` became one argument) named once.
fn one_keyword_once(mut text: String) -> String {
    for joint in ["` or `", "`, `", "` and `"] {
        let mut from = 0;
        while let Some(at) = text[from..].find(joint).map(|i| from + i) {
            let before = text[..at].rfind('`').map(|j| &text[j + 1..at]);
            let after = &text[at + joint.len()..];
            match before {
                Some(keyword) if after.starts_with(&format!("{keyword}`")) => {
                    let cut = joint.len() + keyword.len();
                    text.replace_range(at + 1..at + 1 + cut, "");
                }
                _ => from = at + 1,
            }
        }
    }
    text
}

/// The values a flag takes by name, which its keyword takes as strings.
fn named_values(flag: &str) -> &'static [&'static str] {
    match flag {
        "switch" => &["search", "starts", "mean", "zero"],
        "loop" => &["bounded", "free"],
        "algo" => &["ga", "mfa", "pso", "de"],
        "backend" => &["auto", "cpu", "gpu"],
        "model" | "baseline" => &["classic", "generalized", "linear"],
        _ => &[],
    }
}

/// The keyword argument of `fit`, `read_csv`, `diagnose`, `twin` or
/// `control` that the command's flag `--flag` sets, if there is one.
fn keyword_of(flag: &str) -> Option<String> {
    const SAME: &[&str] = &[
        "pop",
        "gens",
        "algo",
        "seed",
        "backend",
        "effects",
        "free-n",
        "loop",
        "thesis-flow",
        "target-sse",
        "time-budget",
        "stall",
        "input",
        "output",
        "time",
        "resample",
        "split-gaps",
        "dt",
        "seeds",
        "generations",
        "scratch-seeds",
        "max-effects",
        "baseline",
        "model",
        "refine-rounds",
        "blocks",
        "switch",
        "experiment",
        "load",
        "freq",
        "controller",
        "design-data",
        "design-columns",
        "design-load",
        "hysteresis-scale",
        "robustness",
        "tuned-gains",
        "horizon",
        "r-move",
        "reference",
        "warmup",
        "duration",
        "steady-from",
    ];
    let keyword = match flag {
        "from" => "start",
        "effect" => "effects",
        "bound" | "fix" => "bounds",
        f if SAME.contains(&f) => f,
        _ => return None,
    };
    Some(keyword.replace('-', "_"))
}
