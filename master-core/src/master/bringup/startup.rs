//! Applying a slave's configuration at bring-up: the identity check (a slave that is not
//! the one expected is held in PREOP, ETG.1020 §6.4 "Check identity"), the check of its
//! configured PDOs against what its SII offers, and its start-up commands, run in order
//! for each transition (ETG.1020 §6.4, ETG.2100 §6.5 InitCmds).

use crate::mailbox::MailboxError;
use crate::wire::register::AlState;
use crate::wire::sii::SiiImage;
use crate::wire::soe::ElementFlags;

use super::slave_config::{
    MismatchPolicy, SlaveConfigs, StartupAction, TopologyProblem, Transition,
};
use crate::master::access::datagram::fpwr;
use crate::master::context::Context;
use crate::master::error::MasterError;
use crate::master::event::MasterEvent;
use crate::master::record::SlaveRecord;
use crate::wire::register::address as reg;

use std::sync::PoisonError;

/// The configured identity check of one slave: `Some(problem)` (also reported as an
/// event and a log line) when it is not the slave expected.
pub(crate) fn check_identity(ctx: &Context, record: &SlaveRecord) -> Option<TopologyProblem> {
    let info = &record.info;
    let expected = ctx.slave_config_for(info)?.expected?;
    let reason = expected.mismatch(&info.identity)?;
    let problem = TopologyProblem::Mismatch {
        expected,
        found: info.identity,
        reason,
    };
    tracing::warn!(
        position = info.position,
        station = info.station,
        name = %info.name,
        %problem,
        "slave held in PREOP: not the one the configuration expects"
    );
    ctx.emit(MasterEvent::TopologyMismatch {
        position: info.position,
        station: info.station,
        problem: problem.clone(),
    });
    Some(problem)
}

/// Checks the identified slaves of a scan against the configuration: mismatches (those
/// slaves, or all with [`MismatchPolicy::Segment`], get PREOP as requested state),
/// configured slaves missing, slaves no entry names. Every finding is an event and a log
/// line.
pub(crate) fn check_segment(ctx: &Context, records: &mut [SlaveRecord]) -> Result<(), MasterError> {
    let configs: SlaveConfigs = ctx
        .slave_configs
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .clone();
    if configs.slaves.is_empty() {
        return Ok(());
    }
    let mut wrong = false;
    // The first problem, for the error of MismatchPolicy::Stop.
    let mut first: (u16, String) = (0, String::new());
    for record in records.iter_mut().filter(|r| !r.sii.is_empty()) {
        if let Some(problem) = check_identity(ctx, record) {
            if !wrong {
                first = (
                    record.info.position,
                    format!("{} ({}): {problem}", record.info.name, record.info.station),
                );
            }
            wrong = true;
            hold_in_preop(record);
        }
        let info = &record.info;
        if configs.report_extra && configs.for_slave(info).is_none() {
            let problem = TopologyProblem::Extra {
                found: info.identity,
            };
            tracing::warn!(position = info.position, station = info.station, name = %info.name, %problem, "slave not in the configuration");
            ctx.emit(MasterEvent::TopologyMismatch {
                position: info.position,
                station: info.station,
                problem,
            });
        }
    }
    for config in &configs.slaves {
        let Some(address) = config.address else {
            continue;
        };
        if records
            .iter()
            .any(|r| !r.sii.is_empty() && config.names(&r.info))
        {
            continue;
        }
        if config.expected.is_some() && !wrong {
            wrong = true;
            first = (u16::MAX, format!("no slave at {address}"));
        }
        let position = match address {
            crate::master::SlaveAddress::Position(p) => p,
            _ => u16::MAX,
        };
        let station = match address {
            crate::master::SlaveAddress::Station(s) => s,
            crate::master::SlaveAddress::Position(p) => ctx.config.station_of(p).unwrap_or(0),
            crate::master::SlaveAddress::Alias(_) => 0,
        };
        let problem = TopologyProblem::Missing { address };
        tracing::warn!(%address, %problem, "configured slave missing");
        ctx.emit(MasterEvent::TopologyMismatch {
            position,
            station,
            problem,
        });
    }
    if !wrong {
        return Ok(());
    }
    match configs.policy {
        MismatchPolicy::Slave => {}
        MismatchPolicy::Segment => {
            tracing::warn!("the whole segment is held in PREOP: it is not the one configured");
            records.iter_mut().for_each(hold_in_preop);
        }
        MismatchPolicy::Stop => {
            return Err(MasterError::Configuration {
                position: first.0,
                reason: first.1,
            });
        }
    }
    Ok(())
}

