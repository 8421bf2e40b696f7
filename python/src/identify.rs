//! `mckibben.identify`: the thesis' ARX identification (§4.3), the call
//! `mckibben identify` makes.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use mckibben::ident::ArxOrders;
use mckibben::ident::arx::{IdentifyJson, identify as identify_one, identify_jointly};
use mckibben::model::{Model as LibModel, ModelFile};
use mckibben::report::json::Versioned;

use crate::convert::{to_python, value_error};
use crate::data::{Experiments, experiments, located};
use crate::model::{Model, provenance};
use crate::named;

crate::state::with_state! {
    /// What `mckibben.identify` returns: the document `mckibben identify
    /// --json` prints and, for the first order, its model.
    #[pyclass(module = "mckibben", frozen, get_all)]
    pub struct Identification {
        /// The `--json` document (docs/JSON.md, `identify`): the ARX
        /// coefficients, the means removed, each half's fit %, and each
        /// record's where there are several.
        document: Py<PyAny>,
        /// The first-order model (eq. 12) as the linear family `fit`,
        /// `simulate` and `control` read; `None` for other orders.
        model: Option<Py<Model>>,
    }
}

impl Identification {
    /// `__repr__`'s text.
    fn repr(&self, py: Python<'_>) -> PyResult<String> {
        let d = self.document.bind(py);
        Ok(format!(
            "Identification(validation fit {:.2} %)",
            d.get_item("validation_fit_percent")?.extract::<f64>()?
        ))
    }
}

/// Identifies an ARX model as `mckibben identify` does (MATLAB's `arx`
/// and `compare`): the estimation half's means removed, least squares on
/// the first half, the free run validated on the second. `u` is a `Trace`,
/// arrays `u` and `y` sampled every `dt`, or a list of experiments of one
/// muscle, which give one model for all (`identify a.csv b.csv`). `na`,
/// `nb`, `nk`: poles, zeros + 1 and input delay.
#[pyfunction]
#[pyo3(signature = (u, y = None, dt = None, *, na = 1, nb = 1, nk = 1))]
pub fn identify(
    py: Python<'_>,
    u: &Bound<'_, PyAny>,
    y: Option<&Bound<'_, PyAny>>,
    #[pyo3(from_py_with = named::dt_opt)] dt: Option<f64>,
    #[pyo3(from_py_with = named::na)] na: usize,
    #[pyo3(from_py_with = named::nb)] nb: usize,
    #[pyo3(from_py_with = named::nk)] nk: usize,
) -> PyResult<Identification> {
    let Experiments {
        traces,
        read,
        listed,
    } = experiments(u, y, dt)?;
    let orders = ArxOrders { na, nb, nk };
    let id = py
        .detach(|| match &traces[..] {
            [one] => identify_one(one, orders),
            many => identify_jointly(many, orders),
        })
        .map_err(|e| match &listed {
            Some(records) => located(e.into(), &[records]),
            None => PyValueError::new_err(e.to_string()),
        })?;
    let sources: Vec<&str> = traces.iter().map(|t| t.source.as_str()).collect();
    let file = id.first_order_model(&traces[0]).map(|m| {
        ModelFile::new(
            &LibModel::plain(m),
            None,
            provenance("mckibben.identify", &sources, &read, None),
        )
    });
    let document = IdentifyJson {
        identification: &id,
        model: file.clone(),
    };
    Ok(Identification {
        document: to_python(py, &Versioned::new(document))?.unbind(),
        model: file
            .map(|f| Py::new(py, Model::of_file(f).map_err(value_error)?))
            .transpose()?,
    })
}
