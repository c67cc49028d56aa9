//! Datagram commands and their addressing (spec-notes §commands, §addressing).
//!
//! The command byte (datagram offset 0) selects both *how* slaves are addressed (position,
//! configured station address, broadcast or logical) and *what* they do (read, write, both,
//! or read-multiple-write). The 4 address bytes (datagram offsets 2-5) mean different things
//! per addressing mode; [`DatagramAddress`] is their typed reading.

use core::fmt;

use crate::error::{Result, WireError};
use crate::macros::enum_with_unknown;

enum_with_unknown! {
    /// Datagram command (ETG.1000.4 command types, Wireshark `EcCmd` names, spec-notes §commands).
    pub enum Command(u8) {
        /// No operation: slaves ignore the datagram.
        Nop = 0x00,
        /// Auto-increment (position) physical read.
        Aprd = 0x01,
        /// Auto-increment physical write.
        Apwr = 0x02,
        /// Auto-increment physical read-write (exchange).
        Aprw = 0x03,
        /// Configured-address (node) physical read.
        Fprd = 0x04,
        /// Configured-address physical write.
        Fpwr = 0x05,
        /// Configured-address physical read-write.
        Fprw = 0x06,
        /// Broadcast read (slaves OR their memory into the data).
        Brd = 0x07,
        /// Broadcast write.
        Bwr = 0x08,
        /// Broadcast read-write.
        Brw = 0x09,
        /// Logical memory read (through read FMMUs).
        Lrd = 0x0A,
        /// Logical memory write (through write FMMUs).
        Lwr = 0x0B,
        /// Logical memory read-write.
        Lrw = 0x0C,
        /// Auto-increment read, multiple write (addressed slave reads, all others write).
        Armw = 0x0D,
        /// Configured-address read, multiple write (DC reference time distribution).
        Frmw = 0x0E,
    }
}

/// How a command addresses slaves (ETG.1000.3, spec-notes §addressing).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AddressingMode {
    /// No addressing: NOP and unknown commands.
    None,
    /// Auto-increment: ADP = −position, every slave increments ADP, ADP == 0 is addressed.
    Position,
    /// Configured station address (or alias) in ADP.
    Node,
    /// All slaves; ADP is only incremented.
    Broadcast,
    /// A 32-bit logical address mapped by FMMUs.
    Logical,
}

impl Command {
    /// The mnemonic as used by the standard and Wireshark ("FPWR"); `"UNKNOWN"` otherwise.
    pub fn name(self) -> &'static str {
        match self {
            Command::Nop => "NOP",
            Command::Aprd => "APRD",
            Command::Apwr => "APWR",
            Command::Aprw => "APRW",
            Command::Fprd => "FPRD",
            Command::Fpwr => "FPWR",
            Command::Fprw => "FPRW",
            Command::Brd => "BRD",
            Command::Bwr => "BWR",
            Command::Brw => "BRW",
            Command::Lrd => "LRD",
            Command::Lwr => "LWR",
            Command::Lrw => "LRW",
            Command::Armw => "ARMW",
            Command::Frmw => "FRMW",
            Command::Unknown(_) => "UNKNOWN",
        }
    }

    /// The long name of the command (ETG.1000.4 wording).
    pub fn description(self) -> &'static str {
        match self {
            Command::Nop => "No Operation",
            Command::Aprd => "Auto Increment Read",
            Command::Apwr => "Auto Increment Write",
            Command::Aprw => "Auto Increment Read Write",
            Command::Fprd => "Configured Address Read",
            Command::Fpwr => "Configured Address Write",
            Command::Fprw => "Configured Address Read Write",
            Command::Brd => "Broadcast Read",
            Command::Bwr => "Broadcast Write",
            Command::Brw => "Broadcast Read Write",
            Command::Lrd => "Logical Memory Read",
            Command::Lwr => "Logical Memory Write",
            Command::Lrw => "Logical Memory Read Write",
            Command::Armw => "Auto Increment Read Multiple Write",
            Command::Frmw => "Configured Read Multiple Write",
            Command::Unknown(_) => "Unknown command",
        }
    }

    /// How this command addresses slaves (ETG.1000.4, spec-notes §commands "Addressing" column).
    pub fn addressing(self) -> AddressingMode {
        match self {
            Command::Aprd | Command::Apwr | Command::Aprw | Command::Armw => {
                AddressingMode::Position
            }
            Command::Fprd | Command::Fpwr | Command::Fprw | Command::Frmw => AddressingMode::Node,
            Command::Brd | Command::Bwr | Command::Brw => AddressingMode::Broadcast,
            Command::Lrd | Command::Lwr | Command::Lrw => AddressingMode::Logical,
            Command::Nop | Command::Unknown(_) => AddressingMode::None,
        }
    }

    /// True if some slave puts memory content into the datagram data (RD, RW and RMW).
    pub fn is_read(self) -> bool {
        matches!(
            self,
            Command::Aprd
                | Command::Aprw
                | Command::Fprd
                | Command::Fprw
                | Command::Brd
                | Command::Brw
                | Command::Lrd
                | Command::Lrw
                | Command::Armw
                | Command::Frmw
        )
    }

    /// True if some slave copies the datagram data into its memory (WR, RW and RMW).
    pub fn is_write(self) -> bool {
        matches!(
            self,
            Command::Apwr
                | Command::Aprw
                | Command::Fpwr
                | Command::Fprw
                | Command::Bwr
                | Command::Brw
                | Command::Lwr
                | Command::Lrw
                | Command::Armw
                | Command::Frmw
        )
    }
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Command::Unknown(raw) => write!(f, "CMD({raw:#04x})"),
            known => f.write_str(known.name()),
        }
    }
}

