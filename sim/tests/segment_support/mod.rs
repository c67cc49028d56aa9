//! Shared test bench for the integration tests: a segment of standard slaves behind a
//! manual time base, frames built with the wire codecs, and a device whose state the test
//! can inspect.

#![allow(dead_code)]

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};

use ecat_wire::command::{Command, DatagramAddress};
use ecat_wire::datagram::{DatagramRepr, FrameBuilder};
use ecat_wire::ethernet::MAX_FRAME_LEN;
use ecat_wire::frame::EthercatFrame;
use ecat_wire::register::al::AlState;
use ecat_wire::register::al_status_code::AlStatusCode;
use ecat_wire::sii::SiiBuilder;
use ecat_wire::sii::fixed::{MailboxProtocols, SiiFixedRepr, SiiMailboxArea};
use ecat_wire::sii::syncm::{SyncmEnable, SyncmEntry, SyncmType};
use sim::device::{Device, DeviceContext, Outbox, ProcessDataSizes};
use sim::esc::{Esc, EscConfig, ManualTime};
use sim::segment::Segment;

/// Source MAC the bench sends from.
pub const MASTER_MAC: [u8; 6] = [0x00, 0x00, 0x00, 0x00, 0x00, 0x01];

/// ETG.1000.4, spec-notes §esc.sm: SM0 at 0x1000 and SM1 at 0x1080, 128 bytes each, enabled.
pub const MAILBOX_SMS: [u8; 16] = [
    0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00, 0x80, 0x10, 0x80, 0x00, 0x22, 0x00, 0x01, 0x00,
];

/// Station address the bench gives position `p`.
pub fn station(p: usize) -> u16 {
    0x1001 + p as u16
}

/// The fixed area of the standard slave (vendor 2, product 0x1234, 128-byte mailboxes at
/// 0x1000/0x1080, CoE).
pub fn fixed() -> SiiFixedRepr {
    SiiFixedRepr {
        pdi_control: 0x0005,
        vendor_id: 2,
        product_code: 0x1234,
        revision: 1,
        serial: 7,
        std_rx_mailbox: SiiMailboxArea {
            offset: 0x1000,
            size: 128,
        },
        std_tx_mailbox: SiiMailboxArea {
            offset: 0x1080,
            size: 128,
        },
        mailbox_protocols: MailboxProtocols(MailboxProtocols::COE),
        version: 1,
        ..SiiFixedRepr::default()
    }
}

/// The standard slave's SII: SM0/SM1 mailboxes, SM2 outputs at 0x1100, SM3 inputs at 0x1180.
pub fn sii(alias: u16) -> Vec<u8> {
    let entry = |start, control, sm_type| SyncmEntry {
        start,
        length: if start < 0x1100 { 128 } else { 0 },
        control,
        status: 0,
        enable: SyncmEnable(1),
        sm_type,
    };
    let mut b = SiiBuilder::new(SiiFixedRepr { alias, ..fixed() });
    b.syncm = vec![
        entry(0x1000, 0x26, SyncmType::MailboxOut),
        entry(0x1080, 0x22, SyncmType::MailboxIn),
        entry(0x1100, 0x64, SyncmType::Outputs),
        entry(0x1180, 0x20, SyncmType::Inputs),
    ];
    b.build().unwrap()
}

/// What a [`TestDevice`] saw and will answer.
#[derive(Debug, Default)]
pub struct DeviceState {
    /// Process-data sizes reported.
    pub sizes: ProcessDataSizes,
    /// Mailbox messages received.
    pub received: Vec<Vec<u8>>,
    /// Whether received messages are echoed back.
    pub echo: bool,
    /// Messages posted on the next polls, one per poll.
    pub unsolicited: VecDeque<Vec<u8>>,
    /// Polls seen.
    pub polls: usize,
    /// Complete output buffers received.
    pub outputs: Vec<Vec<u8>>,
    /// Inputs presented (repeated / truncated to the SM length).
    pub inputs: Vec<u8>,
    /// Number of input reads.
    pub input_reads: usize,
    /// Transitions accepted.
    pub transitions: Vec<(AlState, AlState)>,
    /// Refuse transitions to this state with this code.
    pub refuse: Option<(AlState, AlStatusCode)>,
}

/// A device whose state lives behind a shared handle.
#[derive(Debug, Clone, Default)]
pub struct TestDevice(pub Arc<Mutex<DeviceState>>);