/// Writes the configured SyncManager watchdog (before SAFEOP, ETG.1000.4 §6.3).
pub(crate) async fn write_watchdog(ctx: &Context, record: &SlaveRecord) -> Result<(), MasterError> {
    let watchdog = ctx
        .slave_configs
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .watchdog;
    let Some(watchdog) = watchdog else {
        return Ok(());
    };
    if record.layout.sync_managers.is_empty() {
        return Ok(());
    }
    let station = record.info.station;
    fpwr(
        &ctx.bus,
        station,
        reg::WATCHDOG_DIVIDER,
        watchdog.divider.to_le_bytes(),
        "watchdog divider",
    )
    .await?;
    fpwr(
        &ctx.bus,
        station,
        reg::WATCHDOG_TIME_PROCESS_DATA,
        watchdog.process_data_ticks.to_le_bytes(),
        "process-data watchdog time",
    )
    .await
}

fn hold_in_preop(record: &mut SlaveRecord) {
    let requested = &mut record.info.requested_state;
    if matches!(*requested, AlState::SafeOp | AlState::Op) {
        *requested = AlState::PreOp;
    }
}

/// The configured PDOs of each identified slave that its SII lists PDOs for must be
/// among them (ETG.1000.6 §5.6.7.4.7-8, the SII RxPDO/TxPDO categories); checked at the
/// scan before anything is written, so a wrong index changes nothing.
pub(crate) fn check_pdos(ctx: &Context, records: &[SlaveRecord]) -> Result<(), MasterError> {
    for record in records.iter().filter(|r| !r.sii.is_empty()) {
        let Some(assignments) = ctx.pdo_config_for(&record.info) else {
            continue;
        };
        let position = record.info.position;
        let sii = SiiImage::parse(&record.sii).map_err(|source| MasterError::Malformed {
            position,
            what: "SII",
            source,
        })?;
        let offered: Vec<u16> = sii
            .rxpdo
            .iter()
            .chain(sii.txpdo.iter())
            .map(|p| p.index)
            .collect();
        if offered.is_empty() {
            continue;
        }
        for assignment in &assignments {
            if let Some(pdo) = assignment.pdos.iter().find(|p| !offered.contains(&p.index)) {
                let list: Vec<String> = offered.iter().map(|i| format!("{i:#06x}")).collect();
                return Err(MasterError::Configuration {
                    position,
                    reason: format!(
                        "{} ({}) has no PDO {:#06x} (SM{}); it offers {}",
                        record.info.name,
                        record.info.station,
                        pdo.index,
                        assignment.sync_manager,
                        list.join(", ")
                    ),
                });
            }
        }
    }
    Ok(())
}

/// Runs the slave's start-up commands of `transition`, in order. A failure is reported
/// (event, log), the record held from the watch's retries, and returned.
pub(crate) async fn run(
    ctx: &Context,
    record: &SlaveRecord,
    transition: Transition,
) -> Result<(), MasterError> {
    let info = &record.info;
    let Some(config) = ctx.slave_config_for(info) else {
        return Ok(());
    };
    let commands: Vec<_> = config
        .startup
        .iter()
        .filter(|c| c.transition == transition)
        .collect();
    if commands.is_empty() {
        return Ok(());
    }
    let position = info.position;
    let mailbox = ctx
        .mailboxes
        .slave(info.station)
        .map_err(|_| MasterError::NoMailbox {
            position,
            state: info.al_state,
        })?;
    for command in commands {
        let result = match &command.action {
            StartupAction::Sdo {
                index,
                subindex,
                data,
                complete_access: false,
            } => mailbox.sdo_download(*index, *subindex, data).await,
            StartupAction::Sdo {
                index,
                subindex,
                data,
                complete_access: true,
            } => mailbox.sdo_download_complete(*index, *subindex, data).await,
            StartupAction::Idn { drive, idn, data } => {
                mailbox
                    .soe_write(*drive, (*idn).into(), ElementFlags::VALUE, data)
                    .await
            }
        };
        if let Err(source) = result {
            let abort_code = match &source {
                MailboxError::SdoAbort { code, .. } => Some(u32::from(*code)),
                _ => None,
            };
            let what = command.action.to_string();
            tracing::error!(
                position,
                station = info.station,
                name = %info.name,
                %transition,
                command = %what,
                abort_code = abort_code.map(|c| format!("{c:#010x}")),
                error = %source,
                "start-up command failed; the slave's bring-up stops here"
            );
            ctx.emit(MasterEvent::StartupFailed {
                position,
                station: info.station,
                transition: transition.to_string(),
                command: what.clone(),
                abort_code,
                error: source.to_string(),
            });
            ctx.update(position, |r| r.held = true);
            return Err(MasterError::Startup {
                position,
                transition: transition.to_string(),
                command: what,
                source,
            });
        }
    }
    Ok(())
}
