//! The controller's end of the line protocol: a [`ControlLoop`] driven by a
//! rig over a [`Link`], with a deadline on every sample.
//!
//! - The measurement that closes sample `k − 1` is due within the deadline
//!   after the previous one arrived. If it is **missing** then, the
//!   command in force is held over sample `k` (sent again as `U k`) and the
//!   controller is told; after `max_missing` in a row the rig counts as
//!   silent. A measurement that comes after its sample was held is **late**:
//!   logged and set aside.
//! - A **malformed** line (not the protocol, a field that is not a finite
//!   number) or a **stale** one (a sample already used, or a time stamp that
//!   is not its sample's) ends the run with an error that quotes the line,
//!   and the valve is closed: `U k 0` then `STOP`. Closing is the one command
//!   exempt from the slew limit: the rig can no longer be trusted to carry a
//!   ramp.

use std::time::{Duration, Instant};

use thiserror::Error;

use super::link::{Link, Received};
use super::log::RunLog;
use super::protocol::{FromRig, ToRig, VERSION};
use crate::control::closed_loop::Recorder;
use crate::control::{ControlLoop, Controller, Episode, EpisodeResult, Measurement};

/// How strict the loop is with the rig.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RemoteSettings {
    /// Time a measurement may take after the one before it arrived (the
    /// sample's deadline): the sample time plus the jitter allowed.
    pub deadline: Duration,
    /// Missing measurements in a row after which the run stops.
    pub max_missing: usize,
}

impl RemoteSettings {
    /// The time `mckibben control` gives a rig to answer `HELLO`: a rig
    /// behind `cmd:` is a process that must start first, so this is seconds,
    /// not a sample.
    pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);

    /// The deadline a rig with sample time `dt` (s) gets unless the user
    /// sets one: one sample plus half a sample of jitter, so that it scales
    /// with the rig (15 ms at the thesis' 10 ms).
    pub fn default_deadline(dt: f64) -> Duration {
        Duration::from_secs_f64(1.5 * dt)
    }
}

/// Why a run on a rig stopped early.
#[derive(Debug, Error)]
pub enum RigError {
    #[error("rig {link}, line {line_no} `{line}`: {why}")]
    Malformed {
        link: String,
        line_no: usize,
        line: String,
        why: String,
    },
    #[error("rig {link}, line {line_no} `{line}`: stale measurement: {why}")]
    Stale {
        link: String,
        line_no: usize,
        line: String,
        why: String,
    },
    #[error(
        "rig {link}: no measurement for {samples} samples in a row ({seconds} s); the rig is not answering"
    )]
    Silent {
        link: String,
        samples: usize,
        seconds: f64,
    },
    #[error("rig {link} closed the link at sample {k}: {why}")]
    Closed { link: String, k: usize, why: String },
    #[error("rig {link} reported an error: {text}")]
    Refused { link: String, text: String },
    #[error("rig {link}: {why}")]
    Handshake { link: String, why: String },
    #[error("rig {link}: cannot send: {why}")]
    Send { link: String, why: String },
    #[error("run log {path}: {why}")]
    Log { path: String, why: String },
}

/// A finished run on a rig.
#[derive(Debug, Clone)]
pub struct RemoteRun {
    pub result: EpisodeResult,
    /// Measurements that came after their sample had been held.
    pub late: usize,
}

fn send(link: &mut dyn Link, msg: ToRig) -> Result<(), RigError> {
    link.send(&msg.to_string()).map_err(|e| RigError::Send {
        link: link.describe(),
        why: e.to_string(),
    })
}