impl TestDevice {
    /// Locks the state.
    pub fn state(&self) -> MutexGuard<'_, DeviceState> {
        self.0.lock().unwrap()
    }
}

impl Device for TestDevice {
    fn mailbox_received(&mut self, message: &[u8], _ctx: &DeviceContext, outbox: &mut Outbox) {
        let mut s = self.state();
        s.received.push(message.to_vec());
        if s.echo {
            let _ = outbox.push(message.to_vec());
        }
    }

    fn poll(&mut self, _ctx: &DeviceContext, outbox: &mut Outbox) {
        let mut s = self.state();
        s.polls += 1;
        if let Some(m) = s.unsolicited.pop_front() {
            let _ = outbox.push(m);
        }
    }

    fn process_data_sizes(&self) -> ProcessDataSizes {
        self.state().sizes
    }

    fn outputs_written(&mut self, outputs: &[u8]) {
        self.state().outputs.push(outputs.to_vec());
    }

    fn read_inputs(&mut self, inputs: &mut [u8]) {
        let mut s = self.state();
        s.input_reads += 1;
        for (i, b) in inputs.iter_mut().enumerate() {
            *b = s.inputs.get(i).copied().unwrap_or(0);
        }
    }

    fn state_change(
        &mut self,
        from: AlState,
        to: AlState,
        _ctx: &DeviceContext,
    ) -> Result<(), AlStatusCode> {
        let mut s = self.state();
        match s.refuse {
            Some((state, code)) if state == to => Err(code),
            _ => {
                s.transitions.push((from, to));
                Ok(())
            }
        }
    }
}

/// One datagram to send.
#[derive(Debug, Clone)]
pub struct Dg {
    /// Command.
    pub command: Command,
    /// Raw address (ADP | ADO << 16, or logical).
    pub address: u32,
    /// Data.
    pub data: Vec<u8>,
}

/// A datagram as it came back.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Back {
    /// Data.
    pub data: Vec<u8>,
    /// Working counter.
    pub wkc: u16,
    /// ADP (low 16 bits of the address).
    pub adp: u16,
    /// IRQ field.
    pub irq: u16,
}

impl Back {
    /// Data as a little-endian u16.
    pub fn u16(&self) -> u16 {
        u16::from_le_bytes([self.data[0], self.data[1]])
    }
    /// Data as a little-endian u32.
    pub fn u32(&self) -> u32 {
        u32::from_le_bytes(self.data[..4].try_into().unwrap())
    }
    /// Data as a little-endian u64.
    pub fn u64(&self) -> u64 {
        u64::from_le_bytes(self.data[..8].try_into().unwrap())
    }
}

/// Datagram constructors.
pub fn dg(command: Command, address: DatagramAddress, data: &[u8]) -> Dg {
    Dg {
        command,
        address: address.to_raw(),
        data: data.to_vec(),
    }
}
/// APxx / ARMW to ring position `p`.
pub fn ap(command: Command, p: u16, ado: u16, data: &[u8]) -> Dg {
    dg(command, DatagramAddress::position(p, ado), data)
}
/// FPxx / FRMW to `station`.
pub fn fp(command: Command, station: u16, ado: u16, data: &[u8]) -> Dg {
    dg(command, DatagramAddress::Node { station, ado }, data)
}
/// Broadcast.
pub fn b(command: Command, ado: u16, data: &[u8]) -> Dg {
    dg(command, DatagramAddress::broadcast(ado), data)
}
/// Logical.
pub fn l(command: Command, address: u32, data: &[u8]) -> Dg {
    dg(command, DatagramAddress::Logical(address), data)
}

/// A segment of slaves with inspectable devices.
pub struct Bench {
    /// The segment.
    pub segment: Segment,
    /// Its time base.
    pub time: ManualTime,
    /// The devices, by position.
    pub devices: Vec<TestDevice>,
}

impl Bench {
    /// `n` standard slaves with echoing devices and default ESCs.
    pub fn new(n: usize) -> Self {
        Self::with(n, |_, _| {})
    }

    /// `n` slaves, each ESC configuration adjusted by `f(position, config)`.
    pub fn with(n: usize, f: impl Fn(usize, &mut EscConfig)) -> Self {
        let mut bench = Bench::empty();
        for p in 0..n {
            let mut config = EscConfig::default();
            f(p, &mut config);
            bench.push(config, sii(0));
        }
        bench
    }

