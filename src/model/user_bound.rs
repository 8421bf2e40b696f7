//! A bound a user sets on one parameter of a fit's box (`--bound`, `--fix`,
//! Python's `bounds`), as the command line writes it.

use crate::data::readable;
use serde::{Deserialize, Serialize};

/// A bound a user sets on one parameter (`--bound NAME=LO:HI`, `--fix
/// NAME=VALUE`), by a canonical name or a search coordinate's name.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UserBound {
    pub name: String,
    pub lower: f64,
    pub upper: f64,
}

impl std::fmt::Display for UserBound {
    /// As `--bound` and `--fix` take it: `NAME=LO:HI`, or `NAME=VALUE`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (lower, upper) = (readable(self.lower), readable(self.upper));
        if self.lower == self.upper {
            write!(f, "{}={lower}", self.name)
        } else {
            write!(f, "{}={lower}:{upper}", self.name)
        }
    }
}

impl UserBound {
    /// The bound as the command line gives it: `--fix NAME=VALUE` where
    /// its ends meet, else `--bound NAME=LO:HI`.
    pub fn as_given(&self) -> String {
        let flag = if self.lower == self.upper {
            "--fix"
        } else {
            "--bound"
        };
        format!("{flag} {self}")
    }
}

/// A `--bound` or `--fix` that does not read as a bound (`input` is it
/// as given).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UserBoundError {
    #[error("`{input}`: expected NAME=LO:HI or NAME=VALUE")]
    Form { input: String },
    #[error("`{input}`: `{value}` is not a number")]
    NotANumber { input: String, value: String },
    #[error("`{input}`: `{value}` is not a finite number")]
    NotFinite { input: String, value: String },
    #[error(
        "`{input}`: the box is empty (lower {} is above upper {})",
        readable(*.lower),
        readable(*.upper)
    )]
    Empty {
        input: String,
        lower: f64,
        upper: f64,
    },
}

impl std::str::FromStr for UserBound {
    type Err = UserBoundError;
    /// `NAME=LO:HI` or `NAME=VALUE` (a fixed value: `LO = HI`).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let input = || s.to_string();
        let (name, range) = s
            .split_once('=')
            .ok_or_else(|| UserBoundError::Form { input: input() })?;
        let number = |v: &str| -> Result<f64, UserBoundError> {
            let value = || v.to_string();
            let x: f64 = v.trim().parse().map_err(|_| UserBoundError::NotANumber {
                input: input(),
                value: value(),
            })?;
            if x.is_finite() {
                Ok(x)
            } else {
                Err(UserBoundError::NotFinite {
                    input: input(),
                    value: value(),
                })
            }
        };
        let (lower, upper) = match range.split_once(':') {
            Some((lo, hi)) => (number(lo)?, number(hi)?),
            None => {
                let v = number(range)?;
                (v, v)
            }
        };
        if lower > upper {
            return Err(UserBoundError::Empty {
                input: input(),
                lower,
                upper,
            });
        }
        Ok(UserBound {
            name: name.trim().to_string(),
            lower,
            upper,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bound is written back (a model file's `user_bounds`, a note) as a
    /// person reads it and as `--bound` reads it again, at any magnitude.
    #[test]
    fn a_bound_is_written_as_it_reads_back_at_any_magnitude() {
        for (given, written) in [
            ("alpha=0.5", "alpha=0.5"),
            ("alpha=1e300", "alpha=1e300"),
            ("beta=0:1e-300", "beta=0:1e-300"),
            ("x_s=-2.5:4000", "x_s=-2.5:4000"),
        ] {
            let bound: UserBound = given.parse().unwrap();
            assert_eq!(bound.to_string(), written);
            assert_eq!(written.parse::<UserBound>().unwrap(), bound);
        }
        let empty = "alpha=1e300:1e-300".parse::<UserBound>().unwrap_err();
        assert!(
            empty
                .to_string()
                .contains("lower 1e300 is above upper 1e-300"),
            "{empty}"
        );
    }
}
