//! `twin serve`: the twin plays the rig's end of the line protocol
//! (`crate::rig::protocol`), so that a controller can be run against it as
//! a separate process exactly as against a real rig.
//!
//! Each `HELLO` opens a session on a fresh [`Rig`] (same load, same seed:
//! every session is the same experiment), which starts at rest and whose
//! clock starts with the first command `U 0`. Two paces:
//!
//! - **lockstep** (as fast as possible): the twin advances a sample when the
//!   command for it arrives — the numbers are those of an in-process run;
//! - **real time**: the twin sends sample `k`'s measurement at `k·dt` of
//!   wall time; a command that has not arrived by the next tick is late and
//!   the one in force is held over the sample, as a real rig's board would.
//!
//! Faults can be injected into the measurements (`Fault`), to test how a
//! controller handles a rig that drops, delays or garbles its lines.
//!
//! `READY` announces the twin's sensor ranges. A command outside 0–10 V is
//! refused, not clamped: the session answers `ERR`, closes the input valve
//! and ends. A clamped command would hide the controller's fault and still
//! drive the valve to an end stop.

use std::time::{Duration, Instant};

use super::link::{Link, Received};
use super::plausible::Limits;
use super::protocol::{FromRig, ToRig, VERSION};
use crate::twin::{Rig, Sample, TwinConfig};

/// How the twin keeps time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pace {
    Lockstep,
    RealTime,
}

/// A fault injected into the measurement line of sample `k`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fault {
    /// The line is never sent.
    Drop(u64),
    /// The line is sent this late.
    Delay(u64, Duration),
    /// A malformed line is sent instead.
    Garble(u64),
    /// The line carries the time stamp of ten samples earlier.
    Stale(u64),
    /// The previous sample's line is sent again instead.
    Repeat(u64),
}

/// A `--fault` that is none of the faults' forms (the text as given).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "`{0}`: a fault is drop@K, delay@K=MS, garble@K, stale@K or repeat@K, K ≥ 1: the \
     measurement `M K` it acts on (the first is M 1)"
)]
pub struct NotAFault(pub String);

impl std::str::FromStr for Fault {
    type Err = NotAFault;

    /// `drop@K`, `delay@K=MS`, `garble@K`, `stale@K`, `repeat@K`.
    fn from_str(s: &str) -> Result<Fault, NotAFault> {
        let usage = || NotAFault(s.to_string());
        let (kind, rest) = s.split_once('@').ok_or_else(usage)?;
        let (k, ms) = match rest.split_once('=') {
            Some((k, ms)) => (k, Some(ms)),
            None => (rest, None),
        };
        // No `M 0` is sent: a fault there would never act.
        let k: u64 = k.parse().ok().filter(|&k| k >= 1).ok_or_else(usage)?;
        match (kind, ms) {
            ("drop", None) => Ok(Fault::Drop(k)),
            ("garble", None) => Ok(Fault::Garble(k)),
            ("stale", None) => Ok(Fault::Stale(k)),
            ("repeat", None) => Ok(Fault::Repeat(k)),
            ("delay", Some(ms)) => Ok(Fault::Delay(
                k,
                Duration::from_millis(ms.parse().map_err(|_| usage())?),
            )),
            _ => Err(usage()),
        }
    }
}

/// What `twin serve` plays.
#[derive(Debug, Clone)]
pub struct ServeSettings {
    pub config: TwinConfig,
    pub load_kg: f64,
    pub seed: u64,
    pub pace: Pace,
    pub faults: Vec<Fault>,
    /// A session that receives nothing for this long ends (valve closed).
    pub idle_timeout: Duration,
}

/// How a session ended.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionReport {
    /// Samples the twin advanced.
    pub samples: u64,
    /// Commands that missed their sample (real time only).
    pub late_commands: u64,
    /// Why it ended.
    pub end: String,
}

