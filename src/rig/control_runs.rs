//! The runs of `mckibben control --plant` on a rig outside this process:
//! where the rig is (`cmd:` or `udp:`), a fresh connection per run, the
//! plausibility limits and deadline every run is held to, and the run log
//! that says which of them it ran under. The counterpart of
//! [`crate::control::table::on_twin`] for the in-process twin; it lives here rather than in
//! `control` because `rig` builds on `control` (no import cycle).
//!
//! The settings carry `control`'s flags one for one and every error names
//! the flag it is about, so that the command only parses, calls and prints.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use anyhow::Context as _;

use super::link::{ChildLink, Link, UdpLink};
use super::log::RunLog;
use super::plausible::Limits;
use super::protocol::Ranges;
use super::remote::{RemoteSettings, connect, hang_up, run_remote};
use crate::control::reference::Waveform;
use crate::control::sweep::{self, Ingredients, Run, RunSpec, Shape};
use crate::control::table::Row;
use crate::twin::TwinConfig;

/// The plant of `--plant`: the in-process twin or a rig behind the line
/// protocol.
pub enum PlantSpec {
    Twin,
    Rig(Endpoint),
}

/// Where a rig is.
pub enum Endpoint {
    /// A command whose stdin/stdout speak the protocol.
    Command(String),
    /// A rig taking datagrams at this address.
    Udp(SocketAddr),
}

impl PlantSpec {
    /// Reads `twin`, `cmd:COMMAND` or `udp:HOST:PORT`.
    pub fn parse(spec: &str) -> anyhow::Result<PlantSpec> {
        if spec == "twin" {
            Ok(PlantSpec::Twin)
        } else if let Some(cmd) = spec.strip_prefix("cmd:") {
            anyhow::ensure!(!cmd.trim().is_empty(), "--plant cmd: needs a command");
            Ok(PlantSpec::Rig(Endpoint::Command(cmd.to_string())))
        } else if let Some(addr) = spec.strip_prefix("udp:") {
            use std::net::ToSocketAddrs;
            let a = addr
                .to_socket_addrs()
                .with_context(|| format!("--plant udp:{addr}: not a HOST:PORT"))?
                .next()
                .ok_or_else(|| anyhow::anyhow!("--plant udp:{addr}: no address"))?;
            Ok(PlantSpec::Rig(Endpoint::Udp(a)))
        } else {
            anyhow::bail!("--plant `{spec}`: expected twin, cmd:COMMAND or udp:HOST:PORT")
        }
    }
}

impl Endpoint {
    /// A new link to the rig: each run starts its own command, or its own
    /// socket, so that no run inherits another's state.
    fn open(&self) -> anyhow::Result<Box<dyn Link>> {
        Ok(match self {
            Endpoint::Command(cmd) => Box::new(
                ChildLink::spawn(cmd).with_context(|| format!("--plant: cannot start `{cmd}`"))?,
            ),
            Endpoint::Udp(addr) => {
                Box::new(UdpLink::connect(*addr).with_context(|| format!("--plant udp:{addr}"))?)
            }
        })
    }
}

/// What every run on a rig is held to: `control`'s `--plant`, `--deadline`,
/// `--max-missing`, `--pressure-range`, `--displacement-range`,
/// `--max-speed`, `--max-implausible` and `--log`.
pub struct RigRunSettings {
    /// The `--plant` spec as given: the rows' plant and the log's command.
    pub plant: String,
    pub endpoint: Endpoint,
    /// Deadline of each sample (ms); `None`: [`RemoteSettings::default_deadline`].
    pub deadline_ms: Option<f64>,
    pub max_missing: usize,
    /// Pressures (MPa) the rig's sensor can read; `None`: see `ranges`.
    pub pressure_range: Option<(f64, f64)>,
    /// Displacements (mm) the rig's sensor can read; `None`: see `ranges`.
    pub displacement_range: Option<(f64, f64)>,
    pub max_speed_mm_s: f64,
    pub max_implausible: usize,
    /// Folder of the run logs; `None`: no log.
    pub log_dir: Option<PathBuf>,
    /// Raised by Ctrl-C: the run in progress ends with the valve closed,
    /// and no other starts.
    pub interrupt: Arc<AtomicBool>,
}

impl RigRunSettings {
    /// Missing measurements in a row that end a run unless `--max-missing`
    /// says otherwise: a tenth of a second of silence at the rig's 10 ms.
    pub const DEFAULT_MAX_MISSING: usize = 10;
    /// Implausible measurements in a row that end a run unless
    /// `--max-implausible` says otherwise.
    pub const DEFAULT_MAX_IMPLAUSIBLE: usize = 3;
}

