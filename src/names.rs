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

/// The item of `all` whose `name` is `s` in any case (`PSO`, `Stair`), or
/// the error that names `what` and the list.
pub fn one_of<T: Copy>(
    what: &'static str,
    s: &str,
    all: &[T],
    name: impl Fn(T) -> &'static str,
) -> Result<T, UnknownName> {
    all.iter()
        .copied()
        .find(|&t| name(t).eq_ignore_ascii_case(s.trim()))
        .ok_or_else(|| {
            let names: Vec<&str> = all.iter().map(|&t| name(t)).collect();
            let expected = match names.split_last() {
                Some((last, [])) => last.to_string(),
                Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
                None => "nothing".into(),
            };
            UnknownName {
                what,
                got: s.to_string(),
                expected,
            }
        })
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
