//! Experiments: the library's [`mckibben::data::Trace`] as a Python class,
//! and its CSV reader.

use std::path::PathBuf;

use numpy::{PyArray1, PyReadonlyArray1, ToPyArray};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};

use mckibben::data::csv::{DataError, Gaps, ReadOptions, read_traces_with_notes};
use mckibben::model::file::ReadSettings;

use crate::args::real;
use crate::convert::{in_python_terms, open_error, os_error, sample_time, series, value_error};
use crate::named;

/// One recorded experiment on a uniform time base: the model's input and
/// output columns and any other columns the file carried. `read_csv`
/// returns it; `Trace(input, output, dt)` makes one from arrays.
#[pyclass(module = "mckibben", frozen)]
#[derive(Clone)]
pub struct Trace {
    pub inner: mckibben::data::Trace,
    /// How it was read (`read_csv`'s time column, resampling and gap
    /// splitting; the time column's name alone for arrays): a model fitted
    /// on it records them, so that `simulate --from` reads a file as the
    /// model's data were read.
    pub read: ReadSettings,
}

#[pymethods]
impl Trace {
    /// A trace on the time base `t = k·dt` from two series of equal length.
    /// The three column names are the ones a model fitted on it records
    /// and `simulate --from` reads, so they must be distinct and not empty.
    #[new]
    #[pyo3(signature = (input, output, dt, input_name = "pressure", output_name = "displacement", source = "python", time_name = "t"))]
    fn new(
        input: &Bound<'_, PyAny>,
        output: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = named::dt)] dt: f64,
        #[pyo3(from_py_with = named::input_name)] input_name: &str,
        #[pyo3(from_py_with = named::output_name)] output_name: &str,
        #[pyo3(from_py_with = named::source)] source: &str,
        #[pyo3(from_py_with = named::time_name)] time_name: &str,
    ) -> PyResult<Trace> {
        column_names(time_name, input_name, output_name)?;
        let names = ArrayNames {
            input: "input",
            output: "output",
            dt: "dt",
        };
        let mut inner = arrays_trace(input, output, dt, source, &names)?;
        inner.input_name = input_name.to_string();
        inner.output_name = output_name.to_string();
        inner.time_name = time_name.to_string();
        Ok(Trace {
            inner,
            read: timed_only(time_name),
        })
    }

    /// Where the trace came from (a path, `file.csv[2]` for a piece).
    #[getter]
    fn source(&self) -> &str {
        &self.inner.source
    }

    /// Time in seconds.
    #[getter]
    fn t<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.t.to_pyarray(py)
    }

    /// The model input.
    #[getter]
    fn input<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.input.to_pyarray(py)
    }

    /// The measured output.
    #[getter]
    fn output<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.output.to_pyarray(py)
    }

    /// The time column's name (`t` for a trace made from arrays).
    #[getter]
    fn time_name(&self) -> &str {
        &self.inner.time_name
    }

    /// The input column's name (`pressure` for a trace made from arrays,
    /// read as MPa: the shipped data's convention).
    #[getter]
    fn input_name(&self) -> &str {
        &self.inner.input_name
    }

    /// The output column's name (`displacement` for a trace made from
    /// arrays, read as mm: the shipped data's convention).
    #[getter]
    fn output_name(&self) -> &str {
        &self.inner.output_name
    }

    /// The sample time: the mean step of the time base (s).
    #[getter]
    fn dt(&self) -> f64 {
        self.inner.dt()
    }

    /// The other columns, by name.
    #[getter]
    fn extra<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (name, v) in &self.inner.extra {
            d.set_item(name, v.to_pyarray(py))?;
        }
        Ok(d)
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    /// Pickles as its columns and how it was read, so that a trace crosses
    /// to worker processes and `copy.deepcopy` copies it: every sample to
    /// the bit, its names, source and read settings as they were (a model
    /// fitted on the copy records the same).
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let t = &self.inner;
        let extra = PyList::empty(py);
        for (name, v) in &t.extra {
            extra.append((name, v.to_pyarray(py)))?;
        }
        let read = serde_json::to_string(&self.read)
            .map_err(|e| crate::convert::runtime_error(e.into()))?;
        let state = (
            &t.source,
            &t.time_name,
            t.t.to_pyarray(py),
            &t.input_name,
            t.input.to_pyarray(py),
            &t.output_name,
            t.output.to_pyarray(py),
            extra,
            &t.cut_from,
            read,
        )
            .into_pyobject(py)?;
        Ok((py.get_type::<Trace>().getattr("_from_state")?, state))
    }

    /// The trace `__reduce__` pickled.
    #[classmethod]
    #[allow(clippy::too_many_arguments)]
    fn _from_state(
        _class: &Bound<'_, pyo3::types::PyType>,
        source: String,
        time_name: String,
        t: PyReadonlyArray1<'_, f64>,
        input_name: String,
        input: PyReadonlyArray1<'_, f64>,
        output_name: String,
        output: PyReadonlyArray1<'_, f64>,
        extra: Vec<(String, PyReadonlyArray1<'_, f64>)>,
        cut_from: Option<String>,
        read: &str,
    ) -> PyResult<Trace> {
        let read = serde_json::from_str(read).map_err(|e| value_error(e.into()))?;
        Ok(Trace {
            inner: mckibben::data::Trace {
                source,
                time_name,
                t: t.as_slice()?.to_vec(),
                input_name,
                input: input.as_slice()?.to_vec(),
                output_name,
                output: output.as_slice()?.to_vec(),
                extra: extra
                    .into_iter()
                    .map(|(name, v)| Ok((name, v.as_slice()?.to_vec())))
                    .collect::<PyResult<_>>()?,
                cut_from,
            },
            read,
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "Trace({:?}: {} samples at dt = {} s, {} -> {})",
            self.inner.source,
            self.inner.len(),
            self.inner.dt(),
            self.inner.input_name,
            self.inner.output_name
        )
    }
}

/// Checks that the time, input and output columns' names could head one
/// CSV file that reads back: none empty, no two the same.
fn column_names(time: &str, input: &str, output: &str) -> PyResult<()> {
    let named = [
        ("time_name", time),
        ("input_name", input),
        ("output_name", output),
    ];
    for (i, (arg, name)) in named.iter().enumerate() {
        if name.trim().is_empty() {
            return Err(PyValueError::new_err(format!(
                "{arg} is empty: a column needs a name"
            )));
        }
        if let Some((other, _)) = named[..i].iter().find(|(_, n)| n == name) {
            return Err(PyValueError::new_err(format!(
                "{other} and {arg} are both {name:?}: a file could not tell the columns apart"
            )));
        }
    }
    Ok(())
}

/// How a trace made from arrays counts as read: its time column's name.
pub fn timed_only(time_name: &str) -> ReadSettings {
    ReadSettings {
        time: Some(time_name.to_string()),
        ..ReadSettings::default()
    }
}

/// The names of a trace's input, output and sample time in messages: the
/// arguments they were passed as.
pub struct ArrayNames<'a> {
    pub input: &'a str,
    pub output: &'a str,
    pub dt: &'a str,
}

