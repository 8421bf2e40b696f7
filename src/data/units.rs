//! Units of a data column, read off its name: a model file records them so
//! that a model fitted in one unit is never run on data in another.

/// Units a column name may end in (`pressure_psi`, `disp_mm`, `p [kPa]`,
/// `x (m)`), lower-case, with the spelling a model file records. Inches
/// only as `_inch` or in brackets (`x [in]`): `valve_in` is the input valve.
const KNOWN: [(&str, &str); 34] = [
    ("mpa", "MPa"),
    ("kpa", "kPa"),
    ("hpa", "hPa"),
    ("pa", "Pa"),
    ("bar", "bar"),
    ("mbar", "mbar"),
    ("atm", "atm"),
    ("psi", "psi"),
    ("ksi", "ksi"),
    // Gauges and European and Asian datasheets.
    ("mmhg", "mmHg"),
    ("torr", "Torr"),
    ("cmh2o", "cmH2O"),
    ("inh2o", "inH2O"),
    ("kgf/cm2", "kgf/cm2"),
    ("kgf/cm\u{b2}", "kgf/cm2"),
    ("kg/cm2", "kgf/cm2"),
    ("n/m2", "Pa"),
    ("n/m\u{b2}", "Pa"),
    ("n/mm2", "MPa"),
    ("n/mm\u{b2}", "MPa"),
    ("mm", "mm"),
    ("cm", "cm"),
    ("m", "m"),
    ("um", "µm"),
    // The micro sign and the Greek mu, which keyboards give alike.
    ("\u{b5}m", "µm"),
    ("\u{3bc}m", "µm"),
    ("inch", "in"),
    ("ft", "ft"),
    ("v", "V"),
    ("mv", "mV"),
    ("n", "N"),
    ("kg", "kg"),
    ("g", "g"),
    ("deg", "deg"),
];

/// What a column name states as its unit, lower-case: the text inside
/// trailing brackets or parentheses (`p [kPa]`, `x (m)`), else after the
/// last `_`, space or `/` (`disp_mm`, `pressure kPa`, ISO's `p/kPa`), or
/// a known unit with a `/` of its own after the last `_` or space
/// (`p_kgf/cm2`, `pressure N/mm2`).
fn stated(name: &str) -> Option<String> {
    let bracketed = name
        .strip_suffix(']')
        .and_then(|s| s.rsplit_once('['))
        .or_else(|| name.strip_suffix(')').and_then(|s| s.rsplit_once('(')))
        .map(|(_, unit)| unit);
    if let Some(unit) = bracketed {
        return Some(unit.trim().to_ascii_lowercase());
    }
    let lower = name.to_ascii_lowercase();
    let per_area = KNOWN.iter().map(|(k, _)| *k).find(|k| {
        k.contains('/')
            && lower
                .strip_suffix(k)
                .is_some_and(|rest| rest.ends_with(['_', ' ']))
    });
    if let Some(unit) = per_area {
        return Some(unit.to_string());
    }
    let tail = name.rsplit_once(['_', ' ', '/']).map(|(_, unit)| unit)?;
    Some(tail.trim().to_ascii_lowercase())
}

/// Pressure units a gauge's `g` or an absolute `a` may follow (`psig`,
/// `kPag`, `bara`), lower-case.
const PRESSURES: [&str; 4] = ["psi", "kpa", "mpa", "bar"];

/// A pressure `unit` (as [`unit_of`] spells it) read from zero at vacuum:
/// another unit than the gauge's, since the two differ by the day's
/// atmosphere, which no column states.
fn absolute(unit: &str) -> String {
    format!("{unit} (abs)")
}

