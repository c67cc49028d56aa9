//! The serde model of a segment description. Field names are what the TOML file uses.

use std::net::Ipv4Addr;

use serde::{Deserialize, Serialize};

/// A segment: slaves in line order (position 0 is next to the master).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Topology {
    /// Cable redundancy: the last slave's port 1 is wired back to the master's backup port
    /// (`ring = true`); default: a line ending at the last slave.
    #[serde(default, skip_serializing_if = "is_false")]
    pub ring: bool,
    /// The slaves, by ring position.
    #[serde(default, rename = "slave")]
    pub slaves: Vec<SlaveSpec>,
}

impl Topology {
    /// Parses a TOML description.
    pub fn from_toml(text: &str) -> Result<Self, toml::de::Error> {
        toml::from_str(text)
    }

    /// The description as TOML.
    pub fn to_toml(&self) -> Result<String, toml::ser::Error> {
        toml::to_string_pretty(self)
    }
}

/// A mailbox protocol a slave supports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Protocol {
    /// CANopen over EtherCAT (SDO server over the dictionary).
    Coe,
    /// Ethernet over EtherCAT.
    Eoe,
    /// File access over EtherCAT.
    Foe,
    /// Servo profile over EtherCAT (the default IDN set).
    Soe,
    /// Vendor specific over EtherCAT (an echo service).
    Voe,
}

/// One slave.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlaveSpec {
    /// Device name (SII name string, CoE 0x1008).
    pub name: String,
    /// EtherCAT vendor ID.
    pub vendor_id: u32,
    /// Product code.
    pub product_code: u32,
    /// Revision number.
    #[serde(default)]
    pub revision: u32,
    /// Serial number.
    #[serde(default)]
    pub serial: u32,
    /// Configured station alias (SII word 4).
    #[serde(default)]
    pub alias: u16,
    /// CoE device type 0x1000 (profile in the low word; 0x0192 = CiA 402).
    #[serde(default)]
    pub device_type: u32,
    /// Mailbox SyncManager sizes; none for a slave without mailbox.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mailbox: Option<MailboxSpec>,
    /// Mailbox protocols (ignored without a mailbox).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub protocols: Vec<Protocol>,
    /// ESC options.
    #[serde(default)]
    pub esc: EscSpec,
    /// The process-data application.
    #[serde(default)]
    pub application: Application,
    /// RxPDOs (outputs, master → slave) and TxPDOs (inputs), in SII and dictionary order.
    #[serde(default, rename = "pdo", skip_serializing_if = "Vec::is_empty")]
    pub pdos: Vec<PdoSpec>,
    /// CoE objects beyond the standard ones the builder derives.
    #[serde(default, rename = "object", skip_serializing_if = "Vec::is_empty")]
    pub objects: Vec<CoeObject>,
    /// SoE: number of drives (each with the default IDN set).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub soe_drives: u8,
    /// SoE: IDNs added to the default set, or replacing default ones with the same number.
    #[serde(default, rename = "idn", skip_serializing_if = "Vec::is_empty")]
    pub idns: Vec<IdnSpec>,
    /// FoE files present at power-on.
    #[serde(default, rename = "foe_file", skip_serializing_if = "Vec::is_empty")]
    pub foe_files: Vec<FoeFileSpec>,
    /// EoE settings.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eoe: Option<EoeSpec>,
    /// VoE vendor ID (default: the slave's own vendor ID).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub voe_vendor_id: Option<u32>,
    /// FoE BUSY phases while "flashing" written files (none by default: some masters, such
    /// as pysoem, do not handle BUSY on writes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub foe_busy: Option<FoeBusySpec>,
    /// FoE store capacity in bytes, all files together (default 1 MiB, what a small
    /// slave's flash would hold); a write beyond it is refused with "disk full".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub foe_capacity: Option<usize>,
}

/// FoE store capacity without `foe_capacity`.
pub const DEFAULT_FOE_CAPACITY: usize = 1 << 20;

