//! A UDP client of our own that speaks the layout of the gateway manual's sample clients
//! (docs/gateway.md, "Compatibility layout"): the mailbox type code in bits 7:4 of the type
//! byte (3 CoE, 4 SoE, 5 FoE, 15 VoE), no counter, SoE as op code / drive << 3 | element /
//! IDN, FoE with the file name at offset 5. Its requests are built byte for byte as the
//! manual's Python and Rust clients build theirs (the two build the same bytes for every
//! sample), and [`replay`] sends their seven samples in the manual's order and checks every
//! answer. Shared by the in-process test (master-core) and the ecatd tests (tests/).
#![allow(dead_code)]

use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::time::Duration;

/// The manual's type codes.
pub const COE: u8 = 0x03;
pub const SOE: u8 = 0x04;
pub const FOE: u8 = 0x05;
pub const VOE: u8 = 0x0F;

/// The first slave of the manual's examples (station address 1001).
pub const SLAVE: u16 = 0x03E9;
/// The manual's VoE vendor.
pub const VENDOR: u32 = 0x0000_1164;

/// One reply: the type code from bits 7:4, the rest of its type byte, the address, the data.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CompatReply {
    pub code: u8,
    pub low_nibble: u8,
    pub address: u16,
    pub data: Vec<u8>,
}

/// The client: one UDP socket, as each of the manual's clients has.
pub struct CompatClient {
    pub socket: UdpSocket,
    pub gateway: SocketAddr,
}

