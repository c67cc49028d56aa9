//! Bringing one slave up: station address, identity and SII, mailbox SyncManagers,
//! process-data SyncManagers and FMMUs, and the walk through the AL states.

use tokio::time::Instant;

use crate::mailbox::SlaveMailboxConfig;
use crate::wire::WireError;
use crate::wire::register::address::{
    self as reg, fmmu as fmmu_address, sync_manager as sm_address,
};
use crate::wire::register::info::INFO_LEN;
use crate::wire::register::{
    AlState, AlStatusCode, DlStatus, EscInfo, EscInfoRepr, Fmmu, FmmuRepr, SyncManager,
    SyncManagerRepr,
};
use crate::wire::sii::fmmu::FmmuUsage;
use crate::wire::sii::{SiiImage, SiiMailboxArea};

use super::al::{self, Who};
use super::dc;
use super::eeprom::Eeprom;
use super::mailboxes;
use super::slave_config::Transition;
use super::startup;
use crate::master::access::datagram::{apwr, fprd, fprd_u16, fpwr};
use crate::master::context::Context;
use crate::master::error::MasterError;
use crate::master::event::MasterEvent;
use crate::master::info::{Identity, ProcessDataInfo, SlaveInfo};
use crate::master::process_data::layout::ProcessDataLayout;
use crate::master::process_data::mailbox_status;
use crate::master::process_data::pdo_config;
use crate::master::record::SlaveRecord;

/// How many completed cycles the master waits for after SAFEOP, so that every output
/// SyncManager has been written before OP is requested (a slave refuses OP without valid
/// outputs, 0x0019).
const CYCLES_BEFORE_OP: u64 = 2;

fn malformed(position: u16, what: &'static str) -> impl FnOnce(WireError) -> MasterError {
    move |source| MasterError::Malformed {
        position,
        what,
        source,
    }
}

/// The EEPROM interface of `station` with the master's timing.
pub(crate) fn eeprom(ctx: &Context, station: u16) -> Eeprom<'_> {
    Eeprom::new(
        &ctx.bus,
        station,
        ctx.config.poll_interval,
        ctx.config.eeprom_timeout,
    )
}

fn mailbox_layout(
    station: u16,
    rx: SiiMailboxArea,
    tx: SiiMailboxArea,
    sii: &SiiImage<'_>,
) -> Option<SlaveMailboxConfig> {
    (rx.is_present() && tx.is_present()).then_some(SlaveMailboxConfig {
        station,
        write: crate::mailbox::MailboxArea {
            start: rx.offset,
            len: rx.size,
        },
        read: crate::mailbox::MailboxArea {
            start: tx.offset,
            len: tx.size,
        },
        protocols: sii.fixed.mailbox_protocols,
    })
}

/// Gives the slave at `position` its station address and learns what it is: ESC
/// information, alias, the whole SII, DL status, AL status. `previous` is what the master
/// knew of this position before (its requested state and image place are kept).
pub(crate) async fn identify(
    ctx: &Context,
    position: u16,
    previous: Option<&SlaveRecord>,
) -> Result<SlaveRecord, MasterError> {
    let bus = &ctx.bus;
    let station = ctx
        .config
        .station_of(position)
        .ok_or(MasterError::TooManySlaves {
            count: position,
            base: ctx.config.station_base,
        })?;
    apwr(
        bus,
        position,
        reg::STATION_ADDRESS,
        station.to_le_bytes(),
        "station address",
    )
    .await?;
    let info = fprd(bus, station, reg::TYPE, INFO_LEN, "ESC information").await?;
    let esc = EscInfo::new_checked(&info[..])
        .and_then(|view| EscInfoRepr::parse(&view))
        .map_err(malformed(position, "ESC information"))?;
    let alias = fprd_u16(bus, station, reg::STATION_ALIAS, "station alias").await?;
    let eeprom = eeprom(ctx, station);
    eeprom.take().await?;
    let image = eeprom.read_image(ctx.config.max_sii_words).await?;
    let sii = SiiImage::parse(&image).map_err(malformed(position, "SII"))?;
    let dl = fprd(bus, station, reg::DL_STATUS, DlStatus::LEN, "DL status").await?;
    let dl_status = DlStatus::parse(&dl).map_err(malformed(position, "DL status"))?;
    let name = sii.name().unwrap_or_default().to_owned();
    let who = Who {
        position,
        station,
        name: &name,
    };
    let status = al::read_status(bus, who).await?;
    let fixed = &sii.fixed;
    let info = SlaveInfo {
        position,
        station,
        alias,
        identity: Identity {
            vendor_id: fixed.vendor_id,
            product_code: fixed.product_code,
            revision: fixed.revision,
            serial: fixed.serial,
        },
        esc,
        mailbox: mailbox_layout(station, fixed.std_rx_mailbox, fixed.std_tx_mailbox, &sii),
        boot_mailbox: mailbox_layout(station, fixed.boot_rx_mailbox, fixed.boot_tx_mailbox, &sii),
        dl_status,
        al_state: status.status.state,
        al_error: status.status.error,
        al_status_code: status.code,
        requested_state: previous.map_or(ctx.config.target_state, |p| p.info.requested_state),
        process_data: previous.map(|p| p.info.process_data).unwrap_or_default(),
        present: true,
        device_type: previous.map_or(0, |p| p.info.device_type),
        name,
    };
    let layout = previous.map(|p| p.layout.clone()).unwrap_or_default();
    Ok(SlaveRecord {
        info,
        sii: image,
        layout,
        pdo_written: false,
        held: false,
    })
}

