//! The built-in five-slave segment (also `sim/topologies/default.toml`).
//!
//! | pos | name | mailbox | protocols | process data |
//! |---|---|---|---|---|
//! | 0 | ECATD-SIM Drive | 128/128 | CoE SoE FoE VoE EoE | drive: 0x1600 (0x6040, 0x607A) / 0x1A00 (0x6041, 0x6064); SoE: default IDNs, S-0-0032 with 4 bytes, P-0-0100; FoE `firmware.bin` (1024 bytes); VoE for vendor 0x00001164 |
//! | 1 | ECATD-SIM DO8 | none | – | 8 digital outputs |
//! | 2 | ECATD-SIM DI8 | none | – | 8 digital inputs, wired to slave 1's outputs (`wired_to = 1`) |
//! | 3 | ECATD-SIM CoE Store | 128/128 | CoE | none; 0x2000 OCTET_STRING of 4096 bytes |
//! | 4 | ECATD-SIM EoE Port | 128/128 | EoE | none |
//!
//! The DI8's inputs are wired to the DO8's outputs, as on a test bench: input *n* is on
//! while output *n* is, from the same frame on (the DO8 comes first in the line), and its
//! [`InputDriver`](crate::device::dio::InputDriver) turns inputs on in parallel with the
//! wire. A test that needs the DI8 free of the DO8 takes the wire off:
//!
//! ```
//! use sim::topology::{Application, Topology};
//!
//! let mut topology = Topology::default_segment();
//! topology.slaves[2].application = Application::DigitalInputs { channels: 8, wired_to: None };
//! ```

use std::net::Ipv4Addr;

use super::model::{
    Application, CoeObject, EoeSpec, EscSpec, FoeFileSpec, IdnSpec, MailboxSpec, PdoEntrySpec,
    PdoSpec, Protocol, SlaveSpec, Topology,
};

/// The vendor ID of every built-in simulated slave: 0xE0000001.
///
/// EtherCAT vendor IDs are assigned by the ETG from the bottom up (real ones are small numbers,
/// e.g. Beckhoff 0x00000002; even the newest members are far below 0x01000000), so an ID with
/// the top bits set cannot belong to a real vendor in any foreseeable future. It marks a
/// device as simulated at a glance; a master must never ship configuration that relies on it.
pub const SIM_VENDOR_ID: u32 = 0xE000_0001;

/// The test pattern object on slave 3: 0x2000, 4096 bytes.
pub const LARGE_OBJECT_SIZE: usize = 4096;

fn mailbox() -> Option<MailboxSpec> {
    Some(MailboxSpec {
        rx_size: 128,
        tx_size: 128,
        start: None,
    })
}

fn base(name: &str, product_code: u32) -> SlaveSpec {
    SlaveSpec {
        name: name.to_string(),
        vendor_id: SIM_VENDOR_ID,
        product_code,
        revision: 0x0001_0000,
        serial: 0,
        alias: 0,
        device_type: 0,
        mailbox: None,
        protocols: Vec::new(),
        esc: EscSpec::default(),
        application: Application::None,
        pdos: Vec::new(),
        objects: Vec::new(),
        soe_drives: 1,
        idns: Vec::new(),
        foe_files: Vec::new(),
        eoe: None,
        voe_vendor_id: None,
        foe_busy: None,
        foe_capacity: None,
    }
}

fn pdo_entry(index: u16, subindex: u8, bits: u8, data_type: &str, name: &str) -> PdoEntrySpec {
    PdoEntrySpec {
        index,
        subindex,
        bits,
        data_type: data_type.to_string(),
        name: name.to_string(),
    }
}

fn object(index: u16, data_type: &str, access: &str, name: &str, value: i64) -> CoeObject {
    CoeObject {
        index,
        subindex: 0,
        data_type: data_type.to_string(),
        access: access.to_string(),
        name: name.to_string(),
        value: Some(toml::Value::Integer(value)),
        size: None,
    }
}

fn channels(base_index: u16, prefix: &str) -> Vec<PdoEntrySpec> {
    (1..=8)
        .map(|ch| pdo_entry(base_index, ch, 1, "BOOLEAN", &format!("{prefix} {ch}")))
        .collect()
}

fn drive() -> SlaveSpec {
    SlaveSpec {
        serial: 1,
        device_type: 0x0002_0192,
        mailbox: mailbox(),
        protocols: vec![
            Protocol::Coe,
            Protocol::Soe,
            Protocol::Foe,
            Protocol::Voe,
            Protocol::Eoe,
        ],
        application: Application::Drive,
        pdos: vec![
            PdoSpec {
                index: 0x1600,
                sm: 2,
                name: "Outputs".into(),
                entries: vec![
                    pdo_entry(0x6040, 0, 16, "UNSIGNED16", "Controlword"),
                    pdo_entry(0x607A, 0, 32, "INTEGER32", "Target position"),
                ],
            },
            PdoSpec {
                index: 0x1A00,
                sm: 3,
                name: "Inputs".into(),
                entries: vec![
                    pdo_entry(0x6041, 0, 16, "UNSIGNED16", "Statusword"),
                    pdo_entry(0x6064, 0, 32, "INTEGER32", "Position actual value"),
                ],
            },
        ],
        objects: vec![
            object(0x6040, "UNSIGNED16", "rw_rx", "Controlword", 0),
            object(0x6041, "UNSIGNED16", "ro_tx", "Statusword", 0),
            object(0x607A, "INTEGER32", "rw_rx", "Target position", 0),
            object(0x6064, "INTEGER32", "ro_tx", "Position actual value", 0),
        ]
        .into_iter()
        .chain(super::diag_history::drive_history())
        .collect(),
        idns: vec![operation_mode(), motor_temperature()],
        foe_files: vec![FoeFileSpec {
            name: "firmware.bin".into(),
            content: None,
            size: 1024,
            password: 0,
        }],
        eoe: Some(EoeSpec {
            ip: Some(Ipv4Addr::new(192, 168, 100, 10)),
        }),
        voe_vendor_id: Some(0x0000_1164),
        ..base("ECATD-SIM Drive", 0x0000_0001)
    }
}

