//! SyncManager channels: the access rules an ESC enforces on process RAM (spec-notes §esc.sm).
//!
//! - **Mailbox (1-buffer) mode**: the data lives in RAM at the SM's address. The writer may
//!   write only while the buffer is empty and must start at the SM start; writing the last
//!   byte commits (full). The reader may read only while full, starting at the SM start;
//!   reading the last byte empties it. Everything else is blocked (no working counter).
//! - **Buffered (3-buffer) mode**: three private buffers; the reader always gets the last
//!   completely written buffer, the writer fills a free one, and the buffer changes when the
//!   last byte is accessed. ECAT accesses in the SM's direction always succeed and may start
//!   anywhere inside the SM (bit-granular FMMUs map parts of a byte).
//!
//! Every access is clipped at the SM end. Disabling a SyncManager, or changing its start,
//! length or control while it is enabled, resets it (empty mailbox, no buffer written).

use ecat_wire::register::address as reg;
use ecat_wire::register::sync_manager::{
    SM_LEN, SmActivate, SmControl, SmDirection, SmMode, SmPdiControl, SmStatus, SyncManager,
};

use crate::device::Device;

use super::memory::{Memory, SM_AREA_START};

/// Base register address of SM `n`.
pub(crate) fn base(n: u8) -> u32 {
    u32::from(reg::SM_BASE) + u32::from(n) * SM_LEN as u32
}

/// A copy of SM `n`'s register set, read through wire's view of it.
pub(crate) fn registers(mem: &Memory, n: u8) -> SyncManager<[u8; SM_LEN]> {
    let mut raw = [0; SM_LEN];
    mem.read_into(base(n), &mut raw);
    SyncManager::new_unchecked(raw)
}

/// Changes SM `n`'s register set in place through wire's view of it.
pub(crate) fn update_registers(
    mem: &mut Memory,
    n: u8,
    change: impl FnOnce(&mut SyncManager<&mut [u8]>),
) {
    if let Some(raw) = mem.get_mut(base(n), SM_LEN) {
        change(&mut SyncManager::new_unchecked(raw));
    }
}

/// What the master configured in one SM register set, as the ESC applies it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct SmConfig {
    /// Physical start address.
    pub start: u16,
    /// Length in bytes.
    pub length: u16,
    /// Raw control byte.
    pub control: u8,
    /// Enabled by the master (activate bit 0) and not deactivated by the PDI, with a
    /// non-empty range inside the digital I/O registers or the process RAM.
    pub active: bool,
}

impl SmConfig {
    /// Reads SM `n`'s registers. `ram_end` is one past the last RAM address.
    pub fn from_registers(mem: &Memory, n: u8, ram_end: u32) -> Self {
        let sm = registers(mem, n);
        let (start, length) = (sm.start(), sm.length());
        let enabled = SmActivate::decode(sm.activate_raw()).enable;
        let pdi_off = SmPdiControl::decode(sm.pdi_control_raw()).deactivate;
        let end = u32::from(start) + u32::from(length);
        let in_ram = u32::from(start) >= SM_AREA_START && end <= ram_end;
        SmConfig {
            start,
            length,
            control: sm.control_raw(),
            active: enabled && !pdi_off && length > 0 && in_ram,
        }
    }

    /// The decoded control byte.
    pub fn control(&self) -> SmControl {
        SmControl::decode(self.control)
    }

    /// One past the last address.
    pub fn end(&self) -> u32 {
        u32::from(self.start) + u32::from(self.length)
    }

    /// Whether `addr` lies inside the SM.
    pub fn contains(&self, addr: u32) -> bool {
        (u32::from(self.start)..self.end()).contains(&addr)
    }
}

/// The 3-buffer state of a buffered SyncManager.
#[derive(Debug, Clone)]
struct ThreeBuffer {
    buffers: [Vec<u8>; 3],
    /// Last completely written buffer.
    latest: Option<usize>,
    /// Buffer the writer has opened and not finished.
    writing: Option<usize>,
    /// Buffer the reader has opened and not finished.
    reading: Option<usize>,
}

impl ThreeBuffer {
    fn new(length: u16) -> Self {
        let b = vec![0; usize::from(length)];
        ThreeBuffer {
            buffers: [b.clone(), b.clone(), b],
            latest: None,
            writing: None,
            reading: None,
        }
    }

    /// A buffer that is neither the latest complete one nor open for reading or writing;
    /// with three buffers one always exists.
    fn free(&self) -> usize {
        (0..3)
            .find(|i| {
                Some(*i) != self.latest && Some(*i) != self.reading && Some(*i) != self.writing
            })
            .unwrap_or(0)
    }
}

