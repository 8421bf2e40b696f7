//! The controller's end of the line protocol: a [`ControlLoop`] driven by a
//! rig over a [`Link`], with a deadline on every sample.
//!
//! - The measurement that closes sample `k − 1` is due within the deadline
//!   after the previous one arrived. If it is **missing** then, the
//!   command in force is held over sample `k` (sent again as `U k`) and the
//!   controller is told; after `max_missing` in a row the rig counts as
//!   silent. A measurement that comes after its sample was held is **late**:
//!   logged and set aside.
//! - A well-formed measurement the rig cannot have taken (outside its
//!   ranges, or a jump its load cannot make: `plausible`) is **implausible**:
//!   held and logged like a missing one, never shown to the controller;
//!   after `max_implausible` in a row the run ends with the valve closed.
//! - A **malformed** line (not the protocol, a field that is not a finite
//!   number) or a **stale** one (a sample already used, or a time stamp that
//!   is not its sample's) ends the run with an error that quotes the line,
//!   and the valve is closed: `U k 0` then `STOP`. Closing is the one command
//!   exempt from the slew limit: the rig can no longer be trusted to carry a
//!   ramp.
//! - A rig that **goes away** (end of stream, a broken pipe) ends the run
//!   with an error that names the last sample exchanged; the log says
//!   whether the close could still be delivered.
//! - Every `U` passes one last guard before it goes out: a command that is
//!   not a number in 0–10 V is never sent, whatever the controller computed;
//!   the run ends with the valve closed instead.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use thiserror::Error;

use super::link::{Link, Received};
use super::log::RunLog;
use super::plausible::{Implausible, Limits, Plausibility};
use super::protocol::{FromRig, Ranges, ToRig, VERSION, VOLTS};
use crate::control::closed_loop::Recorder;
use crate::control::runtime::Command;
use crate::control::{ControlLoop, Controller, Episode, EpisodeResult, Measurement};

/// How strict the loop is with the rig.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RemoteSettings {
    /// Time a measurement may take after the one before it arrived (the
    /// sample's deadline): the sample time plus the jitter allowed.
    pub deadline: Duration,
    /// Missing measurements in a row after which the run stops.
    pub max_missing: usize,
    /// What a measurement must satisfy to be shown to the controller.
    pub limits: Limits,
    /// Implausible measurements in a row after which the run stops.
    pub max_implausible: usize,
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
    #[error(
        "rig {link}, line {line_no} `{line}`: implausible measurement ({count} in a row): {why}"
    )]
    Implausible {
        link: String,
        line_no: usize,
        line: String,
        why: Implausible,
        count: usize,
    },
    #[error("rig {link} went away ({why}); last exchanged: {last}")]
    Gone {
        link: String,
        why: String,
        last: String,
    },
    #[error(
        "rig {link}: the controller computed `U {k} {volts}`, not a valve command ({}–{} V); not sent",
        VOLTS.0,
        VOLTS.1
    )]
    Command { link: String, k: u64, volts: f64 },
    #[error("rig {link} reported an error: {text}")]
    Refused { link: String, text: String },
    #[error("rig {link}: {why}")]
    Handshake { link: String, why: String },
    #[error("rig {link}: cannot send: {why}")]
    Send { link: String, why: String },
    #[error("run log {path}: {why}")]
    Log { path: String, why: String },
    #[error("rig {link}: interrupted (Ctrl-C) before sample {k}")]
    Interrupted { link: String, k: usize },
}

/// A finished run on a rig.
#[derive(Debug, Clone)]
pub struct RemoteRun {
    pub result: EpisodeResult,
    /// Measurements that came after their sample had been held.
    pub late: usize,
}

/// Sends `msg`: the last guard between a controller and the valve. A
/// command that is not a finite number in 0–10 V does not go out.
fn send(link: &mut dyn Link, msg: ToRig) -> Result<(), RigError> {
    if let ToRig::Command { k, volts } = msg
        && !(VOLTS.0..=VOLTS.1).contains(&volts)
    {
        return Err(RigError::Command {
            link: link.describe(),
            k,
            volts,
        });
    }
    link.send(&msg.to_string()).map_err(|e| RigError::Send {
        link: link.describe(),
        why: e.to_string(),
    })
}

