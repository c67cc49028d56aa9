//! The server's parsers of caller input, driven by arbitrary text, for the fuzz target
//! `server_input` (fuzz/) and the corpus replay test: slave names, values by type, numbers
//! and states from paths and the command line, Host headers, EoE IP settings and
//! `[[watch]]` entries. Each parser runs on the whole text and on each of its lines; what a
//! parser accepts must come back the same through its text form.

use std::net::SocketAddr;

use master_core::master::SlaveAddress;

use crate::config::watch::Number;
use crate::http::browser::AllowedHosts;
use crate::input::ip::{from_settings, to_settings};
use crate::input::state::parse_state;
use crate::input::value::{ValueType, decode, encode, parse_number};
use crate::service::view::state_name;
use crate::service::{IpView, parse_slave};
use crate::watch::{Target, WatchSpec};

const TYPES: [ValueType; 13] = [
    ValueType::Bool,
    ValueType::U8,
    ValueType::U16,
    ValueType::U32,
    ValueType::U64,
    ValueType::I8,
    ValueType::I16,
    ValueType::I32,
    ValueType::I64,
    ValueType::F32,
    ValueType::F64,
    ValueType::String,
    ValueType::Hex,
];

/// Runs every parser on `data` (as UTF-8, invalid sequences replaced). Panics if a parser
/// panics or an accepted input does not come back the same through its text form.
#[doc(hidden)]
pub fn inputs(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let lines: Vec<&str> = text.lines().collect();
    for one in std::iter::once(text.as_ref()).chain(lines.iter().copied()) {
        slave_name(one);
        value_text(one);
        number(one);
        state(one);
        host(one);
    }
    if let Some((&ty, bytes)) = data.split_first() {
        value_bytes(TYPES[usize::from(ty) % TYPES.len()], bytes);
    }
    let field = |i: usize| lines.get(i).map(|s| (*s).to_owned());
    ip_settings(IpView {
        mac: field(0),
        ip: field(1),
        subnet_mask: field(2),
        default_gateway: field(3),
        dns_server: field(4),
        dns_name: field(5),
    });
    watch(WatchSpec {
        slave: field(0).unwrap_or_default(),
        sdo: field(1).filter(|s| !s.starts_with(['S', 'P', 's', 'p'])),
        index: field(3).map(Number::Text),
        subindex: field(4).map(Number::Text),
        idn: field(1).filter(|s| s.starts_with(['S', 'P', 's', 'p'])),
        pdo: field(5).filter(|s| s.contains(':')),
        drive: data.first().copied().unwrap_or(0) & 7,
        period_ms: 1000,
        value_type: field(2),
        name: None,
    });
}

fn slave_name(text: &str) {
    if let Ok(address) = parse_slave(text) {
        let canonical = match address {
            SlaveAddress::Position(p) => p.to_string(),
            SlaveAddress::Station(s) => format!("#{s:#x}"),
            SlaveAddress::Alias(a) => format!("@{a}"),
        };
        assert_eq!(parse_slave(&canonical).ok(), Some(address), "{canonical}");
    }
}

/// Two encodings of the same value: equal bytes, or both the same-width NaN.
fn same_value(ty: ValueType, a: &[u8], b: &[u8]) -> bool {
    let nan = |bytes: &[u8]| match ty {
        ValueType::F32 => bytes
            .try_into()
            .is_ok_and(|b| f32::from_le_bytes(b).is_nan()),
        ValueType::F64 => bytes
            .try_into()
            .is_ok_and(|b| f64::from_le_bytes(b).is_nan()),
        _ => false,
    };
    a == b || (nan(a) && nan(b))
}

/// Text a caller writes as a value: what encodes must decode and encode to the same bytes.
fn value_text(text: &str) {
    for ty in TYPES {
        let _ = text.parse::<ValueType>();
        let Ok(bytes) = encode(ty, text) else {
            continue;
        };
        let shown = decode(ty, &bytes).expect("encoded bytes decode");
        if ty == ValueType::String {
            continue;
        }
        let again = encode(ty, &shown).expect("decoded text encodes");
        assert!(
            same_value(ty, &again, &bytes),
            "{ty:?} {text:?} -> {shown:?}"
        );
    }
}

/// Bytes read from a slave: what decodes must encode back to the same bytes (booleans
/// other than 0 and 1 and strings excepted: they are shown, not kept).
fn value_bytes(ty: ValueType, bytes: &[u8]) {
    let Ok(shown) = decode(ty, bytes) else {
        return;
    };
    if ty == ValueType::String || (ty == ValueType::Bool && bytes[0] > 1) {
        return;
    }
    let again = encode(ty, &shown).expect("decoded text encodes");
    assert!(
        same_value(ty, &again, bytes),
        "{ty:?} {bytes:?} -> {shown:?}"
    );
}

