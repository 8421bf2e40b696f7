//! Pickling the results. `FitResult` and `Diagnosis` are frozen classes
//! made in Rust, which pickle cannot rebuild by itself; without pickling
//! no result comes back from a worker process (`multiprocessing`,
//! `concurrent.futures`, joblib) and `copy.deepcopy` fails.
//! [`with_state!`] defines such a class from one list of its fields, so
//! that its pickled state names every field and none can be forgotten.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Defines the struct as written and, from the same fields, `state`, a
/// dict of every field by name (what the class's `__reduce__` pickles),
/// and `from_state`, the struct rebuilt from such a dict.
macro_rules! with_state {
    ($(#[$meta:meta])* $vis:vis struct $name:ident {
        $($(#[$field_meta:meta])* $field:ident: $type:ty,)*
    }) => {
        $(#[$meta])* $vis struct $name { $($(#[$field_meta])* $field: $type,)* }

        impl $name {
            fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
                let state = PyDict::new(py);
                $(state.set_item(stringify!($field), &self.$field)?;)*
                Ok(state)
            }

            fn from_state(state: &Bound<'_, PyDict>) -> PyResult<Self> {
                Ok(Self {
                    $($field: crate::state::field(state, stringify!($field))?,)*
                })
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
