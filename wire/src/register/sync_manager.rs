//! SyncManager register set, 8 bytes per SM at 0x0800 + 8·n (ETG.1000.4, spec-notes §esc.sm).
//!
//! ```text
//! 0 u16 physical start | 2 u16 length | 4 u8 control | 5 u8 status | 6 u8 activate
//! 7 u8 PDI control
//! ```
//! The same control byte layout is used by the SII SYNCM category (spec-notes §sii.categories).

use core::fmt;

use crate::error::{Result, WireError, need, room};
use crate::field::{self, Field};
use crate::macros::enum_with_unknown;

mod fields {
    use super::Field;
    pub const START: Field = 0..2;
    pub const LENGTH: Field = 2..4;
    pub const CONTROL: usize = 4;
    pub const STATUS: usize = 5;
    pub const ACTIVATE: usize = 6;
    pub const PDI_CONTROL: usize = 7;
}

/// Size of one SyncManager register set.
pub const SM_LEN: usize = fields::PDI_CONTROL + 1;

enum_with_unknown! {
    /// Operation mode, control bits 0-1.
    pub enum SmMode(u8) {
        /// 00: 3-buffer mode (process data).
        Buffered = 0,
        /// 10: 1-buffer handshake mode (mailbox).
        Mailbox = 2,
    }
}

enum_with_unknown! {
    /// Direction, control bits 2-3 (seen from the ECAT side).
    pub enum SmDirection(u8) {
        /// 00: ECAT reads, PDI writes (inputs, mailbox in).
        Read = 0,
        /// 01: ECAT writes, PDI reads (outputs, mailbox out).
        Write = 1,
    }
}

/// SM control byte (offset 4). Bit 7 is reserved: dropped on decode, written 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SmControl {
    /// Bits 0-1.
    pub mode: SmMode,
    /// Bits 2-3.
    pub direction: SmDirection,
    /// Bit 4: interrupt in the ECAT event request register.
    pub ecat_irq: bool,
    /// Bit 5: interrupt in the AL event request register (PDI).
    pub pdi_irq: bool,
    /// Bit 6: ECAT writes retrigger the process-data watchdog.
    pub watchdog: bool,
}

impl SmControl {
    /// SM0 mailbox out (master → slave): 0x26.
    pub const MAILBOX_OUT: SmControl = SmControl {
        mode: SmMode::Mailbox,
        direction: SmDirection::Write,
        ecat_irq: false,
        pdi_irq: true,
        watchdog: false,
    };
    /// SM1 mailbox in (slave → master): 0x22.
    pub const MAILBOX_IN: SmControl = SmControl {
        mode: SmMode::Mailbox,
        direction: SmDirection::Read,
        ecat_irq: false,
        pdi_irq: true,
        watchdog: false,
    };
    /// Process-data outputs: 0x64 (buffered, write, PDI IRQ, watchdog).
    pub const OUTPUTS: SmControl = SmControl {
        mode: SmMode::Buffered,
        direction: SmDirection::Write,
        ecat_irq: false,
        pdi_irq: true,
        watchdog: true,
    };
    /// Process-data inputs: 0x20 (buffered, read, PDI IRQ).
    pub const INPUTS: SmControl = SmControl {
        mode: SmMode::Buffered,
        direction: SmDirection::Read,
        ecat_irq: false,
        pdi_irq: true,
        watchdog: false,
    };

    /// Decodes the control byte.
    pub fn decode(raw: u8) -> Self {
        SmControl {
            mode: SmMode::from(raw & 0x03),
            direction: SmDirection::from((raw >> 2) & 0x03),
            ecat_irq: raw & 0x10 != 0,
            pdi_irq: raw & 0x20 != 0,
            watchdog: raw & 0x40 != 0,
        }
    }

    /// Encodes the control byte; refuses a mode or direction wider than 2 bits.
    pub fn encode(&self) -> Result<u8> {
        let mode = u8::from(self.mode);
        let direction = u8::from(self.direction);
        if mode > 3 || direction > 3 {
            return Err(WireError::Invalid {
                what: "SM control",
                reason: "mode or direction does not fit in 2 bits",
            });
        }
        Ok(mode
            | (direction << 2)
            | (u8::from(self.ecat_irq) << 4)
            | (u8::from(self.pdi_irq) << 5)
            | (u8::from(self.watchdog) << 6))
    }
}

/// SM status byte (offset 5, read-only for ECAT). Bit 2 is reserved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SmStatus {
    /// Bit 0: the buffer was written.
    pub irq_write: bool,
    /// Bit 1: the buffer was read.
    pub irq_read: bool,
    /// Bit 3: mailbox full (mailbox mode).
    pub mailbox_full: bool,
    /// Bits 4-5: last written buffer (0-2), 3 = none written yet (buffered mode).
    pub buffer_state: u8,
    /// Bit 6: read buffer in use.
    pub read_buffer_open: bool,
    /// Bit 7: write buffer in use.
    pub write_buffer_open: bool,
}