impl CompatClient {
    /// A client of the gateway at `gateway`; `wait` is how long it waits for a reply.
    pub fn new(gateway: SocketAddr, wait: Duration) -> CompatClient {
        let socket = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0)).expect("client socket");
        socket.set_read_timeout(Some(wait)).expect("timeout");
        CompatClient { socket, gateway }
    }

    /// The frame of `_build_frame` / `build_frame`: EtherCAT header (length 6 + n, type 5),
    /// mailbox length, address, channel/priority 0, `mb_type << 4`, data.
    pub fn frame(address: u16, mb_type: u8, data: &[u8]) -> Vec<u8> {
        let mb_len = data.len() as u16;
        let ecat_header: u16 = (0x05 << 12) | ((6 + mb_len) & 0x07FF);
        let mut frame = Vec::with_capacity(8 + data.len());
        frame.extend_from_slice(&ecat_header.to_le_bytes());
        frame.extend_from_slice(&mb_len.to_le_bytes());
        frame.extend_from_slice(&address.to_le_bytes());
        frame.push(0x00);
        frame.push(mb_type << 4);
        frame.extend_from_slice(data);
        frame
    }

    /// `send_request`: one datagram out, the next one in.
    pub fn send_request(&self, address: u16, mb_type: u8, data: &[u8]) -> Option<CompatReply> {
        self.socket
            .send_to(&Self::frame(address, mb_type, data), self.gateway)
            .expect("send");
        self.receive()
    }

    /// The next reply, or `None` at the read timeout.
    pub fn receive(&self) -> Option<CompatReply> {
        let mut buf = [0u8; 4096];
        let (len, _) = self.socket.recv_from(&mut buf).ok()?;
        let reply = &buf[..len];
        assert!(len >= 8, "short reply {reply:02X?}");
        let ecat = u16::from_le_bytes([reply[0], reply[1]]);
        assert_eq!(ecat >> 12, 5, "EtherCAT header type");
        let mb_len = usize::from(u16::from_le_bytes([reply[2], reply[3]]));
        assert_eq!(usize::from(ecat & 0x07FF), 6 + mb_len, "lengths agree");
        assert_eq!(len, 8 + mb_len, "the whole message");
        Some(CompatReply {
            code: reply[7] >> 4,
            low_nibble: reply[7] & 0x0F,
            address: u16::from_le_bytes([reply[4], reply[5]]),
            data: reply[8..].to_vec(),
        })
    }

    pub fn coe_sdo_read(&self, address: u16, index: u16, subindex: u8) -> Option<CompatReply> {
        let mut co_data = vec![0u8; 8];
        co_data[1] = 0x20;
        co_data[2] = 0x40;
        co_data[3..5].copy_from_slice(&index.to_le_bytes());
        co_data[5] = subindex;
        self.send_request(address, COE, &co_data)
    }

    pub fn coe_sdo_write(
        &self,
        address: u16,
        index: u16,
        subindex: u8,
        value: &[u8],
    ) -> Option<CompatReply> {
        let mut co_data = vec![0u8; 6 + value.len()];
        co_data[1] = 0x20;
        co_data[2] = 0x20;
        co_data[3..5].copy_from_slice(&index.to_le_bytes());
        co_data[5] = subindex;
        co_data[6..].copy_from_slice(value);
        self.send_request(address, COE, &co_data)
    }

    pub fn soe_read(
        &self,
        address: u16,
        idn: u16,
        drive_no: u8,
        element: u8,
    ) -> Option<CompatReply> {
        let mut soe_data = vec![0u8; 4];
        soe_data[0] = 0x01;
        soe_data[1] = (drive_no << 3) | (element & 0x07);
        soe_data[2..4].copy_from_slice(&idn.to_le_bytes());
        self.send_request(address, SOE, &soe_data)
    }

    pub fn soe_write(
        &self,
        address: u16,
        idn: u16,
        value: &[u8],
        drive_no: u8,
        element: u8,
    ) -> Option<CompatReply> {
        let mut soe_data = vec![0u8; 4 + value.len()];
        soe_data[0] = 0x02;
        soe_data[1] = (drive_no << 3) | (element & 0x07);
        soe_data[2..4].copy_from_slice(&idn.to_le_bytes());
        soe_data[4..].copy_from_slice(value);
        self.send_request(address, SOE, &soe_data)
    }

    pub fn foe_read(&self, address: u16, filename: &str) -> Option<CompatReply> {
        let name = filename.as_bytes();
        let mut foe_data = vec![0u8; 5 + name.len() + 1];
        foe_data[0] = 0x01;
        foe_data[5..5 + name.len()].copy_from_slice(name);
        self.send_request(address, FOE, &foe_data)
    }

    /// An FoE write request in the same layout (the manual lists op code 2).
    pub fn foe_write(&self, address: u16, filename: &str) -> Option<CompatReply> {
        let name = filename.as_bytes();
        let mut foe_data = vec![0u8; 5 + name.len() + 1];
        foe_data[0] = 0x02;
        foe_data[5..5 + name.len()].copy_from_slice(name);
        self.send_request(address, FOE, &foe_data)
    }

    pub fn voe_send(
        &self,
        address: u16,
        vendor_id: u32,
        vendor_type: u16,
        data: &[u8],
    ) -> Option<CompatReply> {
        let mut voe_data = vec![0u8; 6 + data.len()];
        voe_data[0..4].copy_from_slice(&vendor_id.to_le_bytes());
        voe_data[4..6].copy_from_slice(&vendor_type.to_le_bytes());
        voe_data[6..].copy_from_slice(data);
        self.send_request(address, VOE, &voe_data)
    }
}

/// What the replay expects from the segment.
pub struct Expected {
    /// 0x1018:01 of the master's dictionary.
    pub master_vendor_id: u32,
    /// S-0-0032 of the drive before the replay's write.
    pub operation_mode_before: u32,
    /// The first bytes of `firmware.bin`, as many as one FoE packet of the drive holds.
    pub firmware_first_packet: Vec<u8>,
}

/// An expedited SDO upload response (CoE data) for `index:subindex`: its value.
pub fn upload_value(reply: &CompatReply, index: u16, subindex: u8) -> Vec<u8> {
    assert_eq!((reply.code, reply.low_nibble), (COE, 0), "{reply:02X?}");
    let d = &reply.data;
    assert!(d.len() >= 10, "{reply:02X?}");
    assert_eq!(d[1] >> 4, 3, "CoE service 3 (SDO response): {reply:02X?}");
    assert_eq!(
        d[2] & 0xE3,
        0x43,
        "expedited upload response with size: {reply:02X?}"
    );
    assert_eq!(u16::from_le_bytes([d[3], d[4]]), index);
    assert_eq!(d[5], subindex);
    let size = 4 - usize::from((d[2] >> 2) & 0x03);
    d[6..6 + size].to_vec()
}