#[derive(Debug, Clone)]
enum SmState {
    /// Not active: accesses fall through to plain memory rules.
    Inactive,
    /// 1-buffer handshake.
    Mailbox { full: bool },
    /// 3-buffer mode.
    Buffered(ThreeBuffer),
}

/// One SyncManager channel: its applied configuration and buffer state.
#[derive(Debug, Clone)]
pub(crate) struct SmChannel {
    index: u8,
    config: SmConfig,
    state: SmState,
    /// Status bit 0: the writer completed a buffer (cleared when the reader opens it).
    irq_write: bool,
    /// Status bit 1: the reader completed a buffer (cleared when the writer opens one).
    irq_read: bool,
}

impl SmChannel {
    /// An inactive channel for SM `index`.
    pub fn new(index: u8) -> Self {
        SmChannel {
            index,
            config: SmConfig::default(),
            state: SmState::Inactive,
            irq_write: false,
            irq_read: false,
        }
    }

    /// The applied configuration.
    pub fn config(&self) -> SmConfig {
        self.config
    }

    /// Whether the channel is active and covers `addr`.
    pub fn covers(&self, addr: u32) -> bool {
        self.config.active && self.config.contains(addr)
    }

    /// Whether the channel is an active mailbox in `direction`.
    pub fn is_mailbox(&self, direction: SmDirection) -> bool {
        matches!(self.state, SmState::Mailbox { .. })
            && self.config.control().direction == direction
    }

    /// Mailbox mode: whether the buffer is full.
    pub fn is_full(&self) -> bool {
        matches!(self.state, SmState::Mailbox { full: true })
    }

    /// Buffered mode: whether a complete buffer has been written since activation.
    pub fn has_complete_buffer(&self) -> bool {
        matches!(&self.state, SmState::Buffered(tb) if tb.latest.is_some())
    }

    /// Whether the channel has something for the ECAT side (mirrored in 0x0210): the PDI
    /// completed the buffer of a read-direction SM, or consumed that of a write-direction
    /// SM.
    pub fn ecat_event(&self) -> bool {
        match self.config.control().direction {
            SmDirection::Read => self.irq_write,
            _ => self.irq_read,
        }
    }

    /// Re-reads the registers; a changed configuration resets the channel. Returns whether
    /// anything changed.
    pub fn refresh(&mut self, mem: &mut Memory, ram_end: u32) -> bool {
        let config = SmConfig::from_registers(mem, self.index, ram_end);
        if config == self.config {
            return false;
        }
        self.config = config;
        self.reset(mem);
        true
    }

    /// Empties the channel according to its current configuration.
    pub fn reset(&mut self, mem: &mut Memory) {
        self.state = if !self.config.active {
            SmState::Inactive
        } else {
            match self.config.control().mode {
                SmMode::Mailbox => SmState::Mailbox { full: false },
                SmMode::Buffered => SmState::Buffered(ThreeBuffer::new(self.config.length)),
                // Reserved modes: the ESC does not redirect; treat the SM as inactive.
                SmMode::Unknown(_) => SmState::Inactive,
            }
        };
        self.irq_write = false;
        self.irq_read = false;
        self.publish_status(mem);
    }

    /// The status byte (offset 5) for the current state.
    pub fn status(&self) -> u8 {
        let mut status = SmStatus {
            irq_write: self.irq_write,
            irq_read: self.irq_read,
            ..SmStatus::default()
        };
        match &self.state {
            SmState::Inactive => {}
            SmState::Mailbox { full } => status.mailbox_full = *full,
            SmState::Buffered(tb) => {
                // Bits 4-5: last written buffer, 3 = none yet.
                status.buffer_state = tb.latest.map_or(3, |i| i as u8);
                status.read_buffer_open = tb.reading.is_some();
                status.write_buffer_open = tb.writing.is_some();
            }
        }
        // buffer_state is at most 3, so encoding cannot fail.
        status.encode().unwrap_or(0)
    }

    fn publish_status(&self, mem: &mut Memory) {
        let status = self.status();
        update_registers(mem, self.index, |sm| sm.set_status_raw(status));
    }

    /// Offset of `addr` in the SM and the number of bytes of a `len`-byte access that fall
    /// inside it.
    fn clip(&self, addr: u32, len: usize) -> (usize, usize) {
        let offset = addr.saturating_sub(u32::from(self.config.start)) as usize;
        let n = len.min(usize::from(self.config.length).saturating_sub(offset));
        (offset, n)
    }

