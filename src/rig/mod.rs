//! Running a controller on a rig that lives outside this process: the line
//! protocol (`protocol`, documented in docs/RIG_PROTOCOL.md), its transports
//! (`link`: a child process's stdin/stdout, this process's own, UDP), the
//! controller's end with its deadlines (`remote`), the check that a
//! measurement can be one (`plausible`), the run log written as the run
//! goes (`log`) and `mckibben control`'s runs made of these
//! (`control_runs`); the twin playing the rig's end (`serve`), here beside the
//! protocol rather than in `twin`, so that `twin` stays below `control` and
//! `rig` (no import cycle).

pub mod control_runs;
pub mod link;
pub mod log;
pub mod plausible;
pub mod protocol;
pub mod remote;
pub mod serve;

pub use link::{ChildLink, Link, Received, StdioLink, UdpLink};
pub use log::RunLog;
pub use plausible::{Limits, Plausibility};
pub use protocol::Ranges;
pub use remote::{RemoteRun, RemoteSettings, RigError, connect, run_remote};
