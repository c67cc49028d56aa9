//! The emulated EtherCAT Slave Controller (ESC): one slave's registers, process RAM,
//! SyncManagers, FMMUs, SII EEPROM interface, AL state machine, DL status and distributed
//! clock, driven datagram by datagram as a frame passes (spec-notes §frame, §sii, §dc, §esc.emulation).
//!
//! The ESC owns everything a real ESC chip does plus the parts of the slave firmware that
//! every slave shares (AL transitions and their checks, mailbox SyncManager handling, the
//! repeat procedure). The application behind the PDI is a [`Device`]: the ESC hands it
//! mailbox messages, outputs and state changes, and asks it for inputs.
//!
//! One file per job: `memory` (the byte space), `registers` (write masks, reset values),
//! `physical` (who may access which address), `command` (the 15 datagram commands and
//! their working counters), `sync_manager`, `fmmu`, `mailbox`, `eeprom`, `al`, `dl`, `dc`,
//! `watchdog` and [`time`].
//!
//! # Decisions on points the sources leave open
//!
//! - **Process RAM** (≥ 0x1000) is reachable only inside an active SyncManager (with its
//!   mailbox/buffered rules) or, outside any SyncManager, inside an enabled FMMU's physical
//!   range (KickCAT's rule, spec-notes §esc.emulation). Other RAM accesses are blocked (no working
//!   counter). An access that starts in the register area is clipped at 0x1000.
//! - **SyncManager accesses**: mailbox accesses must start at the SM start; buffered ones
//!   may start anywhere inside (bit-granular FMMUs). Accesses against the SM's direction
//!   are blocked, except that the master may read back its own outputs (the last complete
//!   buffer). Changing start, length or control of an enabled SM resets it, like disabling
//!   it. SyncManagers may also cover the digital I/O registers from 0x0F00, as simple
//!   terminals' do.
//! - **SyncManagers start deactivated by the PDI** (0x0807 bit 0 = 1): the slave enables
//!   SM0/SM1 on INIT → PREOP/BOOT and the process-data SMs on PREOP → SAFEOP after checking
//!   them, and deactivates them again when going down (as SOES does). The SM control check
//!   compares mode and direction (bits 0-3) only, since masters differ in the IRQ bits.
//! - **The firmware is instantaneous**: a message committed to SM0 reaches the device at
//!   the end of that datagram and its reply is in SM1 for the next datagram. SM0 is left
//!   full (writes get WKC 0) while the device's outbox is full, so replies are never lost.
//! - **No EEPROM, no PDI**: with a bad SII checksum the PDI is not operational (DL status
//!   bit 0 = 0) and nobody answers AL control writes; the slave stays in INIT.
//! - Writes to read-only registers are ignored but counted in the working counter.

mod al;
mod chain;
mod command;
mod config;
mod dc;
mod dl;
mod eeprom;
mod fmmu;
mod mailbox;
mod memory;
mod physical;
mod registers;
mod sync_manager;
pub mod time;
mod watchdog;

pub use chain::Chain;
use ecat_wire::register::address as reg;
use ecat_wire::register::al::{AlState, AlStatus};
use ecat_wire::register::al_status_code::AlStatusCode;

use crate::device::{Device, DeviceContext};

pub use config::{DcConfig, EscConfig, MAX_RAM_SIZE};
pub use dl::ErrorCounter;
pub use time::{ManualTime, MonotonicTime, TimeSource};

use dc::DcState;
use dl::Ports;
use eeprom::Eeprom;
use mailbox::MailboxState;
use memory::Memory;
use registers::Layout;
use sync_manager::SmChannel;

/// When a frame passes this slave, in ns of the segment's time base.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FrameTiming {
    /// The frame's first bit arrives at port 0 (and reaches the processing unit).
    pub port0_ns: u64,
    /// The frame comes back in at port 1; `None` when port 1 is closed.
    pub port1_ns: Option<u64>,
}

/// ECAT events that stay pending until the master reads the register that reports them.
#[derive(Debug, Clone, Copy, Default)]
struct Events {
    /// DL status changed (0x0210 bit 2), cleared by reading 0x0110.
    dl_status: bool,
    /// AL status changed (0x0210 bit 3), cleared by reading 0x0130.
    al_status: bool,
}