/// Serves sessions on `link` until it closes; `report` hears of each one.
pub fn serve(
    link: &mut dyn Link,
    settings: &ServeSettings,
    mut report: impl FnMut(&SessionReport),
) -> anyhow::Result<()> {
    loop {
        let line = match link.recv(None) {
            Received::Line(line) => line,
            Received::Closed(_) => return Ok(()),
            Received::Timeout => continue,
        };
        match ToRig::parse(&line) {
            Ok(ToRig::Hello { version }) if version == VERSION => {
                let dt = settings.config.sample_time_s;
                let ranges = Some(Limits::of_twin(&settings.config).ranges);
                link.send(
                    &FromRig::Ready {
                        version,
                        dt,
                        ranges,
                    }
                    .to_string(),
                )?;
                let r = Session::new(settings).run(link)?;
                report(&r);
                link.end_session();
            }
            Ok(ToRig::Hello { version }) => link.send(
                &FromRig::Error(format!(
                    "protocol version {version} is not spoken here (this rig speaks {VERSION})"
                ))
                .to_string(),
            )?,
            Ok(_) => link.send(&FromRig::Error("say HELLO first".into()).to_string())?,
            Err(e) => link.send(&FromRig::Error(format!("`{line}`: {e}")).to_string())?,
        }
    }
}

/// One run of the twin for one controller.
struct Session<'s> {
    settings: &'s ServeSettings,
    rig: Rig,
    /// Samples advanced: the last measurement sent is `M k`.
    k: u64,
    u: f64,
    late: u64,
    last_line: String,
}

/// What the next message did to the session.
enum Next {
    Command(f64),
    End(String),
}

impl<'s> Session<'s> {
    fn new(settings: &'s ServeSettings) -> Self {
        Session {
            settings,
            rig: Rig::new(&settings.config, settings.load_kg, settings.seed),
            k: 0,
            u: 0.0,
            late: 0,
            last_line: String::new(),
        }
    }

    fn report(&self, end: String) -> SessionReport {
        SessionReport {
            samples: self.k,
            late_commands: self.late,
            end,
        }
    }

    /// Waits until `until` (`None`: the idle timeout) for the command of
    /// sample `k`, skipping late ones for earlier samples.
    fn command(
        &mut self,
        link: &mut dyn Link,
        k: u64,
        until: Option<Instant>,
    ) -> anyhow::Result<Option<Next>> {
        loop {
            let wait = match until {
                Some(t) => t.saturating_duration_since(Instant::now()),
                None => self.settings.idle_timeout,
            };
            match link.recv(Some(wait)) {
                Received::Timeout if until.is_some() => return Ok(None),
                Received::Timeout => {
                    return Ok(Some(Next::End(format!(
                        "no command for {:.0} s",
                        self.settings.idle_timeout.as_secs_f64()
                    ))));
                }
                Received::Closed(why) => {
                    return Ok(Some(Next::End(format!("link closed ({why})"))));
                }
                Received::Line(line) => match ToRig::parse(&line) {
                    Ok(ToRig::Command { k: j, volts }) if j == k => {
                        return Ok(Some(Next::Command(volts)));
                    }
                    Ok(ToRig::Command { k: j, .. }) if j < k => continue,
                    Ok(ToRig::Stop) => return Ok(Some(Next::End("STOP".into()))),
                    Ok(other) => {
                        let why = format!("`{other}` while the command for sample {k} was due");
                        link.send(
                            &FromRig::Error(format!("{why}; input valve closed")).to_string(),
                        )?;
                        return Ok(Some(Next::End(why)));
                    }
                    Err(e) => {
                        let why = format!("`{line}`: {e}");
                        link.send(
                            &FromRig::Error(format!("{why}; input valve closed")).to_string(),
                        )?;
                        return Ok(Some(Next::End(why)));
                    }
                },
            }
        }
    }