/// The unit `tail` (lower-case, as [`stated`] gives it) names, with a
/// pressure's gauge or absolute mark: `psig` and `psi gauge` are psi, the
/// gauge pressure a muscle's sensor reads; `psia` and `kPa abs` are
/// [`absolute`].
fn known(tail: &str) -> Option<String> {
    let plain = |key: &str| {
        KNOWN
            .iter()
            .find(|(k, _)| *k == key)
            .map(|(_, u)| u.to_string())
    };
    if let Some(unit) = plain(tail) {
        return Some(unit);
    }
    let pressure = |key: &str| PRESSURES.contains(&key).then(|| plain(key)).flatten();
    if let Some((unit, mark)) = tail.rsplit_once([' ', '_']) {
        let unit = pressure(unit.trim())?;
        return match mark.trim() {
            "g" | "gauge" | "gage" => Some(unit),
            "a" | "abs" | "absolute" => Some(absolute(&unit)),
            _ => None,
        };
    }
    if let Some(unit) = tail.strip_suffix('g').and_then(pressure) {
        return Some(unit);
    }
    tail.strip_suffix('a')
        .and_then(pressure)
        .map(|u| absolute(&u))
}

/// The shipped data's column names, which state no unit, and their units
/// (README.md, "Data format").
pub const SHIPPED: [(&str, &str); 4] = [
    ("pressure", "MPa"),
    ("displacement", "mm"),
    ("valve_in", "V"),
    ("valve_out", "V"),
];

/// The unit a column name states, if it states one: a known unit after the
/// last `_`, or inside trailing brackets or parentheses; the shipped data's
/// names are in their units ([`SHIPPED`]).
pub fn unit_of(column: &str) -> Option<String> {
    let name = column.trim();
    if let Some((_, unit)) = SHIPPED.iter().find(|(shipped, _)| *shipped == name) {
        return Some(unit.to_string());
    }
    let tail = stated(name)?;
    if tail == "in" && (name.ends_with(']') || name.ends_with(')')) {
        return Some("in".into());
    }
    // A gauge's or an absolute mark after the unit (`pressure_kPa_gauge`,
    // `p kPa abs`): the unit is the word before it.
    if let Some((rest, mark)) = name.rsplit_once(['_', ' ', '/'])
        && matches!(
            mark.trim().to_ascii_lowercase().as_str(),
            "gauge" | "gage" | "abs" | "absolute"
        )
    {
        let unit = stated(rest.trim())?;
        return known(&format!("{unit} {}", mark.trim().to_ascii_lowercase()));
    }
    known(&tail)
}

/// The unit a column's name states in brackets or parentheses (`p
/// [kgf/mm2]`) where it is none [`unit_of`] knows: the name is taken to
/// state no unit, and a model fitted on it records none.
pub fn unknown_bracketed_unit(column: &str) -> Option<String> {
    let name = column.trim();
    let bracketed = name.ends_with(']') || name.ends_with(')');
    let unit = stated(name)?;
    let time = names_a_time(name);
    (bracketed && !unit.is_empty() && !time && unit_of(name).is_none()).then(|| {
        let (_, inside) = name[..name.len() - 1]
            .rsplit_once(['[', '('])
            .unwrap_or_default();
        inside.trim().to_string()
    })
}

/// The unit a time column's name states where it is not seconds (`t_ms`,
/// `time [us]`, `t (min)`): its name and how many of it make a second.
/// Time is read in seconds, so such a column is converted on reading and
/// back on writing. `None` for a name in seconds (`t_s`, `time [s]`) or
/// that states no unit.
pub fn time_unit_other_than_seconds(column: &str) -> Option<(&'static str, f64)> {
    match stated(column.trim())?.as_str() {
        "ms" | "msec" => Some(("milliseconds", 1e3)),
        "us" | "µs" | "μs" | "usec" => Some(("microseconds", 1e6)),
        "ns" => Some(("nanoseconds", 1e9)),
        "min" => Some(("minutes", 1.0 / 60.0)),
        "h" | "hr" => Some(("hours", 1.0 / 3600.0)),
        _ => None,
    }
}