/// The runs `plan` holds ([`sweep::plan`]; the rig's load is not ours to
/// know, so theirs is NaN) on the rig, each on a fresh connection, with
/// their rows; `progress` hears of each run before it starts.
pub fn on_rig(
    plan: &[RunSpec],
    settings: &RigRunSettings,
    ing: &Ingredients,
    shape: &Shape,
    progress: &dyn Fn(String),
) -> anyhow::Result<(Vec<Row>, Vec<Run>)> {
    // Whether every run can go on a rig sampled every `dt` s: checked at
    // the first connection, so that it refuses a plan a later run would
    // fail on before any run drove the rig (and none is lost), and again
    // only where a later connection announces another sample time.
    let fits_at = std::cell::Cell::new(None);
    let plan_fits = |dt: f64| -> anyhow::Result<()> {
        if fits_at.get() == Some(dt) {
            return Ok(());
        }
        for spec in plan {
            sweep::build(spec.kind, spec.hysteresis_scale, ing, dt).with_context(|| {
                format!("{} cannot run on {}", spec.kind.label(), settings.plant)
            })?;
            shape.episode(spec.freq_rad_s).check(dt).map_err(|why| {
                anyhow::anyhow!(
                    "--freq {}: the rig samples every {dt} s: {why}",
                    spec.freq_rad_s
                )
            })?;
        }
        fits_at.set(Some(dt));
        Ok(())
    };
    let mut rows = Vec::new();
    let mut runs = Vec::new();
    for (i, spec) in plan.iter().enumerate() {
        progress(format!(
            "[{}/{}] {} at {} rad/s on {}",
            i + 1,
            plan.len(),
            sweep::run_label(spec.kind, spec.hysteresis_scale),
            spec.freq_rad_s,
            settings.plant
        ));
        let (run, late) = run_on_rig(spec, settings, ing, shape, &plan_fits)?;
        rows.push(Row::of(&run, &settings.plant, None, late));
        runs.push(run);
    }
    Ok((rows, runs))
}

/// One run of `spec` on the rig, and how many of its measurements came
/// late, once `plan_fits` the sample time the rig announces (else the
/// session ends at once, before any command). The deadline scales with
/// that sample time unless one is given.
fn run_on_rig(
    spec: &RunSpec,
    settings: &RigRunSettings,
    ing: &Ingredients,
    shape: &Shape,
    plan_fits: &dyn Fn(f64) -> anyhow::Result<()>,
) -> anyhow::Result<(Run, usize)> {
    let mut link = settings.endpoint.open()?;
    let (dt, announced) = connect(link.as_mut(), RemoteSettings::CONNECT_TIMEOUT)?;
    if let Err(e) = plan_fits(dt) {
        hang_up(link.as_mut());
        return Err(e);
    }
    let (ranges, source) = ranges(settings, announced);
    let remote_settings = RemoteSettings {
        deadline: settings.deadline_ms.map_or_else(
            || RemoteSettings::default_deadline(dt),
            |ms| Duration::from_secs_f64(ms / 1000.0),
        ),
        max_missing: settings.max_missing,
        limits: Limits {
            ranges,
            max_speed_mm_s: settings.max_speed_mm_s,
        },
        max_implausible: settings.max_implausible,
    };
    let mut controller = sweep::build(spec.kind, spec.hysteresis_scale, ing, dt)?;
    let mut log = match &settings.log_dir {
        Some(dir) => {
            // A steps run at ω has a name of its own, as its table CSV.
            let (suffix, flag) = match shape.waveform {
                Waveform::Sine => ("", ""),
                Waveform::Steps => ("_steps", " --reference steps"),
            };
            // So does a run with its model's hysteresis scaled.
            let (scaled, scaled_flag) = match spec.hysteresis_scale {
                1.0 => (String::new(), String::new()),
                scale => (
                    format!("_hysteresis{scale}"),
                    format!(" --hysteresis-scale {scale}"),
                ),
            };
            let path = dir.join(format!(
                "{}{scaled}_{}rad{suffix}.csv",
                spec.kind.label(),
                spec.freq_rad_s
            ));
            // The header says what the run was held to, so that a log read
            // later explains its own events.
            RunLog::create(
                &path,
                &[
                    format!(
                        "mckibben control --controller {}{scaled_flag} --freq {}{flag} --plant {}",
                        spec.kind.label(),
                        spec.freq_rad_s,
                        settings.plant
                    ),
                    format!(
                        "rig {} (dt {dt} s), deadline {:.1} ms",
                        link.describe(),
                        remote_settings.deadline.as_secs_f64() * 1000.0
                    ),
                    format!(
                        "plausible: pressure {}…{} MPa, displacement {}…{} mm ({source}), at most {} mm/s",
                        ranges.pressure_mpa.0,
                        ranges.pressure_mpa.1,
                        ranges.displacement_mm.0,
                        ranges.displacement_mm.1,
                        settings.max_speed_mm_s
                    ),
                ],
            )
            .with_context(|| format!("--log {}", path.display()))?
        }
        None => RunLog::none(),
    };
    let episode = shape.episode(spec.freq_rad_s);
    let remote = run_remote(
        link.as_mut(),
        dt,
        controller.as_mut(),
        &episode,
        &remote_settings,
        &mut log,
        &settings.interrupt,
    )?;
    let run = Run {
        spec: *spec,
        result: remote.result,
        stats: controller.stats(),
    };
    Ok((run, remote.late))
}

/// The ranges a measurement must be in, and where they come from: a flag
/// wins over what the rig announced in READY, which wins over the twin's
/// own limits.
fn ranges(settings: &RigRunSettings, announced: Option<Ranges>) -> (Ranges, String) {
    let (base, rest) = match announced {
        Some(r) => (r, "announced by the rig"),
        None => (Limits::of_twin(&TwinConfig::default()).ranges, "the twin's"),
    };
    let ranges = Ranges {
        pressure_mpa: settings.pressure_range.unwrap_or(base.pressure_mpa),
        displacement_mm: settings.displacement_range.unwrap_or(base.displacement_mm),
    };
    let given = "from the command line";
    let source = match (
        settings.pressure_range.is_some(),
        settings.displacement_range.is_some(),
    ) {
        (true, true) => given.to_string(),
        (false, false) => rest.to_string(),
        (true, false) => format!("pressure {given}, displacement {rest}"),
        (false, true) => format!("displacement {given}, pressure {rest}"),
    };
    (ranges, source)
}
