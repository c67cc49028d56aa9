//! Helpers for the ESC's unit tests: a standard SII image, a test device, and running one
//! datagram through an ESC.

use ecat_wire::Emit;
use ecat_wire::command::{Command, DatagramAddress};
use ecat_wire::datagram::{Datagram, DatagramRepr};
use ecat_wire::register::al::AlState;
use ecat_wire::register::al_status_code::AlStatusCode;
use ecat_wire::sii::SiiBuilder;
use ecat_wire::sii::fixed::{MailboxProtocols, SiiFixedRepr, SiiMailboxArea};
use ecat_wire::sii::syncm::{SyncmEnable, SyncmEntry, SyncmType};

use crate::device::{Device, DeviceContext, Outbox, ProcessDataSizes};

use super::{Esc, EscConfig};

/// The fixed area of the standard test slave: vendor 2, product 0x1234, 128-byte mailboxes
/// at 0x1000/0x1080, CoE.
pub fn fixed() -> SiiFixedRepr {
    SiiFixedRepr {
        pdi_control: 0x0005,
        vendor_id: 2,
        product_code: 0x1234,
        revision: 1,
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

/// SYNCM entries: SM0/SM1 mailboxes, SM2 outputs at 0x1100, SM3 inputs at 0x1180.
pub fn syncm() -> Vec<SyncmEntry> {
    let entry = |start, length, control, sm_type| SyncmEntry {
        start,
        length,
        control,
        status: 0,
        enable: SyncmEnable(1),
        sm_type,
    };
    vec![
        entry(0x1000, 128, 0x26, SyncmType::MailboxOut),
        entry(0x1080, 128, 0x22, SyncmType::MailboxIn),
        entry(0x1100, 0, 0x64, SyncmType::Outputs),
        entry(0x1180, 0, 0x20, SyncmType::Inputs),
    ]
}

/// A valid image of the standard test slave.
pub fn sii_image() -> Vec<u8> {
    let mut b = SiiBuilder::new(fixed());
    b.syncm = syncm();
    b.build().unwrap()
}

/// A device that echoes mailbox messages, records outputs and counts input reads.
#[derive(Debug, Default)]
pub struct TestDevice {
    /// Process-data sizes it reports.
    pub sizes: ProcessDataSizes,
    /// Mailbox messages received.
    pub received: Vec<Vec<u8>>,
    /// Outputs received.
    pub outputs: Vec<Vec<u8>>,
    /// Number of input reads.
    pub input_reads: u8,
    /// State changes seen.
    pub transitions: Vec<(AlState, AlState)>,
    /// Refuse transitions to this state with this code.
    pub refuse: Option<(AlState, AlStatusCode)>,
}

impl Device for TestDevice {
    fn mailbox_received(&mut self, message: &[u8], _ctx: &DeviceContext, outbox: &mut Outbox) {
        self.received.push(message.to_vec());
        let _ = outbox.push(message.to_vec());
    }

    fn process_data_sizes(&self) -> ProcessDataSizes {
        self.sizes
    }

    fn outputs_written(&mut self, outputs: &[u8]) {
        self.outputs.push(outputs.to_vec());
    }

    fn read_inputs(&mut self, inputs: &mut [u8]) {
        self.input_reads = self.input_reads.wrapping_add(1);
        inputs.fill(self.input_reads);
    }

    fn state_change(
        &mut self,
        from: AlState,
        to: AlState,
        _ctx: &DeviceContext,
    ) -> Result<(), AlStatusCode> {
        match self.refuse {
            Some((state, code)) if state == to => Err(code),
            _ => {
                self.transitions.push((from, to));
                Ok(())
            }
        }
    }
}

/// The standard test slave.
pub fn slave() -> (Esc, TestDevice) {
    slave_with(|_| {})
}

/// The standard test slave with a modified configuration.
pub fn slave_with(f: impl FnOnce(&mut EscConfig)) -> (Esc, TestDevice) {
    let mut config = EscConfig::default();
    f(&mut config);
    (Esc::new(config, sii_image()), TestDevice::default())
}

/// The standard test slave whose SII carries `alias`.
pub fn slave_with_alias(alias: u16) -> (Esc, TestDevice) {
    let mut image = sii_image();
    ecat_wire::sii::set_alias(&mut image, alias).unwrap();
    slave_with_image(image)
}

/// A slave with a given SII image.
pub fn slave_with_image(image: Vec<u8>) -> (Esc, TestDevice) {
    (Esc::new(EscConfig::default(), image), TestDevice::default())
}

/// A datagram after it passed the ESC.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    /// Data.
    pub data: Vec<u8>,
    /// Working counter.
    pub wkc: u16,
    /// ADP.
    pub adp: u16,
    /// IRQ field.
    pub irq: u16,
}

fn run(
    esc: &mut Esc,
    dev: &mut TestDevice,
    command: Command,
    raw_address: u32,
    data: &[u8],
) -> Reply {
    let repr = DatagramRepr {
        address: raw_address,
        ..DatagramRepr::request(command, 0, DatagramAddress::Logical(0), data)
    };
    let mut bytes = repr.to_vec().unwrap();
    let mut dg = Datagram::new_checked(&mut bytes[..]).unwrap();
    esc.process_datagram(&mut dg, dev);
    Reply {
        data: dg.data().to_vec(),
        wkc: dg.wkc(),
        adp: dg.adp(),
        irq: dg.irq(),
    }
}

/// Runs a physical or broadcast datagram.
pub fn exec(
    esc: &mut Esc,
    dev: &mut TestDevice,
    command: Command,
    adp: u16,
    ado: u16,
    data: &[u8],
) -> Reply {
    run(
        esc,
        dev,
        command,
        u32::from(adp) | u32::from(ado) << 16,
        data,
    )
}

/// Runs a logical datagram.
pub fn exec_logical(
    esc: &mut Esc,
    dev: &mut TestDevice,
    command: Command,
    address: u32,
    data: &[u8],
) -> Reply {
    run(esc, dev, command, address, data)
}

/// ETG.1000.4, spec-notes §esc.sm: SM0 at 0x1000 and SM1 at 0x1080, 128 bytes each, enabled.
pub const MAILBOX_SMS: [u8; 16] = [
    0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00, 0x80, 0x10, 0x80, 0x00, 0x22, 0x00, 0x01, 0x00,
];

/// Writes the mailbox SyncManagers.
pub fn configure_mailbox(esc: &mut Esc, dev: &mut TestDevice) {
    assert_eq!(
        exec(esc, dev, Command::Apwr, 0, 0x0800, &MAILBOX_SMS).wkc,
        1
    );
}

/// Writes AL control and returns (AL status, AL status code).
pub fn request(esc: &mut Esc, dev: &mut TestDevice, control: u16) -> (u16, u16) {
    exec(esc, dev, Command::Apwr, 0, 0x0120, &control.to_le_bytes());
    let r = exec(esc, dev, Command::Aprd, 0, 0x0130, &[0; 6]);
    (
        u16::from_le_bytes([r.data[0], r.data[1]]),
        u16::from_le_bytes([r.data[4], r.data[5]]),
    )
}

/// Configures the mailbox and goes to PREOP.
pub fn bring_to_preop(esc: &mut Esc, dev: &mut TestDevice) {
    configure_mailbox(esc, dev);
    assert_eq!(request(esc, dev, 0x0002), (0x0002, 0));
}

/// Writes SM2 (outputs at 0x1100) and SM3 (inputs at 0x1180) with the given lengths.
pub fn configure_process_data(esc: &mut Esc, dev: &mut TestDevice, outputs: u16, inputs: u16) {
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
    assert_eq!(exec(esc, dev, Command::Apwr, 0, 0x0810, &sms).wkc, 1);
}
