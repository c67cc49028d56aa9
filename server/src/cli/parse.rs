//! The command line's argument forms: numbers (decimal or `0x` hex), hex data, AL state
//! names, value types (IgH's names too) and IDNs (`S-0-0011`, `P-0-0100` or a number).

use proto::v1 as pb;
use server::input::value::{ValueType, parse_number};
use tonic::Status;

use crate::failure::Failure;

/// A failed call as the command line reports it: classed by what ecatd answered.
pub fn failed(status: Status) -> Failure {
    Failure::from(status)
}

/// A number in the one syntax.
pub fn num<T: TryFrom<u64>>(text: &str, what: &str) -> Result<T, String> {
    parse_number(text, what).map_err(|e| e.message)
}

/// A value type by name.
pub fn typed(ty: &str) -> Result<ValueType, String> {
    ty.parse().map_err(|e: server::service::ApiError| e.message)
}

/// Hex bytes.
pub fn unhex(text: &str) -> Result<Vec<u8>, String> {
    hex::decode(text.trim()).map_err(|_| format!("{text:?} is not hex"))
}

/// An SoE IDN: `S-0-0011`, `P-0-0100` or a number (`0x8064`).
pub fn idn(text: &str) -> Result<u32, String> {
    server::input::value::parse_idn(text, "IDN")
        .map(u32::from)
        .map_err(|e| e.message)
}

/// An AL state by name (`INIT`, `PREOP`, `BOOT`, `SAFEOP`, `OP`, any case), as ecatd reads
/// it.
pub fn state(name: &str) -> Result<pb::AlState, String> {
    server::input::state::parse_state(name)
        .map(server::grpc::convert::pb_state)
        .map_err(|err| err.message)
}

/// A slave's state as the listings print it: its AL state, or `ABSENT` while it does not
/// answer (its last AL state says nothing of now).
pub fn slave_state_text(slave: &pb::Slave) -> &'static str {
    if slave.present {
        state_text(slave.state)
    } else {
        "ABSENT"
    }
}

/// The name of an AL state as IgH prints it.
pub fn state_text(value: i32) -> &'static str {
    server::grpc::convert::state_of(value).map_or("UNKNOWN", |state| state.name())
}
