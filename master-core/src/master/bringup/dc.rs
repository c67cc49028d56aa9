//! Distributed clocks (ETG.1000.4, spec-notes §dc): propagation delays measured through the port
//! receive-time latch, system-time offsets, static drift compensation at the scan, the
//! reference clock's time distributed in every cycle (FRMW 0x0910, see `image`), and SYNC0
//! activation before SAFEOP.
//!
//! The first DC slave is the reference clock; the master follows it (it does not steer the
//! reference to its own clock). Delays are computed for a line (each slave entered at port
//! 0, left at the next open port): a slave's loop time is the time from passing port 0 to
//! the frame's return at its last open port, and the delay between consecutive DC slaves is
//! half the difference of their loop times (spec-notes §dc). Branches are not measured separately.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use futures_util::future::try_join_all;

use crate::bus::redundancy::{RingClock, RingState};
use crate::bus::{BusHandle, Pending};
use crate::wire::register::address as reg;
use crate::wire::register::dc::{
    DcActivation, ECAT_EPOCH_UNIX_SECS, OffsetDelay, PortReceiveTimes, SPEED_COUNTER_START_DEFAULT,
    read_time,
};
use crate::wire::sii::SiiImage;

use crate::master::access::datagram::{fprd, fpwr};
use crate::master::context::Context;
use crate::master::error::MasterError;
use crate::master::record::SlaveRecord;

use super::dc_settings::DcSlave;
use super::slave_config::{SlaveDc, SyncSignal};

/// Reference-time datagrams submitted at once during static drift compensation.
const DRIFT_BATCH: u32 = 32;

/// The master's clock in EtherCAT time: ns since 2000-01-01.
fn ecat_now() -> u64 {
    let unix = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap_or_default();
    let since = unix.saturating_sub(Duration::from_secs(ECAT_EPOCH_UNIX_SECS));
    u64::try_from(since.as_nanos()).unwrap_or(u64::MAX)
}

/// The time the frame spent behind a slave entered at port 0: from port 0 to its return
/// at the last open port in processing order (3, 1, 2); 0 at the end of the line.
fn loop_time(record: &SlaveRecord, times: &PortReceiveTimes) -> u32 {
    let dl = &record.info.dl_status;
    [2usize, 1, 3]
        .into_iter()
        .find(|&port| dl.port_active(port))
        .and_then(|port| times.span(0, port))
        .unwrap_or(0)
}

/// Propagation delays along a line from the loop times of consecutive DC slaves.
pub(crate) fn line_delays(loops: &[u32]) -> Vec<u32> {
    let mut delays = Vec::with_capacity(loops.len());
    let mut delay: i64 = 0;
    let mut previous: Option<u32> = None;
    for &l in loops {
        if let Some(p) = previous {
            delay += (i64::from(p) - i64::from(l)) / 2;
        }
        delays.push(u32::try_from(delay.max(0)).unwrap_or(u32::MAX));
        previous = Some(l);
    }
    delays
}

