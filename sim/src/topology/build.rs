//! From a [`Topology`] to a running [`Segment`]: per slave the SII image, the ESC and the
//! device stack.
//!
//! Memory layout of every slave (the one the SII advertises and the ESC checks): SM0 (mailbox
//! out) at 0x1000, SM1 (mailbox in) right behind it; process-data SyncManagers from the first
//! 0x80-aligned address after the mailboxes (0x1000 without a mailbox), each taking room for
//! its three buffers.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use master_core::od::access::presets::{RO_TX, RW_PREOP, RW_RX, WO};
use master_core::od::{DictionaryBuilder, Entry, Object, PdoEntry, SmType, StaticDictionary};
use master_core::od::{Identity, ValueError};
use master_core::wire::WireError;
use master_core::wire::coe::{DataType, ObjectAccess, ObjectCode};
use master_core::wire::sii::SiiBuilder;
use master_core::wire::sii::fixed::{MailboxProtocols, SiiFixedRepr, SiiMailboxArea};
use master_core::wire::sii::fmmu::FmmuUsage;
use master_core::wire::sii::general::{CoeDetails, GeneralRepr, PhysicalPorts};
use master_core::wire::sii::pdo::{Pdo, PdoFlags, SiiPdoEntry};
use master_core::wire::sii::syncm::{SyncmEnable, SyncmEntry, SyncmType};
use thiserror::Error;

use crate::device::coe::{CoeService, EmergencyTrigger, SharedDictionary};
use crate::device::coe_quirks::CoeQuirks;
use crate::device::dio::{DigitalInputs, DigitalOutputs, InputDriver, OutputProbe};
use crate::device::eoe::{EoeService, IpConfig};
use crate::device::foe::{BusyPhase, FileStore, FoeFile, FoeService};
use crate::device::voe::VoeEcho;
use crate::device::{Drive, MailboxStack, SlaveDevice};
use crate::esc::{DcConfig, Esc, EscConfig, ManualTime};
use crate::segment::Segment;

use super::model::{
    Application, CoeObject, EscSpec, PdoSpec, Protocol, SlaveSpec, Topology, pattern,
};
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
            let store = FileStore::new(1 << 20);
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
            stack = stack.with(EoeService::new(config));
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

/// A data type by its CoE name (`UNSIGNED16`, ...).
pub(crate) fn data_type(name: &str) -> Option<DataType> {
    (0u16..0x40)
        .map(DataType::from)
        .find(|dt| dt.name().eq_ignore_ascii_case(name))
}

fn access(name: &str) -> Option<ObjectAccess> {
    Some(match name {
        "ro" => ObjectAccess::RO,
        "rw" => ObjectAccess::RW,
        "wo" => WO,
        "rw_preop" => RW_PREOP,
        "ro_tx" => RO_TX,
        "rw_rx" => RW_RX,
        _ => return None,
    })
}

fn value_error(index: u16, subindex: u8, e: ValueError) -> String {
    format!("0x{index:04X}:{subindex:02X}: {e}")
}

/// One entry from its description.
fn entry(obj: &CoeObject) -> Result<Entry, String> {
    let at = format!("0x{:04X}:{:02X}", obj.index, obj.subindex);
    let dt = data_type(&obj.data_type)
        .ok_or_else(|| format!("{at}: unknown data type {:?}", obj.data_type))?;
    let access =
        access(&obj.access).ok_or_else(|| format!("{at}: unknown access {:?}", obj.access))?;
    typed_entry(obj, dt, access).map_err(|e| value_error(obj.index, obj.subindex, e))
}