fn one() -> u8 {
    1
}

fn is_one(v: &u8) -> bool {
    *v == 1
}

/// Mailbox SyncManager sizes; SM0 starts at `start` (0x1000 unless set), SM1 right behind it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MailboxSpec {
    /// SM0 (master → slave) length in bytes.
    pub rx_size: u16,
    /// SM1 (slave → master) length in bytes.
    pub tx_size: u16,
    /// SM0 start address the SII announces; 0x1000 when absent. A start the ESC's RAM does
    /// not cover (at or above `0x1000 + esc.ram_kib` KiB) makes a broken slave: a master that
    /// configures the mailbox as the SII says is refused INIT → PREOP with AL status code
    /// 0x0016 (invalid mailbox configuration).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<u16>,
}

impl MailboxSpec {
    /// SM0 start address.
    pub fn sm0_start(&self) -> u16 {
        self.start.unwrap_or(0x1000)
    }

    /// SM1 start address: right behind SM0.
    pub fn sm1_start(&self) -> u16 {
        self.sm0_start().wrapping_add(self.rx_size)
    }
}

/// ESC options, and how the slave's firmware behind it answers its mailbox.
///
/// The firmware switches make the slave behave like other slave stacks than ours, so that
/// tests keep a master honest about them; all are off by default:
///
/// ```toml
/// [slave.esc]
/// sdo_abort_in_request = true         # SDO aborts in CoE service 2, as SOES sends them
/// sdo_abort_keeps_command_bits = true # abort command 0x80 | the request's low 5 bits
/// sdo_info_short_errors = true        # SDO Info errors of mailbox length 6, code outside
/// refuse_complete_access = true       # complete access aborted with 0x08000000
/// sdo_abort_length_mismatch = true    # wrong-length downloads aborted with 0x06070010
/// response_delay_us = 2000            # every reply reaches SM1 2 ms after the request
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EscSpec {
    /// Process RAM in KiB (at most 60).
    #[serde(default = "default_ram_kib")]
    pub ram_kib: u16,
    /// DC propagation delay from the previous device to this slave, in ns.
    #[serde(default = "default_hop_delay")]
    pub hop_delay_ns: u32,
    /// SDO aborts go out in CoE service 2 (SDO request) instead of 3: ETG.1000.6 §5.6.2.7
    /// names the abort "Abort SDO Transfer Request", and SOES sends every abort that way.
    #[serde(default, skip_serializing_if = "is_false")]
    pub sdo_abort_in_request: bool,
    /// An SDO abort's command byte keeps the request's low 5 bits (0x8b, 0x8f, 0x91, ...),
    /// only the command specifier (bits 5-7 = 4) marking it, as some stacks send it.
    #[serde(default, skip_serializing_if = "is_false")]
    pub sdo_abort_keeps_command_bits: bool,
    /// SDO Information error replies declare a mailbox length of 6 and leave the abort
    /// code outside it.
    #[serde(default, skip_serializing_if = "is_false")]
    pub sdo_info_short_errors: bool,
    /// Complete access (upload and download) is refused with SDO abort 0x08000000.
    #[serde(default, skip_serializing_if = "is_false")]
    pub refuse_complete_access: bool,
    /// Every wrong-length download is aborted with 0x06070010 (as SOES does), not with
    /// 0x06070012 (too long) or 0x06070013 (too short).
    #[serde(default, skip_serializing_if = "is_false")]
    pub sdo_abort_length_mismatch: bool,
    /// Every mailbox message the slave sends reaches its send mailbox (SM1) only this many
    /// microseconds after it was made (a slow firmware); other slaves and frames are not
    /// held up meanwhile. 0: at once.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub response_delay_us: u32,
}

fn is_zero(v: &u32) -> bool {
    *v == 0
}

fn default_ram_kib() -> u16 {
    8
}