/// A line the rig sent that the protocol refused, as an error quotes it:
/// control characters and other bytes escaped (`\u{1b}`), so that a rig
/// sending binary cannot drive the user's terminal through the message.
fn shown(line: &str) -> String {
    line.escape_debug().to_string()
}

/// `HELLO` / `READY`, waiting `timeout` for the answer: returns the rig's
/// sample time and the ranges it announced, if it did.
pub fn connect(link: &mut dyn Link, timeout: Duration) -> Result<(f64, Option<Ranges>), RigError> {
    let fail = |link: &dyn Link, why: String| RigError::Handshake {
        link: link.describe(),
        why,
    };
    send(link, ToRig::Hello { version: VERSION })?;
    match link.recv(Some(timeout)) {
        Received::Line(line) => match FromRig::parse(&line) {
            Ok(FromRig::Ready {
                version,
                dt,
                ranges,
            }) if version == VERSION => Ok((dt, ranges)),
            Ok(FromRig::Ready { version, .. }) => Err(fail(
                link,
                format!("speaks protocol version {version}, this build {VERSION}"),
            )),
            Ok(FromRig::Error(text)) => Err(RigError::Refused {
                link: link.describe(),
                text,
            }),
            Ok(other) => Err(fail(link, format!("expected READY, got `{other}`"))),
            Err(e) => Err(fail(link, format!("line 1 `{}`: {e}", shown(&line)))),
        },
        Received::Timeout => Err(fail(
            link,
            format!("no READY within {:.1} s of HELLO", timeout.as_secs_f64()),
        )),
        Received::Closed(why) => Err(fail(link, format!("closed before READY: {why}"))),
    }
}

/// Ends a session before its first command: `STOP` (the valve was never
/// moved), its `BYE` not waited for long.
pub fn hang_up(link: &mut dyn Link) {
    let _ = send(link, ToRig::Stop);
    let _ = link.recv(Some(Duration::from_millis(200)));
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
    interrupt: &AtomicBool,
) -> Result<RemoteRun, RigError> {
    episode.check(dt).map_err(|why| RigError::Handshake {
        link: link.describe(),
        why: format!("sample time {dt} s: {why}"),
    })?;
    let (reference, times) = episode.schedule(dt);
    let n = reference.len();
    let lp = ControlLoop::new(controller, reference.clone(), episode.limits, episode.u0);
    let record = Recorder::new(lp.name(), n);
    let state = Session {
        held: vec![false; n + 1],
        used: vec![false; n + 1],
        line_no: 1, // READY was line 1
        late: 0,
        in_a_row: 0,
        implausible: 0,
        measured: None,
        commanded: None,
    };
    let mut run = RemoteLoop {
        link,
        interrupt,
        dt,
        episode,
        settings,
        plausible: Plausibility::new(settings.limits, dt),
        log_path: log.path().display().to_string(),
        log,
        lp,
        record,
        reference,
        times,
        state,
    };
    let result = run.drive();
    run.finish(result)
}

/// A run on a rig in progress: the line to the rig, the loop it drives and
/// what the run records and logs, and what the run knows of its samples.
struct RemoteLoop<'a, 'c> {
    link: &'a mut dyn Link,
    /// Raised by Ctrl-C: the run ends before its next sample, as after an
    /// error, with the valve closed.
    interrupt: &'a AtomicBool,
    dt: f64,
    episode: &'a Episode,
    settings: &'a RemoteSettings,
    plausible: Plausibility,
    /// The run log's path, for its errors.
    log_path: String,
    log: &'a mut RunLog,
    lp: ControlLoop<'c>,
    record: Recorder,
    /// Each sample's reference and time.
    reference: Vec<f64>,
    times: Vec<f64>,
    state: Session,
}

/// A run log's write result, its error naming the log at `path`.
fn logged(path: &str, r: std::io::Result<()>) -> Result<(), RigError> {
    r.map_err(|e| RigError::Log {
        path: path.to_string(),
        why: e.to_string(),
    })
}

