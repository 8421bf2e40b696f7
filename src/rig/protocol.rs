//! The line protocol between a controller and a rig (docs/RIG_PROTOCOL.md).
//!
//! One message per line, ASCII, fields separated by single spaces, numbers
//! in decimal (written with Rust's shortest round-trip form, so a value
//! crosses the link unchanged):
//!
//! ```text
//! controller → rig                      rig → controller
//! HELLO 1                               READY 1 <dt s> [<ranges>]
//! U <k> <volts>                         M <k> <t s> <pressure MPa> <displacement mm>
//! STOP                                  BYE <samples>
//!                                       ERR <text>
//! ```
//!
//! `U k v` holds the input valve at `v` volts (0–10) over sample `k`;
//! `M k …` is the measurement that closes sample `k − 1`, taken at
//! `t = k·dt` after the run started. `STOP` closes the input valve (0 V; the
//! output valve opens and the muscle drains) and ends the run. `READY` may
//! carry the ranges the rig's sensors can read (`<p min> <p max> <x min>
//! <x max>`, MPa and mm), an addition a rig that leaves them out need not
//! know about.

use std::fmt;

/// Version of the protocol this build speaks.
pub const VERSION: u32 = 1;

/// Longest line accepted (bytes); a longer one is malformed.
pub const MAX_LINE: usize = 4096;

/// The longest sample time a `READY` may announce (s).
pub const MAX_DT_S: f64 = 60.0;

/// The valve commands a `U` may carry (V): the proportional valves take
/// 0–10 V. Anything else is malformed, whichever end reads it.
pub const VOLTS: (f64, f64) = (0.0, 10.0);

/// What a rig's sensors can read: a measurement outside is not one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ranges {
    /// Gauge pressure (MPa), lowest and highest.
    pub pressure_mpa: (f64, f64),
    /// Displacement (mm, contraction positive), lowest and highest.
    pub displacement_mm: (f64, f64),
}

impl fmt::Display for Ranges {
    /// The four fields as `READY` carries them.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (p, x) = (self.pressure_mpa, self.displacement_mm);
        write!(f, "{} {} {} {}", p.0, p.1, x.0, x.1)
    }
}

/// A message from the controller to the rig.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ToRig {
    Hello { version: u32 },
    Command { k: u64, volts: f64 },
    Stop,
}

/// A message from the rig to the controller.
#[derive(Debug, Clone, PartialEq)]
pub enum FromRig {
    Ready {
        version: u32,
        dt: f64,
        /// The ranges the rig announces, if it does.
        ranges: Option<Ranges>,
    },
    Measurement {
        k: u64,
        t: f64,
        pressure_mpa: f64,
        displacement_mm: f64,
    },
    Bye {
        samples: u64,
    },
    Error(String),
}

impl fmt::Display for ToRig {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ToRig::Hello { version } => write!(f, "HELLO {version}"),
            ToRig::Command { k, volts } => write!(f, "U {k} {volts}"),
            ToRig::Stop => f.write_str("STOP"),
        }
    }
}

impl fmt::Display for FromRig {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FromRig::Ready {
                version,
                dt,
                ranges: None,
            } => write!(f, "READY {version} {dt}"),
            FromRig::Ready {
                version,
                dt,
                ranges: Some(r),
            } => write!(f, "READY {version} {dt} {r}"),
            FromRig::Measurement {
                k,
                t,
                pressure_mpa,
                displacement_mm,
            } => write!(f, "M {k} {t} {pressure_mpa} {displacement_mm}"),
            FromRig::Bye { samples } => write!(f, "BYE {samples}"),
            FromRig::Error(text) => write!(f, "ERR {text}"),
        }
    }
}

/// Why a line is malformed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Malformed(pub String);