fn typed_entry(obj: &CoeObject, dt: DataType, access: ObjectAccess) -> Result<Entry, ValueError> {
    let v = obj.value.as_ref();
    let int = || v.and_then(toml::Value::as_integer).unwrap_or(0);
    let sub = obj.subindex;
    let name = obj.name.as_str();
    let bytes_entry = |bytes: Vec<u8>| {
        let len = bytes.len().max(obj.size.unwrap_or(0));
        Ok(Entry::with_capacity(sub, name, dt, access, bytes, len))
    };
    let conv = |_| ValueError::OutOfRange {
        data_type: dt,
        value: int().to_string(),
    };
    match dt {
        DataType::Boolean => {
            let b = v.and_then(toml::Value::as_bool).unwrap_or(int() != 0);
            Entry::new(sub, name, dt, access, b)
        }
        DataType::Integer8 => Entry::new(sub, name, dt, access, i8::try_from(int()).map_err(conv)?),
        DataType::Integer16 => {
            Entry::new(sub, name, dt, access, i16::try_from(int()).map_err(conv)?)
        }
        DataType::Integer32 => {
            Entry::new(sub, name, dt, access, i32::try_from(int()).map_err(conv)?)
        }
        DataType::Integer64 => Entry::new(sub, name, dt, access, int()),
        DataType::Unsigned8 => {
            Entry::new(sub, name, dt, access, u8::try_from(int()).map_err(conv)?)
        }
        DataType::Unsigned16 => {
            Entry::new(sub, name, dt, access, u16::try_from(int()).map_err(conv)?)
        }
        DataType::Unsigned32 => {
            Entry::new(sub, name, dt, access, u32::try_from(int()).map_err(conv)?)
        }
        DataType::Unsigned64 => {
            Entry::new(sub, name, dt, access, u64::try_from(int()).map_err(conv)?)
        }
        DataType::Real32 => {
            let f = v.and_then(toml::Value::as_float).unwrap_or(0.0);
            Entry::new(sub, name, dt, access, f as f32)
        }
        DataType::Real64 => {
            let f = v.and_then(toml::Value::as_float).unwrap_or(0.0);
            Entry::new(sub, name, dt, access, f)
        }
        DataType::VisibleString => bytes_entry(
            v.and_then(toml::Value::as_str)
                .unwrap_or("")
                .as_bytes()
                .to_vec(),
        ),
        DataType::OctetString | DataType::Domain | DataType::UnicodeString => {
            match v.and_then(toml::Value::as_str) {
                Some(text) => bytes_entry(text.as_bytes().to_vec()),
                None => bytes_entry(pattern(obj.size.unwrap_or(0))),
            }
        }
        _ => Err(ValueError::TypeMismatch {
            data_type: dt,
            rust_type: "a topology value",
        }),
    }
}

/// Adds the described extra objects: VARs for subindex 0, RECORDs for the rest.
fn extra_objects(
    mut b: DictionaryBuilder,
    objects: &[CoeObject],
) -> Result<DictionaryBuilder, String> {
    let mut records: BTreeMap<u16, Vec<&CoeObject>> = BTreeMap::new();
    for obj in objects {
        if obj.subindex == 0 {
            let e = entry(obj)?;
            b = b.object(Object {
                index: obj.index,
                name: obj.name.clone(),
                object_code: ObjectCode::Var,
                data_type: e.data_type,
                entries: vec![e],
                zero_count_to_write: false,
            });
        } else {
            records.entry(obj.index).or_default().push(obj);
        }
    }
    for (index, entries) in records {
        let mut built = Vec::new();
        for obj in entries {
            built.push(entry(obj)?);
        }
        b = b.record(index, &format!("Object 0x{index:04X}"), |mut r| {
            for e in built {
                r = r.raw(e);
            }
            r
        });
    }
    Ok(b)
}

/// The CoE dictionary: standard objects derived from the description, then the extras.
pub(crate) fn dictionary(spec: &SlaveSpec) -> Result<StaticDictionary, String> {
    let mut b = StaticDictionary::builder()
        .device_type(spec.device_type)
        .error_register(0)
        .device_name(&spec.name)
        .identity(Identity {
            vendor_id: spec.vendor_id,
            product_code: spec.product_code,
            revision: spec.revision,
            serial: spec.serial,
        });
    let mut sm_types = vec![SmType::MailboxOut, SmType::MailboxIn];
    let max_sm = spec.pdos.iter().map(|p| p.sm).max().unwrap_or(3).max(3);
    for sm in 2..=max_sm {
        let pdo = spec.pdos.iter().find(|p| p.sm == sm);
        sm_types.push(match pdo {
            Some(p) if p.is_rx() => SmType::Outputs,
            Some(_) => SmType::Inputs,
            None if sm == 2 => SmType::Outputs,
            None if sm == 3 => SmType::Inputs,
            None => SmType::Unused,
        });
    }
    b = b.sm_types(&sm_types);
    for pdo in &spec.pdos {
        let entries: Vec<PdoEntry> = pdo
            .entries
            .iter()
            .map(|e| PdoEntry::new(e.index, e.subindex, e.bits))
            .collect();
        b = b.pdo_mapping(pdo.index, &pdo.name, &entries, 8);
    }
    let assigned = |rx: bool| -> Vec<u16> {
        spec.pdos
            .iter()
            .filter(|p| p.is_rx() == rx)
            .map(|p| p.index)
            .collect()
    };
    b = b
        .rx_pdo_assign(&assigned(true), 4)
        .tx_pdo_assign(&assigned(false), 4);
    extra_objects(b, &spec.objects)?
        .build()
        .map_err(|e| e.to_string())
}

