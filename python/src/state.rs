//! Pickling the results. `FitResult`, `Diagnosis`, `Identification` and
//! `ControlResult` are frozen classes made in Rust, which pickle cannot
//! rebuild by itself; without pickling no result comes back from a worker
//! process (`multiprocessing`, `concurrent.futures`, joblib) and
//! `copy.deepcopy` fails. [`with_state!`] defines such a class from one
//! list of its fields, so that its pickled state names every field and none
//! can be forgotten.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Defines the struct as written and, from the same fields, its Python
/// methods: `__reduce__`, which pickles a dict of every field by name,
/// `_from_state`, which rebuilds the struct from such a dict, and
/// `__repr__`, which calls the struct's own `repr`.
macro_rules! with_state {
    ($(#[$meta:meta])* $vis:vis struct $name:ident {
        $($(#[$field_meta:meta])* $field:ident: $type:ty,)*
    }) => {
        $(#[$meta])* $vis struct $name { $($(#[$field_meta])* $field: $type,)* }

        #[pymethods]
        impl $name {
            /// Pickles as every field's value, so that a result made in a
            /// worker process comes back whole.
            fn __reduce__<'py>(
                &self,
                py: Python<'py>,
            ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, pyo3::types::PyDict>,))> {
                let state = pyo3::types::PyDict::new(py);
                $(state.set_item(stringify!($field), &self.$field)?;)*
                Ok((py.get_type::<$name>().getattr("_from_state")?, (state,)))
            }

            /// The result `__reduce__` pickled.
            #[classmethod]
            fn _from_state(
                _class: &Bound<'_, pyo3::types::PyType>,
                state: &Bound<'_, pyo3::types::PyDict>,
            ) -> PyResult<$name> {
                Ok($name {
                    $($field: crate::state::field(state, stringify!($field))?,)*
                })
            }

            fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
                self.repr(py)
            }
        }
    };
}
pub(crate) use with_state;

/// The field `name` of a pickled state, as its type.
pub fn field<'py, T: FromPyObjectOwned<'py>>(
    state: &Bound<'py, PyDict>,
    name: &str,
) -> PyResult<T> {
    let value = state.get_item(name)?.ok_or_else(|| {
        PyValueError::new_err(format!("the pickled result has no field `{name}`"))
    })?;
    value.extract().map_err(Into::into)
}
