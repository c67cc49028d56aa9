//! From a [`Topology`] to a running [`Segment`]: per slave the SII image (`sii.rs`), the CoE
//! dictionary (`dictionary.rs`), the ESC and the device stack, assembled here.
//!
//! Memory layout of every slave (the one the SII advertises and the ESC checks): SM0 (mailbox
//! out) at 0x1000, SM1 (mailbox in) right behind it; process-data SyncManagers from the first
//! 0x80-aligned address after the mailboxes (0x1000 without a mailbox), each taking room for
//! its three buffers.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use ecat_wire::WireError;
use thiserror::Error;

use crate::device::coe::{CoeService, EmergencyTrigger, SharedDictionary};
use crate::device::coe_quirks::CoeQuirks;
use crate::device::dio::{DigitalInputs, DigitalOutputs, InputDriver, OutputProbe};
use crate::device::eoe::{EoeService, HostPort, IpConfig, factory_mac};
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
    /// The physical inputs of a digital input terminal. On a terminal wired to outputs
    /// (`wired_to`) it drives the inputs in parallel with the wire.
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

/// Builds the segment described by `topology` (a ring with `ring = true`).
pub fn build(topology: &Topology) -> Result<Segment, BuildError> {
    build_with_handles(topology).map(|b| b.segment)
}

/// Builds the segment and keeps handles into its slaves. With `ring = true` the last slave's
/// port 1 is wired back to the master's backup port ([`Segment::set_ring`]).
pub fn build_with_handles(topology: &Topology) -> Result<Built, BuildError> {
    let time = ManualTime::new(0);
    let mut segment = Segment::new(Box::new(time.clone()));
    let mut slaves = Vec::new();
    let mut outputs = output_terminals(topology);
    let wires = wires(topology, &outputs)?;
    for (position, spec) in topology.slaves.iter().enumerate() {
        let terminals = Terminals {
            outputs: outputs[position].take(),
            wire: wires[position].clone(),
        };
        let (esc, device, handles) = build_slave(position, spec, terminals)?;
        segment.push(esc, Box::new(device));
        slaves.push(handles);
    }
    segment.set_ring(topology.ring);
    Ok(Built {
        segment,
        time,
        slaves,
    })
}

/// The built parts of one slave.
type SlaveParts = (Esc, SlaveDevice, SlaveHandles);

/// The digital output terminal of every slave that has one, by position. They are made
/// before any slave is built because an input terminal wired to one needs its output
/// state, wherever it sits in the line.
fn output_terminals(topology: &Topology) -> Vec<Option<DigitalOutputs>> {
    topology
        .slaves
        .iter()
        .map(|spec| match spec.application {
            Application::DigitalOutputs { channels } => Some(DigitalOutputs::new(channels)),
            _ => None,
        })
        .collect()
}

/// For every slave by position, the outputs its digital inputs are wired to (`wired_to`),
/// after checking that they name an output terminal with enough channels.
fn wires(
    topology: &Topology,
    outputs: &[Option<DigitalOutputs>],
) -> Result<Vec<Option<OutputProbe>>, BuildError> {
    topology
        .slaves
        .iter()
        .enumerate()
        .map(|(position, spec)| {
            let Application::DigitalInputs {
                channels,
                wired_to: Some(to),
            } = spec.application
            else {
                return Ok(None);
            };
            let invalid = |reason: String| BuildError::Invalid {
                position,
                name: spec.name.clone(),
                reason: format!("wired_to = {to}: {reason}"),
            };
            let target = usize::from(to);
            let Some(other) = topology.slaves.get(target) else {
                return Err(invalid(format!(
                    "no slave at position {to} (the topology has {})",
                    topology.slaves.len()
                )));
            };
            match &outputs[target] {
                None => Err(invalid(format!(
                    "slave {to} ({}) has no digital outputs",
                    other.name
                ))),
                Some(terminal) if terminal.channels() < channels => Err(invalid(format!(
                    "slave {to} ({}) has {} digital outputs, {channels} inputs need as many",
                    other.name,
                    terminal.channels()
                ))),
                Some(terminal) => Ok(Some(terminal.probe())),
            }
        })
        .collect()
}

/// The digital I/O parts made ahead of one slave (see [`output_terminals`] and [`wires`]).
struct Terminals {
    /// Its output terminal, if it is a digital output slave.
    outputs: Option<DigitalOutputs>,
    /// The outputs its inputs are wired to, if it is a wired digital input slave.
    wire: Option<OutputProbe>,
}

fn build_slave(
    position: usize,
    spec: &SlaveSpec,
    terminals: Terminals,
) -> Result<SlaveParts, BuildError> {
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
                factory_mac: Some(factory_mac(position as u16)),
                ..IpConfig::default()
            };
            let port = HostPort::default();
            handles.eoe_port = Some(port.clone());
            stack = stack.with(
                EoeService::new(config)
                    .with_tcp_host(true)
                    .with_host_port(port)
                    .with_address_filter(),
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
            let dio = terminals
                .outputs
                .unwrap_or_else(|| DigitalOutputs::new(channels));
            handles.outputs = Some(dio.probe());
            device = device.with_process(dio);
        }
        Application::DigitalInputs { channels, .. } => {
            let dio = match &terminals.wire {
                Some(outputs) => DigitalInputs::wired(channels, outputs),
                None => DigitalInputs::new(channels),
            };
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
