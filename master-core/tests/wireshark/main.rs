//! Wireshark agrees with our codecs.
//!
//! Frames of every kind the wire layer can build are written to a pcap file and decoded by
//! `tshark`: no frame may be malformed or carry an error-level expert item, and the fields
//! Wireshark decodes must equal what we encoded. Wireshark's EtherCAT dissectors are an
//! authority independent of our master and simulator, which share these codecs.

mod tshark;

use std::collections::BTreeMap;

use master_core::wire::command::{Command, DatagramAddress};
use master_core::wire::datagram::{DatagramRepr, FrameBuilder};

const SOURCE_MAC: [u8; 6] = [0x02, 0x00, 0x00, 0x00, 0x00, 0x01];

/// One frame of the capture and the fields Wireshark must decode from it.
struct Case {
    what: String,
    frame: Vec<u8>,
    expect: Vec<(&'static str, String)>,
}

/// A frame holding the given datagrams.
fn frame(datagrams: &[DatagramRepr<'_>]) -> Vec<u8> {
    let mut buf = vec![0u8; 1514];
    let mut builder = FrameBuilder::new(&mut buf).expect("frame buffer");
    for d in datagrams {
        builder.push(d).expect("datagram fits");
    }
    let len = builder.finish(SOURCE_MAC).expect("finish frame");
    buf.truncate(len);
    buf
}

fn hex8(v: u8) -> String {
    format!("0x{v:02x}")
}
fn hex16(v: u16) -> String {
    format!("0x{v:04x}")
}

/// One datagram of every command, with the address form that command uses.
fn datagram_cases() -> Vec<Case> {
    let all = [
        Command::Nop,
        Command::Aprd,
        Command::Apwr,
        Command::Aprw,
        Command::Fprd,
        Command::Fpwr,
        Command::Fprw,
        Command::Brd,
        Command::Bwr,
        Command::Brw,
        Command::Lrd,
        Command::Lwr,
        Command::Lrw,
        Command::Armw,
        Command::Frmw,
    ];
    let data = [0x11u8, 0x22, 0x33, 0x44];
    all.iter()
        .enumerate()
        .map(|(i, &command)| {
            let index = 0x40 + i as u8;
            let (address, mut expect) = match command {
                Command::Aprd | Command::Apwr | Command::Aprw | Command::Armw => (
                    DatagramAddress::position(2, 0x0130),
                    vec![("ecat.adp", hex16(0xfffe)), ("ecat.ado", hex16(0x0130))],
                ),
                Command::Fprd | Command::Fprw | Command::Fpwr | Command::Frmw => (
                    DatagramAddress::Node {
                        station: 0x03e9,
                        ado: 0x0910,
                    },
                    vec![("ecat.adp", hex16(0x03e9)), ("ecat.ado", hex16(0x0910))],
                ),
                Command::Brd | Command::Bwr | Command::Brw | Command::Nop => (
                    DatagramAddress::broadcast(0x0000),
                    vec![("ecat.ado", hex16(0x0000))],
                ),
                _ => (
                    DatagramAddress::Logical(0x0001_1000),
                    vec![("ecat.lad", "0x00011000".to_owned())],
                ),
            };
            expect.push(("ecat.cmd", hex8(u8::from(command))));
            expect.push(("ecat.idx", hex8(index)));
            Case {
                what: format!("{} datagram", command.name()),
                frame: frame(&[DatagramRepr::request(command, index, address, &data)]),
                expect,
            }
        })
        .collect()
}

/// Several datagrams in one frame: the seed capture's cyclic frame (LRD inputs, LWR outputs,
/// LRD of the mapped mailbox-status bit, FRMW of the reference clock).
fn cyclic_frame_case() -> Case {
    let inputs = [0u8; 2];
    let outputs = [0xaa, 0x55];
    let status = [0u8; 1];
    let dc = [0u8; 8];
    let frame = frame(&[
        DatagramRepr::request(
            Command::Lrd,
            0x10,
            DatagramAddress::Logical(0x11000),
            &inputs,
        ),
        DatagramRepr::request(
            Command::Lwr,
            0x11,
            DatagramAddress::Logical(0x12000),
            &outputs,
        ),
        DatagramRepr::request(
            Command::Lrd,
            0x12,
            DatagramAddress::Logical(0x40000),
            &status,
        ),
        DatagramRepr::request(
            Command::Frmw,
            0x13,
            DatagramAddress::Node {
                station: 0x03e9,
                ado: 0x0910,
            },
            &dc,
        ),
    ]);
    Case {
        what: "cyclic frame".to_owned(),
        frame,
        expect: vec![
            ("ecat.cmd", "0x0a,0x0b,0x0a,0x0e".to_owned()),
            ("ecat.idx", "0x10,0x11,0x12,0x13".to_owned()),
        ],
    }
}

fn all_cases() -> Vec<Case> {
    let mut cases = datagram_cases();
    cases.push(cyclic_frame_case());
    cases
}

#[test]
fn wireshark_decodes_every_frame_kind_as_encoded() {
    let cases = all_cases();
    let frames: Vec<Vec<u8>> = cases.iter().map(|c| c.frame.clone()).collect();
    let capture = tshark::Capture::write("every-kind", &frames);

    let flagged = tshark::flagged_frames(&capture);
    assert!(
        flagged.is_empty(),
        "Wireshark flags frames {flagged:?} as malformed or erroneous:\n{}",
        tshark::verbose(&capture)
    );
    let verbose = tshark::verbose(&capture);
    assert!(
        !verbose.contains("Malformed"),
        "malformed packet in:\n{verbose}"
    );
    assert!(
        !verbose.contains("[Expert Info (Error"),
        "expert error in:\n{verbose}"
    );

    let mut names: Vec<&str> = cases
        .iter()
        .flat_map(|c| c.expect.iter().map(|(k, _)| *k))
        .collect();
    names.sort_unstable();
    names.dedup();
    let decoded: Vec<BTreeMap<String, String>> = tshark::fields(&capture, &names);
    assert_eq!(decoded.len(), cases.len(), "one decoded line per frame");

    let mut mismatches = Vec::new();
    for (case, fields) in cases.iter().zip(&decoded) {
        for (name, want) in &case.expect {
            let got = fields.get(*name).map(String::as_str).unwrap_or("<absent>");
            if !got.eq_ignore_ascii_case(want) {
                mismatches.push(format!("{}: {name} = {got}, encoded {want}", case.what));
            }
        }
    }
    assert!(
        mismatches.is_empty(),
        "Wireshark disagrees:\n{}",
        mismatches.join("\n")
    );
}