fn default_hop_delay() -> u32 {
    150
}

impl Default for EscSpec {
    fn default() -> Self {
        EscSpec {
            ram_kib: default_ram_kib(),
            hop_delay_ns: default_hop_delay(),
            sdo_abort_in_request: false,
            sdo_abort_keeps_command_bits: false,
            sdo_info_short_errors: false,
            refuse_complete_access: false,
            sdo_abort_length_mismatch: false,
            response_delay_us: 0,
        }
    }
}

/// What exchanges the process data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Application {
    /// No process data.
    #[default]
    None,
    /// A CiA-402-like drive mapped through its dictionary (needs CoE).
    Drive,
    /// Digital outputs, one bit per channel.
    DigitalOutputs {
        /// Number of channels.
        channels: u16,
    },
    /// Digital inputs, one bit per channel.
    DigitalInputs {
        /// Number of channels.
        channels: u16,
        /// The ring position of a [`Application::DigitalOutputs`] slave whose outputs are
        /// wired back to these inputs, as on a test bench: input channel *n* is on whenever
        /// that slave's output channel *n* is on. Absent: the inputs are free, set only
        /// through the slave's [`InputDriver`](crate::device::dio::InputDriver).
        ///
        /// ```toml
        /// application = { kind = "digital_inputs", channels = 8, wired_to = 1 }
        /// ```
        ///
        /// The output slave must be in the same topology and have at least `channels`
        /// outputs; building the topology refuses anything else, naming the input slave and
        /// `wired_to`. The [`InputDriver`](crate::device::dio::InputDriver) still works on a
        /// wired slave, in parallel with the wire (an input is on when its output or the
        /// driver says so; see [`DigitalInputs`](crate::device::dio::DigitalInputs)).
        ///
        /// The wire is read as a frame passes the input slave: with the output slave
        /// before it in the line (a smaller position), an LRW's outputs show in its own
        /// inputs; with the output slave behind it, one frame later.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        wired_to: Option<u16>,
    },
}

/// A PDO. Its direction follows from `index`: 0x1600..=0x17FF RxPDO, 0x1A00..=0x1BFF TxPDO.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PdoSpec {
    /// PDO index.
    pub index: u16,
    /// SyncManager carrying it.
    pub sm: u8,
    /// PDO name.
    pub name: String,
    /// Mapped entries, in image order.
    #[serde(rename = "entry")]
    pub entries: Vec<PdoEntrySpec>,
}

impl PdoSpec {
    /// Whether this is an RxPDO (outputs).
    pub fn is_rx(&self) -> bool {
        (0x1600..0x1800).contains(&self.index)
    }

    /// Bits the PDO takes.
    pub fn bits(&self) -> u32 {
        self.entries.iter().map(|e| u32::from(e.bits)).sum()
    }
}

/// One mapped entry.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PdoEntrySpec {
    /// Object index (0 for a gap).
    pub index: u16,
    /// Subindex.
    #[serde(default)]
    pub subindex: u8,
    /// Bit length.
    pub bits: u8,
    /// Data type name (e.g. `UNSIGNED16`, `BOOLEAN`).
    pub data_type: String,
    /// Entry name.
    pub name: String,
}

/// An extra CoE object or entry. Entries with subindex 0 are VARs; entries sharing an index
/// with subindex ≥ 1 make a RECORD (SI0 made by the builder).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoeObject {
    /// Object index.
    pub index: u16,
    /// Subindex.
    #[serde(default)]
    pub subindex: u8,
    /// Data type name (e.g. `UNSIGNED16`, `INTEGER32`, `VISIBLE_STRING`, `OCTET_STRING`).
    pub data_type: String,
    /// Access: `ro`, `rw`, `wo`, `rw_preop`, `ro_tx` (TxPDO-mappable), `rw_rx`
    /// (RxPDO-mappable).
    pub access: String,
    /// Object (VAR) or entry name.
    pub name: String,
    /// Initial value (integer, float, bool, string, or for byte objects a list of byte
    /// values); zero/empty when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value: Option<toml::Value>,
    /// For byte objects without a value: the size in bytes, filled with the test pattern
    /// byte *i* = *i* mod 251 (a prime, so the pattern never lines up with segment sizes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<usize>,
}