/// One emulated EtherCAT Slave Controller.
#[derive(Debug)]
pub struct Esc {
    config: EscConfig,
    layout: Layout,
    mem: Memory,
    sms: Vec<SmChannel>,
    eeprom: Eeprom,
    mailbox: MailboxState,
    dc: DcState,
    ports: Ports,
    events: Events,
    frame: FrameTiming,
    /// How many bytes of the 'R' 'E' 'S' reset sequence have been written to 0x0040.
    reset_sequence: usize,
    /// When the process-data watchdog was last restarted; `None` when it is not running.
    watchdog_trigger: Option<u64>,
    /// Reused buffers so that datagram processing does not allocate.
    scratch: Vec<u8>,
    scratch2: Vec<u8>,
}

impl Esc {
    /// An ESC with `config` and the EEPROM content `sii` (bytes, little-endian words; an odd
    /// trailing byte is padded with 0xFF), powered on at time 0 with its link on port 0 up
    /// and nothing behind port 1.
    pub fn new(config: EscConfig, sii: Vec<u8>) -> Self {
        let layout = Layout::of(&config);
        let sms = (0..layout.sm_count).map(SmChannel::new).collect();
        let mut esc = Esc {
            mem: Memory::new(config.effective_ram_size()),
            layout,
            sms,
            eeprom: Eeprom::new(sii),
            mailbox: MailboxState::new(),
            dc: DcState::new(0),
            ports: Ports::new(),
            events: Events::default(),
            frame: FrameTiming::default(),
            reset_sequence: 0,
            watchdog_trigger: None,
            scratch: Vec::new(),
            scratch2: Vec::new(),
            config,
        };
        esc.power_on(0);
        esc
    }

    /// The configuration the ESC was built with.
    pub fn config(&self) -> &EscConfig {
        &self.config
    }

    /// Changes how the local clock runs (start value, drift, hop delay), e.g. to give each
    /// slave of a test segment its own clock; takes effect at once.
    pub fn set_dc_config(&mut self, dc: DcConfig) {
        self.config.dc = dc;
    }

    /// Power-cycles the ESC at time `now_ns`: every register goes back to its reset value,
    /// buffers and the mailbox queue are emptied, the clock restarts, and the EEPROM is
    /// loaded again. The SII image (including anything the master wrote to it) survives.
    pub fn power_cycle(&mut self, now_ns: u64) {
        self.power_on(now_ns);
    }

    fn power_on(&mut self, now_ns: u64) {
        registers::load_reset_values(&mut self.mem, &self.config);
        let ram_end = self.mem.end();
        for sm in &mut self.sms {
            sm.refresh(&mut self.mem, ram_end);
            sm.reset(&mut self.mem);
        }
        self.mailbox.clear();
        self.dc = DcState::new(now_ns);
        self.events = Events::default();
        self.reset_sequence = 0;
        self.watchdog_trigger = None;
        self.frame = FrameTiming {
            port0_ns: now_ns,
            port1_ns: None,
        };
        self.load_eeprom_config();
        self.update_dl_status();
    }

    /// Runs every datagram of an EtherCAT payload (the bytes after the EtherCAT header)
    /// through this ESC in place, then lets the device post mailbox messages.
    ///
    /// A malformed datagram chain stops processing at the bad datagram and counts an ECAT
    /// processing unit error (0x030C); nothing in the payload can make this panic.
    pub fn process_frame(
        &mut self,
        payload: &mut [u8],
        device: &mut dyn Device,
        timing: FrameTiming,
    ) {
        let chain = Chain::of(payload);
        self.process_chain(payload, &chain, device, timing);
    }

    /// [`Esc::process_frame`] with the payload's chain read already (once for all the
    /// slaves a frame passes: [`Chain`]).
    pub fn process_chain(
        &mut self,
        payload: &mut [u8],
        chain: &Chain,
        device: &mut dyn Device,
        timing: FrameTiming,
    ) {
        self.frame = timing;
        self.check_watchdog(timing.port0_ns, device);
        // The firmware runs between frames, not only when one passes: a reply that came due
        // since the last frame is in SM1 for this frame's first read, as on a real slave
        // whose application writes SM1 over the PDI at its own time (spec-notes
        // §mbx.handshake). Without this, a delayed reply would wait one frame more.
        self.run_firmware(device);
        for mut datagram in chain.datagrams(payload) {
            self.process_datagram(&mut datagram, device);
        }
        if chain.malformed() {
            self.count_error(ErrorCounter::ProcessingUnit);
        }
        self.end_of_frame(device);
    }

