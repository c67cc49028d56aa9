//! The topology watch: notices slaves that disappear, come back or are replaced, reports
//! them, and brings them back to their requested state without a new scan.
//!
//! Each look: a BRD counts the slaves that answer; each known slave's AL status is read at
//! its station address. A slave that answers is checked for an AL error or a state other
//! than the requested one and repaired. A slave that does not answer while the count says
//! its position is populated has lost its station address (a power cycle) or was replaced:
//! it is addressed by position, identified again and configured. A slave behind the end of
//! the counted line is lost.

use std::sync::Arc;
use std::time::Duration;

use crate::bus::{BusError, DatagramRequest};
use crate::wire::register::address as reg;
use crate::wire::register::al::AL_STATUS_BLOCK_LEN;
use crate::wire::register::{AlStatusBlock, AlStatusBlockRepr};

use super::configure::{bring_to, identify};
use super::dc;
use super::mailboxes;
use super::reset::reset_one;
use super::startup;
use crate::master::access::datagram::apwr;
use crate::master::context::Context;
use crate::master::error::MasterError;
use crate::master::event::MasterEvent;
use crate::master::record::SlaveRecord;
use crate::wire::register::AlState;

/// Looks at the segment every `interval` until the master's runtime stops.
pub(crate) async fn watch(ctx: Arc<Context>, interval: Duration) {
    loop {
        tokio::time::sleep(interval).await;
        // A failed look (frames lost, say) is simply repeated at the next tick.
        let _ = look(&ctx).await;
    }
}

/// One look at the segment.
pub(crate) async fn look(ctx: &Arc<Context>) -> Result<(), MasterError> {
    let _topology = ctx.topology.lock().await;
    let known: Vec<SlaveRecord> = ctx.lock().list.clone();
    if known.is_empty() {
        return Ok(());
    }
    let count = match ctx.bus.brd(reg::TYPE, 2).await {
        Ok(reply) => reply.wkc,
        // Not even the broadcast came back, after the bus's retries: nothing answers behind
        // the master's port (cable to the first slave, its power, or the link itself). Every
        // known slave is then lost; without this a silent segment kept its slaves "present".
        Err(BusError::Timeout { .. }) => 0,
        Err(err) => return Err(MasterError::bus("count slaves")(err)),
    };
    // All status reads at once: the bus packs them into as few frames as fit.
    let pendings: Vec<_> = known
        .iter()
        .map(|r| {
            let request =
                DatagramRequest::fprd(r.info.station, reg::AL_STATUS, AL_STATUS_BLOCK_LEN);
            ctx.bus.submit(request)
        })
        .collect();
    let mut first_error = None;
    for (record, pending) in known.into_iter().zip(pendings) {
        let result = match pending.await {
            Ok(reply) => one(ctx, record, reply.wkc, &reply.data, count).await,
            // A silent segment (count 0): the status read could not come back either.
            Err(BusError::Timeout { .. }) if count == 0 => one(ctx, record, 0, &[], 0).await,
            Err(source) => Err(MasterError::Bus {
                what: "AL status",
                source,
            }),
        };
        // One slave's trouble does not keep the others from being looked at.
        if let Err(err) = result {
            first_error.get_or_insert(err);
        }
    }
    first_error.map_or(Ok(()), Err)
}

/// What to do about one known slave, given its answer to the AL status read.
async fn one(
    ctx: &Context,
    record: SlaveRecord,
    wkc: u16,
    data: &[u8],
    count: u16,
) -> Result<(), MasterError> {
    let info = &record.info;
    // A slave the scan could not identify (no SII) is identified again like one that came
    // back.
    let identified = !record.sii.is_empty();
    if wkc == 1 && identified {
        let status = AlStatusBlock::new_checked(data)
            .and_then(|view| AlStatusBlockRepr::parse(&view))
            .map_err(|source| MasterError::Malformed {
                position: info.position,
                what: "AL status",
                source,
            })?;
        still_there(ctx, &record, status).await
    } else if info.position < count {
        if info.present && identified {
            lost(ctx, &record);
        }
        come_back(ctx, record).await
    } else {
        if info.present {
            lost(ctx, &record);
        }
        Ok(())
    }
}

