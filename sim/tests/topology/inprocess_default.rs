//! The default topology through `InProcessLink`, driven by hand with frames built by the
//! master's codecs: what a master sees when it opens the simulator.

use ecat_link::{Link, MAX_FRAME_LEN, Wait};
use ecat_wire::Emit;
use ecat_wire::coe::sdo::SdoFrame;
use ecat_wire::coe::sdo_payload::SdoPayload;
use ecat_wire::coe::sdo_request::SdoRequest;
use ecat_wire::coe::sdo_response::SdoResponse;
use ecat_wire::command::{Command, DatagramAddress};
use ecat_wire::datagram::{DatagramRepr, FrameBuilder};
use ecat_wire::frame::EthercatFrame;
use ecat_wire::mailbox::{HEADER_LEN, Mailbox, MailboxHeader, MailboxType};
use sim::device::coe::lock_dictionary;
use sim::link::InProcessLink;
use sim::topology::{SIM_VENDOR_ID, Topology, build_with_handles};

const STATION: u16 = 0x1001;
/// SM0 at 0x1000 and SM1 at 0x1080, 128 bytes each, enabled (as the drive's SII says).
const MAILBOX_SMS: [u8; 16] = [
    0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00, 0x80, 0x10, 0x80, 0x00, 0x22, 0x00, 0x01, 0x00,
];

struct Master {
    link: InProcessLink,
    counter: u8,
}

impl Master {
    /// Sends one frame of datagrams; returns (data, wkc) per datagram.
    fn exchange(
        &mut self,
        datagrams: &[(Command, DatagramAddress, Vec<u8>)],
    ) -> Vec<(Vec<u8>, u16)> {
        let mut buf = vec![0u8; MAX_FRAME_LEN];
        let mut builder = FrameBuilder::new(&mut buf).unwrap();
        for (i, (command, address, data)) in datagrams.iter().enumerate() {
            builder
                .push(&DatagramRepr::request(*command, i as u8, *address, data))
                .unwrap();
        }
        let len = builder.finish([0, 0, 0, 0, 0, 1]).unwrap();
        self.link.send(&buf[..len]).unwrap();
        let mut rx = vec![0u8; MAX_FRAME_LEN];
        let n = self
            .link
            .recv(&mut rx, Wait::NoWait)
            .unwrap()
            .expect("frame returned");
        let frame = EthercatFrame::parse(&rx[..n]).unwrap();
        frame
            .datagrams()
            .unwrap()
            .map(|d| {
                let d = d.unwrap();
                (d.data.to_vec(), d.wkc)
            })
            .collect()
    }

    fn fp(&mut self, command: Command, ado: u16, data: Vec<u8>) -> (Vec<u8>, u16) {
        let address = DatagramAddress::Node {
            station: STATION,
            ado,
        };
        self.exchange(&[(command, address, data)]).remove(0)
    }

    /// Station address, mailbox SMs, INIT → PREOP for the drive at position 0.
    fn bring_up_drive(&mut self) {
        let (_, wkc) = self
            .exchange(&[(
                Command::Apwr,
                DatagramAddress::position(0, 0x0010),
                STATION.to_le_bytes().to_vec(),
            )])
            .remove(0);
        assert_eq!(wkc, 1);
        assert_eq!(self.fp(Command::Fpwr, 0x0800, MAILBOX_SMS.to_vec()).1, 1);
        assert_eq!(
            self.fp(Command::Fpwr, 0x0120, 0x0002u16.to_le_bytes().to_vec())
                .1,
            1
        );
        let (status, _) = self.fp(Command::Fprd, 0x0130, vec![0; 6]);
        assert_eq!(status[0] & 0x1F, 0x02, "PREOP, no error");
    }

    /// Writes one CoE request into SM0 and reads the reply from SM1.
    fn coe(&mut self, data: &[u8]) -> Vec<u8> {
        self.counter = self.counter % 7 + 1;
        let header = MailboxHeader {
            length: data.len() as u16,
            address: 0,
            channel: 0,
            priority: 0,
            mailbox_type: MailboxType::Coe,
            counter: self.counter,
        };
        let mut message = vec![0u8; 128];
        let mut view = Mailbox::new_unchecked(&mut message[..]);
        header.emit(&mut view).unwrap();
        message[HEADER_LEN..HEADER_LEN + data.len()].copy_from_slice(data);
        assert_eq!(self.fp(Command::Fpwr, 0x1000, message).1, 1);
        for _ in 0..8 {
            let (sm1_status, _) = self.fp(Command::Fprd, 0x080D, vec![0]);
            if sm1_status[0] & 0x08 != 0 {
                let (reply, wkc) = self.fp(Command::Fprd, 0x1080, vec![0; 128]);
                assert_eq!(wkc, 1);
                let view = Mailbox::new_checked(&reply[..]).unwrap();
                let header = MailboxHeader::parse(&view).unwrap();
                assert_eq!(header.mailbox_type, MailboxType::Coe);
                return reply[HEADER_LEN..HEADER_LEN + usize::from(header.length)].to_vec();
            }
        }
        panic!("no reply in SM1");
    }

