//! A call of the control runs stopped from outside (Ctrl-C, Python's
//! `KeyboardInterrupt`): between two runs on the twin, or in the PID's
//! tuning between two generations.

use crate::optim::stop::StopFlag;

/// The error of a call stopped by its [`super::session::ControlPlan::stop`].
#[derive(Debug, thiserror::Error)]
#[error("the control runs were interrupted before their table; nothing was printed or written")]
pub struct Interrupted;

/// [`Interrupted`] where `stop` is raised.
pub(crate) fn go_on(stop: &StopFlag) -> anyhow::Result<()> {
    if stop.raised() {
        return Err(Interrupted.into());
    }
    Ok(())
}