/// `HELLO` / `READY`, waiting `timeout` for the answer: returns the rig's
/// sample time.
pub fn connect(link: &mut dyn Link, timeout: Duration) -> Result<f64, RigError> {
    let fail = |link: &dyn Link, why: String| RigError::Handshake {
        link: link.describe(),
        why,
    };
    send(link, ToRig::Hello { version: VERSION })?;
    match link.recv(Some(timeout)) {
        Received::Line(line) => match FromRig::parse(&line) {
            Ok(FromRig::Ready { version, dt }) if version == VERSION => Ok(dt),
            Ok(FromRig::Ready { version, .. }) => Err(fail(
                link,
                format!("speaks protocol version {version}, this build {VERSION}"),
            )),
            Ok(FromRig::Error(text)) => Err(RigError::Refused {
                link: link.describe(),
                text,
            }),
            Ok(other) => Err(fail(link, format!("expected READY, got `{other}`"))),
            Err(e) => Err(fail(link, format!("line 1 `{line}`: {e}"))),
        },
        Received::Timeout => Err(fail(
            link,
            format!("no READY within {:.1} s of HELLO", timeout.as_secs_f64()),
        )),
        Received::Closed(why) => Err(fail(link, format!("closed before READY: {why}"))),
    }
}

/// Runs `controller` over `episode` on a connected rig with sample time
/// `dt`, writing `log` as it goes. On any error the valve is closed first.
pub fn run_remote(
    link: &mut dyn Link,
    dt: f64,
    controller: &mut dyn Controller,
    episode: &Episode,
    settings: &RemoteSettings,
    log: &mut RunLog,
) -> Result<RemoteRun, RigError> {
    let (reference, times) = episode.schedule(dt);
    let n = reference.len();
    let mut lp = ControlLoop::new(controller, reference.clone(), episode.limits, episode.u0);
    let mut record = Recorder::new(lp.name(), n);
    let mut state = Session {
        held: vec![false; n + 1],
        used: vec![false; n + 1],
        line_no: 1, // READY was line 1
        late: 0,
        in_a_row: 0,
    };
    let log_path = log.path().display().to_string();
    let logged = |r: std::io::Result<()>| {
        r.map_err(|e| RigError::Log {
            path: log_path.clone(),
            why: e.to_string(),
        })
    };
    let first = lp.first();
    send(
        link,
        ToRig::Command {
            k: 0,
            volts: first.volts,
        },
    )?;
    // Each measurement is due `deadline` after the one before it arrived
    // (or after the first command, or after the last deadline that passed):
    // on the rig's own rhythm, whatever the controller's compute time.
    let mut anchor = Instant::now();
    let mut result = Ok(());
    while !lp.done() {
        let k = lp.next_sample();
        let left = settings.deadline.saturating_sub(anchor.elapsed());
        // The samples this wait settles: (sample, measurement or None).
        let settled: Vec<(usize, Option<Measurement>)> = match link.recv(Some(left)) {
            Received::Timeout => {
                anchor = Instant::now();
                vec![(k, None)]
            }
            Received::Closed(why) => {
                result = Err(RigError::Closed {
                    link: link.describe(),
                    k,
                    why,
                });
                break;
            }
            Received::Line(line) => match state.accept(link, &line, k, dt, n) {
                Err(e) => {
                    result = Err(e);
                    break;
                }
                Ok(Accepted::Late(j)) => {
                    let note =
                        format!("sample {j}: late measurement set aside (its sample was held)");
                    if let Err(e) = logged(log.event(&note)) {
                        result = Err(e);
                        break;
                    }
                    continue;
                }
                // Samples the rig skipped were missing; their commands held.
                Ok(Accepted::Use(j, m)) => {
                    anchor = Instant::now();
                    (k..j).map(|i| (i, None)).chain([(j, Some(m))]).collect()
                }
            },
        };
        let mut last = first;
        for (i, m) in settled {
            let prev = lp.command_in_force();
            last = lp.step(m);
            record.push(
                times[i - 1],
                reference[i - 1],
                m,
                prev,
                last.volts,
                lp.last_time,
                &episode.limits,
            );
            let written = match m {
                Some(m) => {
                    state.in_a_row = 0;
                    state.used[i] = true;
                    log.row(
                        times[i - 1],
                        reference[i - 1],
                        m.pressure_mpa,
                        m.displacement_mm,
                        last.volts,
                    )
                }
                None => {
                    state.in_a_row += 1;
                    state.held[i] = true;
                    log.event(&format!(
                        "sample {i}: no measurement within {} ms; held {} V",
                        settings.deadline.as_millis(),
                        last.volts
                    ))
                }
            };
            if let Err(e) = logged(written) {
                result = Err(e);
                break;
            }
        }
        if result.is_err() {
            break;
        }
        if state.in_a_row >= settings.max_missing {
            result = Err(RigError::Silent {
                link: link.describe(),
                samples: state.in_a_row,
                seconds: state.in_a_row as f64 * dt,
            });
            break;
        }
        if !lp.done() {
            if let Err(e) = send(
                link,
                ToRig::Command {
                    k: last.k as u64,
                    volts: last.volts,
                },
            ) {
                result = Err(e);
                break;
            }
        }
    }
    match result {
        Ok(()) => {
            let _ = send(link, ToRig::Stop);
            // The rig's BYE is a courtesy; do not wait long for it.
            let _ = link.recv(Some(Duration::from_millis(200)));
            let _ = log.event("run complete; STOP sent");
            Ok(RemoteRun {
                result: record.finish(episode),
                late: state.late,
            })
        }
        Err(e) => {
            let k = lp.next_sample() as u64;
            let _ = send(link, ToRig::Command { k, volts: 0.0 });
            let _ = send(link, ToRig::Stop);
            let _ = log.event(&format!("error: {e}"));
            let _ = log.event(&format!("valve closed: U {k} 0, STOP"));
            Err(e)
        }
    }
}