impl SmStatus {
    /// Decodes the status byte.
    pub fn decode(raw: u8) -> Self {
        SmStatus {
            irq_write: raw & 0x01 != 0,
            irq_read: raw & 0x02 != 0,
            mailbox_full: raw & 0x08 != 0,
            buffer_state: (raw >> 4) & 0x03,
            read_buffer_open: raw & 0x40 != 0,
            write_buffer_open: raw & 0x80 != 0,
        }
    }

    /// Encodes the status byte; refuses a buffer state above 3.
    pub fn encode(&self) -> Result<u8> {
        if self.buffer_state > 3 {
            return Err(WireError::Invalid {
                what: "SM status",
                reason: "buffer state does not fit in 2 bits",
            });
        }
        Ok(u8::from(self.irq_write)
            | (u8::from(self.irq_read) << 1)
            | (u8::from(self.mailbox_full) << 3)
            | (self.buffer_state << 4)
            | (u8::from(self.read_buffer_open) << 6)
            | (u8::from(self.write_buffer_open) << 7))
    }
}

/// SM activate byte (offset 6). Bits 2-5 are reserved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SmActivate {
    /// Bit 0: SyncManager enabled.
    pub enable: bool,
    /// Bit 1: mailbox repeat request (toggled by the master, ETG.1000.4, spec-notes §mbx.repeat).
    pub repeat_request: bool,
    /// Bit 6: DC latch event on ECAT access.
    pub latch_ecat: bool,
    /// Bit 7: DC latch event on PDI access.
    pub latch_pdi: bool,
}

impl SmActivate {
    /// Decodes the activate byte.
    pub fn decode(raw: u8) -> Self {
        SmActivate {
            enable: raw & 0x01 != 0,
            repeat_request: raw & 0x02 != 0,
            latch_ecat: raw & 0x40 != 0,
            latch_pdi: raw & 0x80 != 0,
        }
    }

    /// Encodes the activate byte.
    pub fn encode(&self) -> u8 {
        u8::from(self.enable)
            | (u8::from(self.repeat_request) << 1)
            | (u8::from(self.latch_ecat) << 6)
            | (u8::from(self.latch_pdi) << 7)
    }
}

/// SM PDI control byte (offset 7, written by the PDI). Bits 2-7 are reserved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SmPdiControl {
    /// Bit 0: SyncManager deactivated by the PDI.
    pub deactivate: bool,
    /// Bit 1: repeat acknowledge (equals the repeat request once the mailbox is re-posted).
    pub repeat_ack: bool,
}

impl SmPdiControl {
    /// Decodes the PDI control byte.
    pub fn decode(raw: u8) -> Self {
        SmPdiControl {
            deactivate: raw & 0x01 != 0,
            repeat_ack: raw & 0x02 != 0,
        }
    }

    /// Encodes the PDI control byte.
    pub fn encode(&self) -> u8 {
        u8::from(self.deactivate) | (u8::from(self.repeat_ack) << 1)
    }
}

/// View of one 8-byte SyncManager register set.
#[derive(Debug, Clone)]
pub struct SyncManager<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> SyncManager<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        SyncManager { buffer }
    }

    /// Wraps a buffer and checks that the 8 bytes are present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let view = Self::new_unchecked(buffer);
        view.check_len()?;
        Ok(view)
    }

    /// Checks that the 8 bytes are present.
    pub fn check_len(&self) -> Result<()> {
        need("SyncManager", self.buffer.as_ref(), SM_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Physical start address.
    pub fn start(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::START.start)
    }

    /// Length in bytes.
    pub fn length(&self) -> u16 {
        field::u16_le(self.buffer.as_ref(), fields::LENGTH.start)
    }

    /// Raw control byte.
    pub fn control_raw(&self) -> u8 {
        self.buffer.as_ref()[fields::CONTROL]
    }

    /// Raw status byte.
    pub fn status_raw(&self) -> u8 {
        self.buffer.as_ref()[fields::STATUS]
    }

    /// Raw activate byte.
    pub fn activate_raw(&self) -> u8 {
        self.buffer.as_ref()[fields::ACTIVATE]
    }

    /// Raw PDI control byte.
    pub fn pdi_control_raw(&self) -> u8 {
        self.buffer.as_ref()[fields::PDI_CONTROL]
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> SyncManager<T> {
    /// Sets the physical start address.
    pub fn set_start(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::START.start, value)
    }

    /// Sets the length.
    pub fn set_length(&mut self, value: u16) {
        field::set_u16_le(self.buffer.as_mut(), fields::LENGTH.start, value)
    }

    /// Sets the raw control byte.
    pub fn set_control_raw(&mut self, value: u8) {
        self.buffer.as_mut()[fields::CONTROL] = value
    }

    /// Sets the raw status byte.
    pub fn set_status_raw(&mut self, value: u8) {
        self.buffer.as_mut()[fields::STATUS] = value
    }

    /// Sets the raw activate byte.
    pub fn set_activate_raw(&mut self, value: u8) {
        self.buffer.as_mut()[fields::ACTIVATE] = value
    }

    /// Sets the raw PDI control byte.
    pub fn set_pdi_control_raw(&mut self, value: u8) {
        self.buffer.as_mut()[fields::PDI_CONTROL] = value
    }
}

/// A parsed SyncManager register set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SyncManagerRepr {
    /// Physical start address.
    pub start: u16,
    /// Length in bytes.
    pub length: u16,
    /// Control byte.
    pub control: SmControl,
    /// Status byte (the master writes 0).
    pub status: SmStatus,
    /// Activate byte.
    pub activate: SmActivate,
    /// PDI control byte (the master writes 0).
    pub pdi_control: SmPdiControl,
}