/// The experiments `fit` and `identify` take as `u` (with `y` and `dt`):
/// one (a `Trace`, or arrays `u` and `y` sampled every `dt`), or a list of
/// them (a list, or a tuple of `Trace`s or `(u, y, dt)` tuples), as
/// `mckibben fit a.csv b.csv` takes files.
pub struct Experiments {
    pub traces: Vec<mckibben::data::Trace>,
    /// How the first was read.
    pub read: ReadSettings,
    /// The list, where one was given: a record the library refuses is named
    /// by its place in it ([`located`]).
    pub listed: Option<Records>,
}

pub fn experiments(
    u: &Bound<'_, PyAny>,
    y: Option<&Bound<'_, PyAny>>,
    dt: Option<f64>,
) -> PyResult<Experiments> {
    // A tuple of Traces or of (u, y, dt) tuples is such a list; a tuple of
    // numbers (one input) is not.
    let experiment = |i: Bound<'_, PyAny>| {
        i.cast::<Trace>().is_ok() || i.cast::<PyTuple>().is_ok_and(|t| t.len() == 3)
    };
    let traces_only = u
        .cast::<PyTuple>()
        .is_ok_and(|t| !t.is_empty() && t.iter().all(experiment));
    let listed = match u.cast::<PyList>().is_ok() || traces_only {
        true if y.is_none() && dt.is_none() => Some(traces(u, "u")?),
        _ => None,
    };
    let (traces, read) = match &listed {
        Some(records) => (records.traces.clone(), records.read.clone()),
        None => {
            let (trace, read) = data_arg(u, y, dt)?;
            (vec![trace], read)
        }
    };
    Ok(Experiments {
        traces,
        read,
        listed,
    })
}