fn number(text: &str) {
    if let Ok(n) = parse_number::<u32>(text, "index") {
        assert_eq!(parse_number::<u32>(&n.to_string(), "index").ok(), Some(n));
        assert_eq!(
            parse_number::<u32>(&format!("{n:#x}"), "index").ok(),
            Some(n)
        );
        let narrow = parse_number::<u8>(text, "subindex").ok();
        assert_eq!(narrow, u8::try_from(n).ok(), "narrowing {text:?}");
    }
}

fn state(text: &str) {
    if let Ok(s) = parse_state(text) {
        assert_eq!(parse_state(&state_name(s)).ok(), Some(s));
    }
}

/// A Host header: a port after a plain name does not change the decision.
fn host(text: &str) {
    let listen: SocketAddr = ([127, 0, 0, 1], 8080).into();
    let hosts = AllowedHosts::new(listen, &["ecat.example".to_owned()]);
    let allowed = hosts.allows(text);
    if !text.contains([':', '[', ']']) {
        assert_eq!(hosts.allows(&format!("{text}:80")), allowed, "{text:?}");
    }
}

/// EoE IP settings from a REST body: what parses comes back the same through the text
/// form, and an accepted MAC address is six pairs of hex digits.
fn ip_settings(view: IpView) {
    let Ok(settings) = to_settings(&view) else {
        return;
    };
    let shown = from_settings(&settings);
    assert_eq!(to_settings(&shown).ok(), Some(settings));
    if let (Some(given), Some(mac)) = (view.mac.filter(|m| !m.is_empty()), shown.mac) {
        assert_eq!(
            given.to_ascii_lowercase().replace('-', ":"),
            mac,
            "MAC {given:?}"
        );
    }
}

/// A `[[watch]]` entry: a CoE target comes back the same through its label.
fn watch(spec: WatchSpec) {
    let _ = spec.check();
    let _ = spec.value_type();
    if let Ok(Target::Sdo { index, subindex }) = spec.target() {
        let label = Target::Sdo { index, subindex }.label();
        let again = WatchSpec {
            sdo: Some(label),
            idn: None,
            ..spec
        };
        assert_eq!(again.target(), Ok(Target::Sdo { index, subindex }));
    }
}

/// The application interface's socket lines and entry records, driven by arbitrary bytes,
/// for the fuzz target `app_socket` (what a program sends ecatd, what ecatd sends a
/// program, a region's entry table). Panics if a parser panics or an accepted line or
/// record does not come back the same through its text or byte form.
#[doc(hidden)]
pub fn app_socket(data: &[u8]) {
    use ecat_app::entry::Entry;
    use ecat_app::protocol::{Line, Request};
    let text = String::from_utf8_lossy(data);
    for line in std::iter::once(text.as_ref()).chain(text.lines()) {
        if let Ok(request) = Request::parse(line) {
            assert_eq!(
                Request::parse(&request.to_string()),
                Ok(request),
                "{line:?}"
            );
        }
        if let Ok(answer) = Line::parse(line) {
            assert_eq!(
                Line::parse(&answer.to_string()).as_ref(),
                Ok(&answer),
                "{line:?}"
            );
        }
    }
    for record in data.chunks_exact(ecat_app::shm::ENTRY_SIZE) {
        let record: &[u8; ecat_app::shm::ENTRY_SIZE] = record.try_into().unwrap_or(&[0; 64]);
        if let Some(entry) = Entry::decode(record) {
            let again = Entry::decode(&entry.encode());
            assert_eq!(again.as_ref(), Some(&entry));
            // Reading and writing any entry within any image never panics.
            let mut image = data.to_vec();
            let value = entry.get_i64(&image);
            entry.set(&mut image, value as u64);
            let _ = entry.accepts(value);
        }
    }
}

/// The body of a process-data force (`PUT /api/v1/slaves/{slave}/process-data/...`), driven
/// by arbitrary bytes, for the fuzz target `process_data_body`: the JSON body and its value.
#[doc(hidden)]
pub fn process_data_body(data: &[u8]) {
    use crate::http::rest::process_data::{ForceBody, input};
    if let Ok(body) = serde_json::from_slice::<ForceBody>(data) {
        let _ = input(&body.value);
    }
    if let Ok(value) = serde_json::from_slice::<serde_json::Value>(data) {
        let _ = input(&value);
    }
}
