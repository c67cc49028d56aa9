//! FMMUs: translating logical addresses to physical ones, byte- or bit-granular
//! (ETG.1000.4, spec-notes §esc.fmmu, §esc.emulation).
//!
//! An FMMU maps `bit_count` consecutive logical bits, starting at bit `logical_start_bit`
//! of byte `logical_start`, onto consecutive physical bits starting at bit
//! `physical_start_bit` of `physical_start`. A logical datagram touches the bits where its
//! range and the mapping overlap; the physical side then follows the usual rules
//! ([`super::physical`], i.e. SyncManager buffers for process data). Partial physical bytes
//! are read-modify-written so unmapped bits keep their value.

use ecat_wire::register::address as reg;
use ecat_wire::register::fmmu::{FMMU_LEN, Fmmu, FmmuRepr};

use crate::device::Device;

use super::Esc;
use super::physical::Origin;

/// Where one FMMU and one logical datagram overlap.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Overlap {
    /// First overlapping bit, counted from the start of the datagram data.
    frame_bit: u64,
    /// The physical bit it maps to, counted from address 0.
    phys_bit: u64,
    /// Number of overlapping bits.
    bits: u64,
}

impl Overlap {
    /// The overlap of `fmmu` with a datagram at logical `address` carrying `len` bytes.
    fn of(fmmu: &FmmuRepr, address: u32, len: usize) -> Option<Self> {
        let count = u64::from(fmmu.bit_count());
        let map_start = u64::from(fmmu.logical_start) * 8 + u64::from(fmmu.logical_start_bit);
        let map_end = map_start + count;
        let dg_start = u64::from(address) * 8;
        let dg_end = dg_start + len as u64 * 8;
        let from = map_start.max(dg_start);
        let to = map_end.min(dg_end);
        (from < to).then(|| Overlap {
            frame_bit: from - dg_start,
            phys_bit: u64::from(fmmu.physical_start) * 8
                + u64::from(fmmu.physical_start_bit)
                + (from - map_start),
            bits: to - from,
        })
    }

    /// Whether frame and physical side are whole, aligned bytes.
    fn byte_aligned(&self) -> bool {
        self.frame_bit.is_multiple_of(8)
            && self.phys_bit.is_multiple_of(8)
            && self.bits.is_multiple_of(8)
    }

    /// First physical byte and number of physical bytes touched.
    fn phys_bytes(&self) -> (u32, usize) {
        let first = self.phys_bit / 8;
        let end = (self.phys_bit + self.bits).div_ceil(8);
        (
            u32::try_from(first).unwrap_or(u32::MAX),
            (end - first) as usize,
        )
    }

    /// Frame byte offset and length of a byte-aligned overlap.
    fn frame_bytes(&self) -> (usize, usize) {
        ((self.frame_bit / 8) as usize, (self.bits / 8) as usize)
    }
}

fn bit(buf: &[u8], n: u64) -> bool {
    buf.get((n / 8) as usize)
        .is_some_and(|b| b >> (n % 8) & 1 != 0)
}

fn set_bit(buf: &mut [u8], n: u64, value: bool) {
    if let Some(b) = buf.get_mut((n / 8) as usize) {
        let mask = 1 << (n % 8);
        if value {
            *b |= mask;
        } else {
            *b &= !mask;
        }
    }
}

impl Esc {
    /// FMMU `n`'s registers.
    fn fmmu(&self, n: u8) -> Option<FmmuRepr> {
        let base = u32::from(reg::fmmu(n)?);
        let bytes = self.mem.get(base, FMMU_LEN)?;
        FmmuRepr::parse(&Fmmu::new_checked(bytes).ok()?).ok()
    }