/// `fit`'s and `Evaluator`'s `u`, `y` and `dt`.
pub const UY: ArrayNames<'static> = ArrayNames {
    input: "u",
    output: "y",
    dt: "dt",
};

/// A trace from two series and a sample time, every value checked, named
/// in messages as `names` says.
pub fn arrays_trace(
    input: &Bound<'_, PyAny>,
    output: &Bound<'_, PyAny>,
    dt: f64,
    source: &str,
    names: &ArrayNames<'_>,
) -> PyResult<mckibben::data::Trace> {
    let u = series(input, names.input)?;
    let y = series(output, names.output)?;
    if u.len() != y.len() {
        return Err(PyValueError::new_err(format!(
            "{} and {} differ in length: {} and {} samples",
            names.input,
            names.output,
            u.len(),
            y.len()
        )));
    }
    if u.len() < 2 {
        return Err(PyValueError::new_err(
            "a trace needs at least 2 samples (one time step)",
        ));
    }
    // At most a day a step: the times `k·dt` stay finite.
    let dt = sample_time(dt, names.dt)?;
    Ok(mckibben::data::Trace::uniform(source, dt, u, y))
}

/// The experiment an API call is about, and how it was read: a `Trace`
/// (then `y` and `dt` stay `None`), or the arrays `u`, `y` and the sample
/// time `dt`.
pub fn data_arg(
    u: &Bound<'_, PyAny>,
    y: Option<&Bound<'_, PyAny>>,
    dt: Option<f64>,
) -> PyResult<(mckibben::data::Trace, ReadSettings)> {
    if let Ok(trace) = u.cast::<Trace>() {
        if y.is_some() || dt.is_some() {
            return Err(PyValueError::new_err(
                "pass either a Trace, or the arrays u and y with dt, not both",
            ));
        }
        let trace = trace.get();
        return Ok((trace.inner.clone(), trace.read.clone()));
    }
    // Said for what is missing, and for a list of Traces where one
    // experiment is taken (an Evaluator scores one record).
    // Only a list or a tuple is looked into: a generator would lose its
    // first item to the look.
    let listed = (u.is_instance_of::<PyList>() || u.is_instance_of::<PyTuple>())
        && u.get_item(0)
            .is_ok_and(|first| first.cast::<Trace>().is_ok());
    match (y, dt) {
        (Some(_), _) | (_, Some(_)) if listed => Err(PyValueError::new_err(
            "u is a list of Traces, each with its own output and sample time: leave y and dt out",
        )),
        _ if listed => Err(PyValueError::new_err(
            "u is a list of Traces, and this takes one experiment: pass one Trace, or the \
             arrays u and y with dt",
        )),
        (Some(y), Some(dt)) => {
            let trace = arrays_trace(u, y, dt, "python", &UY)?;
            let read = timed_only(&trace.time_name);
            Ok((trace, read))
        }
        (Some(_), None) => Err(PyValueError::new_err(
            "give the sample time dt with the arrays u and y (or pass a Trace)",
        )),
        (None, Some(_)) => Err(PyValueError::new_err(
            "give the output y with the input u and dt (or pass a Trace)",
        )),
        (None, None) => Err(PyValueError::new_err(
            "give the output y and the sample time dt with the input u (or pass a Trace)",
        )),
    }
}

/// A data file's error as Python's exception: the `OSError` `open` raises
/// when it cannot be read ([`open_error`], or [`os_error`] where the OS gave
/// no errno), `ValueError` for its content; the message is the library's
/// (file, line, column, what).
fn data_error(e: DataError) -> PyErr {
    let message = in_python_terms(&e.to_string());
    match &e {
        DataError::Io { path, source } => {
            open_error(source, path).unwrap_or_else(|| os_error(source, message))
        }
        _ => PyValueError::new_err(message),
    }
}

