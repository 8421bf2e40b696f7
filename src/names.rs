//! The error of a name read from a closed list (an algorithm, a model
//! family, an effect): below every module that keeps such a list, so that
//! they share one type; and the refusal of a list that names a value twice.

/// A name that is none of the list's, with the list: "unknown `what` `got`:
/// expected `expected`".
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown {what} `{got}`: expected {expected}")]
pub struct UnknownName {
    /// What the list names ("algorithm", "model family", "effect").
    pub what: &'static str,
    /// The name as given (or as the list compares it).
    pub got: String,
    /// The names it could have been, as a phrase ("ga, mfa, pso or de").
    pub expected: String,
}

/// Refuses a list flag that names a value twice, saying what `twice` would
/// do (`sweep --pop 4,4` fits each case twice; `control --freq 1,1` runs
/// and reports each run twice).
pub fn given_once<T: PartialEq + std::fmt::Display>(
    flag: &str,
    values: &[T],
    twice: &str,
) -> anyhow::Result<()> {
    for (i, v) in values.iter().enumerate() {
        anyhow::ensure!(!values[..i].contains(v), "{flag} names {v} twice: {twice}");
    }
    Ok(())
}
