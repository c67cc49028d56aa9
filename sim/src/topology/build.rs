//! From a [`Topology`] to a running [`Segment`]: per slave the SII image (`sii.rs`), the CoE
//! dictionary (`dictionary.rs`), the ESC and the device stack, assembled here.
//!
//! Memory layout of every slave (the one the SII advertises and the ESC checks): SM0 (mailbox
//! out) at 0x1000, SM1 (mailbox in) right behind it; process-data SyncManagers from the first
//! 0x80-aligned address after the mailboxes (0x1000 without a mailbox), each taking room for
//! its three buffers.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use master_core::wire::WireError;
use thiserror::Error;

use crate::device::coe::{CoeService, EmergencyTrigger, SharedDictionary};
use crate::device::coe_quirks::CoeQuirks;
use crate::device::dio::{DigitalInputs, DigitalOutputs, InputDriver, OutputProbe};
use crate::device::eoe::{EoeService, HostPort, IpConfig};
use crate::device::foe::{BusyPhase, FileStore, FoeFile, FoeService};
use crate::device::voe::VoeEcho;
use crate::device::{Drive, MailboxStack, SlaveDevice};
use crate::esc::{DcConfig, Esc, EscConfig, ManualTime};
use crate::segment::Segment;

use super::dictionary::dictionary;
use super::model::{Application, EscSpec, Protocol, SlaveSpec, Topology, pattern};
use super::sii::sii;
use super::soe::soe_service;

