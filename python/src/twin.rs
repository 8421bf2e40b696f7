//! `mckibben.twin`: an experiment on the rig twin, the run `mckibben twin`
//! makes, as a `Trace`.

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use mckibben::twin::experiment::{DEFAULT_FREQ_RAD_S, Kind, RunSpec};

use crate::args::real;
use crate::convert::{given, in_python_terms};
use crate::data::{Trace, timed_only};
use crate::named;

/// Runs an experiment on the rig twin, as `mckibben twin` does: `stair`
/// (the identification staircase), `sine` (the thesis' PI tracking a sine
/// of `freq` rad/s, default 1) or `multisine` (its phases from `seed`),
/// under `load` kg, its sensor noise from `seed`; `effects` scales the
/// twin's non-ideal effects by name (`{"friction": 0, "creep": 1}`: 1 as
/// documented, 0 off). Returns the recording as a `Trace`: the pressure
/// (MPa) in, the displacement (mm) out, the valves' voltages, the load and
/// the sine's reference in `.extra`, every sample the file `mckibben twin`
/// writes holds; `.source` is the command that writes that file.
#[pyfunction]
#[pyo3(signature = (experiment = "stair", load = 4.5, seed = 1, freq = None, effects = None))]
pub fn twin(
    py: Python<'_>,
    #[pyo3(from_py_with = named::experiment)] experiment: &str,
    #[pyo3(from_py_with = named::load)] load: f64,
    #[pyo3(from_py_with = named::seed_arg)] seed: u64,
    #[pyo3(from_py_with = named::freq)] freq: Option<f64>,
    effects: Option<&Bound<'_, PyAny>>,
) -> PyResult<Trace> {
    let kind: Kind = experiment
        .parse()
        .map_err(|e: mckibben::names::UnknownName| PyValueError::new_err(e.to_string()))?;
    if freq.is_some() && kind != Kind::Sine {
        return Err(PyValueError::new_err(format!(
            "freq sets the sine's frequency: experiment=\"sine\" (got experiment={:?})",
            kind.as_str()
        )));
    }
    let spec = RunSpec {
        kind,
        load_kg: load,
        seed,
        freq_rad_s: freq.unwrap_or(DEFAULT_FREQ_RAD_S),
        effects: effects
            .map(effect_settings)
            .transpose()?
            .unwrap_or_default(),
    };
    let trace = py
        .detach(|| spec.run())
        .map_err(|e| PyValueError::new_err(in_python_terms(&e.to_string())))?;
    Ok(Trace {
        read: timed_only(&trace.time_name),
        inner: trace,
    })
}

/// `effects` (any mapping) as the command's `--effect NAME=VALUE`
/// settings, in the mapping's order: names are the keys, scales the values.
pub fn effect_settings(obj: &Bound<'_, PyAny>) -> PyResult<Vec<String>> {
    let d = match obj.cast::<PyDict>() {
        Ok(d) => d.clone(),
        Err(_) => {
            let mapping = obj.py().import("collections.abc")?.getattr("Mapping")?;
            if !obj.is_instance(&mapping)? {
                return Err(PyTypeError::new_err(format!(
                    "effects must be a dict of scales by name, e.g. {{\"friction\": 0}}, got {}",
                    given(obj)
                )));
            }
            PyDict::from_sequence(&obj.call_method0("items")?)?
        }
    };
    d.iter()
        .map(|(name, scale)| {
            let name: String = name.extract().map_err(|_| {
                PyTypeError::new_err(format!(
                    "effects' keys must be effect names (str), got {}",
                    given(&name)
                ))
            })?;
            let scale = real(&scale, &format!("effects[{name:?}]"))?;
            // `{}` prints an f64 so that it parses back to the same bits.
            Ok(format!("{name}={scale}"))
        })
        .collect()
}