/// Measures and sets every DC slave among `records` (in ring order), compensates static
/// drift, and hands the reference clock to the cyclic exchange. Returns what was set.
pub(crate) async fn configure(
    ctx: &Context,
    records: &[SlaveRecord],
) -> Result<Vec<DcSlave>, MasterError> {
    let settings = ctx.config.dc;
    let dc: Vec<&SlaveRecord> = records
        .iter()
        .filter(|r| r.info.esc.features.dc_supported())
        .collect();
    if !settings.enabled || dc.is_empty() {
        ctx.image.set_dc_reference(None);
        return Ok(Vec::new());
    }
    let bus = &ctx.bus;
    // A closed ring has no loop to time: the latch frame passes every slave once and
    // leaves through the backup port. The ring's last slave closes its port 1 for the
    // measurement, so that the frame comes back through every port 1 as on a line
    // (spec-notes §redundancy).
    let ring_end = match (bus.ring(), records.last()) {
        (Some(ring), Some(last)) if ring.status().state == RingState::Closed => {
            ring.set_held(true);
            let closed = fpwr(
                bus,
                last.info.station,
                reg::DL_CONTROL_LOOP,
                [LOOP_PORT1_CLOSED],
                "close the ring's end for the DC measurement",
            )
            .await;
            if let Err(err) = closed {
                ring.set_held(false);
                return Err(err);
            }
            Some(last.info.position)
        }
        _ => None,
    };
    let measured = measure(ctx, &dc, ring_end).await;
    if let (Some(ring), Some(last)) = (bus.ring(), records.last())
        && ring_end.is_some()
    {
        let reopened = fpwr(
            bus,
            last.info.station,
            reg::DL_CONTROL_LOOP,
            [0u8],
            "reopen the ring's end after the DC measurement",
        )
        .await;
        ring.set_held(false);
        reopened?;
    }
    let (master_time, measured) = measured?;
    let loops: Vec<u32> = measured.iter().map(|(_, _, l)| *l).collect();
    let delays = line_delays(&loops);
    let mut slaves = Vec::with_capacity(dc.len());
    for ((record, (times, pu, _)), delay) in dc.iter().zip(&measured).zip(delays) {
        // System time = master time at the latch, plus the time the latch frame took from
        // the reference to this slave (it saw the frame that much later).
        let offset = master_time.wrapping_sub(*pu).wrapping_add(u64::from(delay)) as i64;
        let station = record.info.station;
        slaves.push(DcSlave {
            position: record.info.position,
            station,
            reference: slaves.is_empty(),
            receive_times: times.0,
            processing_unit_time: *pu,
            delay_ns: delay,
            offset,
        });
    }
    // Every slave's settings at once: the writes share frames.
    try_join_all(dc.iter().zip(&slaves).map(|(record, slave)| async move {
        write_offset_delay(bus, record, slave.offset, slave.delay_ns).await?;
        reset_filter(bus, slave.station).await
    }))
    .await?;
    let reference = slaves.first().map(|s| s.station);
    if let Some(reference) = reference {
        compensate_static_drift(ctx, reference, settings.static_drift_frames).await?;
    }
    let count = u16::try_from(slaves.len()).unwrap_or(u16::MAX);
    if let Some(ring) = ctx.bus.ring() {
        // On a ring, the side of a break without the reference takes its time from its
        // own first clock (spec-notes §redundancy).
        let clocks: Vec<RingClock> = slaves
            .iter()
            .map(|s| RingClock {
                position: s.position,
                station: s.station,
            })
            .collect();
        ring.set_clocks(&clocks);
    }
    ctx.image
        .set_dc_reference(reference.map(|station| (station, count)));
    Ok(slaves)
}

/// The DC loop setting that closes port 1 (DL control bits 10-11 = 11b, ETG.1000.4 §6;
/// spec-notes §esc.dl), as the byte at 0x0101.
const LOOP_PORT1_CLOSED: u8 = 0b0000_1100;

/// What one latch measured per DC slave: port receive times, processing-unit time and
/// loop time; with the master's time at the latch. On a ring opened at its end
/// (`ring_end`), the end slave's loop is nil, as a line's last slave's.
async fn measure(
    ctx: &Context,
    dc: &[&SlaveRecord],
    ring_end: Option<u16>,
) -> Result<(u64, Vec<(PortReceiveTimes, u64, u32)>), MasterError> {
    let master_time = ecat_now();
    let slaves: Vec<(u16, u16, &SlaveRecord)> = dc
        .iter()
        .map(|r| (r.info.position, r.info.station, *r))
        .collect();
    let mut measured = latch(ctx, &slaves).await?;
    if let Some(end) = ring_end.and_then(|p| slaves.iter().position(|s| s.0 == p)) {
        measured[end].2 = 0;
    }
    Ok((master_time, measured))
}

/// Latches the receive times (BWR 0x0900) and reads back each DC slave's port times,
/// processing-unit time and loop time, in the order given. The slaves are read at once:
/// their reads share frames, where one after the other they took a round trip each.
async fn latch(
    ctx: &Context,
    slaves: &[(u16, u16, &SlaveRecord)],
) -> Result<Vec<(PortReceiveTimes, u64, u32)>, MasterError> {
    let bus = &ctx.bus;
    bus.bwr(reg::DC_RECEIVE_TIME_PORT0, [0u8; 4])
        .await
        .map_err(MasterError::bus("latch DC receive times"))?;
    try_join_all(
        slaves
            .iter()
            .map(|&(position, station, record)| async move {
                let (times, pu) = read_latched(bus, position, station).await?;
                Ok((times, pu, loop_time(record, &times)))
            }),
    )
    .await
}

