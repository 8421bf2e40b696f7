//! The `--json` contract: every command's JSON output is a typed struct
//! wrapped in [`Versioned`], which puts [`SCHEMA_VERSION`] first.
//! `docs/JSON.md` documents each command's fields; `tests/json_contract.rs`
//! checks the outputs against it.

use serde::Serialize;

/// Version of the `--json` outputs' shape, shared by every command. It is
/// bumped when a field is removed, renamed or changes meaning or type;
/// adding a field does not bump it.
pub const SCHEMA_VERSION: u32 = 5;

/// A `--json` document: `schema_version`, then the fields of `body`.
#[derive(Debug, Serialize)]
pub struct Versioned<T> {
    pub schema_version: u32,
    #[serde(flatten)]
    pub body: T,
}

impl<T: Serialize> Versioned<T> {
    pub fn new(body: T) -> Versioned<T> {
        Versioned {
            schema_version: SCHEMA_VERSION,
            body,
        }
    }

    /// The document, pretty-printed (two-space indent).
    pub fn to_string_pretty(&self) -> serde_json::Result<String> {
        serde_json::to_string_pretty(self)
    }
}

/// Values (numbers by default) by name, serialized as a JSON object whose
/// keys keep this order (e.g. a model's parameters in canonical order).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Named<T = f64>(pub Vec<(String, T)>);

impl Named {
    /// Pairs `names` with `values` (the shorter one sets the length).
    pub fn zip<S: AsRef<str>>(names: &[S], values: &[f64]) -> Named {
        Named(
            names
                .iter()
                .zip(values)
                .map(|(n, &v)| (n.as_ref().to_string(), v))
                .collect(),
        )
    }

    /// The value named `name`, if any.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.0.iter().find(|(n, _)| n == name).map(|&(_, v)| v)
    }
}

impl<S: AsRef<str>, T> FromIterator<(S, T)> for Named<T> {
    fn from_iter<I: IntoIterator<Item = (S, T)>>(iter: I) -> Named<T> {
        Named(
            iter.into_iter()
                .map(|(n, v)| (n.as_ref().to_string(), v))
                .collect(),
        )
    }
}

impl<T: Serialize> Serialize for Named<T> {
    fn serialize<Z: serde::Serializer>(&self, s: Z) -> Result<Z::Ok, Z::Error> {
        use serde::ser::SerializeMap;
        let mut map = s.serialize_map(Some(self.0.len()))?;
        for (n, v) in &self.0 {
            map.serialize_entry(n, v)?;
        }
        map.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn versioned_puts_the_version_first_and_named_keeps_order() {
        #[derive(Serialize)]
        struct Body {
            params: Named,
        }
        let body = Body {
            params: Named::zip(&["b", "a"], &[2.0, 1.0]),
        };
        let text = serde_json::to_string(&Versioned::new(body)).unwrap();
        assert_eq!(
            text,
            format!(r#"{{"schema_version":{SCHEMA_VERSION},"params":{{"b":2.0,"a":1.0}}}}"#)
        );
    }
}
