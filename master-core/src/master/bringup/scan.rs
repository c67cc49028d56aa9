//! Bringing the whole segment up (spec-notes §bringup): count, reset, identify every slave,
//! then move them all to the target state together, so that their datagrams share frames.

use std::future::Future;
use std::sync::{Arc, PoisonError};

use tokio::task::JoinSet;

use crate::wire::register::AlState;
use crate::wire::register::address as reg;
use crate::wire::sii::SiiImage;

use super::configure::{bring_to, identify};
use super::dc;
use super::mailboxes;
use super::reset::reset_all;
use super::startup;
use crate::mailbox::SlaveMailbox;
use crate::master::context::Context;
use crate::master::error::MasterError;
use crate::master::event::MasterEvent;
use crate::master::info::{ProcessDataInfo, SlaveInfo};
use crate::master::process_data::groups;
use crate::master::process_data::image::{GROUP_STRIDE, GroupSlot, LOGICAL_BASE, MAX_GROUPS};
use crate::master::process_data::pdo_config;
use crate::master::record::SlaveRecord;

/// What a scan found and did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScanReport {
    /// Every slave, by ring position, as it is after the scan.
    pub slaves: Vec<SlaveInfo>,
    /// Slaves that did not reach the target state, and why (a refusal names the slave and
    /// its AL status code). The other slaves are not held back by them.
    pub failures: Vec<MasterError>,
}

/// Runs `work` for each record at once on the master's runtime; results by position.
pub(crate) async fn for_each<F, Fut, T>(
    ctx: &Arc<Context>,
    records: Vec<SlaveRecord>,
    work: F,
) -> Vec<(u16, Result<T, MasterError>)>
where
    F: Fn(Arc<Context>, SlaveRecord) -> Fut,
    Fut: Future<Output = Result<T, MasterError>> + Send + 'static,
    T: Send + 'static,
{
    let mut tasks = JoinSet::new();
    for record in records {
        let position = record.info.position;
        let fut = work(Arc::clone(ctx), record);
        tasks.spawn(async move { (position, fut.await) });
    }
    let mut results = Vec::new();
    while let Some(joined) = tasks.join_next().await {
        // A task only ends early if the runtime shuts down.
        results.push(joined.unwrap_or((u16::MAX, Err(MasterError::Stopped))));
    }
    results.sort_by_key(|(position, _)| *position);
    results
}

/// The first state every slave is brought to, before the process-data layout is made.
fn first_stop(target: AlState) -> AlState {
    match target {
        AlState::Init | AlState::Boot => target,
        _ => AlState::PreOp,
    }
}

/// Scans the segment and brings every slave to the configured target state.
pub(crate) async fn scan(ctx: Arc<Context>) -> Result<ScanReport, MasterError> {
    let _topology = ctx.topology.lock().await;
    let count = ctx
        .bus
        .brd(reg::TYPE, 2)
        .await
        .map_err(MasterError::bus("count slaves"))?
        .wkc;
    if count > 0 && ctx.config.station_of(count - 1).is_none() {
        return Err(MasterError::TooManySlaves {
            count,
            base: ctx.config.station_base,
        });
    }
    ctx.lock().list.clear();
    mailboxes::release_all(&ctx);
    ctx.image.set_groups(Vec::new());
    ctx.image.reset_status(count);
    ctx.image.set_dc_reference(None);
    ctx.dc
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .clear();
    if count == 0 {
        return Ok(ScanReport {
            slaves: Vec::new(),
            failures: Vec::new(),
        });
    }
    reset_all(&ctx.bus, count).await?;

    let target = ctx.config.target_state;
    let mut tasks = JoinSet::new();
    for position in 0..count {
        let ctx = Arc::clone(&ctx);
        tasks.spawn(async move { (position, identify(&ctx, position, None).await) });
    }
    let mut failures = Vec::new();
    let mut all = Vec::new();
    while let Some(joined) = tasks.join_next().await {
        let (position, result) = joined.map_err(|_| MasterError::Stopped)?;
        match result {
            Ok(record) => all.push(record),
            Err(err) => {
                failures.push(err);
                // Checked above: every position has a station address.
                let station = ctx.config.station_of(position).unwrap_or(0);
                all.push(SlaveRecord::unidentified(position, station, target));
            }
        }
    }
    all.sort_by_key(|r| r.info.position);
    // Before anything is written: a configured PDO the slave does not have fails the scan
    // with every slave still in INIT.
    startup::check_pdos(&ctx, &all)?;
    startup::check_segment(&ctx, &mut all)?;
    let identified: Vec<SlaveRecord> = all.iter().filter(|r| !r.sii.is_empty()).cloned().collect();
    for record in &identified {
        let i = &record.info;
        ctx.emit(MasterEvent::SlaveFound {
            position: i.position,
            station: i.station,
            identity: i.identity,
            name: i.name.clone(),
        });
    }
    ctx.lock().list = all;

    // Clocks before any slave reaches SAFEOP (offsets, delays, converged drift).
    match dc::configure(&ctx, &identified).await {
        Ok(dc) => *ctx.dc.lock().unwrap_or_else(PoisonError::into_inner) = dc,
        Err(err) => failures.push(err),
    }

    let first = first_stop(target);
    let mut ready = Vec::new();
    for (position, result) in for_each(&ctx, identified, move |ctx, record| async move {
        bring_to(&ctx, &record, first).await
    })
    .await
    {
        match result {
            Ok(()) => ready.push(position),
            Err(err) => failures.push(err),
        }
    }

    if first == AlState::PreOp {
        let ready = lay_out(&ctx, &ready, &mut failures).await?;
        let records: Vec<SlaveRecord> = ready.iter().filter_map(|&p| ctx.record(p)).collect();
        // The requested state: the target, or PREOP for a slave held by the configuration.
        for (_, result) in for_each(&ctx, records, move |ctx, record| async move {
            let to = match record.info.requested_state {
                AlState::PreOp => AlState::PreOp,
                _ => target,
            };
            bring_to(&ctx, &record, to).await
        })
        .await
        {
            if let Err(err) = result {
                failures.push(err);
            }
        }
    }
    // Wrong working counters while the slaves were on their way up are no errors.
    ctx.image.clear_wkc_errors();
    let slaves = ctx.lock().list.iter().map(|r| r.info.clone()).collect();
    Ok(ScanReport { slaves, failures })
}