impl CoeObject {
    /// A VAR object of type UNSIGNED32 with `access` (see [`CoeObject::access`]), value zero.
    pub fn unsigned32(index: u16, access: &str, name: &str) -> CoeObject {
        CoeObject {
            index,
            subindex: 0,
            data_type: "UNSIGNED32".into(),
            access: access.into(),
            name: name.into(),
            value: None,
            size: None,
        }
    }
}

/// One SoE IDN of a drive (ETG.1000.6, spec-notes §soe): its elements as they travel on the wire.
///
/// Byte elements (`min`, `max`, `value`, `default`) are little-endian, as in the SoE
/// messages; for a list IDN they are the list contents without the 4-byte length header
/// (the drive adds it on a read).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IdnSpec {
    /// IDN number as on the wire: S-0-nnnn is nnnn, P-0-nnnn is 0x8000 + nnnn (bits 12-14
    /// hold the parameter set).
    pub idn: u16,
    /// The drive (0..=7) that has it; absent: every drive of the slave.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive: Option<u8>,
    /// Element 2, the name.
    pub name: String,
    /// Element 3, the attribute as its raw u32: bits 0-15 conversion factor, 16-17 element
    /// size (0: 1, 1: 2, 2: 4, 3: 8 bytes), 18 list, 19 procedure command, 20-22 data type
    /// (0 binary, 1 unsigned, 2 signed, 3 hex, 4 text, 5 IDN, 6 float), 24-27 decimal
    /// places, 28-30 write-protected in PREOP/SAFEOP/OP. Bits 23 and 31 are reserved (0).
    pub attribute: u32,
    /// Element 4, the unit; absent: a read of it answers error 0x4001.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unit: Option<String>,
    /// Element 5, minimum input value; absent: 0x5001.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min: Option<Vec<u8>>,
    /// Element 6, maximum input value; absent: 0x6001.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max: Option<Vec<u8>>,
    /// Element 7, the operation data at power-on; absent: the default value.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value: Option<Vec<u8>>,
    /// The default value; absent: a read of it answers 0x8001.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub default: Option<Vec<u8>>,
    /// The value cannot be written at all (writes answer 0x7004).
    #[serde(default, skip_serializing_if = "is_false")]
    pub read_only: bool,
    /// For a list IDN: its maximum length in bytes (default: the value's length).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub list_capacity: Option<u16>,
}

fn is_false(v: &bool) -> bool {
    !*v
}

/// An FoE file.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FoeFileSpec {
    /// File name.
    pub name: String,
    /// Text content; when absent, `size` bytes of the test pattern.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub content: Option<String>,
    /// Size when no content is given.
    #[serde(default)]
    pub size: usize,
    /// FoE password (0 = none).
    #[serde(default)]
    pub password: u32,
}

/// FoE BUSY answers around file writes, as a slave gives while erasing and programming.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FoeBusySpec {
    /// BUSY answers before the ACK 0 of a write request (erasing).
    #[serde(default)]
    pub after_write_request: u16,
    /// BUSY answers before the ACK of the last DATA packet (programming).
    #[serde(default)]
    pub after_last_packet: u16,
    /// Only files whose names end with this get the phases (absent: every file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file_suffix: Option<String>,
}

/// EoE settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EoeSpec {
    /// IP address the slave has before any Set IP parameter.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ip: Option<Ipv4Addr>,
}

/// The test pattern for sized objects and files: byte *i* = *i* mod 251.
pub fn pattern(size: usize) -> Vec<u8> {
    (0..size).map(|i| (i % 251) as u8).collect()
}
