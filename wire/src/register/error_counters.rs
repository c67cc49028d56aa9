//! Error counter block 0x0300–0x0313 (ETG.1000.4, spec-notes §esc.errors).
//!
//! ```text
//! 0x00 + 2n u8 invalid frame counter port n | 0x01 + 2n u8 RX error counter port n
//! 0x08 + n  u8 forwarded RX error port n    | 0x0C u8 processing unit | 0x0D u8 PDI errors
//! 0x0E u8 PDI error code | 0x0F reserved    | 0x10 + n u8 lost link counter port n
//! ```

use core::fmt;

use crate::error::{Result, need, room};
use crate::field::Field;

mod fields {
    use super::Field;
    pub const RX_ERRORS: Field = 0x00..0x08;
    pub const FORWARDED: Field = 0x08..0x0C;
    pub const PROCESSING_UNIT: usize = 0x0C;
    pub const PDI: usize = 0x0D;
    pub const PDI_ERROR_CODE: usize = 0x0E;
    pub const RESERVED: usize = 0x0F;
    pub const LOST_LINK: Field = 0x10..0x14;
}

/// Size of the whole block (KickCAT reads all 20 bytes).
pub const ERROR_COUNTERS_LEN: usize = fields::LOST_LINK.end;

/// View of the 20-byte error counter block.
#[derive(Debug, Clone)]
pub struct ErrorCounters<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> ErrorCounters<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        ErrorCounters { buffer }
    }

    /// Wraps a buffer and checks that the 20 bytes are present.
    pub fn new_checked(buffer: T) -> Result<Self> {
        let view = Self::new_unchecked(buffer);
        view.check_len()?;
        Ok(view)
    }

    /// Checks that the 20 bytes are present.
    pub fn check_len(&self) -> Result<()> {
        need("error counters", self.buffer.as_ref(), ERROR_COUNTERS_LEN)
    }

    /// Returns the underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Invalid frame counter of `port` (0-3); 0 for other ports.
    pub fn invalid_frame(&self, port: usize) -> u8 {
        self.byte_at(fields::RX_ERRORS.start, 2 * port, 8)
    }

    /// RX error counter of `port` (0-3); 0 for other ports.
    pub fn rx_error(&self, port: usize) -> u8 {
        self.byte_at(fields::RX_ERRORS.start, 2 * port + 1, 8)
    }

    /// Forwarded RX error counter of `port` (0-3).
    pub fn forwarded_rx_error(&self, port: usize) -> u8 {
        self.byte_at(fields::FORWARDED.start, port, 4)
    }

    /// ECAT processing unit error counter.
    pub fn processing_unit(&self) -> u8 {
        self.buffer.as_ref()[fields::PROCESSING_UNIT]
    }

    /// PDI error counter.
    pub fn pdi(&self) -> u8 {
        self.buffer.as_ref()[fields::PDI]
    }

    /// PDI error code.
    pub fn pdi_error_code(&self) -> u8 {
        self.buffer.as_ref()[fields::PDI_ERROR_CODE]
    }

    /// Lost link counter of `port` (0-3).
    pub fn lost_link(&self, port: usize) -> u8 {
        self.byte_at(fields::LOST_LINK.start, port, 4)
    }

    fn byte_at(&self, base: usize, index: usize, limit: usize) -> u8 {
        if index < limit {
            self.buffer.as_ref().get(base + index).copied().unwrap_or(0)
        } else {
            0
        }
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> ErrorCounters<T> {
    /// Mutable access to the whole 20-byte block (counters are plain bytes).
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        &mut self.buffer.as_mut()[..ERROR_COUNTERS_LEN]
    }
}

/// Parsed error counters (ETG.1000.4, spec-notes §esc.errors).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ErrorCountersRepr {
    /// Invalid frame (CRC) counters per port.
    pub invalid_frame: [u8; 4],
    /// RX error (PHY) counters per port.
    pub rx_error: [u8; 4],
    /// Forwarded RX error counters per port.
    pub forwarded_rx_error: [u8; 4],
    /// ECAT processing unit error counter.
    pub processing_unit: u8,
    /// PDI error counter.
    pub pdi: u8,
    /// PDI error code.
    pub pdi_error_code: u8,
    /// Lost link counters per port.
    pub lost_link: [u8; 4],
}