/// Whether a column name reads as a time: `t`, `time` or `timestamp`, or
/// a name that states a unit of time (`t_s`, `time_ms`, `elapsed (s)`).
/// `--dt` refuses a file with such a column rather than read its rows by
/// count and leave its clock, gaps and glitches unread.
pub fn names_a_time(column: &str) -> bool {
    let name = column.trim().to_ascii_lowercase();
    matches!(name.as_str(), "t" | "time" | "timestamp")
        || stated(&name).is_some_and(|unit| {
            matches!(
                unit.as_str(),
                "s" | "sec"
                    | "ms"
                    | "msec"
                    | "us"
                    | "µs"
                    | "μs"
                    | "usec"
                    | "ns"
                    | "min"
                    | "h"
                    | "hr"
            )
        })
}

/// How many millimetres one of `unit` (as [`unit_of`] spells it) is, for
/// the lengths a muscle's stroke is written in; `None` for any other unit.
pub fn millimetres_in(unit: &str) -> Option<f64> {
    match unit {
        "mm" => Some(1.0),
        "cm" => Some(10.0),
        "m" => Some(1000.0),
        "µm" => Some(1e-3),
        "in" => Some(25.4),
        "ft" => Some(304.8),
        _ => None,
    }
}

/// How many MPa one of `unit` (as [`unit_of`] spells it) is, for the
/// pressures a muscle is driven with; `None` for any other unit.
pub fn megapascals_in(unit: &str) -> Option<f64> {
    match unit {
        "MPa" => Some(1.0),
        "kPa" => Some(1e-3),
        "Pa" => Some(1e-6),
        "hPa" | "mbar" => Some(1e-4),
        "bar" => Some(0.1),
        "atm" => Some(0.101325),
        // 1 psi = 6894.757293168 Pa (the international pound and inch).
        "psi" => Some(6.894757293168e-3),
        "ksi" => Some(6.894757293168),
        // 1 mmHg = 133.322387415 Pa; 1 Torr = 101325/760 Pa.
        "mmHg" => Some(1.33322387415e-4),
        "Torr" => Some(0.101325 / 760.0),
        // Conventional water columns: 98.0665 Pa a cm, 249.08891 Pa an inch.
        "cmH2O" => Some(9.80665e-5),
        "inH2O" => Some(2.4908891e-4),
        // A kilogram-force on a square centimetre: 98066.5 Pa.
        "kgf/cm2" => Some(0.0980665),
        _ => None,
    }
}

/// How many millimetres one unit of the column `column` is, where its name
/// states a length ([`unit_of`], then the unit's size in mm); `None` where it
/// states none.
pub fn stated_length_in_mm(column: &str) -> Option<f64> {
    unit_of(column).as_deref().and_then(millimetres_in)
}

/// A record's column and a model's column in two units of one kind (a
/// pressure in kPa and one in psi, a stroke in m and one in mm), where the
/// record's name states its unit in so many words: a shipped name
/// (`pressure`) is in its unit by convention only, and may be in the
/// model's already, so it is no unit to convert ([`between`]).
#[derive(Debug, Clone, PartialEq)]
pub struct UnitPair {
    /// The record's unit and the model's, as [`unit_of`] spells them.
    pub record: String,
    pub model: String,
    /// Their sizes in the kind's common unit (MPa or mm).
    per_record: f64,
    per_model: f64,
}

impl UnitPair {
    /// The factor that takes a value in the record's unit to the model's.
    pub fn to_model(&self) -> f64 {
        self.per_record / self.per_model
    }

    /// The factor that takes a value in the model's unit to the record's.
    pub fn to_record(&self) -> f64 {
        self.per_model / self.per_record
    }
}