/// S-0-0032 "Primary operation mode" on the drive with a 4-byte value instead of the
/// default set's 2 bytes: the gateway manual's sample clients (docs/gateway.md) write it
/// with a 4-byte value (1000), and the default segment answers every one of their samples.
fn operation_mode() -> IdnSpec {
    let u32_bytes = |v: u32| v.to_le_bytes().to_vec();
    IdnSpec {
        idn: 32,
        drive: None,
        name: "Primary operation mode".into(),
        // Conversion factor 1, 4-byte element, hexadecimal.
        attribute: 0x0032_0001,
        unit: None,
        min: None,
        max: None,
        value: Some(u32_bytes(0x0002)),
        default: Some(u32_bytes(0x0002)),
        read_only: false,
        list_capacity: None,
    }
}

/// P-0-0100 on the drive: an IDN from the topology rather than the default set, with every
/// element (0.1 °C steps: u16, one decimal place).
fn motor_temperature() -> IdnSpec {
    let u16_bytes = |v: u16| v.to_le_bytes().to_vec();
    IdnSpec {
        idn: 0x8000 | 100,
        drive: None,
        name: "Motor temperature".into(),
        // Conversion factor 1, 2-byte element, unsigned, 1 decimal place.
        attribute: 0x0111_0001,
        unit: Some("degC".into()),
        min: Some(u16_bytes(0)),
        max: Some(u16_bytes(1500)),
        value: Some(u16_bytes(253)),
        default: Some(u16_bytes(200)),
        read_only: true,
        list_capacity: None,
    }
}

fn digital_outputs() -> SlaveSpec {
    SlaveSpec {
        serial: 2,
        application: Application::DigitalOutputs { channels: 8 },
        pdos: vec![PdoSpec {
            index: 0x1600,
            sm: 0,
            name: "Outputs".into(),
            entries: channels(0x7000, "Output"),
        }],
        ..base("ECATD-SIM DO8", 0x0000_0002)
    }
}

fn digital_inputs() -> SlaveSpec {
    SlaveSpec {
        serial: 3,
        // Outputs wired back to inputs, as on a test bench: a master (or a test) sees its
        // own outputs come back without a physical side to drive.
        application: Application::DigitalInputs {
            channels: 8,
            wired_to: Some(1),
        },
        pdos: vec![PdoSpec {
            index: 0x1A00,
            sm: 0,
            name: "Inputs".into(),
            entries: channels(0x6000, "Input"),
        }],
        ..base("ECATD-SIM DI8", 0x0000_0003)
    }
}

fn coe_store() -> SlaveSpec {
    SlaveSpec {
        serial: 4,
        mailbox: mailbox(),
        protocols: vec![Protocol::Coe],
        objects: vec![
            CoeObject {
                index: 0x2000,
                subindex: 0,
                data_type: "OCTET_STRING".into(),
                access: "rw".into(),
                name: "Large object".into(),
                value: None,
                size: Some(LARGE_OBJECT_SIZE),
            },
            object(0x2001, "UNSIGNED32", "rw", "Parameter", 0x1234_5678),
        ],
        ..base("ECATD-SIM CoE Store", 0x0000_0004)
    }
}

fn eoe_port() -> SlaveSpec {
    SlaveSpec {
        serial: 5,
        mailbox: mailbox(),
        protocols: vec![Protocol::Eoe],
        eoe: Some(EoeSpec {
            ip: Some(Ipv4Addr::new(192, 168, 100, 14)),
        }),
        ..base("ECATD-SIM EoE Port", 0x0000_0005)
    }
}

impl Topology {
    /// The built-in segment: drive, 8 digital outputs, 8 digital inputs, a CoE device with a
    /// 4 KiB object, an EoE device (see the module documentation).
    pub fn default_segment() -> Topology {
        Topology {
            ring: false,
            slaves: vec![
                drive(),
                digital_outputs(),
                digital_inputs(),
                coe_store(),
                eoe_port(),
            ],
        }
    }
}

impl Topology {
    /// A segment of `count` slaves for scale tests and benchmarks: the built-in segment's
    /// slaves repeated in order (so every fifth slave is a drive with a mailbox), each with
    /// its own serial number (its position + 1). The EoE devices get no IP address, so that
    /// no two endpoints answer for the same one. Each repetition's DI8 is wired to the DO8
    /// of the same repetition.
    pub fn repeated(count: usize) -> Topology {
        let pattern = Topology::default_segment().slaves;
        let slaves = (0..count)
            .map(|position| {
                let mut slave = pattern[position % pattern.len()].clone();
                slave.serial = u32::try_from(position + 1).unwrap_or(u32::MAX);
                if let Some(eoe) = slave.eoe.as_mut() {
                    eoe.ip = None;
                }
                if let Application::DigitalInputs { wired_to, .. } = &mut slave.application {
                    // The pattern's position, moved to this repetition (a segment too long
                    // for 16-bit positions goes without the wire rather than failing).
                    let first = position - position % pattern.len();
                    *wired_to = wired_to.and_then(|to| u16::try_from(first + usize::from(to)).ok());
                }
                slave
            })
            .collect();
        Topology {
            ring: false,
            slaves,
        }
    }
}