    /// No slaves yet.
    pub fn empty() -> Self {
        let time = ManualTime::new(1_000_000_000);
        Bench {
            segment: Segment::new(Box::new(time.clone())),
            time,
            devices: Vec::new(),
        }
    }

    /// Appends a slave.
    pub fn push(&mut self, config: EscConfig, sii: Vec<u8>) -> TestDevice {
        let device = TestDevice::default();
        device.state().echo = true;
        self.segment
            .push(Esc::new(config, sii), Box::new(device.clone()));
        self.devices.push(device.clone());
        device
    }

    /// The device at position `p`.
    pub fn dev(&self, p: usize) -> MutexGuard<'_, DeviceState> {
        self.devices[p].state()
    }

    /// The ESC at position `p`.
    pub fn esc(&self, p: usize) -> &Esc {
        self.segment.esc(p).unwrap()
    }

    /// Sends one frame; `None` if the segment did not return it.
    pub fn try_send(&mut self, datagrams: &[Dg]) -> Option<Vec<Back>> {
        let mut buf = vec![0u8; MAX_FRAME_LEN];
        let mut builder = FrameBuilder::new(&mut buf).unwrap();
        for (i, d) in datagrams.iter().enumerate() {
            let repr = DatagramRepr {
                address: d.address,
                ..DatagramRepr::request(d.command, i as u8, DatagramAddress::Logical(0), &d.data)
            };
            builder.push(&repr).unwrap();
        }
        let len = builder.finish(MASTER_MAC).unwrap();
        let frame = &mut buf[..len];
        if !self.segment.process(frame) {
            return None;
        }
        let parsed = EthercatFrame::parse(frame).unwrap();
        assert_eq!(
            parsed.ethernet.source[0] & 0x02,
            0x02,
            "returned by a slave"
        );
        let back = parsed
            .datagrams()
            .unwrap()
            .map(|d| {
                let d = d.unwrap();
                Back {
                    data: d.data.to_vec(),
                    wkc: d.wkc,
                    adp: d.address as u16,
                    irq: d.irq,
                }
            })
            .collect();
        Some(back)
    }

    /// Sends one frame that must come back.
    pub fn send(&mut self, datagrams: &[Dg]) -> Vec<Back> {
        self.try_send(datagrams).expect("frame returned")
    }

    /// Sends one datagram.
    pub fn one(&mut self, d: Dg) -> Back {
        self.send(&[d]).remove(0)
    }

    /// Gives every slave its station address (0x1001 + position), as a master does.
    pub fn assign_addresses(&mut self) {
        for p in 0..self.segment.reachable() {
            let r = self.one(ap(
                Command::Apwr,
                p as u16,
                0x0010,
                &station(p).to_le_bytes(),
            ));
            assert_eq!(r.wkc, 1);
        }
    }

    /// Writes AL control of `station` and reads back (AL status, AL status code).
    pub fn request(&mut self, station: u16, control: u16) -> (u16, u16) {
        let r = self.send(&[
            fp(Command::Fpwr, station, 0x0120, &control.to_le_bytes()),
            fp(Command::Fprd, station, 0x0130, &[0; 6]),
        ]);
        assert_eq!(r[0].wkc, 1);
        (r[1].u16(), u16::from_le_bytes([r[1].data[4], r[1].data[5]]))
    }

    /// Configures the mailbox of `station` and brings it to PREOP.
    pub fn bring_to_preop(&mut self, station: u16) {
        assert_eq!(
            self.one(fp(Command::Fpwr, station, 0x0800, &MAILBOX_SMS))
                .wkc,
            1
        );
        assert_eq!(self.request(station, 0x0002), (0x0002, 0));
    }

    /// Writes SM2 (outputs at 0x1100) and SM3 (inputs at 0x1180) of `station`.
    pub fn configure_process_data(&mut self, station: u16, outputs: u16, inputs: u16) {
        let o = outputs.to_le_bytes();
        let i = inputs.to_le_bytes();
        let sms = [
            0x00,
            0x11,
            o[0],
            o[1],
            0x64,
            0x00,
            u8::from(outputs > 0),
            0x00,
            0x80,
            0x11,
            i[0],
            i[1],
            0x20,
            0x00,
            u8::from(inputs > 0),
            0x00,
        ];
        assert_eq!(self.one(fp(Command::Fpwr, station, 0x0810, &sms)).wkc, 1);
    }
}