impl RemoteLoop<'_, '_> {
    /// Drives the loop to its last sample: the first command, then, for
    /// every sample, the wait for its measurement, the controller's steps
    /// over what the wait settled and the next command. The first error
    /// ends it.
    fn drive(&mut self) -> Result<(), RigError> {
        let first = self.lp.first();
        self.state.command(self.link, 0, first.volts)?;
        // Each measurement is due `deadline` after the one before it arrived
        // (or after the first command, or after the last deadline that passed):
        // on the rig's own rhythm, whatever the controller's compute time.
        let mut anchor = Instant::now();
        while !self.lp.done() {
            let k = self.lp.next_sample();
            if self.interrupt.load(Ordering::SeqCst) {
                return Err(RigError::Interrupted {
                    link: self.link.describe(),
                    k,
                });
            }
            let Some(settled) = self.wait(k, &mut anchor)? else {
                continue;
            };
            let last = self.settle(settled, first)?;
            if self.state.in_a_row >= self.settings.max_missing {
                return Err(RigError::Silent {
                    link: self.link.describe(),
                    samples: self.state.in_a_row,
                    seconds: self.state.in_a_row as f64 * self.dt,
                });
            }
            if !self.lp.done() {
                self.state.command(self.link, last.k as u64, last.volts)?;
            }
        }
        Ok(())
    }

    /// Waits until the deadline of the measurement closing sample `k − 1`
    /// (from `anchor`, moved on when a measurement arrives or the deadline
    /// passes): the samples the wait settles, and what settled each; `None`
    /// where a late measurement was set aside and the sample is still due.
    fn wait(
        &mut self,
        k: usize,
        anchor: &mut Instant,
    ) -> Result<Option<Vec<(usize, Settled)>>, RigError> {
        let left = self.settings.deadline.saturating_sub(anchor.elapsed());
        let line = match self.link.recv(Some(left)) {
            Received::Timeout => {
                *anchor = Instant::now();
                return Ok(Some(vec![(k, Settled::Missing)]));
            }
            Received::Closed(why) => return Err(self.state.gone(self.link, why)),
            Received::Line(line) => line,
        };
        let n = self.reference.len();
        match self.state.accept(self.link, &line, k, self.dt, n)? {
            Accepted::Late(j) => {
                let note = format!("sample {j}: late measurement set aside (its sample was held)");
                logged(&self.log_path, self.log.event(&note))?;
                Ok(None)
            }
            // Samples the rig skipped were missing; their commands held.
            Accepted::Use(j, m) => {
                *anchor = Instant::now();
                let last = match self.plausible.check(j, &m) {
                    Ok(()) => {
                        self.state.implausible = 0;
                        Settled::Measured(m)
                    }
                    Err(why) => {
                        self.state.implausible += 1;
                        if self.state.implausible >= self.settings.max_implausible {
                            return Err(RigError::Implausible {
                                link: self.link.describe(),
                                line_no: self.state.line_no,
                                line,
                                why,
                                count: self.state.implausible,
                            });
                        }
                        Settled::Implausible(format!("line {} `{line}`: {why}", self.state.line_no))
                    }
                };
                Ok(Some(
                    (k..j)
                        .map(|i| (i, Settled::Missing))
                        .chain([(j, last)])
                        .collect(),
                ))
            }
        }
    }

    /// Steps the controller over every settled sample, in order, recording
    /// and logging each: a measured one shown to the controller, a missing
    /// or implausible one held. Returns the last command computed (`first`
    /// where nothing settled).
    fn settle(
        &mut self,
        settled: Vec<(usize, Settled)>,
        first: Command,
    ) -> Result<Command, RigError> {
        let (times, reference) = (&self.times, &self.reference);
        let mut last = first;
        for (i, s) in settled {
            let m = match s {
                Settled::Measured(m) => Some(m),
                _ => None,
            };
            let prev = self.lp.command_in_force();
            last = self.lp.step(m);
            self.record.push(
                times[i - 1],
                reference[i - 1],
                m,
                prev,
                last.volts,
                self.lp.last_time,
                &self.episode.limits,
            );
            let state = &mut self.state;
            let written = match s {
                Settled::Measured(m) => {
                    state.in_a_row = 0;
                    state.used[i] = true;
                    state.measured = Some((i, state.line_no));
                    self.log.row(
                        times[i - 1],
                        reference[i - 1],
                        m.pressure_mpa,
                        m.displacement_mm,
                        last.volts,
                    )
                }
                Settled::Missing => {
                    state.in_a_row += 1;
                    state.held[i] = true;
                    self.log.event(&format!(
                        "sample {i}: no measurement within {} ms; held {} V",
                        self.settings.deadline.as_millis(),
                        last.volts
                    ))
                }
                // Held like a missing one, but counted apart: the rig did
                // answer. Not `held`: a second line for the sample is stale.
                Settled::Implausible(why) => self.log.event(&format!(
                    "sample {i}: implausible measurement, {why}; held {} V",
                    last.volts
                )),
            };
            logged(&self.log_path, written)?;
        }
        Ok(last)
    }

