//! SoE IDNs from the topology file: TOML → built segment → SoE reads through the ESC's
//! mailbox return the configured elements; bad IDN descriptions are refused when building.

use ecat_link::{Link, MAX_FRAME_LEN, Wait};
use ecat_wire::Emit;
use ecat_wire::command::{Command, DatagramAddress};
use ecat_wire::datagram::{DatagramRepr, FrameBuilder};
use ecat_wire::frame::EthercatFrame;
use ecat_wire::mailbox::{HEADER_LEN, Mailbox, MailboxHeader, MailboxType};
use ecat_wire::soe::{
    ElementFlags, Idn, IdnOrFragments, SoeAttribute, SoeError, SoeOpcode, SoePacket, SoeRepr,
};
use sim::link::InProcessLink;
use sim::topology::{BuildError, IdnSpec, Topology, build};

const STATION: u16 = 0x1001;
/// SM0 at 0x1000 and SM1 at 0x1080, 128 bytes each (the slave below declares 128/128).
const MAILBOX_SMS: [u8; 16] = [
    0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00, 0x80, 0x10, 0x80, 0x00, 0x22, 0x00, 0x01, 0x00,
];

const TOPOLOGY: &str = r#"
[[slave]]
name = "SoE drive pair"
vendor_id = 0xE0000001
product_code = 0x10
mailbox = { rx_size = 128, tx_size = 128 }
protocols = ["soe"]
soe_drives = 2

# A new parameter on both drives, with every element.
[[slave.idn]]
idn = 0x8065
name = "Brake release delay"
attribute = 0x00120001   # factor 1, 4-byte element, unsigned
unit = "ms"
min = [0, 0, 0, 0]
max = [0x10, 0x27, 0, 0]  # 10000
value = [50, 0, 0, 0]
default = [40, 0, 0, 0]

# The default S-0-0032 replaced on drive 1 only.
[[slave.idn]]
idn = 32
drive = 1
name = "Operation mode (drive 1)"
attribute = 0x00310001   # factor 1, 2-byte element, hex
default = [0x0B, 0x00]

# A text list on drive 0 with room to grow.
[[slave.idn]]
idn = 0x8066
drive = 0
name = "Axis label"
attribute = 0x00440001   # 1-byte elements, list, text
value = [65, 120, 105, 115, 32, 88]  # "Axis X"
list_capacity = 32
read_only = true
"#;

struct Master {
    link: InProcessLink,
    counter: u8,
}

impl Master {
    fn fp(&mut self, command: Command, ado: u16, data: &[u8]) -> (Vec<u8>, u16) {
        let mut buf = vec![0u8; MAX_FRAME_LEN];
        let mut builder = FrameBuilder::new(&mut buf).unwrap();
        let address = DatagramAddress::Node {
            station: STATION,
            ado,
        };
        builder
            .push(&DatagramRepr::request(command, 0, address, data))
            .unwrap();
        let len = builder.finish([0, 0, 0, 0, 0, 1]).unwrap();
        self.link.send(&buf[..len]).unwrap();
        let mut rx = vec![0u8; MAX_FRAME_LEN];
        let n = self.link.recv(&mut rx, Wait::NoWait).unwrap().unwrap();
        let frame = EthercatFrame::parse(&rx[..n]).unwrap();
        let d = frame.datagrams().unwrap().next().unwrap().unwrap();
        (d.data.to_vec(), d.wkc)
    }