    /// Sends the measurement `M k`, with any fault for `k` applied.
    fn send_measurement(&mut self, link: &mut dyn Link, s: Sample) -> anyhow::Result<()> {
        let dt = self.settings.config.sample_time_s;
        let k = self.k;
        let line = |t: f64| {
            FromRig::Measurement {
                k,
                t,
                pressure_mpa: s.pressure_mpa,
                displacement_mm: s.displacement_mm,
            }
            .to_string()
        };
        let honest = line(s.t);
        let mut out = Some(honest.clone());
        for f in &self.settings.faults {
            match *f {
                Fault::Drop(j) if j == k => out = None,
                Fault::Delay(j, d) if j == k => std::thread::sleep(d),
                Fault::Garble(j) if j == k => {
                    out = Some(format!("M {k} {} 0.2O {}", s.t, s.displacement_mm))
                }
                Fault::Stale(j) if j == k => out = Some(line(s.t - 10.0 * dt)),
                Fault::Repeat(j) if j == k => out = Some(self.last_line.clone()),
                _ => {}
            }
        }
        if let Some(out) = out {
            link.send(&out)?;
        }
        self.last_line = honest;
        Ok(())
    }

    fn run(mut self, link: &mut dyn Link) -> anyhow::Result<SessionReport> {
        match self.command(link, 0, None)? {
            Some(Next::Command(v)) => self.u = v,
            Some(Next::End(why)) => return Ok(self.close(why)),
            None => unreachable!("no deadline before the first command"),
        }
        let dt = self.settings.config.sample_time_s;
        let start = Instant::now();
        let tick = |k: u64| start + Duration::from_secs_f64(dt * k as f64);
        loop {
            let sample = self.rig.step(self.u);
            self.k += 1;
            // Past its physics the twin has nothing true to send: it ends
            // the session as a rig's own fault would.
            if let Some(why) = left_physics(&self.rig, &sample) {
                link.send(&FromRig::Error(format!("{why}; input valve closed")).to_string())?;
                return Ok(self.close(why));
            }
            if self.settings.pace == Pace::RealTime {
                std::thread::sleep(tick(self.k).saturating_duration_since(Instant::now()));
            }
            self.send_measurement(link, sample)?;
            let until = (self.settings.pace == Pace::RealTime).then(|| tick(self.k + 1));
            match self.command(link, self.k, until)? {
                Some(Next::Command(v)) => self.u = v,
                Some(Next::End(why)) => return Ok(self.close(why)),
                // Real time: no command by the next tick; hold the one in force.
                None => self.late += 1,
            }
        }
    }

    /// Ends the session with the input valve closed.
    fn close(mut self, why: String) -> SessionReport {
        self.u = 0.0;
        self.report(format!("{why}; input valve closed ({} V)", self.u))
    }
}

/// Why the twin's last `sample` is outside its physics, if it is: the
/// load's ringing has left the muscle slack, or a reading is not finite.
fn left_physics(rig: &Rig, sample: &Sample) -> Option<String> {
    if let Some(from) = rig.slack_from() {
        return Some(format!(
            "the load's ringing left the muscle slack at sample {from}, which the twin does not \
             model (a smaller --effect ringing)"
        ));
    }
    let finite = sample.pressure_mpa.is_finite() && sample.displacement_mm.is_finite();
    (!finite).then(|| {
        format!(
            "the twin's readings are not finite at t = {:.3} s: it left its physics (another \
             load, or --effect scales nearer 1)",
            sample.t
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each fault's form reads; one at `M 0`, which is never sent, would
    /// never act and is refused, as is any other text.
    #[test]
    fn faults_read_from_measurement_one_on() {
        assert_eq!("drop@1".parse(), Ok(Fault::Drop(1)));
        assert_eq!("repeat@7".parse(), Ok(Fault::Repeat(7)));
        assert_eq!(
            "delay@3=250".parse(),
            Ok(Fault::Delay(3, Duration::from_millis(250)))
        );
        for bad in [
            "drop@0",
            "repeat@0",
            "delay@0=5",
            "drop",
            "drop@x",
            "melt@3",
        ] {
            let err = bad.parse::<Fault>().unwrap_err();
            assert_eq!(err, NotAFault(bad.to_string()));
            assert!(err.to_string().contains("K ≥ 1"), "{err}");
        }
    }
}