/// The units of the record's column `record` and the model's column
/// `model`, where they differ and both are of the kind `size` measures
/// ([`megapascals_in`], [`millimetres_in`]), the record's stated in its
/// name ([`UnitPair`]); `None` otherwise (the same unit, none stated, a
/// unit of another kind: what [`crate::model::file::check_units`] judges).
pub fn between(record: &str, model: &str, size: fn(&str) -> Option<f64>) -> Option<UnitPair> {
    let conventional = SHIPPED.iter().any(|(shipped, _)| *shipped == record.trim());
    let (from, to) = (unit_of(record)?, unit_of(model)?);
    if conventional || from == to {
        return None;
    }
    Some(UnitPair {
        per_record: size(&from)?,
        per_model: size(&to)?,
        record: from,
        model: to,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stated_unit_pairs_with_a_models_of_its_kind() {
        let kpa = between("p_kPa", "pressure_psi", megapascals_in).unwrap();
        assert_eq!((kpa.record.as_str(), kpa.model.as_str()), ("kPa", "psi"));
        assert!((kpa.to_record() - 6.894757293168).abs() < 1e-12);
        assert!((kpa.to_model() * kpa.to_record() - 1.0).abs() < 1e-15);
        let m = between("x_m", "displacement", millimetres_in).unwrap();
        assert_eq!(m.to_model(), 1000.0);
        // The shipped name is in MPa by convention only: not converted.
        assert_eq!(between("pressure", "p_kPa", megapascals_in), None);
        // The same unit, none stated, another kind.
        assert_eq!(between("p_kPa", "pressure_kPa", megapascals_in), None);
        assert_eq!(between("p", "pressure_kPa", megapascals_in), None);
        assert_eq!(between("valve_V", "pressure", megapascals_in), None);
        assert_eq!(between("x_m", "pressure", megapascals_in), None);
    }

    #[test]
    fn units_come_from_suffixes_and_brackets_or_not_at_all() {
        assert_eq!(unit_of("pressure_psi").as_deref(), Some("psi"));
        assert_eq!(unit_of("disp_mm").as_deref(), Some("mm"));
        assert_eq!(unit_of("p [kPa]").as_deref(), Some("kPa"));
        assert_eq!(unit_of("x (m)").as_deref(), Some("m"));
        assert_eq!(unit_of("pressure").as_deref(), Some("MPa"));
        assert_eq!(unit_of("valve_in").as_deref(), Some("V"));
        assert_eq!(unit_of("t_s"), None);
        assert_eq!(megapascals_in("kPa"), Some(1e-3));
        assert_eq!(megapascals_in("mm"), None);
        assert_eq!(unit_of("load"), None);
        // Both mus, inches where they cannot be the input valve.
        assert_eq!(unit_of("x_\u{b5}m").as_deref(), Some("µm"));
        assert_eq!(unit_of("x_\u{3bc}m").as_deref(), Some("µm"));
        assert_eq!(unit_of("stroke [in]").as_deref(), Some("in"));
        assert_eq!(unit_of("stroke_inch").as_deref(), Some("in"));
        assert_eq!(unit_of("valve_out").as_deref(), Some("V"));
        assert_eq!(unit_of("p_mbar").as_deref(), Some("mbar"));
        assert_eq!(megapascals_in("hPa"), Some(1e-4));
        assert_eq!(stated_length_in_mm("disp_ft"), Some(304.8));
    }

    /// The pressure units of gauges and datasheets beside SI's and psi:
    /// `p [kgf/cm2]` and `p_mmHg` were read as stating no unit, and a
    /// model fitted on them ran on MPa without a word.
    #[test]
    fn gauge_and_datasheet_pressures_are_units_too() {
        for (name, unit, mpa) in [
            ("p [kgf/cm2]", "kgf/cm2", 0.0980665),
            ("p (kgf/cm\u{b2})", "kgf/cm2", 0.0980665),
            ("p [kg/cm2]", "kgf/cm2", 0.0980665),
            ("p_mmHg", "mmHg", 1.33322387415e-4),
            ("p_torr", "Torr", 1.3332236842105263e-4),
            ("pressure_inH2O", "inH2O", 2.4908891e-4),
            ("p [cmH2O]", "cmH2O", 9.80665e-5),
            ("p [N/m2]", "Pa", 1e-6),
            ("p [N/mm2]", "MPa", 1.0),
            ("p_ksi", "ksi", 6.894757293168),
            // After `_` or a space too, the unit's own `/` kept.
            ("p_kgf/cm2", "kgf/cm2", 0.0980665),
            ("pressure N/mm2", "MPa", 1.0),
            ("p [N/mm\u{b2}]", "MPa", 1.0),
        ] {
            assert_eq!(unit_of(name).as_deref(), Some(unit), "{name}");
            assert_eq!(megapascals_in(unit), Some(mpa), "{name}");
        }
    }

    /// A unit in brackets that no table holds is named, so the reader can
    /// say it reads the column as stating none; a word after `_` is not a
    /// unit ("stroke_left"), nor is a known unit or a time's.
    #[test]
    fn an_unknown_unit_in_brackets_is_named() {
        assert_eq!(
            unknown_bracketed_unit("p [kgf/mm2]").as_deref(),
            Some("kgf/mm2")
        );
        assert_eq!(
            unknown_bracketed_unit("x (furlong)").as_deref(),
            Some("furlong")
        );
        for name in [
            "p [kPa]",
            "stroke_left",
            "pressure",
            "t [ms]",
            "p ()",
            "x (m)",
        ] {
            assert_eq!(unknown_bracketed_unit(name), None, "{name}");
        }
    }

    /// A space or ISO's `/` before the unit, and a pressure's gauge mark,
    /// state it as well: a `pressure_psig` column was read as stating no
    /// unit, and a model fitted on it ran on MPa without a word.
    #[test]
    fn other_spellings_state_the_same_units() {
        for (name, unit) in [
            ("pressure kPa", "kPa"),
            ("p/kPa", "kPa"),
            ("disp mm", "mm"),
            ("pressure_psig", "psi"),
            ("p_kPag", "kPa"),
            ("p (barg)", "bar"),
            ("pressure_MPa_gauge", "MPa"),
            ("p [kPa g]", "kPa"),
            ("p (psi gauge)", "psi"),
            ("pressure_psia", "psi (abs)"),
            ("p_bara", "bar (abs)"),
            ("pressure_kPa_abs", "kPa (abs)"),
            ("p [kPa abs]", "kPa (abs)"),
        ] {
            assert_eq!(unit_of(name).as_deref(), Some(unit), "{name}");
        }
        // An absolute pressure differs from a gauge's by the day's
        // atmosphere: no factor converts it.
        assert_eq!(megapascals_in("psi (abs)"), None);
        // Words that are not units, and marks on no pressure.
        for name in [
            "valve in",
            "p_raw",
            "disp_mm_gauge",
            "load_ga",
            "stroke_gauge",
            "x/p0",
        ] {
            assert_eq!(unit_of(name), None, "{name}");
        }
        assert_eq!(
            time_unit_other_than_seconds("time ms"),
            Some(("milliseconds", 1e3))
        );
    }

    #[test]
    fn a_time_column_named_in_another_unit_than_seconds_is_found() {
        for name in ["t_ms", "time [ms]", "t (us)", "t_µs", "time_min", "t [h]"] {
            assert!(time_unit_other_than_seconds(name).is_some(), "{name}");
        }
        for name in [
            "t",
            "t_s",
            "time [s]",
            "time_sec",
            "t (s)",
            "time_s",
            "timestamp",
        ] {
            assert_eq!(time_unit_other_than_seconds(name), None, "{name}");
        }
    }

    #[test]
    fn lengths_convert_to_millimetres_and_other_units_do_not() {
        let mm = stated_length_in_mm;
        assert_eq!(mm("disp_m"), Some(1000.0));
        assert_eq!(mm("x (cm)"), Some(10.0));
        assert_eq!(mm("stroke_mm"), Some(1.0));
        assert_eq!(mm("displacement"), Some(1.0));
        assert_eq!(mm("gap_um"), Some(1e-3));
        assert_eq!(mm("angle_deg"), None);
        assert_eq!(mm("force_n"), None);
        assert_eq!(mm("y"), None);
    }
}