impl fmt::Display for Malformed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// The fields of `line` after its keyword, checked for count.
fn fields<'a>(line: &'a str, keyword: &str, names: &[&str]) -> Result<Vec<&'a str>, Malformed> {
    let got: Vec<&str> = line.split_ascii_whitespace().skip(1).collect();
    if got.len() != names.len() {
        return Err(Malformed(format!(
            "`{keyword}` takes {} field(s) ({}), got {}",
            names.len(),
            names.join(" "),
            got.len()
        )));
    }
    Ok(got)
}

/// A pair of numbers, the lower first.
fn range(lo: &str, hi: &str, name: &str) -> Result<(f64, f64), Malformed> {
    let (a, b) = (number(lo, name)?, number(hi, name)?);
    if a >= b {
        return Err(Malformed(format!(
            "{name} range `{lo} {hi}` is empty (the lower end first)"
        )));
    }
    Ok((a, b))
}

fn number(field: &str, name: &str) -> Result<f64, Malformed> {
    match field.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(Malformed(format!(
            "{name} `{field}` is not a finite number"
        ))),
    }
}

fn index(field: &str, name: &str) -> Result<u64, Malformed> {
    field.parse::<u64>().map_err(|_| {
        Malformed(format!(
            "{name} `{field}` is not a sample index (0, 1, 2, …)"
        ))
    })
}

/// A protocol version: a word, not a sample index cut to one (`as u32`
/// read 2³² + 1 as version 1).
fn version(field: &str) -> Result<u32, Malformed> {
    field.parse::<u32>().map_err(|_| {
        Malformed(format!(
            "version `{field}` is not a protocol version (1, 2, …)"
        ))
    })
}

fn check_ascii(line: &str) -> Result<(), Malformed> {
    if line.len() > MAX_LINE {
        return Err(Malformed(format!("longer than {MAX_LINE} bytes")));
    }
    if !line.is_ascii() || line.chars().any(|c| c.is_ascii_control() && c != '\t') {
        return Err(Malformed("not a line of printable ASCII".into()));
    }
    Ok(())
}

impl FromRig {
    /// Parses one line (without its line break).
    pub fn parse(line: &str) -> Result<FromRig, Malformed> {
        check_ascii(line)?;
        match line.split_ascii_whitespace().next() {
            Some("READY") => {
                // The ranges are optional: two fields, or all six.
                let names = ["version", "dt", "p_min", "p_max", "x_min", "x_max"];
                let short = line.split_ascii_whitespace().count() <= 3;
                let f = fields(line, "READY", if short { &names[..2] } else { &names })?;
                let version = version(f[0])?;
                let dt = number(f[1], "dt")?;
                // A minute at most: a longer sample is a unit slip (ms
                // for s), and the deadlines are made from it.
                if !(dt > 0.0 && dt <= MAX_DT_S) {
                    return Err(Malformed(format!(
                        "dt `{}` is not a sample time above 0 and at most {MAX_DT_S} s",
                        f[1]
                    )));
                }
                let ranges = if short {
                    None
                } else {
                    Some(Ranges {
                        pressure_mpa: range(f[2], f[3], "pressure")?,
                        displacement_mm: range(f[4], f[5], "displacement")?,
                    })
                };
                Ok(FromRig::Ready {
                    version,
                    dt,
                    ranges,
                })
            }
            Some("M") => {
                let f = fields(line, "M", &["k", "t", "pressure_mpa", "displacement_mm"])?;
                Ok(FromRig::Measurement {
                    k: index(f[0], "k")?,
                    t: number(f[1], "t")?,
                    pressure_mpa: number(f[2], "pressure_mpa")?,
                    displacement_mm: number(f[3], "displacement_mm")?,
                })
            }
            Some("BYE") => {
                let f = fields(line, "BYE", &["samples"])?;
                Ok(FromRig::Bye {
                    samples: index(f[0], "samples")?,
                })
            }
            Some("ERR") => Ok(FromRig::Error(
                line.trim_start()
                    .strip_prefix("ERR")
                    .unwrap_or("")
                    .trim()
                    .to_string(),
            )),
            Some(other) => Err(Malformed(format!(
                "unknown message `{other}` (expected READY, M, BYE or ERR)"
            ))),
            None => Err(Malformed("empty line".into())),
        }
    }
}