    fn sdo(&mut self, request: SdoRequest<'_>) -> Vec<u8> {
        let data = request.to_vec().unwrap();
        self.coe(&data)
    }

    /// A complete SDO upload (expedited or segmented).
    fn upload(&mut self, index: u16, subindex: u8) -> Vec<u8> {
        let reply = self.sdo(SdoRequest::InitiateUpload {
            index,
            subindex,
            complete_access: false,
        });
        let frame = SdoFrame::new_checked(&reply[..]).unwrap();
        let (mut value, total) = match SdoResponse::parse(&frame).unwrap() {
            SdoResponse::InitiateUpload { payload, .. } => match payload {
                SdoPayload::Expedited(bytes) => return bytes.to_vec(),
                SdoPayload::Normal {
                    complete_size,
                    data,
                } => (data.to_vec(), complete_size),
                other => panic!("unexpected payload {other:?}"),
            },
            other => panic!("unexpected response {other:?}"),
        };
        let mut toggle = false;
        while value.len() < total as usize {
            let reply = self.sdo(SdoRequest::UploadSegment { toggle });
            let frame = SdoFrame::new_checked(&reply[..]).unwrap();
            match SdoResponse::parse(&frame).unwrap() {
                SdoResponse::UploadSegment {
                    toggle: t,
                    last,
                    data,
                } => {
                    assert_eq!(t, toggle);
                    value.extend_from_slice(data);
                    if last {
                        break;
                    }
                }
                other => panic!("unexpected response {other:?}"),
            }
            toggle = !toggle;
        }
        value
    }
}

fn master() -> (Master, Vec<sim::topology::SlaveHandles>) {
    let built = build_with_handles(&Topology::default_segment()).unwrap();
    let master = Master {
        link: InProcessLink::new(built.segment),
        counter: 0,
    };
    (master, built.slaves)
}

#[test]
fn broadcast_read_counts_five_slaves() {
    let (mut m, _) = master();
    let r = m.exchange(&[(Command::Brd, DatagramAddress::broadcast(0x0000), vec![0; 2])]);
    assert_eq!(r[0].1, 5);
}

#[test]
fn drive_answers_identity_over_the_mailbox() {
    let (mut m, _) = master();
    m.bring_up_drive();
    let vendor = m.upload(0x1018, 1);
    assert_eq!(vendor, SIM_VENDOR_ID.to_le_bytes());
    let name = m.upload(0x1008, 0);
    assert_eq!(name, b"ECATD-SIM Drive");
}

#[test]
fn large_object_uploads_segmented_with_its_pattern() {
    let (mut m, _) = master();
    // Slave 3 (the CoE store) gets the station address instead of the drive.
    let (_, wkc) = m
        .exchange(&[(
            Command::Apwr,
            DatagramAddress::position(3, 0x0010),
            STATION.to_le_bytes().to_vec(),
        )])
        .remove(0);
    assert_eq!(wkc, 1);
    assert_eq!(m.fp(Command::Fpwr, 0x0800, MAILBOX_SMS.to_vec()).1, 1);
    assert_eq!(
        m.fp(Command::Fpwr, 0x0120, 0x0002u16.to_le_bytes().to_vec())
            .1,
        1
    );
    let value = m.upload(0x2000, 0);
    let expected: Vec<u8> = (0..4096).map(|i| (i % 251) as u8).collect();
    assert_eq!(value, expected);
}

#[test]
fn one_download_is_counted_once() {
    let (mut m, handles) = master();
    m.bring_up_drive();
    let reply = m.sdo(SdoRequest::InitiateDownload {
        index: 0x607A,
        subindex: 0,
        complete_access: false,
        payload: SdoPayload::Expedited(&1234i32.to_le_bytes()),
    });
    let frame = SdoFrame::new_checked(&reply[..]).unwrap();
    assert!(matches!(
        SdoResponse::parse(&frame).unwrap(),
        SdoResponse::InitiateDownload { index: 0x607A, .. }
    ));
    let dict = handles[0].dictionary.clone().unwrap();
    let dict = lock_dictionary(&dict);
    assert_eq!(dict.write_count(0x607A), 1);
    assert_eq!(dict.get::<i32>(0x607A, 0).unwrap(), 1234);
}