    /// An ECAT read of `out.len()` bytes at `addr` (inside the SM). Returns whether the
    /// access took place. `device` fills the inputs of a read-direction buffered SM when
    /// the reader opens a buffer; without one the PDI republishes the last buffer.
    pub fn ecat_read(
        &mut self,
        mem: &mut Memory,
        addr: u32,
        out: &mut [u8],
        device: Option<&mut dyn Device>,
    ) -> bool {
        let (offset, n) = self.clip(addr, out.len());
        let length = usize::from(self.config.length);
        let direction = self.config.control().direction;
        let done = match &mut self.state {
            SmState::Inactive => false,
            SmState::Mailbox { full } => {
                if direction != SmDirection::Read || offset != 0 || !*full {
                    false
                } else {
                    mem.read_into(addr, &mut out[..n]);
                    self.irq_write = false;
                    if offset + n == length {
                        *full = false;
                        self.irq_read = true;
                    }
                    true
                }
            }
            SmState::Buffered(tb) => {
                match direction {
                    SmDirection::Read => {
                        if offset == 0 || tb.reading.is_none() {
                            // The reader opens a buffer: the PDI has just written the newest
                            // inputs, which become the last complete buffer.
                            let fresh = tb.free();
                            match (device, tb.latest) {
                                (Some(dev), _) => dev.read_inputs(&mut tb.buffers[fresh]),
                                (None, Some(latest)) => {
                                    let copy = tb.buffers[latest].clone();
                                    tb.buffers[fresh] = copy;
                                }
                                (None, None) => tb.buffers[fresh].fill(0),
                            }
                            tb.latest = Some(fresh);
                            tb.reading = Some(fresh);
                            self.irq_write = false;
                        }
                        if let Some(b) = tb.reading {
                            out[..n].copy_from_slice(&tb.buffers[b][offset..offset + n]);
                        }
                        if offset + n == length {
                            tb.reading = None;
                            self.irq_read = true;
                        }
                    }
                    // The master reading back its own outputs sees the last complete buffer.
                    _ => match tb.latest {
                        Some(b) => out[..n].copy_from_slice(&tb.buffers[b][offset..offset + n]),
                        None => out[..n].fill(0),
                    },
                }
                true
            }
        };
        self.publish_status(mem);
        done
    }

    /// An ECAT write of `data` at `addr` (inside the SM). Returns whether the access took
    /// place and, for a buffered SM, hands a completed buffer to `device`.
    pub fn ecat_write(
        &mut self,
        mem: &mut Memory,
        addr: u32,
        data: &[u8],
        device: Option<&mut dyn Device>,
    ) -> bool {
        let (offset, n) = self.clip(addr, data.len());
        let length = usize::from(self.config.length);
        let direction = self.config.control().direction;
        let done = match &mut self.state {
            SmState::Inactive => false,
            SmState::Mailbox { full } => {
                if direction != SmDirection::Write || offset != 0 || *full {
                    false
                } else {
                    mem.write_from(addr, &data[..n]);
                    self.irq_read = false;
                    if offset + n == length {
                        *full = true;
                        self.irq_write = true;
                    }
                    true
                }
            }
            SmState::Buffered(tb) => {
                if direction != SmDirection::Write {
                    // ECAT cannot write an input SyncManager.
                    false
                } else {
                    let w = match tb.writing {
                        Some(w) => w,
                        None => {
                            // A fresh buffer starts as a copy of the last complete one, so
                            // a partial write leaves the other bytes as the master last
                            // wrote them.
                            let w = tb.free();
                            match tb.latest {
                                Some(l) => copy_buffer(&mut tb.buffers, l, w),
                                None => tb.buffers[w].fill(0),
                            }
                            tb.writing = Some(w);
                            self.irq_read = false;
                            w
                        }
                    };
                    tb.buffers[w][offset..offset + n].copy_from_slice(&data[..n]);
                    if offset + n == length {
                        tb.latest = Some(w);
                        tb.writing = None;
                        self.irq_write = true;
                        if let Some(dev) = device {
                            dev.outputs_written(&tb.buffers[w]);
                        }
                    }
                    true
                }
            }
        };
        self.publish_status(mem);
        done
    }

    /// What an access at `addr` would see, without any side effect (for read-modify-write
    /// of partial bytes through bit-granular FMMUs).
    pub fn peek(&self, mem: &Memory, addr: u32, out: &mut [u8]) {
        let (offset, n) = self.clip(addr, out.len());
        match &self.state {
            SmState::Inactive | SmState::Mailbox { .. } => mem.read_into(addr, &mut out[..n]),
            SmState::Buffered(tb) => {
                let b = tb.writing.or(tb.reading).or(tb.latest);
                match b {
                    Some(b) => out[..n].copy_from_slice(&tb.buffers[b][offset..offset + n]),
                    None => out[..n].fill(0),
                }
            }
        }
    }