/// Writes SM0/SM1 for the standard (or bootstrap) mailbox, from the SII (spec-notes §mbx.handshake).
async fn configure_mailbox(ctx: &Context, info: &SlaveInfo, boot: bool) -> Result<(), MasterError> {
    let mailbox = if boot {
        info.boot_mailbox
    } else {
        info.mailbox
    };
    let Some(m) = mailbox else {
        return Ok(());
    };
    let mut bytes = [0u8; 16];
    let (sm0, sm1) = bytes.split_at_mut(8);
    SyncManagerRepr::mailbox_out(m.write.start, m.write.len)
        .emit(&mut SyncManager::new_unchecked(sm0))
        .and_then(|()| {
            SyncManagerRepr::mailbox_in(m.read.start, m.read.len)
                .emit(&mut SyncManager::new_unchecked(sm1))
        })
        .map_err(malformed(info.position, "mailbox SyncManagers"))?;
    fpwr(
        &ctx.bus,
        info.station,
        reg::SM_BASE,
        bytes,
        "mailbox SyncManagers",
    )
    .await
}

/// Maps the slave's "mailbox full" bit into the cyclic frame (see `mailbox_status`).
async fn map_mailbox_status(ctx: &Context, record: &SlaveRecord) -> Result<(), MasterError> {
    let sii = SiiImage::parse(&record.sii).map_err(malformed(record.info.position, "SII"))?;
    mailbox_status::map(ctx, &record.info, &sii).await
}

/// The FMMU kept for the mailbox-status bit of the slave of `info`, if any.
fn reserved_fmmu(ctx: &Context, info: &SlaveInfo, sii: &SiiImage<'_>) -> Option<u8> {
    (ctx.config.map_mailbox_status && info.mailbox.is_some())
        .then(|| mailbox_status::status_fmmu(sii, info.esc.fmmu_count))
        .flatten()
}

/// Which FMMU serves each process-data SyncManager: the FMMUs the SII marks for outputs
/// (inputs) in order, then any FMMU not used otherwise; never `reserved` (the
/// mailbox-status FMMU).
fn fmmu_plan(
    sii: &SiiImage<'_>,
    fmmu_count: u8,
    reserved: Option<u8>,
    layout: &ProcessDataLayout,
    pd: ProcessDataInfo,
) -> Vec<(u8, FmmuRepr)> {
    // An ESC reporting no FMMU count is taken to have the usual 16 at most.
    let count = match usize::from(fmmu_count) {
        0 => 16,
        n => n.min(16),
    };
    let mut taken = [false; 16];
    if let Some(slot) = reserved.and_then(|r| taken.get_mut(usize::from(r))) {
        *slot = true;
    }
    let mut plan = Vec::new();
    let (mut out_at, mut in_at) = (pd.outputs_offset, pd.inputs_offset);
    for sm in &layout.sync_managers {
        let wanted = if sm.outputs {
            FmmuUsage::Outputs
        } else {
            FmmuUsage::Inputs
        };
        let marked = sii
            .fmmu
            .iter()
            .enumerate()
            .position(|(i, &u)| u == wanted && i < count && !taken[i]);
        let free = || {
            (0..count).find(|&i| {
                !taken[i]
                    && !matches!(
                        sii.fmmu.get(i),
                        Some(FmmuUsage::Outputs | FmmuUsage::Inputs | FmmuUsage::SyncManagerStatus)
                    )
            })
        };
        let Some(index) = marked.or_else(free) else {
            break;
        };
        taken[index] = true;
        let logical = if sm.outputs { &mut out_at } else { &mut in_at };
        let repr = if sm.outputs {
            FmmuRepr::outputs(*logical, sm.length, sm.start)
        } else {
            FmmuRepr::inputs(*logical, sm.length, sm.start)
        };
        *logical += u32::from(sm.length);
        plan.push((index as u8, repr));
    }
    plan
}