/// The 4 address bytes of a datagram read according to its command (spec-notes §datagram, §addressing).
///
/// On the wire the bytes are ADP (u16 LE) then ADO (u16 LE), or one u32 LE logical address;
/// so as a little-endian u32, `raw = adp | ado << 16`.
///
/// Position and broadcast addresses keep the raw ADP rather than a position or nothing:
/// slaves increment ADP as the datagram passes, so in a returned datagram it no longer
/// names a position (a returned BRD carries the number of slaves it passed, spec-notes §commands), and
/// keeping the wire value makes decode/encode lossless.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DatagramAddress {
    /// Auto-increment addressing.
    Position {
        /// The raw ADP as on the wire: `0u16.wrapping_sub(p)` for ring position `p` when
        /// sent; see [`DatagramAddress::position`] and [`DatagramAddress::ring_position`].
        adp: u16,
        /// Register / memory offset in the slave.
        ado: u16,
    },
    /// Configured station address (or alias) addressing.
    Node {
        /// Station address (register 0x0010) or alias (0x0012).
        station: u16,
        /// Register / memory offset in the slave.
        ado: u16,
    },
    /// Broadcast addressing.
    Broadcast {
        /// Raw ADP: sent as 0, incremented by every slave (so it counts slaves on return).
        adp: u16,
        /// Register / memory offset in every slave.
        ado: u16,
    },
    /// Logical addressing through FMMUs.
    Logical(u32),
}

impl DatagramAddress {
    /// Auto-increment address of the slave at ring position `position` (0 = first slave).
    pub const fn position(position: u16, ado: u16) -> Self {
        DatagramAddress::Position {
            adp: 0u16.wrapping_sub(position),
            ado,
        }
    }

    /// Broadcast address as sent by a master (ADP 0).
    pub const fn broadcast(ado: u16) -> Self {
        DatagramAddress::Broadcast { adp: 0, ado }
    }

    /// For a position address, the ring position it addresses (`(−ADP) mod 65536`).
    pub const fn ring_position(&self) -> Option<u16> {
        match self {
            DatagramAddress::Position { adp, .. } => Some(0u16.wrapping_sub(*adp)),
            _ => None,
        }
    }

    /// The addressing mode this address belongs to.
    pub const fn mode(&self) -> AddressingMode {
        match self {
            DatagramAddress::Position { .. } => AddressingMode::Position,
            DatagramAddress::Node { .. } => AddressingMode::Node,
            DatagramAddress::Broadcast { .. } => AddressingMode::Broadcast,
            DatagramAddress::Logical(_) => AddressingMode::Logical,
        }
    }