fn lost(ctx: &Context, record: &SlaveRecord) {
    let info = &record.info;
    mailboxes::release(ctx, info.station);
    ctx.update(info.position, |r| r.info.present = false);
    ctx.emit(MasterEvent::SlaveLost {
        position: info.position,
        station: info.station,
        name: info.name.clone(),
    });
}

/// A slave answering at its station address: note a return, report an error, restore its
/// requested state.
async fn still_there(
    ctx: &Context,
    record: &SlaveRecord,
    status: AlStatusBlockRepr,
) -> Result<(), MasterError> {
    let info = &record.info;
    if !info.present && status.status.state != AlState::Init && info.mailbox.is_some() {
        // Back from a cut link with its station address: its mailbox was let go when it
        // was lost, and the slave still counts its mailbox messages on from then
        // (ETG.1000.4, spec-notes §mbx.counter). Through INIT both sides start
        // their counters afresh and the mailbox is taken over again.
        return come_back(ctx, record.clone()).await;
    }
    if !info.present {
        ctx.update(info.position, |r| r.info.present = true);
        ctx.emit(MasterEvent::SlaveFound {
            position: info.position,
            station: info.station,
            identity: info.identity,
            name: info.name.clone(),
        });
    }
    let (state, error) = (status.status.state, status.status.error);
    if error && !info.al_error {
        ctx.emit(MasterEvent::AlError {
            position: info.position,
            station: info.station,
            name: info.name.clone(),
            state,
            code: status.code,
        });
    }
    if state != info.al_state && !error {
        ctx.emit(MasterEvent::StateChanged {
            position: info.position,
            station: info.station,
            from: info.al_state,
            to: state,
        });
    }
    // A refusal the master already reported stays marked while the slave sits in the state
    // it kept (the error indication itself was acknowledged), so it is not retried at every
    // look; a new scan or request tries again.
    let refused = info.al_error && state == info.al_state;
    ctx.update(info.position, |r| {
        r.info.al_state = state;
        r.info.al_error = error || refused;
        if error || !refused {
            r.info.al_status_code = status.code;
        }
    });
    if (state != info.requested_state || error) && !info.al_error && !record.held {
        let mut current = record.clone();
        current.info.al_state = state;
        bring_to(ctx, &current, info.requested_state).await?;
    }
    Ok(())
}

/// A slave at a known position that lost its station address: give it back, reset it,
/// identify it, and configure it to its requested state.
async fn come_back(ctx: &Context, old: SlaveRecord) -> Result<(), MasterError> {
    let info = &old.info;
    apwr(
        &ctx.bus,
        info.position,
        reg::STATION_ADDRESS,
        info.station.to_le_bytes(),
        "station address",
    )
    .await?;
    mailboxes::release(ctx, info.station);
    reset_one(&ctx.bus, info.station).await?;
    let mut record = identify(ctx, info.position, Some(&old)).await?;
    let new = &record.info;
    if new.identity == info.identity || old.sii.is_empty() {
        ctx.emit(MasterEvent::SlaveFound {
            position: new.position,
            station: new.station,
            identity: new.identity,
            name: new.name.clone(),
        });
    } else {
        ctx.emit(MasterEvent::SlaveReplaced {
            position: new.position,
            station: new.station,
            old: info.identity,
            new: new.identity,
            name: new.name.clone(),
        });
    }
    record.info.present = true;
    // A device other than the one configured is held in PREOP (ETG.1020 §6.4).
    if startup::check_identity(ctx, &record).is_some()
        && matches!(record.info.requested_state, AlState::SafeOp | AlState::Op)
    {
        record.info.requested_state = AlState::PreOp;
    }
    ctx.update(info.position, |r| *r = record.clone());
    // Its clock restarted with the power: delay and offset again before SAFEOP.
    dc::restore(ctx, &record).await?;
    bring_to(ctx, &record, record.info.requested_state).await
}