    /// PDI side of a write-direction mailbox: takes the whole buffer if it is full and
    /// empties it.
    pub fn pdi_take(&mut self, mem: &mut Memory) -> Option<Vec<u8>> {
        if !self.is_mailbox(SmDirection::Write) || !self.is_full() {
            return None;
        }
        let data = mem
            .get(
                u32::from(self.config.start),
                usize::from(self.config.length),
            )
            .map(<[u8]>::to_vec)
            .unwrap_or_default();
        self.state = SmState::Mailbox { full: false };
        self.irq_write = false;
        self.irq_read = true;
        self.publish_status(mem);
        Some(data)
    }

    /// PDI side of a read-direction mailbox: posts `message` (clipped to the SM length, the
    /// rest of the buffer zeroed) if the buffer is empty. Returns whether it was posted.
    pub fn pdi_post(&mut self, mem: &mut Memory, message: &[u8]) -> bool {
        if !self.is_mailbox(SmDirection::Read) || self.is_full() {
            return false;
        }
        let length = usize::from(self.config.length);
        if let Some(buf) = mem.get_mut(u32::from(self.config.start), length) {
            let n = message.len().min(length);
            buf[..n].copy_from_slice(&message[..n]);
            buf[n..].fill(0);
        }
        self.state = SmState::Mailbox { full: true };
        self.irq_write = true;
        self.irq_read = false;
        self.publish_status(mem);
        true
    }
}