    /// Reads the raw address (datagram bytes 2-5 as a LE u32) for `command`.
    ///
    /// Returns `None` for commands without addressing (NOP, unknown commands).
    pub fn decode(command: Command, raw: u32) -> Option<Self> {
        let adp = (raw & 0xFFFF) as u16;
        let ado = (raw >> 16) as u16;
        match command.addressing() {
            AddressingMode::Position => Some(DatagramAddress::Position { adp, ado }),
            AddressingMode::Node => Some(DatagramAddress::Node { station: adp, ado }),
            AddressingMode::Broadcast => Some(DatagramAddress::Broadcast { adp, ado }),
            AddressingMode::Logical => Some(DatagramAddress::Logical(raw)),
            AddressingMode::None => None,
        }
    }

    /// Reads the 4 address bytes as they appear on the wire.
    pub fn decode_bytes(command: Command, bytes: [u8; 4]) -> Option<Self> {
        Self::decode(command, u32::from_le_bytes(bytes))
    }

    /// The raw address (datagram bytes 2-5 as a LE u32).
    pub const fn to_raw(&self) -> u32 {
        match *self {
            DatagramAddress::Position { adp, ado } | DatagramAddress::Broadcast { adp, ado } => {
                adp as u32 | (ado as u32) << 16
            }
            DatagramAddress::Node { station, ado } => station as u32 | (ado as u32) << 16,
            DatagramAddress::Logical(raw) => raw,
        }
    }

    /// The 4 address bytes as they appear on the wire.
    pub const fn to_bytes(&self) -> [u8; 4] {
        self.to_raw().to_le_bytes()
    }

    /// The raw address for `command`, refusing an address of another addressing mode
    /// (e.g. a logical address with FPRD) instead of sending something unintended.
    pub fn encode(&self, command: Command) -> Result<u32> {
        if command.addressing() != self.mode() {
            return Err(WireError::Invalid {
                what: "datagram address",
                reason: "address does not match the command's addressing mode",
            });
        }
        Ok(self.to_raw())
    }
}