/// Writes the process-data SyncManagers and FMMUs (in PREOP, before SAFEOP).
async fn configure_process_data(ctx: &Context, record: &SlaveRecord) -> Result<(), MasterError> {
    let info = &record.info;
    let sii = SiiImage::parse(&record.sii).map_err(malformed(info.position, "SII"))?;
    for sm in &record.layout.sync_managers {
        let mut bytes = [0u8; 8];
        SyncManagerRepr::enabled(sm.start, sm.length, sm.control)
            .emit(&mut SyncManager::new_unchecked(&mut bytes[..]))
            .map_err(malformed(info.position, "process-data SyncManager"))?;
        let ado = sm_address(sm.index).ok_or(MasterError::InvalidArgument("SyncManager number"))?;
        fpwr(
            &ctx.bus,
            info.station,
            ado,
            bytes,
            "process-data SyncManager",
        )
        .await?;
    }
    let reserved = reserved_fmmu(ctx, info, &sii);
    // The FMMUs map the slave's share at its group's logical addresses.
    let pd = info.process_data;
    let logical = ProcessDataInfo {
        outputs_offset: ctx.image.logical_of(pd.outputs_offset),
        inputs_offset: ctx.image.logical_of(pd.inputs_offset),
        ..pd
    };
    let plan = fmmu_plan(&sii, info.esc.fmmu_count, reserved, &record.layout, logical);
    for (index, fmmu) in plan {
        let mut bytes = [0u8; 16];
        fmmu.emit(&mut Fmmu::new_unchecked(&mut bytes[..]))
            .map_err(malformed(info.position, "FMMU"))?;
        let ado = fmmu_address(index).ok_or(MasterError::InvalidArgument("FMMU number"))?;
        fpwr(&ctx.bus, info.station, ado, bytes, "FMMU").await?;
    }
    Ok(())
}

/// Writes the configured PDO assignment unless the layout was made after writing it.
async fn write_pdo_config(ctx: &Context, record: &SlaveRecord) -> Result<(), MasterError> {
    if record.pdo_written {
        return Ok(());
    }
    if pdo_config::apply(ctx, &record.info).await? {
        ctx.update(record.info.position, |r| r.pdo_written = true);
    }
    Ok(())
}

/// Waits until the cyclic exchange has completed `cycles` more exchanges of the slave's
/// group (a group with a longer period than the master's cycle goes in fewer frames, and
/// the slave needs its outputs before OP).
async fn wait_cycles(ctx: &Context, who: Who<'_>, cycles: u64) -> Result<(), MasterError> {
    let start = ctx.image.completed_for(who.position);
    let deadline = Instant::now() + ctx.config.op_timeout;
    while ctx.image.completed_for(who.position) < start + cycles {
        if Instant::now() >= deadline {
            return Err(MasterError::StateTimeout {
                position: who.position,
                name: who.name.to_owned(),
                to: AlState::Op,
                state: AlState::SafeOp,
            });
        }
        tokio::time::sleep(ctx.config.poll_interval.max(ctx.config.cycle_period)).await;
    }
    Ok(())
}