    /// Ends the run as `result` says: after a run to its end, `STOP`; after
    /// an error, the error logged first and the valve closed (`U k 0`, then
    /// `STOP`), the log saying whether the close could be delivered.
    fn finish(self, result: Result<(), RigError>) -> Result<RemoteRun, RigError> {
        let (link, log) = (self.link, self.log);
        match result {
            Ok(()) => {
                let _ = send(link, ToRig::Stop);
                // The rig's BYE is a courtesy; do not wait long for it.
                let _ = link.recv(Some(Duration::from_millis(200)));
                let _ = log.event("run complete; STOP sent");
                Ok(RemoteRun {
                    result: self.record.finish(self.episode),
                    late: self.state.late,
                })
            }
            Err(e) => {
                // The error goes into the log first: whatever the link does to
                // the close, the log says why the run ended.
                let _ = log.event(&format!("error: {e}"));
                // The close is the command of the sample after the last one
                // sent: the one the rig waits for. A rig that went away may
                // still read its stdin, so it is sent all the same; but only a
                // rig still there closed the valve.
                let k = self.state.commanded.map_or(0, |(k, _)| k + 1);
                let close = send(link, ToRig::Command { k, volts: 0.0 })
                    .and_then(|()| send(link, ToRig::Stop));
                let note = match (close, &e) {
                    (Ok(()), RigError::Gone { .. }) => format!(
                        "U {k} 0, STOP sent after the rig went away: the valve is as the rig left it"
                    ),
                    (Ok(()), _) => format!("valve closed: U {k} 0, STOP"),
                    (Err(RigError::Send { why, .. }), _) => {
                        format!(
                            "U {k} 0, STOP not delivered ({why}): the valve is as the rig left it"
                        )
                    }
                    (Err(other), _) => format!("U {k} 0, STOP not sent: {other}"),
                };
                let _ = log.event(&note);
                Err(e)
            }
        }
    }
}

/// What settled a sample.
enum Settled {
    Measured(Measurement),
    Missing,
    /// Refused by the plausibility check: the line and why.
    Implausible(String),
}

/// What the loop knows of the samples so far.
struct Session {
    held: Vec<bool>,
    used: Vec<bool>,
    line_no: usize,
    late: usize,
    /// Missing measurements in a row.
    in_a_row: usize,
    /// Implausible measurements in a row.
    implausible: usize,
    /// The last sample whose measurement was used, and its line.
    measured: Option<(usize, usize)>,
    /// The last command sent: sample and volts.
    commanded: Option<(u64, f64)>,
}

enum Accepted {
    /// The measurement closing sample `j − 1` (`j` ≥ the one due).
    Use(usize, Measurement),
    /// A measurement for a sample that was held.
    Late(usize),
}

impl Session {
    /// Sends `U k volts` (through the guard) and remembers it.
    fn command(&mut self, link: &mut dyn Link, k: u64, volts: f64) -> Result<(), RigError> {
        match send(link, ToRig::Command { k, volts }) {
            Ok(()) => {
                self.commanded = Some((k, volts));
                Ok(())
            }
            Err(RigError::Send { why, .. }) => Err(self.gone(link, why)),
            Err(e) => Err(e),
        }
    }

    /// The link broke: says which sample was exchanged last, so that the
    /// rig's own record can be matched to this one.
    fn gone(&self, link: &dyn Link, why: String) -> RigError {
        let measured = match self.measured {
            Some((j, line)) => format!("M {j} received (line {line})"),
            None => "no measurement received".into(),
        };
        let commanded = match self.commanded {
            Some((k, v)) => format!("U {k} {v} sent"),
            None => "no command sent".into(),
        };
        RigError::Gone {
            link: link.describe(),
            why,
            last: format!("{measured}, {commanded}"),
        }
    }

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
                line: shown(line),
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