/// One slave's latched times in one read of 0x0900-0x091F: the port receive times, the
/// system time (unused) and the processing unit's receive time (spec-notes §dc).
async fn read_latched(
    bus: &BusHandle,
    position: u16,
    station: u16,
) -> Result<(PortReceiveTimes, u64), MasterError> {
    const PU_AT: usize =
        (reg::DC_RECEIVE_TIME_PROCESSING_UNIT - reg::DC_RECEIVE_TIME_PORT0) as usize;
    let malformed = |what| {
        move |source| MasterError::Malformed {
            position,
            what,
            source,
        }
    };
    let raw = fprd(
        bus,
        station,
        reg::DC_RECEIVE_TIME_PORT0,
        PU_AT + 8,
        "DC receive times",
    )
    .await?;
    let times = PortReceiveTimes::parse(&raw).map_err(malformed("DC receive times"))?;
    let pu = read_time(raw.get(PU_AT..).unwrap_or_default())
        .map_err(malformed("DC processing unit time"))?;
    Ok((times, pu))
}

/// Measures the delay of the slave of `record` again and gives it the offset that brings
/// its clock to the reference's time: for a slave that came back after a power cycle (its
/// clock restarted, its offset and delay registers were cleared). The other DC slaves'
/// settings are kept; one of them (the reference unless it is the one that came back)
/// tells the reference's time at the latch. Nothing to do without DC, for a slave without
/// it, or without another DC slave to take the time from.
pub(crate) async fn restore(ctx: &Context, record: &SlaveRecord) -> Result<(), MasterError> {
    if !ctx.config.dc.enabled || !record.info.esc.features.dc_supported() {
        return Ok(());
    }
    let known: Vec<DcSlave> = ctx
        .dc
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .clone();
    let Some(index) = known
        .iter()
        .position(|s| s.position == record.info.position)
    else {
        return Ok(());
    };
    let Some(source) = known
        .iter()
        .position(|s| s.position != record.info.position)
    else {
        return Ok(());
    };
    let records: Vec<SlaveRecord> = known
        .iter()
        .map(|s| ctx.record(s.position))
        .collect::<Option<_>>()
        .ok_or(MasterError::InvalidArgument("a DC slave left the segment"))?;
    let slaves: Vec<(u16, u16, &SlaveRecord)> = known
        .iter()
        .zip(&records)
        .map(|(s, r)| (s.position, s.station, r))
        .collect();
    let measured = latch(ctx, &slaves).await?;
    let loops: Vec<u32> = measured.iter().map(|(_, _, l)| *l).collect();
    let delays = line_delays(&loops);
    let delay = delays.get(index).copied().unwrap_or(0);
    // The reference's system time when the latch frame passed it, from a slave whose
    // offset still holds: its local time plus offset is its system time, less its delay.
    let from = &known[source];
    let (_, source_pu, _) = measured[source];
    let reference_time = source_pu
        .wrapping_add(from.offset as u64)
        .wrapping_sub(u64::from(
            delays.get(source).copied().unwrap_or(from.delay_ns),
        ));
    let (times, pu, _) = measured[index];
    let offset = reference_time
        .wrapping_add(u64::from(delay))
        .wrapping_sub(pu) as i64;
    write_offset_delay(&ctx.bus, record, offset, delay).await?;
    let source_delay = delays.get(source).copied().unwrap_or(from.delay_ns);
    let offset = settle_offset(ctx, record, from.station, source_delay, delay).await?;
    reset_filter(&ctx.bus, record.info.station).await?;
    let mut dc = ctx
        .dc
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some(slave) = dc.iter_mut().find(|s| s.position == record.info.position) {
        slave.receive_times = times.0;
        slave.processing_unit_time = pu;
        slave.delay_ns = delay;
        slave.offset = offset;
    }
    Ok(())
}

/// Writes a slave's system-time offset and propagation delay (0x0920..0x092B, one write).
async fn write_offset_delay(
    bus: &BusHandle,
    record: &SlaveRecord,
    offset: i64,
    delay: u32,
) -> Result<(), MasterError> {
    let mut block = [0u8; OffsetDelay::LEN];
    OffsetDelay { offset, delay }
        .emit(&mut block)
        .map_err(|source| MasterError::Malformed {
            position: record.info.position,
            what: "DC offset",
            source,
        })?;
    fpwr(
        bus,
        record.info.station,
        reg::DC_SYSTEM_TIME_OFFSET,
        block,
        "DC offset and delay",
    )
    .await
}