impl SyncManagerRepr {
    /// An enabled SM with the given control byte and zero status/PDI control, as SOEM writes.
    pub const fn enabled(start: u16, length: u16, control: SmControl) -> Self {
        SyncManagerRepr {
            start,
            length,
            control,
            status: SmStatus {
                irq_write: false,
                irq_read: false,
                mailbox_full: false,
                buffer_state: 0,
                read_buffer_open: false,
                write_buffer_open: false,
            },
            activate: SmActivate {
                enable: true,
                repeat_request: false,
                latch_ecat: false,
                latch_pdi: false,
            },
            pdi_control: SmPdiControl {
                deactivate: false,
                repeat_ack: false,
            },
        }
    }

    /// SM0 mailbox out (control 0x26).
    pub const fn mailbox_out(start: u16, length: u16) -> Self {
        Self::enabled(start, length, SmControl::MAILBOX_OUT)
    }

    /// SM1 mailbox in (control 0x22).
    pub const fn mailbox_in(start: u16, length: u16) -> Self {
        Self::enabled(start, length, SmControl::MAILBOX_IN)
    }

    /// Process-data outputs (control 0x64).
    pub const fn outputs(start: u16, length: u16) -> Self {
        Self::enabled(start, length, SmControl::OUTPUTS)
    }

    /// Process-data inputs (control 0x20).
    pub const fn inputs(start: u16, length: u16) -> Self {
        Self::enabled(start, length, SmControl::INPUTS)
    }

    /// Parses a checked view; reserved bits are ignored.
    pub fn parse<T: AsRef<[u8]>>(view: &SyncManager<T>) -> Result<Self> {
        view.check_len()?;
        Ok(SyncManagerRepr {
            start: view.start(),
            length: view.length(),
            control: SmControl::decode(view.control_raw()),
            status: SmStatus::decode(view.status_raw()),
            activate: SmActivate::decode(view.activate_raw()),
            pdi_control: SmPdiControl::decode(view.pdi_control_raw()),
        })
    }

    /// Bytes written by [`Self::emit`].
    pub const fn buffer_len(&self) -> usize {
        SM_LEN
    }

    /// Writes the 8 bytes.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, view: &mut SyncManager<T>) -> Result<()> {
        room("SyncManager", view.buffer.as_ref(), SM_LEN)?;
        let control = self.control.encode()?;
        let status = self.status.encode()?;
        view.set_start(self.start);
        view.set_length(self.length);
        view.set_control_raw(control);
        view.set_status_raw(status);
        view.set_activate_raw(self.activate.encode());
        view.set_pdi_control_raw(self.pdi_control.encode());
        Ok(())
    }
}