impl fmt::Display for DatagramAddress {
    /// Wireshark-style: `adp=0x1001 ado=0x0502` or `log=0x00011000`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            DatagramAddress::Position { adp, ado } | DatagramAddress::Broadcast { adp, ado } => {
                write!(f, "adp={adp:#06x} ado={ado:#06x}")
            }
            DatagramAddress::Node { station, ado } => {
                write!(f, "adp={station:#06x} ado={ado:#06x}")
            }
            DatagramAddress::Logical(raw) => write!(f, "log={raw:#010x}"),
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    const ALL: [(u8, &str); 15] = [
        (0x00, "NOP"),
        (0x01, "APRD"),
        (0x02, "APWR"),
        (0x03, "APRW"),
        (0x04, "FPRD"),
        (0x05, "FPWR"),
        (0x06, "FPRW"),
        (0x07, "BRD"),
        (0x08, "BWR"),
        (0x09, "BRW"),
        (0x0A, "LRD"),
        (0x0B, "LWR"),
        (0x0C, "LRW"),
        (0x0D, "ARMW"),
        (0x0E, "FRMW"),
    ];

    #[test]
    fn codes_and_names_match_the_digest_table() {
        for (raw, name) in ALL {
            let cmd = Command::from(raw);
            assert!(!matches!(cmd, Command::Unknown(_)), "{raw:#x} is known");
            assert_eq!(cmd.name(), name);
            assert_eq!(cmd.to_string(), name);
            assert_eq!(u8::from(cmd), raw);
        }
        assert_eq!(Command::from(0x0F), Command::Unknown(0x0F));
        assert_eq!(Command::Unknown(0x0F).to_string(), "CMD(0x0f)");
    }

    #[test]
    fn addressing_modes_per_digest_1_4() {
        use AddressingMode as M;
        let expected = [
            M::None,
            M::Position,
            M::Position,
            M::Position,
            M::Node,
            M::Node,
            M::Node,
            M::Broadcast,
            M::Broadcast,
            M::Broadcast,
            M::Logical,
            M::Logical,
            M::Logical,
            M::Position,
            M::Node,
        ];
        for ((raw, _), mode) in ALL.iter().zip(expected) {
            assert_eq!(Command::from(*raw).addressing(), mode, "cmd {raw:#x}");
        }
        assert_eq!(Command::Unknown(0x20).addressing(), M::None);
    }

    #[test]
    fn read_write_classification() {
        // (read, write) per command code 0..=14, worked out from the command table (spec-notes §commands).
        let expected = [
            (false, false), // NOP
            (true, false),  // APRD
            (false, true),  // APWR
            (true, true),   // APRW
            (true, false),  // FPRD
            (false, true),  // FPWR
            (true, true),   // FPRW
            (true, false),  // BRD
            (false, true),  // BWR
            (true, true),   // BRW
            (true, false),  // LRD
            (false, true),  // LWR
            (true, true),   // LRW
            (true, true),   // ARMW
            (true, true),   // FRMW
        ];
        for ((raw, _), (r, w)) in ALL.iter().zip(expected) {
            let cmd = Command::from(*raw);
            assert_eq!((cmd.is_read(), cmd.is_write()), (r, w), "{cmd}");
        }
    }

    #[test]
    fn position_addresses_of_c2() {
        // spec-notes §commands: APWR to position 0 has ADP bytes `00 00`, position 1 has `ff ff`;
        // both with ADO 0x0010 (`10 00`).
        let p0 = DatagramAddress::position(0, 0x0010);
        let p1 = DatagramAddress::position(1, 0x0010);
        assert_eq!(p0.to_bytes(), [0x00, 0x00, 0x10, 0x00]);
        assert_eq!(p1.to_bytes(), [0xff, 0xff, 0x10, 0x00]);
        assert_eq!(
            DatagramAddress::decode_bytes(Command::Apwr, [0xff, 0xff, 0x10, 0x00]),
            Some(DatagramAddress::Position {
                adp: 0xFFFF,
                ado: 0x0010
            })
        );
        assert_eq!(p1.ring_position(), Some(1));
        assert_eq!(
            DatagramAddress::position(2, 0).to_bytes()[..2],
            [0xfe, 0xff]
        );
    }

    #[test]
    fn node_and_logical_addresses() {
        // ETG.1000.4, spec-notes §esc.sii-if: FPWR to station 0x1001 offset 0x0502 → `01 10 02 05`.
        let node = DatagramAddress::decode_bytes(Command::Fpwr, [0x01, 0x10, 0x02, 0x05]);
        assert_eq!(
            node,
            Some(DatagramAddress::Node {
                station: 0x1001,
                ado: 0x0502
            })
        );
        // spec-notes §capture: address bytes `00 00 01 01` read as logical are 0x01010000.
        assert_eq!(
            DatagramAddress::decode_bytes(Command::Lrd, [0x00, 0x00, 0x01, 0x01]),
            Some(DatagramAddress::Logical(0x0101_0000))
        );
        assert_eq!(DatagramAddress::decode(Command::Nop, 0x1234), None);
        assert_eq!(
            DatagramAddress::Logical(0x11000).to_bytes(),
            [0x00, 0x10, 0x01, 0x00]
        );
        assert_eq!(node.unwrap().to_string(), "adp=0x1001 ado=0x0502");
        assert_eq!(
            DatagramAddress::Logical(0x11000).to_string(),
            "log=0x00011000"
        );
    }

    #[test]
    fn encode_refuses_mismatched_mode() {
        assert!(DatagramAddress::Logical(0).encode(Command::Fprd).is_err());
        assert!(DatagramAddress::broadcast(0).encode(Command::Nop).is_err());
        assert_eq!(
            DatagramAddress::broadcast(0x0101).encode(Command::Bwr),
            Ok(0x0101_0000)
        );
    }

    proptest! {
        #[test]
        fn address_round_trip(cmd in any::<u8>(), raw in any::<u32>()) {
            let cmd = Command::from(cmd);
            match DatagramAddress::decode(cmd, raw) {
                Some(addr) => {
                    prop_assert_eq!(addr.encode(cmd), Ok(raw));
                    prop_assert_eq!(addr.mode(), cmd.addressing());
                }
                None => prop_assert_eq!(cmd.addressing(), AddressingMode::None),
            }
        }

        #[test]
        fn position_conversion_round_trip(p in any::<u16>(), ado in any::<u16>()) {
            prop_assert_eq!(DatagramAddress::position(p, ado).ring_position(), Some(p));
        }
    }
}