/// Resets the slave's time-control loop filter (speed counter start), as after every new
/// offset.
async fn reset_filter(bus: &BusHandle, station: u16) -> Result<(), MasterError> {
    fpwr(
        bus,
        station,
        reg::DC_SPEED_COUNTER_START,
        SPEED_COUNTER_START_DEFAULT.to_le_bytes(),
        "DC filter reset",
    )
    .await
}

/// Reads the system time of the slave of `record` and of a synchronised slave `source`
/// in one frame, with the slave's offset, and corrects the offset by what is left between
/// them: the latch gives the slave's local time, but while it waited for its offset the
/// cyclic reference time may already have slewed its clock, which the local time does not
/// show. Each reading is the reference's time when the frame passed it plus the reader's
/// delay, whatever the order on the ring. Returns the offset in force.
async fn settle_offset(
    ctx: &Context,
    record: &SlaveRecord,
    source: u16,
    source_delay: u32,
    delay: u32,
) -> Result<i64, MasterError> {
    use crate::bus::DatagramRequest;
    let station = record.info.station;
    let pending = ctx.bus.submit_group([
        DatagramRequest::fprd(source, reg::DC_SYSTEM_TIME, 8).expect_wkc(1),
        DatagramRequest::fprd(station, reg::DC_SYSTEM_TIME, 8).expect_wkc(1),
        DatagramRequest::fprd(station, reg::DC_SYSTEM_TIME_OFFSET, 8).expect_wkc(1),
    ]);
    let mut values = [0u64; 3];
    for (value, pending) in values.iter_mut().zip(pending) {
        let reply = pending.await.map_err(MasterError::bus("DC system times"))?;
        *value = read_time(&reply.data).map_err(|source| MasterError::Malformed {
            position: record.info.position,
            what: "DC system time",
            source,
        })?;
    }
    let [at_source, at_slave, offset] = values;
    let error = at_slave
        .wrapping_sub(u64::from(delay))
        .wrapping_sub(at_source.wrapping_sub(u64::from(source_delay))) as i64;
    let offset = (offset as i64).wrapping_sub(error);
    fpwr(
        &ctx.bus,
        station,
        reg::DC_SYSTEM_TIME_OFFSET,
        offset.to_le_bytes(),
        "DC offset",
    )
    .await?;
    Ok(offset)
}

/// Sends `frames` reference-time datagrams, a batch at a time.
async fn compensate_static_drift(
    ctx: &Context,
    reference: u16,
    frames: u32,
) -> Result<(), MasterError> {
    let mut left = frames;
    while left > 0 {
        let batch = left.min(DRIFT_BATCH);
        let pending: Vec<Pending> = (0..batch)
            .map(|_| ctx.bus.frmw(reference, reg::DC_SYSTEM_TIME, 8))
            .collect();
        for p in pending {
            p.await.map_err(MasterError::bus("DC static drift"))?;
        }
        left -= batch;
    }
    Ok(())
}