    /// A rig in memory that answers every `U k` with a plausible `M k+1`
    /// and keeps every line it was sent.
    struct EchoRig {
        sent: Vec<String>,
    }

    impl Link for EchoRig {
        fn send(&mut self, line: &str) -> std::io::Result<()> {
            self.sent.push(line.to_string());
            Ok(())
        }

        fn recv(&mut self, _: Option<Duration>) -> Received {
            match self.sent.last().and_then(|l| ToRig::parse(l).ok()) {
                Some(ToRig::Command { k, .. }) => {
                    let j = k + 1;
                    Received::Line(format!("M {j} {} 0.2 25", j as f64 * 0.01))
                }
                _ => Received::Closed("end of stream".into()),
            }
        }

        fn describe(&self) -> String {
            "echo".into()
        }
    }

    /// A controller that answers 5 V, and from its third command on `bad`
    /// (a bug, where `bad` is no valve command), raising `interrupt` then
    /// (Ctrl-C) where it has one.
    struct Faulty<'a> {
        bad: f64,
        calls: usize,
        interrupt: Option<&'a AtomicBool>,
    }

    impl Controller for Faulty<'_> {
        fn name(&self) -> &str {
            "faulty"
        }

        fn reset(&mut self, _: f64) {
            self.calls = 0;
        }

        fn command(&mut self, _: Measurement, _: &[f64]) -> f64 {
            self.calls += 1;
            if self.calls < 3 {
                return 5.0;
            }
            if let Some(flag) = self.interrupt {
                flag.store(true, Ordering::SeqCst);
            }
            self.bad
        }
    }

    /// A deadline no test machine misses, three misses or implausible
    /// measurements in a row allowed, the twin's ranges.
    fn patient() -> RemoteSettings {
        RemoteSettings {
            deadline: Duration::from_secs(5),
            max_missing: 3,
            limits: Limits::of_twin(&crate::twin::TwinConfig::default()),
            max_implausible: 3,
        }
    }

    #[test]
    fn a_command_outside_0_to_10_volts_never_reaches_the_rig() {
        let settings = patient();
        let episode = Episode::short(3.0, 0.1, 0.1, 0.05);
        for bad in [f64::NAN, f64::INFINITY, 12.0, -0.5, 10.000001] {
            let mut rig = EchoRig { sent: Vec::new() };
            let mut c = Faulty {
                bad,
                calls: 0,
                interrupt: None,
            };
            let out = run_remote(
                &mut rig,
                0.01,
                &mut c,
                &episode,
                &settings,
                &mut RunLog::none(),
                &AtomicBool::new(false),
            );
            let err = out.expect_err("the run must fail").to_string();
            assert!(
                err.contains("`U 3 ") && err.contains("not sent"),
                "{bad}: {err}"
            );
            for line in &rig.sent {
                assert!(ToRig::parse(line).is_ok(), "{bad}: sent `{line}`");
            }
            let tail: Vec<&str> = rig.sent.iter().rev().take(3).map(|s| s.as_str()).collect();
            assert_eq!(tail, ["STOP", "U 3 0", "U 2 5"], "{bad}");
        }
    }

    #[test]
    fn ctrl_c_ends_the_run_with_the_valve_closed() {
        let settings = patient();
        let episode = Episode::short(3.0, 0.1, 0.1, 0.05);
        let flag = AtomicBool::new(false);
        let mut rig = EchoRig { sent: Vec::new() };
        let mut c = Faulty {
            bad: 5.0,
            calls: 0,
            interrupt: Some(&flag),
        };
        let out = run_remote(
            &mut rig,
            0.01,
            &mut c,
            &episode,
            &settings,
            &mut RunLog::none(),
            &flag,
        );
        let err = out.expect_err("the run must stop").to_string();
        assert!(
            err.contains("interrupted (Ctrl-C) before sample 4"),
            "{err}"
        );
        let tail: Vec<&str> = rig.sent.iter().rev().take(3).map(|s| s.as_str()).collect();
        assert_eq!(tail, ["STOP", "U 4 0", "U 3 5"]);
    }
}