impl fmt::Display for SyncManagerRepr {
    /// `SM start=0x1000 len=128 mailbox write PDI-IRQ enabled`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mode = match self.control.mode {
            SmMode::Buffered => "buffered",
            SmMode::Mailbox => "mailbox",
            SmMode::Unknown(_) => "reserved-mode",
        };
        let dir = match self.control.direction {
            SmDirection::Read => "read",
            SmDirection::Write => "write",
            SmDirection::Unknown(_) => "reserved-direction",
        };
        write!(
            f,
            "SM start={:#06x} len={} {mode} {dir}",
            self.start, self.length
        )?;
        if self.control.ecat_irq {
            f.write_str(" ECAT-IRQ")?;
        }
        if self.control.pdi_irq {
            f.write_str(" PDI-IRQ")?;
        }
        if self.control.watchdog {
            f.write_str(" WD")?;
        }
        if self.status.mailbox_full {
            f.write_str(" full")?;
        }
        f.write_str(if self.activate.enable {
            " enabled"
        } else {
            " disabled"
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    // ETG.1000.4, spec-notes §esc.sm: SM0 at 0x1000 len 128, SM1 at 0x1080 len 128.
    static C4: [u8; 16] = [
        0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00, 0x80, 0x10, 0x80, 0x00, 0x22, 0x00, 0x01,
        0x00,
    ];

    #[test]
    fn c4_parse() {
        let sm0 = SyncManagerRepr::parse(&SyncManager::new_checked(&C4[..8]).unwrap()).unwrap();
        let sm1 = SyncManagerRepr::parse(&SyncManager::new_checked(&C4[8..]).unwrap()).unwrap();
        assert_eq!(sm0, SyncManagerRepr::mailbox_out(0x1000, 128));
        assert_eq!(sm1, SyncManagerRepr::mailbox_in(0x1080, 128));
        assert_eq!(sm0.control.mode, SmMode::Mailbox);
        assert_eq!(sm0.control.direction, SmDirection::Write);
        assert_eq!(sm1.control.direction, SmDirection::Read);
        assert_eq!(
            sm0.to_string(),
            "SM start=0x1000 len=128 mailbox write PDI-IRQ enabled"
        );
    }

    #[test]
    fn c4_emit() {
        let mut buf = [0xa5u8; 16];
        SyncManagerRepr::mailbox_out(0x1000, 128)
            .emit(&mut SyncManager::new_unchecked(&mut buf[..8]))
            .unwrap();
        SyncManagerRepr::mailbox_in(0x1080, 128)
            .emit(&mut SyncManager::new_unchecked(&mut buf[8..]))
            .unwrap();
        assert_eq!(buf, C4);
    }

    #[test]
    fn typical_control_bytes() {
        // ETG.1000.4, spec-notes §esc.sm: 0x26, 0x22, 0x64, 0x20.
        assert_eq!(SmControl::MAILBOX_OUT.encode(), Ok(0x26));
        assert_eq!(SmControl::MAILBOX_IN.encode(), Ok(0x22));
        assert_eq!(SmControl::OUTPUTS.encode(), Ok(0x64));
        assert_eq!(SmControl::INPUTS.encode(), Ok(0x20));
        // SOEM's default output SM 0x44: buffered, write, watchdog, no IRQ.
        let c = SmControl::decode(0x44);
        assert_eq!(
            (c.mode, c.direction, c.pdi_irq, c.watchdog),
            (SmMode::Buffered, SmDirection::Write, false, true)
        );
    }

    #[test]
    fn status_bits() {
        // Mailbox full + write interrupt; buffered "no buffer written" = 0x30.
        let s = SmStatus::decode(0x09);
        assert!(s.mailbox_full && s.irq_write && !s.irq_read);
        assert_eq!(SmStatus::decode(0x30).buffer_state, 3);
    }

    #[test]
    fn errors() {
        assert!(SyncManager::new_checked(&C4[..7]).is_err());
        let mut bad = SyncManagerRepr::outputs(0x1100, 2);
        bad.control.mode = SmMode::Unknown(4);
        let mut buf = [0xa5u8; 8];
        assert!(
            bad.emit(&mut SyncManager::new_unchecked(&mut buf[..]))
                .is_err()
        );
        assert_eq!(buf, [0xa5; 8]);
        let mut bad = SyncManagerRepr::outputs(0x1100, 2);
        bad.status.buffer_state = 4;
        assert!(
            bad.emit(&mut SyncManager::new_unchecked(&mut buf[..]))
                .is_err()
        );
        assert_eq!(buf, [0xa5; 8]);
    }

    pub(crate) fn arb_control() -> impl Strategy<Value = SmControl> {
        // Bit 7 is reserved: every other control byte decodes losslessly.
        (0u8..0x80).prop_map(SmControl::decode)
    }

    pub(crate) fn arb_sm() -> impl Strategy<Value = SyncManagerRepr> {
        (
            any::<u16>(),
            any::<u16>(),
            arb_control(),
            any::<u8>(),
            any::<u8>(),
            any::<u8>(),
        )
            .prop_map(
                |(start, length, control, status, activate, pdi)| SyncManagerRepr {
                    start,
                    length,
                    control,
                    status: SmStatus::decode(status),
                    activate: SmActivate::decode(activate),
                    pdi_control: SmPdiControl::decode(pdi),
                },
            )
    }

    proptest! {
        #[test]
        fn round_trip(repr in arb_sm()) {
            let mut buf = [0u8; SM_LEN];
            repr.emit(&mut SyncManager::new_unchecked(&mut buf[..])).unwrap();
            let parsed = SyncManagerRepr::parse(&SyncManager::new_checked(&buf[..]).unwrap()).unwrap();
            prop_assert_eq!(parsed, repr);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..12)) {
            if let Ok(view) = SyncManager::new_checked(&bytes[..]) {
                let _ = SyncManagerRepr::parse(&view).map(|r| r.to_string());
            }
        }
    }
}