/// Moves the slave of `record` from its current state to `to`, one transition at a time,
/// doing what each transition needs first. Reports every change and a refusal as events
/// and keeps the record's state up to date.
pub(crate) async fn bring_to(
    ctx: &Context,
    record: &SlaveRecord,
    to: AlState,
) -> Result<(), MasterError> {
    let info = &record.info;
    let who = Who {
        position: info.position,
        station: info.station,
        name: &info.name,
    };
    let mut current = al::read_status(&ctx.bus, who).await?.status.state;
    for step in al::path(current, to) {
        let transition = Transition {
            from: current,
            to: step,
        };
        let prepared = match step {
            AlState::PreOp if current == AlState::Init => {
                configure_mailbox(ctx, info, false).await?;
                map_mailbox_status(ctx, record).await
            }
            AlState::Boot => configure_mailbox(ctx, info, true).await,
            AlState::SafeOp if current == AlState::PreOp => {
                write_pdo_config(ctx, record).await?;
                startup::run(ctx, record, transition).await?;
                startup::write_watchdog(ctx, record).await?;
                dc::activate_sync0(ctx, record).await?;
                configure_process_data(ctx, record).await
            }
            AlState::Op if !record.layout.sync_managers.is_empty() => {
                wait_cycles(ctx, who, CYCLES_BEFORE_OP).await
            }
            _ => Ok(()),
        };
        prepared?;
        // INIT -> PREOP's commands need the mailbox, which works from PREOP on: they run
        // once the slave is there; every other transition's run before it is requested.
        if transition != Transition::INIT_PREOP && transition != Transition::PREOP_SAFEOP {
            startup::run(ctx, record, transition).await?;
        }
        match al::change_state(&ctx.bus, &ctx.config, who, step).await {
            Ok(status) => {
                ctx.update(info.position, |r| {
                    r.info.al_state = status.status.state;
                    r.info.al_error = false;
                    r.info.al_status_code = status.code;
                });
                mailboxes::follow(ctx, info, current, step);
                ctx.emit(MasterEvent::StateChanged {
                    position: info.position,
                    station: info.station,
                    from: current,
                    to: step,
                });
                current = step;
                if transition == Transition::INIT_PREOP {
                    startup::run(ctx, record, transition).await?;
                }
            }
            Err(err) => {
                if let MasterError::StateRefused { code, .. } = &err {
                    let code: AlStatusCode = *code;
                    ctx.update(info.position, |r| {
                        r.info.al_state = current;
                        r.info.al_error = true;
                        r.info.al_status_code = code;
                    });
                    ctx.emit(MasterEvent::AlError {
                        position: info.position,
                        station: info.station,
                        name: info.name.clone(),
                        state: current,
                        code,
                    });
                }
                return Err(err);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::register::SmControl;
    use crate::wire::sii::SiiBuilder;
    use crate::wire::sii::fixed::SiiFixedRepr;

    use crate::master::process_data::layout::PdSyncManager;

    fn layout() -> ProcessDataLayout {
        let sm = |index, start, length, outputs| PdSyncManager {
            index,
            start,
            length,
            control: if outputs {
                SmControl::OUTPUTS
            } else {
                SmControl::INPUTS
            },
            outputs,
        };
        ProcessDataLayout {
            sync_managers: vec![sm(2, 0x1100, 6, true), sm(3, 0x1400, 4, false)],
            pdos: Vec::new(),
        }
    }

    fn image(fmmu: Vec<FmmuUsage>) -> Vec<u8> {
        let mut b = SiiBuilder::new(SiiFixedRepr::default());
        b.fmmu = fmmu;
        b.build().unwrap()
    }

    const PD: ProcessDataInfo = ProcessDataInfo {
        outputs: 6,
        inputs: 4,
        outputs_offset: 0x20,
        inputs_offset: 0x26,
    };

    #[test]
    fn fmmus_follow_the_sii_usage_and_the_image_offsets() {
        // Inputs first in the SII: FMMU 1 serves the outputs, FMMU 0 the inputs.
        let bytes = image(vec![
            FmmuUsage::Inputs,
            FmmuUsage::Outputs,
            FmmuUsage::SyncManagerStatus,
        ]);
        let sii = SiiImage::parse(&bytes).unwrap();
        assert_eq!(
            fmmu_plan(&sii, 8, None, &layout(), PD),
            vec![
                (1, FmmuRepr::outputs(0x20, 6, 0x1100)),
                (0, FmmuRepr::inputs(0x26, 4, 0x1400)),
            ]
        );
    }

    #[test]
    fn without_usage_free_fmmus_are_taken_within_the_esc_s_count() {
        let bytes = image(Vec::new());
        let sii = SiiImage::parse(&bytes).unwrap();
        assert_eq!(
            fmmu_plan(&sii, 8, None, &layout(), PD),
            vec![
                (0, FmmuRepr::outputs(0x20, 6, 0x1100)),
                (1, FmmuRepr::inputs(0x26, 4, 0x1400)),
            ]
        );
        // An ESC with one FMMU maps what it can.
        assert_eq!(fmmu_plan(&sii, 1, None, &layout(), PD).len(), 1);
    }
}