impl ToRig {
    /// Parses one line (without its line break).
    pub fn parse(line: &str) -> Result<ToRig, Malformed> {
        check_ascii(line)?;
        match line.split_ascii_whitespace().next() {
            Some("HELLO") => {
                let f = fields(line, "HELLO", &["version"])?;
                Ok(ToRig::Hello {
                    version: version(f[0])?,
                })
            }
            Some("U") => {
                let f = fields(line, "U", &["k", "volts"])?;
                let volts = number(f[1], "volts")?;
                if !(VOLTS.0..=VOLTS.1).contains(&volts) {
                    return Err(Malformed(format!(
                        "volts `{}` is outside {}–{} V",
                        f[1], VOLTS.0, VOLTS.1
                    )));
                }
                Ok(ToRig::Command {
                    k: index(f[0], "k")?,
                    volts,
                })
            }
            Some("STOP") => {
                fields(line, "STOP", &[])?;
                Ok(ToRig::Stop)
            }
            Some(other) => Err(Malformed(format!(
                "unknown message `{other}` (expected HELLO, U or STOP)"
            ))),
            None => Err(Malformed("empty line".into())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_message_round_trips() {
        let to = [
            ToRig::Hello { version: 1 },
            ToRig::Command {
                k: 17,
                volts: 5.123456789012345,
            },
            ToRig::Stop,
        ];
        for m in to {
            assert_eq!(ToRig::parse(&m.to_string()).unwrap(), m);
        }
        let from = [
            FromRig::Ready {
                version: 1,
                dt: 0.01,
                ranges: None,
            },
            FromRig::Ready {
                version: 1,
                dt: 0.01,
                ranges: Some(Ranges {
                    pressure_mpa: (-0.04, 0.44),
                    displacement_mm: (-10.5, 55.5),
                }),
            },
            FromRig::Measurement {
                k: 3,
                t: 0.03,
                pressure_mpa: 0.1985,
                displacement_mm: 24.475,
            },
            FromRig::Bye { samples: 3000 },
            FromRig::Error("unsupported version 2".into()),
        ];
        for m in from {
            assert_eq!(FromRig::parse(&m.to_string()).unwrap(), m);
        }
    }

    #[test]
    fn malformed_lines_say_what_is_wrong() {
        let cases = [
            ("M 3 0.03 abc 24.4", "pressure_mpa `abc`"),
            ("M 3 0.03 0.2", "takes 4 field(s)"),
            ("M -1 0.03 0.2 24", "k `-1`"),
            ("M 3 0.03 NaN 24", "not a finite number"),
            ("X 1", "unknown message `X`"),
            ("", "empty line"),
            ("M 3 0.03 0.2 24\u{7}", "printable ASCII"),
            ("READY 1 0.01 0 0.4 -5", "takes 6 field(s)"),
            ("READY 1", "takes 2 field(s)"),
            ("READY 4294967297 0.01", "version `4294967297`"),
            (
                "READY 1 0.01 0.4 0 -5 50",
                "pressure range `0.4 0` is empty",
            ),
        ];
        for (line, why) in cases {
            let err = FromRig::parse(line).unwrap_err().0;
            assert!(err.contains(why), "{line:?}: {err}");
        }
        assert!(ToRig::parse("U 1 inf").is_err());
        let err = ToRig::parse("HELLO 4294967297").unwrap_err().0;
        assert!(err.contains("not a protocol version"), "{err}");
        for volts in ["99", "-5", "10.000001"] {
            let err = ToRig::parse(&format!("U 0 {volts}")).unwrap_err().0;
            assert!(err.contains("outside 0–10 V"), "{volts}: {err}");
        }
        assert!(ToRig::parse("U 0 10").is_ok() && ToRig::parse("U 0 0").is_ok());
        assert!(
            FromRig::parse(&"M ".repeat(3000))
                .unwrap_err()
                .0
                .contains("longer")
        );
    }
}
