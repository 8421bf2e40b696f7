//! Units of a data column, read off its name: a model file records them so
//! that a model fitted in one unit is never run on data in another.

/// Units a column name may end in (`pressure_psi`, `disp_mm`, `p [kPa]`,
/// `x (m)`), lower-case, with the spelling a model file records. Not
/// inches: `valve_in` is the input valve.
const KNOWN: [(&str, &str); 15] = [
    ("mpa", "MPa"),
    ("kpa", "kPa"),
    ("pa", "Pa"),
    ("bar", "bar"),
    ("psi", "psi"),
    ("mm", "mm"),
    ("cm", "cm"),
    ("m", "m"),
    ("um", "µm"),
    ("v", "V"),
    ("mv", "mV"),
    ("n", "N"),
    ("kg", "kg"),
    ("g", "g"),
    ("deg", "deg"),
];

/// The unit a column name states, if it states one: a known unit after the
/// last `_`, or inside trailing brackets or parentheses. The shipped data's
/// `pressure` and `displacement` columns are in MPa and mm (README.md,
/// "Data format").
pub fn unit_of(column: &str) -> Option<String> {
    let name = column.trim();
    match name {
        "pressure" => return Some("MPa".into()),
        "displacement" => return Some("mm".into()),
        _ => {}
    }
    let bracketed = name
        .strip_suffix(']')
        .and_then(|s| s.rsplit_once('['))
        .or_else(|| name.strip_suffix(')').and_then(|s| s.rsplit_once('(')))
        .map(|(_, unit)| unit);
    let tail = bracketed.or_else(|| name.rsplit_once('_').map(|(_, unit)| unit))?;
    let tail = tail.trim().to_ascii_lowercase();
    KNOWN
        .iter()
        .find(|(key, _)| *key == tail)
        .map(|(_, unit)| unit.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_come_from_suffixes_and_brackets_or_not_at_all() {
        assert_eq!(unit_of("pressure_psi").as_deref(), Some("psi"));
        assert_eq!(unit_of("disp_mm").as_deref(), Some("mm"));
        assert_eq!(unit_of("p [kPa]").as_deref(), Some("kPa"));
        assert_eq!(unit_of("x (m)").as_deref(), Some("m"));
        assert_eq!(unit_of("pressure").as_deref(), Some("MPa"));
        assert_eq!(unit_of("valve_in"), None);
        assert_eq!(unit_of("t_s"), None);
        assert_eq!(unit_of("load"), None);
    }
}