    /// Station address, mailbox SMs, PREOP, as a master's bring-up does.
    fn new(topology: &Topology) -> Master {
        let mut m = Master {
            link: InProcessLink::new(build(topology).unwrap()),
            counter: 0,
        };
        let mut buf = vec![0u8; MAX_FRAME_LEN];
        let mut builder = FrameBuilder::new(&mut buf).unwrap();
        builder
            .push(&DatagramRepr::request(
                Command::Apwr,
                0,
                DatagramAddress::position(0, 0x0010),
                &STATION.to_le_bytes(),
            ))
            .unwrap();
        let len = builder.finish([0, 0, 0, 0, 0, 1]).unwrap();
        m.link.send(&buf[..len]).unwrap();
        m.link.recv(&mut buf, Wait::NoWait).unwrap().unwrap();
        assert_eq!(m.fp(Command::Fpwr, 0x0800, &MAILBOX_SMS).1, 1);
        assert_eq!(m.fp(Command::Fpwr, 0x0120, &[0x02, 0x00]).1, 1);
        assert_eq!(m.fp(Command::Fprd, 0x0130, &[0, 0]).0[0] & 0x1F, 0x02);
        m
    }

    /// One SoE read request through SM0, its response from SM1.
    fn read(&mut self, drive: u8, idn: u16, elements: ElementFlags) -> Result<Vec<u8>, SoeError> {
        let repr = SoeRepr {
            opcode: SoeOpcode::ReadRequest,
            drive,
            elements,
            idn_or_fragments: IdnOrFragments::Idn(Idn::from_raw(idn)),
            error: None,
            data: &[],
        };
        let soe = repr.to_vec().unwrap();
        self.counter = self.counter % 7 + 1;
        let header = MailboxHeader {
            length: soe.len() as u16,
            address: 0,
            channel: 0,
            priority: 0,
            mailbox_type: MailboxType::Soe,
            counter: self.counter,
        };
        let mut message = vec![0u8; 128];
        header
            .emit(&mut Mailbox::new_unchecked(&mut message[..]))
            .unwrap();
        message[HEADER_LEN..HEADER_LEN + soe.len()].copy_from_slice(&soe);
        assert_eq!(self.fp(Command::Fpwr, 0x1000, &message).1, 1);
        let (status, _) = self.fp(Command::Fprd, 0x080D, &[0]);
        assert_ne!(status[0] & 0x08, 0, "a response in SM1");
        let (reply, wkc) = self.fp(Command::Fprd, 0x1080, &[0; 128]);
        assert_eq!(wkc, 1);
        let header = MailboxHeader::parse(&Mailbox::new_checked(&reply[..]).unwrap()).unwrap();
        assert_eq!(header.mailbox_type, MailboxType::Soe);
        let body = &reply[HEADER_LEN..HEADER_LEN + usize::from(header.length)];
        let response = SoeRepr::parse(&SoePacket::new_checked(body).unwrap()).unwrap();
        assert_eq!(response.opcode, SoeOpcode::ReadResponse);
        assert_eq!(response.drive, drive);
        match response.error {
            Some(code) => Err(code),
            None => Ok(response.data.to_vec()),
        }
    }
}

/// A list element as it travels: current and maximum length, then the bytes.
fn list(bytes: &[u8], capacity: u16) -> Vec<u8> {
    let mut out = (bytes.len() as u16).to_le_bytes().to_vec();
    out.extend_from_slice(&capacity.to_le_bytes());
    out.extend_from_slice(bytes);
    out
}

fn text(s: &str) -> Vec<u8> {
    list(s.as_bytes(), s.len() as u16)
}

fn spec(topology: &Topology, idn: u16, drive: Option<u8>) -> &IdnSpec {
    topology.slaves[0]
        .idns
        .iter()
        .find(|i| i.idn == idn && i.drive == drive)
        .unwrap()
}

