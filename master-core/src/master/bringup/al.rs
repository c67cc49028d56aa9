//! Moving one slave between AL states (spec-notes §al): request, poll, acknowledge errors.

use tokio::time::Instant;

use crate::bus::BusHandle;
use crate::wire::register::address as reg;
use crate::wire::register::al::AL_STATUS_BLOCK_LEN;
use crate::wire::register::{AlControl, AlState, AlStatusBlock, AlStatusBlockRepr};

use crate::master::access::datagram::{fprd, fpwr};
use crate::master::config::MasterConfig;
use crate::master::error::MasterError;

/// The slave a state change is for, as errors name it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Who<'a> {
    pub position: u16,
    pub station: u16,
    pub name: &'a str,
}

/// Reads AL status and AL status code (6 bytes at 0x0130).
pub(crate) async fn read_status(
    bus: &BusHandle,
    who: Who<'_>,
) -> Result<AlStatusBlockRepr, MasterError> {
    let data = fprd(
        bus,
        who.station,
        reg::AL_STATUS,
        AL_STATUS_BLOCK_LEN,
        "AL status",
    )
    .await?;
    AlStatusBlock::new_checked(&data[..])
        .and_then(|view| AlStatusBlockRepr::parse(&view))
        .map_err(|source| MasterError::Malformed {
            position: who.position,
            what: "AL status",
            source,
        })
}

async fn write_control(
    bus: &BusHandle,
    station: u16,
    control: AlControl,
) -> Result<(), MasterError> {
    let mut bytes = [0u8; AlControl::LEN];
    control
        .emit(&mut bytes)
        .map_err(|_| MasterError::InvalidState(control.state))?;
    fpwr(bus, station, reg::AL_CONTROL, bytes, "AL control").await
}

/// Clears a pending error indication, staying in the current state.
pub(crate) async fn acknowledge(
    bus: &BusHandle,
    who: Who<'_>,
    state: AlState,
) -> Result<(), MasterError> {
    write_control(bus, who.station, AlControl::acknowledge(state)).await
}

/// Requests `to` and waits until the slave is there. A pending error is acknowledged with
/// the request (`to | 0x10`, as SOEM and IgH do). If the slave refuses, its AL status code
/// is read, the error is acknowledged (so the slave is left clean in the state it kept) and
/// returned as [`MasterError::StateRefused`].
pub(crate) async fn change_state(
    bus: &BusHandle,
    config: &MasterConfig,
    who: Who<'_>,
    to: AlState,
) -> Result<AlStatusBlockRepr, MasterError> {
    if matches!(to, AlState::Unknown(_)) {
        return Err(MasterError::InvalidState(to));
    }
    let before = read_status(bus, who).await?;
    if before.status.state == to && !before.status.error {
        return Ok(before);
    }
    let control = if before.status.error {
        AlControl::acknowledge(to)
    } else {
        AlControl::request(to)
    };
    write_control(bus, who.station, control).await?;
    let deadline = Instant::now() + config.timeout_for(to);
    loop {
        let now = read_status(bus, who).await?;
        if now.status.error {
            acknowledge(bus, who, now.status.state).await?;
            return Err(MasterError::StateRefused {
                position: who.position,
                station: who.station,
                name: who.name.to_owned(),
                from: before.status.state,
                to,
                code: now.code,
            });
        }
        if now.status.state == to {
            return Ok(now);
        }
        if Instant::now() >= deadline {
            return Err(MasterError::StateTimeout {
                position: who.position,
                name: who.name.to_owned(),
                to,
                state: now.status.state,
            });
        }
        tokio::time::sleep(config.poll_interval).await;
    }
}

/// The states to pass through from `from` to `to`, one transition at a time, without the
/// starting state: up INIT → PREOP → SAFEOP → OP; down directly (every state may go to
/// INIT, PREOP or SAFEOP below it); BOOT only from INIT.
pub(crate) fn path(from: AlState, to: AlState) -> Vec<AlState> {
    use AlState::{Boot, Init, Op, PreOp, SafeOp};
    let rank = |s: AlState| match s {
        Init | Boot => 0,
        PreOp => 1,
        SafeOp => 2,
        Op => 3,
        AlState::Unknown(_) => 0,
    };
    if to == Boot {
        return if from == Init {
            vec![Boot]
        } else {
            vec![Init, Boot]
        };
    }
    if from == Boot || matches!(from, AlState::Unknown(_)) {
        let mut rest = vec![Init];
        rest.extend(path(Init, to).into_iter().filter(|&s| s != Init));
        return rest;
    }
    if rank(to) <= rank(from) {
        return if to == from { Vec::new() } else { vec![to] };
    }
    [PreOp, SafeOp, Op]
        .into_iter()
        .filter(|&s| rank(s) > rank(from) && rank(s) <= rank(to))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use AlState::{Boot, Init, Op, PreOp, SafeOp};

    #[test]
    fn paths_go_up_one_step_at_a_time_and_down_directly() {
        assert_eq!(path(Init, Op), vec![PreOp, SafeOp, Op]);
        assert_eq!(path(PreOp, SafeOp), vec![SafeOp]);
        assert_eq!(path(Op, Init), vec![Init]);
        assert_eq!(path(Op, PreOp), vec![PreOp]);
        assert_eq!(path(Op, Op), vec![]);
        assert_eq!(path(PreOp, Boot), vec![Init, Boot]);
        assert_eq!(path(Init, Boot), vec![Boot]);
        assert_eq!(path(Boot, PreOp), vec![Init, PreOp]);
        assert_eq!(path(Boot, Init), vec![Init]);
    }
}