/// Reads an experiment CSV file with the library's reader (README.md, "Data
/// format"): columns `time`, `input`, `output` by name. A non-uniform time
/// base is an error unless `resample` (a step in seconds: every column
/// interpolated onto it) or `split_gaps` (cut at every gap and backward
/// jump; then a list of traces is returned), or both (cut only where time
/// runs back or stands still, each piece interpolated across its gaps).
/// The reader's notes (cuts, dropped pieces, text columns) become
/// `UserWarning`s.
#[pyfunction]
#[pyo3(signature = (path, input = "pressure", output = "displacement", time = None, resample = None, split_gaps = false, dt = None))]
#[allow(clippy::too_many_arguments)]
pub fn read_csv<'py>(
    py: Python<'py>,
    #[pyo3(from_py_with = named::csv_path)] path: PathBuf,
    #[pyo3(from_py_with = named::input)] input: &str,
    #[pyo3(from_py_with = named::output)] output: &str,
    #[pyo3(from_py_with = named::time)] time: Option<&str>,
    #[pyo3(from_py_with = named::resample)] resample: Option<f64>,
    #[pyo3(from_py_with = named::split_gaps)] split_gaps: bool,
    #[pyo3(from_py_with = named::dt_opt)] dt: Option<f64>,
) -> PyResult<Bound<'py, PyAny>> {
    // As the command refuses --time beside --dt: one names the file's
    // clock, the other the spacing of a file without one.
    if time.is_some() && dt.is_some() {
        return Err(PyValueError::new_err(
            "time and dt exclude each other: time names the file's clock column, dt the \
             spacing of the rows of a file without one",
        ));
    }
    let time = time.unwrap_or("t");
    // The library's reader would read one column as two (`input="t"` gave
    // time and input the same values).
    let columns = [("time", time), ("input", input), ("output", output)];
    for (i, (arg, name)) in columns.iter().enumerate() {
        if let Some((other, _)) = columns[..i].iter().find(|(_, n)| n == name) {
            return Err(PyValueError::new_err(format!(
                "{other} and {arg} are both {name:?}: each must name a column of its own"
            )));
        }
    }
    let gaps = match (resample, split_gaps) {
        (Some(dt), true) => Gaps::SplitResample(sample_time(dt, "resample")?),
        (Some(dt), false) => Gaps::Resample(sample_time(dt, "resample")?),
        (None, true) => Gaps::Split,
        (None, false) => Gaps::Reject,
    };
    let dt = dt.map(|dt| sample_time(dt, "dt")).transpose()?;
    let opts = ReadOptions {
        time: time.to_string(),
        dt,
        untimed_dt: None,
        input: input.to_string(),
        output: output.to_string(),
        gaps,
    };
    let (traces, notes) = py
        .detach(|| read_traces_with_notes(&path, &opts))
        .map_err(data_error)?;
    let warn = py.import("warnings")?;
    for note in notes {
        warn.call_method1("warn", (in_python_terms(&note),))?;
    }
    let read = ReadSettings {
        time: Some(time.to_string()),
        resample,
        split_gaps,
        dt,
    };
    let mut traces: Vec<Trace> = traces
        .into_iter()
        .map(|inner| Trace {
            inner,
            read: read.clone(),
        })
        .collect();
    if split_gaps {
        return Ok(pyo3::types::PyList::new(py, traces)?.into_any());
    }
    let one = traces
        .pop()
        .ok_or_else(|| PyValueError::new_err(format!("{}: no samples", path.display())))?;
    Ok(Bound::new(py, one)?.into_any())
}

/// The records of an argument that lists experiments (`fit`'s `u`,
/// `diagnose`'s `datasets` and `transfer`): the traces, how the first was
/// read, and each one's place in the list (`datasets[1]`; none for a lone
/// `Trace`).
pub struct Records {
    pub traces: Vec<mckibben::data::Trace>,
    pub read: ReadSettings,
    places: Vec<String>,
}

impl Records {
    /// Each trace with its place in the list, a lone `Trace` with the
    /// argument's name `what`.
    pub fn placed<'a>(
        &'a self,
        what: &'a str,
    ) -> impl Iterator<Item = (&'a mckibben::data::Trace, &'a str)> {
        let place = move |i| self.places.get(i).map_or(what, String::as_str);
        self.traces
            .iter()
            .enumerate()
            .map(move |(i, t)| (t, place(i)))
    }
}