#[test]
fn configured_idn_elements_read_back_on_every_drive() {
    let topology = Topology::from_toml(TOPOLOGY).unwrap();
    let idn = spec(&topology, 0x8065, None);
    let mut m = Master::new(&topology);
    for drive in [0, 1] {
        let read = |m: &mut Master, e| m.read(drive, idn.idn, e);
        assert_eq!(read(&mut m, ElementFlags::NAME), Ok(text(&idn.name)));
        let attribute = read(&mut m, ElementFlags::ATTRIBUTE).unwrap();
        assert_eq!(attribute, idn.attribute.to_le_bytes());
        let decoded = SoeAttribute::from_u32(idn.attribute);
        assert_eq!((decoded.element_size, decoded.list), (4, false));
        assert_eq!(
            read(&mut m, ElementFlags::UNIT),
            Ok(text(idn.unit.as_deref().unwrap()))
        );
        assert_eq!(
            read(&mut m, ElementFlags::MINIMUM).as_ref(),
            Ok(idn.min.as_ref().unwrap())
        );
        assert_eq!(
            read(&mut m, ElementFlags::MAXIMUM).as_ref(),
            Ok(idn.max.as_ref().unwrap())
        );
        assert_eq!(
            read(&mut m, ElementFlags::VALUE).as_ref(),
            Ok(idn.value.as_ref().unwrap())
        );
        assert_eq!(
            read(&mut m, ElementFlags::DEFAULT).as_ref(),
            Ok(idn.default.as_ref().unwrap())
        );
    }
}

#[test]
fn an_override_replaces_the_default_idn_on_its_drive_only() {
    let topology = Topology::from_toml(TOPOLOGY).unwrap();
    let idn = spec(&topology, 32, Some(1));
    let mut m = Master::new(&topology);
    // Drive 1: the file's name, and the default as the value (no value given).
    assert_eq!(m.read(1, 32, ElementFlags::NAME), Ok(text(&idn.name)));
    let default = idn.default.clone().unwrap();
    assert_eq!(m.read(1, 32, ElementFlags::VALUE), Ok(default.clone()));
    // Elements the file leaves out are absent (SoE errors 0x4001 unit, 0x5001 minimum).
    assert_eq!(m.read(1, 32, ElementFlags::UNIT), Err(SoeError::NoUnit));
    assert_eq!(
        m.read(1, 32, ElementFlags::MINIMUM),
        Err(SoeError::NoMinimum)
    );
    // Drive 0 keeps the built-in S-0-0032 (its name differs from the override's).
    let name0 = m.read(0, 32, ElementFlags::NAME).unwrap();
    assert_ne!(name0, text(&idn.name));
    // The drive-0-only text list is on drive 0, with its capacity; drive 1 has no such IDN.
    let label = spec(&topology, 0x8066, Some(0));
    assert_eq!(
        m.read(0, 0x8066, ElementFlags::VALUE),
        Ok(list(
            label.value.as_ref().unwrap(),
            label.list_capacity.unwrap()
        ))
    );
    assert_eq!(m.read(1, 0x8066, ElementFlags::VALUE), Err(SoeError::NoIdn));
}

#[test]
fn inconsistent_idn_descriptions_are_refused() {
    let cases = [
        ("value = [1, 2, 3]", "3 bytes, the attribute says 4"),
        ("value = [1, 0, 0, 0]\nmin = [0]", "min has 1 bytes"),
        (
            "attribute = 0x80120001\nvalue = [1, 0, 0, 0]",
            "reserved bits",
        ),
        ("drive = 2\nvalue = [1, 0, 0, 0]", "drive 2"),
        ("unit = \"ms\"", "needs a value or a default"),
    ];
    for (fields, expected) in cases {
        let attribute = if fields.contains("attribute") {
            ""
        } else {
            "attribute = 0x00120001\n"
        };
        let text = TOPOLOGY
            .split("# A new parameter")
            .next()
            .unwrap()
            .to_owned()
            + "[[slave.idn]]\nidn = 0x8070\nname = \"Bad\"\n"
            + attribute
            + fields
            + "\n";
        let topology = Topology::from_toml(&text).unwrap();
        match build(&topology) {
            Err(BuildError::Invalid { reason, .. }) => {
                assert!(reason.contains("IDN 0x8070"), "{reason}");
                assert!(reason.contains(expected), "{fields}: {reason}");
            }
            other => panic!("{fields}: {other:?}"),
        }
    }
}