    /// The enabled FMMUs.
    fn enabled_fmmus(&self) -> impl Iterator<Item = FmmuRepr> + '_ {
        (0..self.layout.fmmu_count).filter_map(|n| self.enabled_fmmu(n))
    }

    /// FMMU `n` if it is enabled and maps at least one bit.
    fn enabled_fmmu(&self, n: u8) -> Option<FmmuRepr> {
        self.fmmu(n).filter(|f| f.enable && f.bit_count() > 0)
    }

    /// Whether `[addr, addr + len)` lies completely inside one enabled FMMU's physical
    /// range (plain RAM reachable by physical commands, spec-notes §esc.emulation).
    pub(crate) fn fmmu_covers(&self, addr: u32, len: usize) -> bool {
        let end = u64::from(addr) + len as u64;
        len > 0
            && self.enabled_fmmus().any(|f| {
                let start_bit = u64::from(f.physical_start) * 8 + u64::from(f.physical_start_bit);
                let first = start_bit / 8;
                let last = (start_bit + u64::from(f.bit_count())).div_ceil(8);
                first <= u64::from(addr) && end <= last
            })
    }

    /// Runs a logical datagram at `address` through every enabled FMMU: reads (FMMU type
    /// bit 0) copy mapped memory into `data`, writes (type bit 1) copy the data *as
    /// received* into memory. Reads happen first, so a read/write mapping exchanges like
    /// the xRW commands. Returns whether any read and any write took place.
    pub(crate) fn logical(
        &mut self,
        device: &mut dyn Device,
        address: u32,
        data: &mut [u8],
        read: bool,
        write: bool,
    ) -> (bool, bool) {
        let mut received = self.take_scratch(0);
        if write {
            received.extend_from_slice(data);
        }
        let mut read_hit = false;
        let mut write_hit = false;
        // By index rather than collecting the FMMUs: this runs for every logical datagram
        // at every slave, and must not allocate.
        if read {
            for n in 0..self.layout.fmmu_count {
                if let Some(f) = self.enabled_fmmu(n).filter(|f| f.read)
                    && let Some(o) = Overlap::of(&f, address, data.len())
                {
                    read_hit |= self.fmmu_read(device, o, data);
                }
            }
        }
        if write {
            for n in 0..self.layout.fmmu_count {
                if let Some(f) = self.enabled_fmmu(n).filter(|f| f.write)
                    && let Some(o) = Overlap::of(&f, address, received.len())
                {
                    write_hit |= self.fmmu_write(device, o, &received);
                }
            }
        }
        self.scratch = received;
        (read_hit, write_hit)
    }

    fn fmmu_read(&mut self, device: &mut dyn Device, o: Overlap, data: &mut [u8]) -> bool {
        let (phys, phys_len) = o.phys_bytes();
        if o.byte_aligned() {
            let (at, n) = o.frame_bytes();
            return match data.get_mut(at..at + n) {
                Some(target) => self.read_phys(device, phys, target, Origin::Fmmu),
                None => false,
            };
        }
        let mut bytes = vec![0u8; phys_len];
        if !self.read_phys(device, phys, &mut bytes, Origin::Fmmu) {
            return false;
        }
        let shift = o.phys_bit % 8;
        for i in 0..o.bits {
            set_bit(data, o.frame_bit + i, bit(&bytes, shift + i));
        }
        true
    }

    fn fmmu_write(&mut self, device: &mut dyn Device, o: Overlap, received: &[u8]) -> bool {
        let (phys, phys_len) = o.phys_bytes();
        if o.byte_aligned() {
            let (at, n) = o.frame_bytes();
            return match received.get(at..at + n) {
                Some(source) => self.write_phys(device, phys, source, Origin::Fmmu),
                None => false,
            };
        }
        // Partial bytes: merge the mapped bits into what the memory holds now.
        let mut bytes = vec![0u8; phys_len];
        self.peek_phys(phys, &mut bytes);
        let shift = o.phys_bit % 8;
        for i in 0..o.bits {
            set_bit(&mut bytes, shift + i, bit(received, o.frame_bit + i));
        }
        self.write_phys(device, phys, &bytes, Origin::Fmmu)
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use super::*;
    use ecat_wire::command::Command;

    fn fmmu_bytes(f: FmmuRepr) -> Vec<u8> {
        let mut b = vec![0u8; FMMU_LEN];
        f.emit(&mut Fmmu::new_unchecked(&mut b[..])).unwrap();
        b
    }

    #[test]
    fn overlap_arithmetic() {
        let f = FmmuRepr::outputs(0x100, 4, 0x1100);
        let o = Overlap::of(&f, 0x102, 8).unwrap();
        assert_eq!(
            o,
            Overlap {
                frame_bit: 0,
                phys_bit: 0x1102 * 8,
                bits: 16
            }
        );
        assert!(Overlap::of(&f, 0x104, 8).is_none());
        assert!(Overlap::of(&f, 0xF0, 16).is_none());
        let bitwise = FmmuRepr {
            logical_start_bit: 3,
            logical_stop_bit: 3,
            length: 1,
            physical_start: 0x080D,
            physical_start_bit: 3,
            ..FmmuRepr::inputs(0x10, 1, 0)
        };
        let o = Overlap::of(&bitwise, 0x10, 1).unwrap();
        assert_eq!(
            o,
            Overlap {
                frame_bit: 3,
                phys_bit: 0x080D * 8 + 3,
                bits: 1
            }
        );
        assert!(!o.byte_aligned());
        assert_eq!(o.phys_bytes(), (0x080D, 1));
    }

    #[test]
    fn logical_read_and_write_of_plain_ram_through_fmmus() {
        let (mut esc, mut dev) = slave();
        exec(
            &mut esc,
            &mut dev,
            Command::Apwr,
            0,
            0x0600,
            &fmmu_bytes(FmmuRepr::outputs(0x1000, 2, 0x1800)),
        );
        exec(
            &mut esc,
            &mut dev,
            Command::Apwr,
            0,
            0x0610,
            &fmmu_bytes(FmmuRepr::inputs(0x1002, 2, 0x1800)),
        );
        let r = exec_logical(
            &mut esc,
            &mut dev,
            Command::Lwr,
            0x1000,
            &[0xAB, 0xCD, 0, 0],
        );
        assert_eq!(r.wkc, 1);
        let r = exec_logical(&mut esc, &mut dev, Command::Lrd, 0x1000, &[0; 4]);
        assert_eq!((r.wkc, r.data.as_slice()), (1, &[0u8, 0, 0xAB, 0xCD][..]));
        let r = exec_logical(&mut esc, &mut dev, Command::Lrw, 0x1000, &[1, 2, 9, 9]);
        assert_eq!(r.wkc, 3);
        assert_eq!(r.data, vec![1, 2, 0xAB, 0xCD], "reads see the old content");
        assert_eq!(esc.read_u16(0x1800), 0x0201);
        let r = exec_logical(&mut esc, &mut dev, Command::Lrd, 0x2000, &[0; 4]);
        assert_eq!(r.wkc, 0, "no FMMU hit");
    }

    #[test]
    fn bit_granular_write_keeps_other_bits() {
        let (mut esc, mut dev) = slave();
        // Logical bits 0x20.4..0x20.7 → physical 0x1800 bits 2..5.
        let f = FmmuRepr {
            logical_start_bit: 4,
            logical_stop_bit: 7,
            physical_start_bit: 2,
            ..FmmuRepr::outputs(0x20, 1, 0x1800)
        };
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0600, &fmmu_bytes(f));
        esc.write(0x1800, &[0b1100_0011]);
        let r = exec_logical(&mut esc, &mut dev, Command::Lwr, 0x20, &[0b1010_0000]);
        assert_eq!(r.wkc, 1);
        assert_eq!(esc.read_u8(0x1800), 0b1110_1011);
    }
}