/// The traces of `datasets` (a `Trace`, or a list whose items are each a
/// `Trace` or a `(u, y, dt)` tuple), `what` naming the argument; a tuple's
/// source is its place (`transfer[0]`).
pub fn traces(datasets: &Bound<'_, PyAny>, what: &str) -> PyResult<Records> {
    if let Ok(t) = datasets.cast::<Trace>() {
        let t = t.get();
        return Ok(Records {
            traces: vec![t.inner.clone()],
            read: t.read.clone(),
            places: Vec::new(),
        });
    }
    let wrong = || {
        PyTypeError::new_err(format!(
            "{what} must be a Trace or a list of them (read_csv), or of (u, y, dt) tuples"
        ))
    };
    let mut places = Vec::new();
    let mut out = Vec::new();
    let mut first_read = None;
    for (i, item) in datasets.try_iter().map_err(|_| wrong())?.enumerate() {
        let item = item?;
        if let Ok(t) = item.cast::<Trace>() {
            let t = t.get();
            out.push(t.inner.clone());
            first_read.get_or_insert_with(|| t.read.clone());
        } else if let Ok(tuple) = item.cast::<PyTuple>()
            && tuple.len() == 3
        {
            let at = |k: usize| format!("{what}[{i}][{k}]");
            let names = ArrayNames {
                input: &at(0),
                output: &at(1),
                dt: &at(2),
            };
            let dt = real(&tuple.get_item(2)?, names.dt)?;
            let trace = arrays_trace(
                &tuple.get_item(0)?,
                &tuple.get_item(1)?,
                dt,
                &format!("{what}[{i}]"),
                &names,
            )?;
            first_read.get_or_insert_with(|| timed_only(&trace.time_name));
            out.push(trace);
        } else {
            return Err(wrong());
        }
        places.push(format!("{what}[{i}]"));
    }
    match first_read {
        Some(read) => Ok(Records {
            traces: out,
            read,
            places,
        }),
        None => Err(PyValueError::new_err(format!(
            "{what} is empty: give at least one experiment"
        ))),
    }
}

/// A library error about the records, with the record at fault named by
/// its place in its list as well as by its source: the library names it by
/// its source alone, which several traces may share (`python`, the same
/// file). The record is the first whose own checks
/// ([`mckibben::fit::records::Records::of`]) fail with the same cause.
pub fn located(e: anyhow::Error, lists: &[&Records]) -> PyErr {
    let cause = e.root_cause().to_string();
    for records in lists {
        for (t, place) in records.traces.iter().zip(&records.places) {
            let alone = mckibben::fit::records::Records::of(std::slice::from_ref(t), None);
            if !alone.is_err_and(|a| a.root_cause().to_string() == cause) {
                continue;
            }
            return placed(cause, t, place);
        }
    }
    // A cause about two records (the same samples, other steps, other
    // columns) names both by their sources, which both may share (`python
    // and python hold the same samples`): the same checks on the records
    // named by their places as well say which.
    for records in lists {
        let named: Vec<mckibben::data::Trace> = records
            .traces
            .iter()
            .zip(&records.places)
            .map(|(t, place)| {
                let mut t = t.clone();
                if t.source != *place {
                    t.source = format!("{place} ({})", t.source);
                }
                t
            })
            .collect();
        let again =
            mckibben::data::mixed_steps(&named).or_else(|| mckibben::data::unlike_records(&named));
        if let Some(why) = again {
            return PyValueError::new_err(in_python_terms(&why));
        }
    }
    value_error(e)
}

/// An error `cause` about the record `t`, named by its `place` in its list
/// as well as by its source.
pub fn placed(cause: String, t: &mckibben::data::Trace, place: &str) -> PyErr {
    // A tuple's source is its place: named once.
    let message = if t.source == place && cause.contains(place) {
        cause
    } else if let Some(rest) = cause.strip_prefix(&format!("{}: ", t.source)) {
        format!("{place} ({}): {rest}", t.source)
    } else {
        format!("{place}: {cause}")
    };
    PyValueError::new_err(in_python_terms(&message))
}