/// CoE 0x1000 of a slave in PREOP (ETG.1510 0x8nnn:04); 0 without CoE or if the read fails.
async fn device_type(info: &SlaveInfo, mailbox: Option<&SlaveMailbox>) -> u32 {
    let coe = info.mailbox.is_some_and(|m| m.protocols.coe());
    let (true, Some(mailbox)) = (coe, mailbox) else {
        return 0;
    };
    match mailbox.sdo_upload(0x1000, 0).await {
        Ok(bytes) => bytes
            .get(..4)
            .and_then(|b| b.try_into().ok())
            .map_or(0, u32::from_le_bytes),
        Err(_) => 0,
    }
}

/// Writes the configured PDO assignments and decides the process-data layout of the
/// slaves at `positions` (in PREOP), gives each its place in the image, and sizes the
/// image. Returns the slaves laid out; the others' errors go to `failures`.
async fn lay_out(
    ctx: &Arc<Context>,
    positions: &[u16],
    failures: &mut Vec<MasterError>,
) -> Result<Vec<u16>, MasterError> {
    let records: Vec<SlaveRecord> = positions.iter().filter_map(|&p| ctx.record(p)).collect();
    // Mailbox transfers of different slaves share frames: all slaves at once.
    let layouts = for_each(ctx, records, |ctx, record| async move {
        let written = pdo_config::apply(&ctx, &record.info).await?;
        let position = record.info.position;
        let sii = SiiImage::parse(&record.sii).map_err(|source| MasterError::Malformed {
            position,
            what: "SII",
            source,
        })?;
        let mailbox = ctx.mailboxes.slave(record.info.station).ok();
        let device_type = device_type(&record.info, mailbox.as_ref()).await;
        let layout = ctx
            .layout_source
            .layout(&record.info, &sii, mailbox.as_ref())
            .await?;
        Ok((layout, written, device_type))
    })
    .await;
    let definitions = ctx.image.definitions();
    if definitions.len() + 1 > MAX_GROUPS {
        return Err(MasterError::InvalidArgument("too many slave groups"));
    }
    let count = layouts
        .iter()
        .map(|(p, _)| usize::from(*p) + 1)
        .max()
        .unwrap_or(0);
    let member = groups::membership(&definitions, count);
    let mut laid: Vec<Vec<_>> = vec![Vec::new(); definitions.len() + 1];
    for (position, result) in layouts {
        match result {
            Ok(done) => {
                let group = member.get(usize::from(position)).copied().unwrap_or(0);
                laid[group].push((position, done));
            }
            Err(err) => failures.push(err),
        }
    }
    let mut offset: u32 = 0;
    let mut ready = Vec::new();
    let mut slots = Vec::new();
    for (group, members) in laid.into_iter().enumerate() {
        let start = offset;
        let mut expected_wkc: u16 = 0;
        for (position, (layout, written, device_type)) in members {
            let outputs = layout.outputs_len();
            let inputs = layout.inputs_len();
            let pd = ProcessDataInfo {
                outputs: u16::try_from(outputs).unwrap_or(u16::MAX),
                inputs: u16::try_from(inputs).unwrap_or(u16::MAX),
                outputs_offset: offset,
                inputs_offset: offset + outputs as u32,
            };
            offset += (outputs + inputs) as u32;
            let share = if outputs > 0 { 2 } else { 0 } + u16::from(inputs > 0);
            expected_wkc += share;
            ctx.image.set_lrw_share(position, group, share);
            ctx.update(position, |r| {
                r.layout = layout;
                r.info.process_data = pd;
                r.info.device_type = device_type;
                r.pdo_written = written;
            });
            ready.push(position);
        }
        let period = group
            .checked_sub(1)
            .and_then(|d| definitions.get(d))
            .map(|d| d.period);
        slots.push(GroupSlot::new(
            start as usize,
            (offset - start) as usize,
            LOGICAL_BASE + GROUP_STRIDE * group as u32,
            period,
            expected_wkc,
        ));
    }
    // Every group's datagram may go in one frame, each with its header and counter.
    let room = ctx.bus.config().max_data_len();
    let need = offset as usize + slots.len().saturating_sub(1) * crate::wire::datagram::OVERHEAD;
    if need > room {
        return Err(MasterError::ImageTooLarge { need, room });
    }
    ctx.image.set_groups(slots);
    Ok(ready)
}