/// Starts SYNC0 (and SYNC1) on the slave of `record` if its configuration or the master's
/// settings ask for it and the slave has DC and process data (SOEM's `ecx_dcsync0`
/// sequence, ETG.1000.4 §6.8.5, Table 60, spec-notes §dc). A slave configured with DC
/// off gets its SYNC unit stopped.
pub(crate) async fn activate_sync0(ctx: &Context, record: &SlaveRecord) -> Result<(), MasterError> {
    let settings = ctx.config.dc;
    let info = &record.info;
    let bus = &ctx.bus;
    let station = info.station;
    let (sync0, sync1) = match ctx.slave_config_for(info).and_then(|c| c.dc) {
        Some(SlaveDc::Off) => {
            if info.esc.features.dc_supported() {
                fpwr(bus, station, reg::DC_ACTIVATION, [0u8], "SYNC stop").await?;
            }
            return Ok(());
        }
        Some(SlaveDc::Sync { sync0, sync1 }) => (sync0, sync1),
        None => match settings.sync0_cycle {
            Some(cycle) => (
                SyncSignal {
                    cycle,
                    shift: settings.sync0_shift,
                },
                None,
            ),
            None => return Ok(()),
        },
    };
    if !settings.enabled
        || !info.esc.features.dc_supported()
        || record.layout.sync_managers.is_empty()
    {
        return Ok(());
    }
    let nanos = |d: std::time::Duration| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX);
    let cycle_ns = nanos(sync0.cycle).max(1);
    let cycle_reg = u32::try_from(cycle_ns)
        .map_err(|_| MasterError::InvalidArgument("SYNC0 cycle longer than 2^32 ns"))?;
    fpwr(bus, station, reg::DC_ACTIVATION, [0u8], "SYNC0 stop").await?;
    let (unit_control, mut activation) = assign_activate(record);
    let raw = fprd(bus, station, reg::DC_SYSTEM_TIME, 8, "DC system time").await?;
    let now = read_time(&raw).map_err(|source| MasterError::Malformed {
        position: info.position,
        what: "DC system time",
        source,
    })?;
    let start = sync0_start(now, settings.sync0_start_delay, cycle_ns, sync0.shift);
    fpwr(
        bus,
        station,
        reg::DC_CYCLIC_UNIT_CONTROL,
        [unit_control],
        "SYNC unit control",
    )
    .await?;
    fpwr(
        bus,
        station,
        reg::DC_START_TIME,
        start.to_le_bytes(),
        "SYNC0 start time",
    )
    .await?;
    fpwr(
        bus,
        station,
        reg::DC_SYNC0_CYCLE,
        cycle_reg.to_le_bytes(),
        "SYNC0 cycle",
    )
    .await?;
    if let Some(sync1) = sync1 {
        // 0x09A4 is the time from a SYNC0 pulse to the SYNC1 pulse: the cycle plus the
        // shift, as IgH writes it.
        let sync1_reg = u32::try_from(nanos(sync1.cycle).saturating_add(nanos(sync1.shift)))
            .map_err(|_| MasterError::InvalidArgument("SYNC1 cycle longer than 2^32 ns"))?;
        fpwr(
            bus,
            station,
            reg::DC_SYNC1_CYCLE,
            sync1_reg.to_le_bytes(),
            "SYNC1 cycle",
        )
        .await?;
        activation |= DcActivation {
            sync1: true,
            ..DcActivation::default()
        }
        .encode();
    }
    fpwr(
        bus,
        station,
        reg::DC_ACTIVATION,
        [activation],
        "SYNC0 activation",
    )
    .await
}

/// What to write to 0x0980 (cyclic unit control) and 0x0981 (activation): the
/// AssignActivate word of the first operation mode in the slave's SII DC category (low
/// byte 0x0980, high byte 0x0981, as IgH and TwinCAT write it) when it has one, else the
/// SYNC unit on ECAT with cyclic operation and SYNC0.
fn assign_activate(record: &SlaveRecord) -> (u8, u8) {
    let from_sii = SiiImage::parse(&record.sii)
        .ok()
        .and_then(|sii| sii.dc.first().map(|mode| mode.assign_activate))
        .filter(|&word| word >> 8 != 0);
    match from_sii {
        Some(word) => {
            let [unit_control, activation] = word.to_le_bytes();
            (unit_control, activation)
        }
        None => {
            let activation = DcActivation {
                cyclic: true,
                sync0: true,
                ..DcActivation::default()
            };
            (0, activation.encode())
        }
    }
}

/// The first SYNC0 pulse: at least `lead` after `now`, on a multiple of the cycle (so
/// every slave with the same cycle fires together), plus the shift.
pub(crate) fn sync0_start(now: u64, lead: Duration, cycle_ns: u64, shift: Duration) -> u64 {
    let lead = u64::try_from(lead.as_nanos()).unwrap_or(u64::MAX);
    let shift = u64::try_from(shift.as_nanos()).unwrap_or(0);
    let cycle = cycle_ns.max(1);
    (now.saturating_add(lead) / cycle)
        .saturating_add(1)
        .saturating_mul(cycle)
        .saturating_add(shift)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delays_add_up_half_loop_differences() {
        // Hops 200, 300, 120 ns behind the reference: loops 2·(200+300+120), ...
        let loops = [1240, 840, 240, 0];
        assert_eq!(line_delays(&loops), vec![0, 200, 500, 620]);
        assert_eq!(line_delays(&[]), Vec::<u32>::new());
    }

    #[test]
    fn sync0_starts_on_a_cycle_boundary_after_the_lead() {
        let start = sync0_start(
            1_234_567,
            Duration::from_millis(100),
            1_000_000,
            Duration::ZERO,
        );
        assert_eq!(start, 102_000_000);
        let shifted = sync0_start(0, Duration::ZERO, 1_000, Duration::from_nanos(250));
        assert_eq!(shifted, 1_250);
    }
}