/// Copies buffer `from` over buffer `to` in place (no allocation: it runs on every output
/// write). Buffers of one SyncManager all have its length.
fn copy_buffer(buffers: &mut [Vec<u8>; 3], from: usize, to: usize) {
    if from == to || from > 2 || to > 2 {
        return;
    }
    let (low, high) = buffers.split_at_mut(from.max(to));
    let (src, dst) = if from < to {
        (&low[from], &mut high[0])
    } else {
        (&high[0], &mut low[to])
    };
    let n = src.len().min(dst.len());
    dst[..n].copy_from_slice(&src[..n]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::Device;

    const RAM_END: u32 = 0x3000;

    fn configure(mem: &mut Memory, n: u8, start: u16, length: u16, control: u8) -> SmChannel {
        let b = base(n);
        mem.set_u16(b, start);
        mem.set_u16(b + 2, length);
        mem.set_u8(b + 4, control);
        mem.set_u8(b + 6, 0x01);
        mem.set_u8(b + 7, 0x00);
        let mut sm = SmChannel::new(n);
        assert!(sm.refresh(mem, RAM_END));
        sm
    }

    #[test]
    fn mailbox_write_commits_on_last_byte_and_blocks_when_full() {
        let mut mem = Memory::new(0x2000);
        let mut sm = configure(&mut mem, 0, 0x1000, 8, 0x26);
        assert!(
            !sm.ecat_write(&mut mem, 0x1001, &[1; 7], None),
            "must start at the start"
        );
        assert!(
            sm.ecat_write(&mut mem, 0x1000, &[1; 4], None),
            "partial write accepted"
        );
        assert!(!sm.is_full());
        assert!(
            sm.ecat_write(&mut mem, 0x1000, &[2; 10], None),
            "clipped at the SM end"
        );
        assert!(sm.is_full());
        assert_eq!(mem.u8(0x1008), 0, "nothing written past the SM");
        assert_eq!(mem.u8(0x080D - 8), 0x09, "status: full + written");
        assert!(
            !sm.ecat_write(&mut mem, 0x1000, &[3; 8], None),
            "full: blocked"
        );
        assert!(
            !sm.ecat_read(&mut mem, 0x1000, &mut [0; 8], None),
            "wrong direction"
        );
        assert_eq!(sm.pdi_take(&mut mem), Some(vec![2; 8]));
        assert!(!sm.is_full());
        assert_eq!(sm.pdi_take(&mut mem), None);
    }

    #[test]
    fn mailbox_read_needs_full_and_empties_on_last_byte() {
        let mut mem = Memory::new(0x2000);
        let mut sm = configure(&mut mem, 1, 0x1080, 4, 0x22);
        let mut out = [0u8; 4];
        assert!(
            !sm.ecat_read(&mut mem, 0x1080, &mut out, None),
            "empty: blocked"
        );
        assert!(sm.pdi_post(&mut mem, &[7, 8]));
        assert!(!sm.pdi_post(&mut mem, &[9]), "only one message at a time");
        assert!(sm.ecat_read(&mut mem, 0x1080, &mut out[..2], None));
        assert!(sm.is_full(), "last byte not read yet");
        assert!(sm.ecat_read(&mut mem, 0x1080, &mut out, None));
        assert_eq!(out, [7, 8, 0, 0]);
        assert!(!sm.is_full());
        assert!(
            !sm.ecat_write(&mut mem, 0x1080, &[1; 4], None),
            "wrong direction"
        );
    }

    struct Counter(u8, Vec<Vec<u8>>);
    impl Device for Counter {
        fn read_inputs(&mut self, inputs: &mut [u8]) {
            self.0 += 1;
            inputs.fill(self.0);
        }
        fn outputs_written(&mut self, outputs: &[u8]) {
            self.1.push(outputs.to_vec());
        }
    }

    #[test]
    fn buffered_outputs_commit_on_last_byte() {
        let mut mem = Memory::new(0x2000);
        let mut sm = configure(&mut mem, 2, 0x1100, 4, 0x64);
        let mut dev = Counter(0, vec![]);
        assert_eq!(sm.status() & 0x30, 0x30, "no buffer written yet");
        assert!(sm.ecat_write(&mut mem, 0x1100, &[1, 2, 3, 4], Some(&mut dev)));
        assert!(sm.ecat_write(&mut mem, 0x1100, &[5, 6], Some(&mut dev)));
        assert_eq!(dev.1, vec![vec![1, 2, 3, 4]], "partial write not committed");
        let mut back = [0u8; 4];
        assert!(sm.ecat_read(&mut mem, 0x1100, &mut back, None));
        assert_eq!(back, [1, 2, 3, 4], "reader gets the last complete buffer");
        assert!(sm.ecat_write(&mut mem, 0x1103, &[9], Some(&mut dev)));
        assert_eq!(dev.1[1], vec![5, 6, 3, 9]);
        assert!(sm.has_complete_buffer());
    }

    #[test]
    fn buffered_inputs_are_a_consistent_snapshot() {
        let mut mem = Memory::new(0x2000);
        let mut sm = configure(&mut mem, 3, 0x1180, 2, 0x20);
        let mut dev = Counter(0, vec![]);
        let mut a = [0u8; 1];
        assert!(sm.ecat_read(&mut mem, 0x1180, &mut a, Some(&mut dev)));
        let mut b = [0u8; 1];
        assert!(sm.ecat_read(&mut mem, 0x1181, &mut b, Some(&mut dev)));
        assert_eq!(
            (a[0], b[0]),
            (1, 1),
            "same buffer until the last byte was read"
        );
        assert!(sm.ecat_read(&mut mem, 0x1180, &mut [0; 2], Some(&mut dev)));
        assert_eq!(dev.0, 2, "a new read opens a new buffer");
        assert!(!sm.ecat_write(&mut mem, 0x1180, &[0; 2], Some(&mut dev)));
    }

    #[test]
    fn reconfiguring_resets() {
        let mut mem = Memory::new(0x2000);
        let mut sm = configure(&mut mem, 0, 0x1000, 2, 0x26);
        assert!(sm.ecat_write(&mut mem, 0x1000, &[1, 2], None));
        assert!(sm.is_full());
        assert!(!sm.refresh(&mut mem, RAM_END), "unchanged");
        mem.set_u8(base(0) + 6, 0);
        assert!(sm.refresh(&mut mem, RAM_END));
        assert!(!sm.config().active);
        mem.set_u8(base(0) + 6, 1);
        sm.refresh(&mut mem, RAM_END);
        assert!(!sm.is_full(), "disabling resets the mailbox");
        mem.set_u8(base(0) + 7, 1);
        sm.refresh(&mut mem, RAM_END);
        assert!(!sm.config().active, "PDI deactivation");
        mem.set_u8(base(0) + 7, 0);
        mem.set_u16(base(0), 0x2FFF);
        sm.refresh(&mut mem, RAM_END);
        assert!(!sm.config().active, "range beyond RAM");
    }

    #[test]
    fn buffer_copies_go_either_way_and_ignore_bad_indices() {
        let mut buffers = [vec![1u8; 4], vec![2u8; 4], vec![3u8; 4]];
        copy_buffer(&mut buffers, 2, 0);
        assert_eq!(buffers[0], [3; 4]);
        copy_buffer(&mut buffers, 1, 2);
        assert_eq!(buffers[2], [2; 4]);
        copy_buffer(&mut buffers, 1, 3);
        copy_buffer(&mut buffers, 1, 1);
        assert_eq!(buffers, [vec![3; 4], vec![2; 4], vec![2; 4]]);
    }
}
