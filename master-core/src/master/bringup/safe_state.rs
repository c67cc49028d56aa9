//! Bringing the whole segment down to a safe state at once (shutdown): one broadcast AL
//! control write, then broadcast reads of AL status until no slave is above the target.
//!
//! A BRD of AL status (0x0130) returns the OR of every slave's status and counts them in its
//! working counter (ETG.1000.4 §5.4.3, spec-notes §commands); since each AL state is one bit
//! (ETG.1000.6 §5.3.2, spec-notes §al: INIT 1, PREOP 2, BOOT 3, SAFEOP 4, OP 8), "no bit of a
//! state above the target" in the OR means every slave that answered is at or below it.

use std::sync::Arc;
use std::time::Duration;

use tokio::time::Instant;

use crate::bus::{BusHandle, DatagramRequest};
use crate::master::Master;
use crate::master::error::MasterError;
use crate::wire::register::address as reg;
use crate::wire::register::{AlControl, AlState};

/// Pause between two looks at AL status while the slaves move.
const POLL: Duration = Duration::from_millis(5);

/// What [`Master::all_to_safe`] achieved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SafeStateReport {
    /// Slaves that answered the last AL status read.
    pub slaves: u16,
    /// Whether every one of them was at or below the target state at the end.
    pub confirmed: bool,
}

impl Master {
    /// Brings every slave on the segment to `state` (INIT or SAFEOP) at once and confirms it
    /// before `deadline`; it does not wait for a scan or a state change in progress, and
    /// needs no scan at all for INIT (a shutdown during the start-up scan).
    ///
    /// INIT is one broadcast AL control write (with the error acknowledge bit, so a slave
    /// in an error state goes too). SAFEOP is broadcast when every slave is in SAFEOP or OP;
    /// otherwise only the slaves in OP are told (a slave below SAFEOP must not be raised).
    /// The records' requested state becomes `state`, so that nothing restores the old one.
    pub async fn all_to_safe(
        &self,
        state: AlState,
        deadline: Instant,
    ) -> Result<SafeStateReport, MasterError> {
        let above = match state {
            AlState::Init => 0x0E,
            AlState::SafeOp => 0x08,
            other => return Err(MasterError::InvalidState(other)),
        };
        {
            let mut slaves = self.ctx.lock();
            for record in slaves.list.iter_mut() {
                record.info.requested_state = state;
            }
        }
        let stations: Vec<u16> = self.slaves().iter().map(|s| s.station).collect();
        let ctx = Arc::clone(&self.ctx);
        // On the master's runtime, as every bus exchange: any executor may await this.
        self.run(async move { Ok(drive(&ctx.bus, state, above, &stations, deadline).await) })
            .await
    }
}

/// Requests `state` and reads AL status until no slave shows a bit of `above` or `deadline`.
async fn drive(
    bus: &BusHandle,
    state: AlState,
    above: u16,
    stations: &[u16],
    deadline: Instant,
) -> SafeStateReport {
    let mut report = SafeStateReport {
        slaves: 0,
        confirmed: false,
    };
    loop {
        if let Some((count, or)) = status_or(bus).await {
            report.slaves = count;
            report.confirmed = or & above == 0;
            if report.confirmed {
                return report;
            }
            // Repeated until confirmed: a lost write or a slave that came back is told
            // again.
            request(bus, state, or, stations).await;
        }
        if Instant::now() + POLL >= deadline {
            return report;
        }
        tokio::time::sleep(POLL).await;
    }
}

/// The slaves that answered a BRD of AL status, and the OR of their status (low byte).
async fn status_or(bus: &BusHandle) -> Option<(u16, u16)> {
    let reply = bus
        .submit(DatagramRequest::brd(reg::AL_STATUS, 2))
        .await
        .ok()?;
    let bytes: [u8; 2] = reply.data.get(..2)?.try_into().ok()?;
    Some((reply.wkc, u16::from_le_bytes(bytes) & 0x0F))
}

/// Requests `state` from the slaves that are above it; `or` is the OR of their states.
async fn request(bus: &BusHandle, state: AlState, or: u16, stations: &[u16]) {
    let Ok(control) = AlControl::acknowledge(state).encode() else {
        return;
    };
    let below_safeop = 0x03;
    if state == AlState::Init || or & below_safeop == 0 {
        let _ = bus
            .submit(DatagramRequest::bwr(reg::AL_CONTROL, control.to_le_bytes()))
            .await;
        return;
    }
    // Mixed states with SAFEOP as the target: only the slaves in OP, all in one frame.
    let reads = bus.submit_group(
        stations
            .iter()
            .map(|&station| DatagramRequest::fprd(station, reg::AL_STATUS, 2).expect_wkc(1)),
    );
    let mut in_op = Vec::new();
    for (&station, read) in stations.iter().zip(reads) {
        if let Ok(reply) = read.await
            && reply.data.first().is_some_and(|s| s & 0x0F == 0x08)
        {
            in_op.push(station);
        }
    }
    let writes = bus.submit_group(in_op.iter().map(|&station| {
        DatagramRequest::fpwr(station, reg::AL_CONTROL, control.to_le_bytes()).expect_wkc(1)
    }));
    for write in writes {
        let _ = write.await;
    }
}