/// Why a topology cannot be built.
#[derive(Debug, Error)]
pub enum BuildError {
    /// A slave's dictionary declaration is invalid.
    #[error("slave {position} ({name}): dictionary: {reason}")]
    Dictionary {
        /// Ring position.
        position: usize,
        /// Slave name.
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// A slave's SII image cannot be emitted.
    #[error("slave {position} ({name}): SII: {source}")]
    Sii {
        /// Ring position.
        position: usize,
        /// Slave name.
        name: String,
        /// What is wrong.
        source: WireError,
    },
    /// Something in the description makes no sense.
    #[error("slave {position} ({name}): {reason}")]
    Invalid {
        /// Ring position.
        position: usize,
        /// Slave name.
        name: String,
        /// What is wrong.
        reason: String,
    },
}

/// What a test may want to reach inside a built slave.
#[derive(Debug, Clone, Default)]
pub struct SlaveHandles {
    /// The CoE dictionary (write counters, values), for CoE slaves.
    pub dictionary: Option<SharedDictionary>,
    /// The physical outputs of a digital output terminal.
    pub outputs: Option<OutputProbe>,
    /// The physical inputs of a digital input terminal.
    pub inputs: Option<InputDriver>,
    /// The FoE file store.
    pub files: Option<FileStore>,
    /// Raises CoE emergencies on the slave (CoE slaves).
    pub emergencies: Option<EmergencyTrigger>,
    /// The Ethernet side of an EoE slave, to hand to the host (ecat-sim's TAP bridge).
    pub eoe_port: Option<HostPort>,
}

/// A built segment, its time base and per-slave handles.
#[derive(Debug)]
pub struct Built {
    /// The segment.
    pub segment: Segment,
    /// Its manual time base (advance it to move distributed clocks).
    pub time: ManualTime,
    /// Handles by ring position.
    pub slaves: Vec<SlaveHandles>,
}

/// Builds the segment described by `topology`.
pub fn build(topology: &Topology) -> Result<Segment, BuildError> {
    build_with_handles(topology).map(|b| b.segment)
}

/// Builds the segment and keeps handles into its slaves.
pub fn build_with_handles(topology: &Topology) -> Result<Built, BuildError> {
    let time = ManualTime::new(0);
    let mut segment = Segment::new(Box::new(time.clone()));
    let mut slaves = Vec::new();
    for (position, spec) in topology.slaves.iter().enumerate() {
        let (esc, device, handles) = build_slave(position, spec)?;
        segment.push(esc, Box::new(device));
        slaves.push(handles);
    }
    Ok(Built {
        segment,
        time,
        slaves,
    })
}

/// The built parts of one slave.
type SlaveParts = (Esc, SlaveDevice, SlaveHandles);

fn build_slave(position: usize, spec: &SlaveSpec) -> Result<SlaveParts, BuildError> {
    let invalid = |reason: String| BuildError::Invalid {
        position,
        name: spec.name.clone(),
        reason,
    };
    let mut handles = SlaveHandles::default();
    let has = |p: Protocol| spec.mailbox.is_some() && spec.protocols.contains(&p);
    let dictionary = if has(Protocol::Coe) {
        let dict = dictionary(spec).map_err(|reason| BuildError::Dictionary {
            position,
            name: spec.name.clone(),
            reason,
        })?;
        Some(Arc::new(Mutex::new(dict)))
    } else {
        None
    };
    handles.dictionary = dictionary.clone();

    let mut device = SlaveDevice::new();
    if spec.mailbox.is_some() {
        let delay = Duration::from_micros(u64::from(spec.esc.response_delay_us));
        let mut stack = MailboxStack::new().with_response_delay(delay);
        if let Some(dict) = &dictionary {
            let coe = CoeService::shared(Arc::clone(dict)).with_quirks(coe_quirks(&spec.esc));
            handles.emergencies = Some(coe.emergency_trigger());
            stack = stack.with(coe);
        }
        if has(Protocol::Soe) {
            stack = stack.with(soe_service(spec).map_err(invalid)?);
        }
        if has(Protocol::Foe) {
            let store = FileStore::new(
                spec.foe_capacity
                    .unwrap_or(super::model::DEFAULT_FOE_CAPACITY),
            );
            for file in &spec.foe_files {
                let data = match &file.content {
                    Some(text) => text.as_bytes().to_vec(),
                    None => pattern(file.size),
                };
                let mut f = FoeFile::new(data);
                if file.password != 0 {
                    f = f.with_password(file.password);
                }
                store.insert(&file.name, f);
            }
            handles.files = Some(store.clone());
            let mut service = FoeService::new(store);
            if let Some(busy) = &spec.foe_busy {
                service = service.with_busy(BusyPhase {
                    after_write_request: busy.after_write_request,
                    after_last_packet: busy.after_last_packet,
                    file_suffix: busy.file_suffix.clone(),
                    ..BusyPhase::default()
                });
            }
            stack = stack.with(service);
        }
        if has(Protocol::Eoe) {
            let config = IpConfig {
                ip: spec.eoe.and_then(|e| e.ip),
                ..IpConfig::default()
            };
            let port = HostPort::default();
            handles.eoe_port = Some(port.clone());
            stack = stack.with(
                EoeService::new(config)
                    .with_tcp_host(true)
                    .with_host_port(port),
            );
        }
        if has(Protocol::Voe) {
            stack = stack.with(VoeEcho::new(spec.voe_vendor_id.unwrap_or(spec.vendor_id)));
        }
        device = device.with_mailbox(stack);
    }
    match spec.application {
        Application::None => {}
        Application::Drive => {
            let dict = dictionary
                .clone()
                .ok_or_else(|| invalid("a drive needs CoE and a mailbox".into()))?;
            device = device.with_process(Drive::new(dict));
        }
        Application::DigitalOutputs { channels } => {
            let dio = DigitalOutputs::new(channels);
            handles.outputs = Some(dio.probe());
            device = device.with_process(dio);
        }
        Application::DigitalInputs { channels } => {
            let dio = DigitalInputs::new(channels);
            handles.inputs = Some(dio.driver());
            device = device.with_process(dio);
        }
    }

    let protocols = device
        .mailbox()
        .map_or(0, MailboxStack::supported_protocols);
    let sii = sii(spec, protocols).map_err(|source| BuildError::Sii {
        position,
        name: spec.name.clone(),
        source,
    })?;
    let config = EscConfig {
        ram_size: usize::from(spec.esc.ram_kib) * 1024,
        dc: DcConfig {
            hop_delay_ns: spec.esc.hop_delay_ns,
            ..DcConfig::default()
        },
        ..EscConfig::default()
    };
    Ok((Esc::new(config, sii), device, handles))
}

/// The CoE behaviours of other stacks the slave's firmware switches ask for.
fn coe_quirks(esc: &EscSpec) -> CoeQuirks {
    CoeQuirks {
        abort_in_request_service: esc.sdo_abort_in_request,
        abort_keeps_command_bits: esc.sdo_abort_keeps_command_bits,
        short_info_errors: esc.sdo_info_short_errors,
        refuse_complete_access: esc.refuse_complete_access,
        length_mismatch_only: esc.sdo_abort_length_mismatch,
    }
}