/// Replays the manual's seven samples, in its order, and checks each answer; returns the
/// answers.
pub fn replay(client: &CompatClient, expected: &Expected) -> Vec<CompatReply> {
    let mut answers = Vec::new();
    // CoE: the master's 0x1018:01 at address 0.
    let r = client
        .coe_sdo_read(0x0000, 0x1018, 0x01)
        .expect("0x1018:01 answer");
    assert_eq!(r.address, 0);
    assert_eq!(
        upload_value(&r, 0x1018, 1),
        expected.master_vendor_id.to_le_bytes()
    );
    answers.push(r);
    // CoE: 0x6040 read and written on the first slave.
    let r = client
        .coe_sdo_read(SLAVE, 0x6040, 0x00)
        .expect("0x6040 answer");
    assert_eq!(r.address, SLAVE);
    assert_eq!(upload_value(&r, 0x6040, 0).len(), 2);
    answers.push(r);
    let r = client
        .coe_sdo_write(SLAVE, 0x6040, 0x00, &0x0006u16.to_le_bytes())
        .expect("0x6040 write answer");
    assert_eq!((r.code, r.low_nibble), (COE, 0), "{r:02X?}");
    assert_eq!(
        r.data[..6],
        [0x00, 0x30, 0x60, 0x40, 0x60, 0x00],
        "download response for 0x6040:00: {r:02X?}"
    );
    answers.push(r);
    // SoE: S-0-0032, value element, drive 0: read, write 1000, read back.
    let r = client
        .soe_read(SLAVE, 32, 0, 0x05)
        .expect("S-0-0032 answer");
    assert_eq!((r.code, r.low_nibble), (SOE, 0), "{r:02X?}");
    assert_eq!(
        r.data[..4],
        [0x01, 0x05, 0x20, 0x00],
        "read, no error: {r:02X?}"
    );
    assert_eq!(r.data[4..], expected.operation_mode_before.to_le_bytes());
    answers.push(r);
    let r = client
        .soe_write(SLAVE, 32, &1000u32.to_le_bytes(), 0, 0x05)
        .expect("S-0-0032 write answer");
    assert_eq!((r.code, r.low_nibble), (SOE, 0), "{r:02X?}");
    assert_eq!(
        r.data[..4],
        [0x02, 0x05, 0x20, 0x00],
        "write, no error: {r:02X?}"
    );
    answers.push(r);
    let back = client.soe_read(SLAVE, 32, 0, 0x05).expect("S-0-0032 again");
    assert_eq!(
        back.data[4..],
        1000u32.to_le_bytes(),
        "the write took effect"
    );
    // FoE: the first packet of firmware.bin.
    let r = client.foe_read(SLAVE, "firmware.bin").expect("FoE answer");
    assert_eq!((r.code, r.low_nibble), (FOE, 0), "{r:02X?}");
    assert_eq!(r.data[..5], [0x03, 1, 0, 0, 0], "DATA packet 1: {r:02X?}");
    assert_eq!(r.data[5..], expected.firmware_first_packet[..]);
    answers.push(r);
    // VoE: vendor 0x1164, type 1, data 01 02; the simulated slave answers it inverted.
    let r = client
        .voe_send(SLAVE, VENDOR, 0x0001, &[0x01, 0x02])
        .expect("VoE answer");
    assert_eq!((r.code, r.low_nibble), (VOE, 0), "{r:02X?}");
    assert_eq!(r.data, [0x64, 0x11, 0, 0, 0x01, 0x00, 0xFE, 0xFD]);
    answers.push(r);
    answers
}