/// SM lengths and start addresses: mailbox SMs, then one per SM number the PDOs use.
fn syncms(spec: &SlaveSpec) -> Vec<SyncmEntry> {
    let mut entries = Vec::new();
    let mut next = 0x1000u16;
    if let Some(mbx) = spec.mailbox {
        entries.push(SyncmEntry {
            start: mbx.sm0_start(),
            length: mbx.rx_size,
            control: 0x26,
            status: 0,
            enable: SyncmEnable(0x01),
            sm_type: SyncmType::MailboxOut,
        });
        entries.push(SyncmEntry {
            start: mbx.sm1_start(),
            length: mbx.tx_size,
            control: 0x22,
            status: 0,
            enable: SyncmEnable(0x01),
            sm_type: SyncmType::MailboxIn,
        });
        next = mbx
            .sm1_start()
            .saturating_add(mbx.tx_size)
            .next_multiple_of(0x80);
    }
    let used: BTreeSet<u8> = spec.pdos.iter().map(|p| p.sm).collect();
    for sm in used {
        while entries.len() < usize::from(sm) {
            entries.push(SyncmEntry {
                start: 0,
                length: 0,
                control: 0,
                status: 0,
                enable: SyncmEnable(0),
                sm_type: SyncmType::Unspecified,
            });
        }
        let pdos: Vec<&PdoSpec> = spec.pdos.iter().filter(|p| p.sm == sm).collect();
        let bits: u32 = pdos.iter().map(|p| p.bits()).sum();
        let length = u16::try_from(bits.div_ceil(8)).unwrap_or(u16::MAX);
        let outputs = pdos.first().is_some_and(|p| p.is_rx());
        entries.push(SyncmEntry {
            start: next,
            length,
            control: if outputs { 0x64 } else { 0x20 },
            status: 0,
            enable: SyncmEnable(u8::from(length > 0)),
            sm_type: if outputs {
                SyncmType::Outputs
            } else {
                SyncmType::Inputs
            },
        });
        next = next.saturating_add((length * 3).next_multiple_of(0x80).max(0x80));
    }
    entries
}

fn sii(spec: &SlaveSpec, protocols: u16) -> Result<Vec<u8>, WireError> {
    let (rx, tx) = match spec.mailbox {
        Some(m) => (
            SiiMailboxArea {
                offset: m.sm0_start(),
                size: m.rx_size,
            },
            SiiMailboxArea {
                offset: m.sm1_start(),
                size: m.tx_size,
            },
        ),
        None => (SiiMailboxArea::default(), SiiMailboxArea::default()),
    };
    let mut b = SiiBuilder::new(SiiFixedRepr {
        pdi_control: 0x0005,
        alias: spec.alias,
        vendor_id: spec.vendor_id,
        product_code: spec.product_code,
        revision: spec.revision,
        serial: spec.serial,
        boot_rx_mailbox: rx,
        boot_tx_mailbox: tx,
        std_rx_mailbox: rx,
        std_tx_mailbox: tx,
        mailbox_protocols: MailboxProtocols(protocols),
        version: 1,
        ..SiiFixedRepr::default()
    });
    let name = b.add_string(&spec.name)?;
    let group = b.add_string("ECATD-SIM")?;
    let coe = protocols & MailboxProtocols::COE != 0;
    b.general = Some(GeneralRepr {
        group_idx: group,
        order_idx: name,
        name_idx: name,
        // SDO, SDO Information, PDO assignment, PDO configuration, complete access.
        coe_details: CoeDetails(if coe { 0x2F } else { 0 }),
        foe_details: u8::from(protocols & MailboxProtocols::FOE != 0),
        eoe_details: u8::from(protocols & MailboxProtocols::EOE != 0),
        soe_channels: if protocols & MailboxProtocols::SOE != 0 {
            spec.soe_drives
        } else {
            0
        },
        ebus_current_ma: 0,
        // Ports 0 and 1: MII.
        physical_ports: PhysicalPorts(0x0011),
        ..GeneralRepr::default()
    });
    let has_out = spec.pdos.iter().any(PdoSpec::is_rx);
    let has_in = spec.pdos.iter().any(|p| !p.is_rx());
    if has_out {
        b.fmmu.push(FmmuUsage::Outputs);
    }
    if has_in {
        b.fmmu.push(FmmuUsage::Inputs);
    }
    if spec.mailbox.is_some() {
        b.fmmu.push(FmmuUsage::SyncManagerStatus);
    }
    b.syncm = syncms(spec);
    for pdo in &spec.pdos {
        let pdo_name = b.add_string(&pdo.name)?;
        let mut entries = Vec::new();
        for e in &pdo.entries {
            let entry_name = b.add_string(&e.name)?;
            entries.push(SiiPdoEntry {
                index: e.index,
                subindex: e.subindex,
                name_idx: entry_name,
                data_type: data_type(&e.data_type).map_or(0, |dt| u16::from(dt) as u8),
                bit_length: e.bits,
                flags: 0,
            });
        }
        let sii_pdo = Pdo {
            index: pdo.index,
            sync_manager: pdo.sm,
            dc_sync: 0,
            name_idx: pdo_name,
            // Bit 4: mandatory... none set: every PDO is the default assignment.
            flags: PdoFlags(0),
            entries,
        };
        if pdo.is_rx() {
            b.rxpdo.push(sii_pdo);
        } else {
            b.txpdo.push(sii_pdo);
        }
    }
    b.build()
}