    /// Reads `out.len()` bytes of the ESC's memory at `addr` as they are stored, without
    /// any access rule or side effect (test and PDI view). Bytes outside the memory read 0.
    /// SyncManager buffers in 3-buffer mode are not visible here.
    pub fn read(&self, addr: u16, out: &mut [u8]) {
        out.fill(0);
        self.mem.read_into(u32::from(addr), out);
    }

    /// Reads a byte (see [`Esc::read`]).
    pub fn read_u8(&self, addr: u16) -> u8 {
        self.mem.u8(addr.into())
    }

    /// Reads a little-endian u16 (see [`Esc::read`]).
    pub fn read_u16(&self, addr: u16) -> u16 {
        self.mem.u16(addr.into())
    }

    /// Reads a little-endian u32 (see [`Esc::read`]).
    pub fn read_u32(&self, addr: u16) -> u32 {
        self.mem.u32(addr.into())
    }

    /// Reads a little-endian u64 (see [`Esc::read`]).
    pub fn read_u64(&self, addr: u16) -> u64 {
        self.mem.u64(addr.into())
    }

    /// Writes `data` at `addr` directly, as the PDI could: no write masks, no access rules.
    /// SyncManager registers written this way take effect (a changed configuration resets
    /// the SM); other side effects (AL control, EEPROM commands) do not run.
    pub fn write(&mut self, addr: u16, data: &[u8]) {
        self.mem.write_from(u32::from(addr), data);
        self.refresh_sync_managers();
    }

    /// The SII EEPROM image.
    pub fn sii(&self) -> &[u8] {
        self.eeprom.image()
    }

    /// Current AL status (0x0130).
    pub fn al_status(&self) -> AlStatus {
        AlStatus::decode(self.mem.u16(reg::AL_STATUS.into()))
    }

    /// Current AL state.
    pub fn al_state(&self) -> AlState {
        self.al_status().state
    }

    /// AL status code (0x0134).
    pub fn al_status_code(&self) -> AlStatusCode {
        AlStatusCode::from(self.mem.u16(reg::AL_STATUS_CODE.into()))
    }

    /// Configured station address (0x0010).
    pub fn station_address(&self) -> u16 {
        self.mem.u16(reg::STATION_ADDRESS.into())
    }

    /// Configured station alias (0x0012).
    pub fn station_alias(&self) -> u16 {
        self.mem.u16(reg::STATION_ALIAS.into())
    }

    /// Whether the EEPROM loaded correctly and the PDI runs (DL status bit 0).
    pub fn pdi_operational(&self) -> bool {
        self.eeprom.loaded()
    }

    /// Mailbox messages the device has queued and the master has not read yet (waiting
    /// behind the one in SM1, if any).
    pub fn pending_mailbox_messages(&self) -> usize {
        self.mailbox.pending()
    }

    /// What the device is told about the slave.
    pub fn device_context(&self) -> DeviceContext {
        let size = |n: usize| {
            self.sms
                .get(n)
                .map(|sm| sm.config())
                .filter(|c| c.active)
                .map_or(0, |c| c.length)
        };
        DeviceContext {
            station_address: self.station_address(),
            al_state: self.al_state(),
            rx_mailbox_size: size(0),
            tx_mailbox_size: size(1),
        }
    }

    /// Re-reads every SyncManager's registers (after a raw write or a PDI change).
    fn refresh_sync_managers(&mut self) {
        let ram_end = self.mem.end();
        for sm in &mut self.sms {
            sm.refresh(&mut self.mem, ram_end);
        }
    }

    /// After the last datagram of a frame: the device may post (spec-notes §mbx.handshake), then the next queued
    /// message goes into SM1.
    fn end_of_frame(&mut self, device: &mut dyn Device) {
        self.run_firmware(device);
    }

    /// The slave's application between frames: it may post, and the next queued message
    /// goes into SM1.
    fn run_firmware(&mut self, device: &mut dyn Device) {
        self.poll_device(device);
        self.service_mailbox(device);
    }
}

#[cfg(test)]
pub(crate) mod test_support;
