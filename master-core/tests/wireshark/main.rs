//! Wireshark agrees with our codecs.
//!
//! Frames of every kind the wire layer can build are written to a pcap file and decoded by
//! `tshark`: no frame may be malformed or carry an error-level expert item, and the fields
//! Wireshark decodes must equal what we encoded. Wireshark's EtherCAT dissectors are an
//! authority independent of our master and simulator, which share these codecs.

#[path = "../tshark_support/mod.rs"]
mod tshark;

use std::collections::BTreeMap;

use std::net::Ipv4Addr;

use master_core::wire::Emit;
use master_core::wire::coe::info::{
    ObjectDescription, OdList, OdListType, SdoInfoRepr, SdoInfoService,
};
use master_core::wire::coe::{AbortCode, CoeRepr, DataType, ObjectCode, SdoPayload};
use master_core::wire::coe::{SdoRequest, SdoResponse};
use master_core::wire::command::{Command, DatagramAddress};
use master_core::wire::datagram::{DatagramRepr, FrameBuilder};
use master_core::wire::eoe::{EoeRepr, FragmentRepr, IpParameters};
use master_core::wire::foe::{FoeError, FoeRepr};
use master_core::wire::gateway::GatewayRepr;
use master_core::wire::mailbox::{
    ErrorReplyRepr, MailboxErrorCode, MailboxHeader, MailboxMessage, MailboxPayload,
};
use master_core::wire::soe::{ElementFlags, Idn, IdnOrFragments, SoeOpcode, SoeRepr};
use master_core::wire::voe::VoeRepr;

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

/// Several datagrams in one frame: the reference capture's cyclic frame (LRD inputs, LWR outputs,
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

/// Size of the simulated SyncManager mailboxes the mailbox datagrams carry.
const MAILBOX_SIZE: usize = 128;
const SM0: u16 = 0x1000;
const SM1: u16 = 0x1080;

fn mailbox_bytes(payload: MailboxPayload<'_>, counter: u8) -> Vec<u8> {
    let mailbox_type = payload.natural_type().expect("typed payload");
    let message = MailboxMessage {
        header: MailboxHeader {
            length: 0,
            address: 0,
            channel: 0,
            priority: 0,
            mailbox_type,
            counter,
        },
        payload,
    };
    message.to_vec().expect("emit mailbox")
}

/// A mailbox message as the master writes it (FPWR of the whole SM0) or reads it (FPRD of
/// the whole SM1), padded to the mailbox size like on a real bus.
fn mailbox_frame(message: &[u8], to_slave: bool) -> Vec<u8> {
    let mut sm = message.to_vec();
    sm.resize(MAILBOX_SIZE.max(message.len()), 0);
    // A read shows the slave's answer only once the slave has answered (WKC 1), which is
    // also when Wireshark decodes it as a mailbox.
    let (command, ado, wkc) = if to_slave {
        (Command::Fpwr, SM0, 0)
    } else {
        (Command::Fprd, SM1, 1)
    };
    let mut datagram = DatagramRepr::request(
        command,
        0x21,
        DatagramAddress::Node {
            station: 0x03e9,
            ado,
        },
        &sm,
    );
    datagram.wkc = wkc;
    frame(&[datagram])
}

/// The same mailbox message as an ETG.8200 gateway UDP datagram to port 34980.
fn gateway_frame(message: &[u8]) -> Vec<u8> {
    let parsed = MailboxMessage::parse(message).expect("valid mailbox");
    let repr = GatewayRepr {
        header: parsed.header,
        data: &message[6..],
    };
    let payload = repr.to_vec().expect("emit gateway message");
    let builder = etherparse::PacketBuilder::ethernet2(SOURCE_MAC, [0x02, 0, 0, 0, 0, 2])
        .ipv4([127, 0, 0, 1], [127, 0, 0, 1], 64)
        .udp(40000, 34980);
    let mut out = Vec::with_capacity(builder.size(payload.len()));
    builder.write(&mut out, &payload).expect("UDP frame");
    out
}