impl ErrorCountersRepr {
    /// Parses a checked view (the reserved byte 0x030F is ignored).
    pub fn parse<T: AsRef<[u8]>>(view: &ErrorCounters<T>) -> Result<Self> {
        view.check_len()?;
        let per_port = |f: &dyn Fn(usize) -> u8| [f(0), f(1), f(2), f(3)];
        Ok(ErrorCountersRepr {
            invalid_frame: per_port(&|n| view.invalid_frame(n)),
            rx_error: per_port(&|n| view.rx_error(n)),
            forwarded_rx_error: per_port(&|n| view.forwarded_rx_error(n)),
            processing_unit: view.processing_unit(),
            pdi: view.pdi(),
            pdi_error_code: view.pdi_error_code(),
            lost_link: per_port(&|n| view.lost_link(n)),
        })
    }

    /// Bytes written by [`Self::emit`].
    pub const fn buffer_len(&self) -> usize {
        ERROR_COUNTERS_LEN
    }

    /// Writes the 20 bytes (reserved byte 0).
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, view: &mut ErrorCounters<T>) -> Result<()> {
        room("error counters", view.buffer.as_ref(), ERROR_COUNTERS_LEN)?;
        let buf = view.bytes_mut();
        for n in 0..4 {
            buf[fields::RX_ERRORS.start + 2 * n] = self.invalid_frame[n];
            buf[fields::RX_ERRORS.start + 2 * n + 1] = self.rx_error[n];
            buf[fields::FORWARDED.start + n] = self.forwarded_rx_error[n];
            buf[fields::LOST_LINK.start + n] = self.lost_link[n];
        }
        buf[fields::PROCESSING_UNIT] = self.processing_unit;
        buf[fields::PDI] = self.pdi;
        buf[fields::PDI_ERROR_CODE] = self.pdi_error_code;
        buf[fields::RESERVED] = 0;
        Ok(())
    }

    /// Whether every counter is zero.
    pub fn is_clean(&self) -> bool {
        *self == ErrorCountersRepr::default()
    }
}

impl fmt::Display for ErrorCountersRepr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "errors invalid={:?} rx={:?} fwd={:?} lost={:?} pu={} pdi={}",
            self.invalid_frame,
            self.rx_error,
            self.forwarded_rx_error,
            self.lost_link,
            self.processing_unit,
            self.pdi
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn layout_by_hand() {
        let bytes: [u8; 20] = [
            1, 2, 3, 4, 5, 6, 7, 8, // invalid/rx per port interleaved
            9, 10, 11, 12, // forwarded
            13, 14, 15, 0xEE, // PU, PDI, PDI code, reserved
            16, 17, 18, 19, // lost link
        ];
        let r = ErrorCountersRepr::parse(&ErrorCounters::new_checked(&bytes[..]).unwrap()).unwrap();
        assert_eq!(r.invalid_frame, [1, 3, 5, 7]);
        assert_eq!(r.rx_error, [2, 4, 6, 8]);
        assert_eq!(r.forwarded_rx_error, [9, 10, 11, 12]);
        assert_eq!((r.processing_unit, r.pdi, r.pdi_error_code), (13, 14, 15));
        assert_eq!(r.lost_link, [16, 17, 18, 19]);
        let mut out = [0xa5u8; 20];
        r.emit(&mut ErrorCounters::new_unchecked(&mut out[..]))
            .unwrap();
        let mut expected = bytes;
        expected[15] = 0;
        assert_eq!(out, expected);
        let view = ErrorCounters::new_checked(&bytes[..]).unwrap();
        assert_eq!(view.lost_link(4), 0);
        assert!(ErrorCounters::new_checked(&bytes[..19]).is_err());
    }

    proptest! {
        #[test]
        fn round_trip(bytes in proptest::array::uniform20(any::<u8>())) {
            let r = ErrorCountersRepr::parse(&ErrorCounters::new_checked(&bytes[..]).unwrap()).unwrap();
            let mut out = [0u8; 20];
            r.emit(&mut ErrorCounters::new_unchecked(&mut out[..])).unwrap();
            let again = ErrorCountersRepr::parse(&ErrorCounters::new_checked(&out[..]).unwrap()).unwrap();
            prop_assert_eq!(again, r);
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..24)) {
            if let Ok(view) = ErrorCounters::new_checked(&bytes[..]) {
                let _ = ErrorCountersRepr::parse(&view).map(|r| r.to_string());
                let _ = view.rx_error(7);
            }
        }
    }
}