/// What the loop knows of the samples so far.
struct Session {
    held: Vec<bool>,
    used: Vec<bool>,
    line_no: usize,
    late: usize,
    /// Missing measurements in a row.
    in_a_row: usize,
}

enum Accepted {
    /// The measurement closing sample `j − 1` (`j` ≥ the one due).
    Use(usize, Measurement),
    /// A measurement for a sample that was held.
    Late(usize),
}

impl Session {
    /// Checks one line while the measurement closing sample `k − 1` is due.
    fn accept(
        &mut self,
        link: &dyn Link,
        line: &str,
        k: usize,
        dt: f64,
        n: usize,
    ) -> Result<Accepted, RigError> {
        self.line_no += 1;
        let line_no = self.line_no;
        let stale = |why: String| RigError::Stale {
            link: link.describe(),
            line_no,
            line: line.to_string(),
            why,
        };
        match FromRig::parse(line) {
            Err(e) => Err(RigError::Malformed {
                link: link.describe(),
                line_no,
                line: line.to_string(),
                why: e.0,
            }),
            Ok(FromRig::Error(text)) => Err(RigError::Refused {
                link: link.describe(),
                text,
            }),
            Ok(FromRig::Measurement {
                k: j,
                t,
                pressure_mpa,
                displacement_mm,
            }) => {
                let j = j as usize;
                if j < k {
                    if self.held.get(j).copied().unwrap_or(false) && !self.used[j] {
                        self.late += 1;
                        return Ok(Accepted::Late(j));
                    }
                    return Err(stale(format!(
                        "sample {j} was already used (expected sample {k})"
                    )));
                }
                if j > n {
                    return Err(stale(format!("sample {j} is past the run's {n} samples")));
                }
                if (t - j as f64 * dt).abs() > 0.5 * dt {
                    return Err(stale(format!(
                        "its time stamp {t} s is not its sample's ({} s)",
                        j as f64 * dt
                    )));
                }
                Ok(Accepted::Use(
                    j,
                    Measurement {
                        pressure_mpa,
                        displacement_mm,
                    },
                ))
            }
            Ok(other) => Err(RigError::Malformed {
                link: link.describe(),
                line_no,
                line: line.to_string(),
                why: format!("expected a measurement `M k t pressure displacement`, got `{other}`"),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_deadline_is_one_and_a_half_samples_of_the_rig() {
        let close = |got: Duration, want_ms: f64| (got.as_secs_f64() * 1e3 - want_ms).abs() < 1e-6;
        assert!(close(RemoteSettings::default_deadline(0.01), 15.0));
        assert!(close(RemoteSettings::default_deadline(0.1), 150.0));
        assert!(close(RemoteSettings::default_deadline(0.001), 1.5));
    }
}