fn mailbox_case(
    what: &str,
    payload: MailboxPayload<'_>,
    to_slave: bool,
    expect: Vec<(&'static str, String)>,
) -> Vec<Case> {
    let message = mailbox_bytes(payload, 1);
    let mailbox_type = MailboxMessage::parse(&message)
        .expect("reparse")
        .header
        .mailbox_type;
    let mut with_type = expect.clone();
    with_type.push(("ecat_mailbox.type", u8::from(mailbox_type).to_string()));
    vec![
        Case {
            what: format!("{what} in a datagram"),
            frame: mailbox_frame(&message, to_slave),
            expect: with_type.clone(),
        },
        Case {
            what: format!("{what} through the ETG.8200 gateway"),
            frame: gateway_frame(&message),
            expect: with_type,
        },
    ]
}

fn coe(repr: CoeRepr<'_>) -> MailboxPayload<'_> {
    MailboxPayload::Coe(repr)
}

fn sdo_fields(index: u16, subindex: u8, service: u8) -> Vec<(&'static str, String)> {
    vec![
        ("ecat_mailbox.coe.sdoidx", hex16(index)),
        ("ecat_mailbox.coe.sdosub", hex8(subindex)),
        ("ecat_mailbox.coe.type", service.to_string()),
    ]
}

fn coe_cases() -> Vec<Case> {
    let value = [0x34u8, 0x12];
    let long = [0x5au8; 100];
    let mut cases = Vec::new();
    cases.extend(mailbox_case(
        "CoE upload request",
        coe(CoeRepr::SdoRequest(SdoRequest::InitiateUpload {
            index: 0x1018,
            subindex: 1,
            complete_access: false,
        })),
        true,
        sdo_fields(0x1018, 1, 2),
    ));
    cases.extend(mailbox_case(
        "CoE upload response (expedited)",
        coe(CoeRepr::SdoResponse(SdoResponse::InitiateUpload {
            index: 0x1018,
            subindex: 1,
            complete_access: false,
            payload: SdoPayload::Expedited(&[0x02, 0, 0, 0]),
        })),
        false,
        sdo_fields(0x1018, 1, 3),
    ));
    cases.extend(mailbox_case(
        "CoE download request (expedited)",
        coe(CoeRepr::SdoRequest(SdoRequest::InitiateDownload {
            index: 0x6040,
            subindex: 0,
            complete_access: false,
            payload: SdoPayload::Expedited(&value),
        })),
        true,
        sdo_fields(0x6040, 0, 2),
    ));
    cases.extend(mailbox_case(
        "CoE download response",
        coe(CoeRepr::SdoResponse(SdoResponse::InitiateDownload {
            index: 0x6040,
            subindex: 0,
            complete_access: false,
        })),
        false,
        sdo_fields(0x6040, 0, 3),
    ));
    cases.extend(mailbox_case(
        "CoE normal download request",
        coe(CoeRepr::SdoRequest(SdoRequest::InitiateDownload {
            index: 0x2000,
            subindex: 0,
            complete_access: false,
            payload: SdoPayload::Normal {
                complete_size: 200,
                data: &long,
            },
        })),
        true,
        sdo_fields(0x2000, 0, 2),
    ));
    cases.extend(mailbox_case(
        "CoE download segment request",
        coe(CoeRepr::SdoRequest(SdoRequest::DownloadSegment {
            toggle: false,
            last: true,
            data: &long,
        })),
        true,
        vec![("ecat_mailbox.coe.type", "2".to_owned())],
    ));
    cases.extend(mailbox_case(
        "CoE upload segment response",
        coe(CoeRepr::SdoResponse(SdoResponse::UploadSegment {
            toggle: true,
            last: true,
            data: &long[..3],
        })),
        false,
        vec![("ecat_mailbox.coe.type", "3".to_owned())],
    ));
    cases.extend(mailbox_case(
        "CoE abort request",
        coe(CoeRepr::SdoRequest(SdoRequest::Abort {
            index: 0x2000,
            subindex: 0,
            code: AbortCode::from(0x0504_0000),
        })),
        true,
        // Wireshark decodes an abort's code, not its index and subindex.
        vec![
            ("ecat_mailbox.coe.type", "2".to_owned()),
            ("ecat_mailbox.coe.abortcode", "0x05040000".to_owned()),
        ],
    ));
    // Wireshark 4.0 shows an abort *response* only as "SDO Res: Scs 4", without index or code.
    cases.extend(mailbox_case(
        "CoE abort response",
        coe(CoeRepr::SdoResponse(SdoResponse::Abort {
            index: 0x2000,
            subindex: 0,
            code: AbortCode::from(0x0602_0000),
        })),
        false,
        vec![("ecat_mailbox.coe.type", "3".to_owned())],
    ));
    cases.extend(mailbox_case(
        "CoE SDO Information OD list request",
        coe(CoeRepr::SdoInfo(SdoInfoRepr {
            incomplete: false,
            fragments_left: 0,
            service: SdoInfoService::OdListRequest {
                list_type: OdListType::from(1),
            },
        })),
        true,
        vec![
            ("ecat_mailbox.coe.type", "8".to_owned()),
            ("ecat_mailbox.coe.sdoinfoopcode", "1".to_owned()),
        ],
    ));
    cases.extend(mailbox_case(
        "CoE SDO Information OD list response",
        coe(CoeRepr::SdoInfo(SdoInfoRepr {
            incomplete: false,
            fragments_left: 0,
            service: SdoInfoService::OdListResponse(OdList(&[0x01, 0x00, 0x00, 0x10, 0x18, 0x10])),
        })),
        false,
        vec![
            ("ecat_mailbox.coe.type", "8".to_owned()),
            ("ecat_mailbox.coe.sdoinfoopcode", "2".to_owned()),
        ],
    ));
    cases.extend(mailbox_case(
        "CoE SDO Information object description response",
        coe(CoeRepr::SdoInfo(SdoInfoRepr {
            incomplete: false,
            fragments_left: 0,
            service: SdoInfoService::ObjectDescriptionResponse(ObjectDescription {
                index: 0x1018,
                data_type: DataType::from(0x0023),
                max_subindex: 4,
                object_code: ObjectCode::from(9),
                name: b"Identity",
            }),
        })),
        false,
        vec![
            ("ecat_mailbox.coe.sdoinfoopcode", "4".to_owned()),
            ("ecat_mailbox.coe.sdoinfoindex", hex16(0x1018)),
            ("ecat_mailbox.coe.sdoinfoname", "Identity".to_owned()),
        ],
    ));
    cases
}

fn soe_cases() -> Vec<Case> {
    let idn = Idn::new(false, 0, 24).expect("S-0-0024");
    let read = SoeRepr {
        opcode: SoeOpcode::ReadRequest,
        drive: 0,
        elements: ElementFlags::VALUE,
        idn_or_fragments: IdnOrFragments::Idn(idn),
        error: None,
        data: &[],
    };
    let write = SoeRepr {
        opcode: SoeOpcode::WriteRequest,
        data: &[0x10, 0x27, 0x00, 0x00],
        ..read
    };
    let fields = |opcode: u8| {
        vec![
            ("ecat_mailbox.soe_opcode", opcode.to_string()),
            ("ecat_mailbox.soe_idn", hex16(idn.raw())),
        ]
    };
    let mut cases = mailbox_case(
        "SoE read request",
        MailboxPayload::Soe(read),
        true,
        fields(1),
    );
    cases.extend(mailbox_case(
        "SoE read response",
        MailboxPayload::Soe(SoeRepr {
            opcode: SoeOpcode::ReadResponse,
            data: &[0x01, 0x02],
            ..read
        }),
        false,
        fields(2),
    ));
    cases.extend(mailbox_case(
        "SoE write request",
        MailboxPayload::Soe(write),
        true,
        fields(3),
    ));
    cases.extend(mailbox_case(
        "SoE write response",
        MailboxPayload::Soe(SoeRepr {
            opcode: SoeOpcode::WriteResponse,
            data: &[],
            ..read
        }),
        false,
        fields(4),
    ));
    cases
}

fn foe_cases() -> Vec<Case> {
    let data = [0xc3u8; 40];
    let op = |code: u8| vec![("ecat_mailbox.foe_opmode", hex8(code))];
    let with = |code: u8, extra: (&'static str, String)| {
        let mut v = op(code);
        v.push(extra);
        v
    };
    let mut cases = Vec::new();
    cases.extend(mailbox_case(
        "FoE read request",
        MailboxPayload::Foe(FoeRepr::ReadRequest {
            password: 0,
            file_name: b"firmware.bin",
        }),
        true,
        with(1, ("ecat_mailbox.foe_filename", "firmware.bin".to_owned())),
    ));
    cases.extend(mailbox_case(
        "FoE write request",
        MailboxPayload::Foe(FoeRepr::WriteRequest {
            password: 0,
            file_name: b"fw.bin",
        }),
        true,
        with(2, ("ecat_mailbox.foe_filename", "fw.bin".to_owned())),
    ));
    cases.extend(mailbox_case(
        "FoE data",
        MailboxPayload::Foe(FoeRepr::Data {
            packet: 1,
            data: &data,
        }),
        true,
        with(3, ("ecat_mailbox.foe_packetno", "1".to_owned())),
    ));
    cases.extend(mailbox_case(
        "FoE ack",
        MailboxPayload::Foe(FoeRepr::Ack { packet: 7 }),
        false,
        with(4, ("ecat_mailbox.foe_packetno", "7".to_owned())),
    ));
    cases.extend(mailbox_case(
        "FoE error",
        MailboxPayload::Foe(FoeRepr::Error {
            code: FoeError::from(0x8001),
            text: b"not found",
        }),
        false,
        with(5, ("ecat_mailbox.foe_errcode", "32769".to_owned())),
    ));
    cases.extend(mailbox_case(
        "FoE busy",
        MailboxPayload::Foe(FoeRepr::Busy {
            done: 3,
            entire: 10,
            text: b"",
        }),
        false,
        with(6, ("ecat_mailbox.foe_busydone", hex16(3))),
    ));
    cases
}

fn eoe_cases() -> Vec<Case> {
    let ethernet: Vec<u8> = (0..100u8).collect();
    let mut cases = mailbox_case(
        "EoE fragment",
        MailboxPayload::Eoe(EoeRepr::Fragment(FragmentRepr {
            port: 0,
            last: true,
            time_request: false,
            fragment_number: 0,
            offset_field: 4,
            frame_number: 3,
            data: &ethernet,
            timestamp: None,
        })),
        true,
        vec![
            ("ecat_mailbox.eoe.type", "0".to_owned()),
            ("ecat_mailbox.eoe.frame", "3".to_owned()),
        ],
    );
    cases.extend(mailbox_case(
        "EoE set IP request",
        MailboxPayload::Eoe(EoeRepr::SetIpRequest {
            port: 0,
            params: IpParameters {
                mac: Some([0x02, 0x00, 0x00, 0x00, 0x00, 0x05]),
                ip: Some(Ipv4Addr::new(192, 168, 1, 10)),
                subnet_mask: Some(Ipv4Addr::new(255, 255, 255, 0)),
                default_gateway: Some(Ipv4Addr::new(192, 168, 1, 1)),
                dns_server: Some(Ipv4Addr::new(192, 168, 1, 2)),
                dns_name: Some(b"drive0"),
            },
        }),
        true,
        vec![
            ("ecat_mailbox.eoe.type", "2".to_owned()),
            ("ecat_mailbox.eoe.init.ipaddr", "192.168.1.10".to_owned()),
            (
                "ecat_mailbox.eoe.init.subnetmask",
                "255.255.255.0".to_owned(),
            ),
        ],
    ));
    cases
}

fn voe_cases() -> Vec<Case> {
    decoded_only_through_gateway(mailbox_case(
        "VoE",
        MailboxPayload::Voe(VoeRepr {
            vendor_id: 0x0000_1164,
            vendor_type: 1,
            data: &[1, 2, 3, 4],
        }),
        true,
        vec![],
    ))
}

/// Wireshark 4.0 decodes VoE and mailbox error replies only through the gateway; inside a
/// datagram it shows their bytes as plain data (still never malformed, which the
/// capture-wide check asserts), so only the gateway copy has fields to compare.
fn decoded_only_through_gateway(mut cases: Vec<Case>) -> Vec<Case> {
    cases[0].expect.clear();
    cases
}

fn error_reply_cases() -> Vec<Case> {
    decoded_only_through_gateway(mailbox_case(
        "mailbox error reply",
        MailboxPayload::Error(ErrorReplyRepr {
            detail: MailboxErrorCode::from(0x0002),
        }),
        false,
        vec![],
    ))
}

fn all_cases() -> Vec<Case> {
    let mut cases = datagram_cases();
    cases.push(cyclic_frame_case());
    cases.extend(coe_cases());
    cases.extend(soe_cases());
    cases.extend(foe_cases());
    cases.extend(eoe_cases());
    cases.extend(voe_cases());
    cases.extend(error_reply_cases());
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
