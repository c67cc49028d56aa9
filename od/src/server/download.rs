//! SDO download (write): expedited, normal in one frame, or segmented with toggle and
//! complete-size checks (ETG.1000.6, spec-notes §coe.sdo).

use ecat_wire::coe::AbortCode;
use ecat_wire::coe::sdo_payload::SdoPayload;
use ecat_wire::coe::sdo_response::SdoResponse;
use ecat_wire::register::AlState;

use super::super::access::check_write;
use super::super::dictionary::Dictionary;
use super::reply::Replies;
use super::{Transfer, complete};

/// A segmented download in progress.
#[derive(Debug)]
pub(super) struct Download {
    index: u16,
    subindex: u8,
    complete_access: bool,
    /// The complete size the client announced.
    expected: usize,
    data: Vec<u8>,
    toggle: bool,
}

/// The parts of an initiate download request the server uses.
pub(super) struct Initiate<'a> {
    pub(super) index: u16,
    pub(super) subindex: u8,
    pub(super) complete_access: bool,
    pub(super) payload: SdoPayload<'a>,
    /// Command bit 0: without it an expedited value's size is the object's.
    pub(super) size_indicated: bool,
}

/// Initiate download request.
pub(super) fn initiate(
    transfer: &mut Transfer,
    dict: &mut dyn Dictionary,
    req: Initiate<'_>,
    state: AlState,
    out: &mut Replies<'_>,
) {
    let (index, subindex, ca) = (req.index, req.subindex, req.complete_access);
    let data = match req.payload {
        SdoPayload::Expedited(value) if !req.size_indicated && !ca => {
            unsized_value(dict, index, subindex, value)
        }
        SdoPayload::Expedited(value) => value,
        SdoPayload::SizeUnspecified { data } => data,
        SdoPayload::Normal {
            complete_size,
            data,
        } => {
            let expected = usize::try_from(complete_size).unwrap_or(usize::MAX);
            if data.len() < expected {
                if let Err(code) = precheck(dict, index, subindex, ca, expected, state) {
                    return out.abort(index, subindex, code);
                }
                *transfer = Transfer::Download(Download {
                    index,
                    subindex,
                    complete_access: ca,
                    expected,
                    data: data.to_vec(),
                    toggle: false,
                });
                return out.sdo(&ack(index, subindex));
            }
            data
        }
    };
    match store(dict, index, subindex, ca, data, state) {
        Ok(()) => out.sdo(&ack(index, subindex)),
        Err(code) => out.abort(index, subindex, code),
    }
}

/// Download segment request.
pub(super) fn segment(
    transfer: &mut Transfer,
    dict: &mut dyn Dictionary,
    toggle: bool,
    last: bool,
    data: &[u8],
    state: AlState,
    out: &mut Replies<'_>,
) {
    let Transfer::Download(down) = transfer else {
        *transfer = Transfer::Idle;
        return out.abort(0, 0, AbortCode::UnknownCommand);
    };
    let (index, subindex) = (down.index, down.subindex);
    if toggle != down.toggle {
        *transfer = Transfer::Idle;
        return out.abort(index, subindex, AbortCode::ToggleBit);
    }
    // The segments must add up to the announced size, no more and (at the end) no less.
    if down.data.len() + data.len() > down.expected
        || (last && down.data.len() + data.len() != down.expected)
    {
        *transfer = Transfer::Idle;
        return out.abort(index, subindex, AbortCode::LengthMismatch);
    }
    down.data.extend_from_slice(data);
    down.toggle = !down.toggle;
    if !last {
        return out.sdo(&SdoResponse::DownloadSegment { toggle });
    }
    let Transfer::Download(done) = std::mem::take(transfer) else {
        return;
    };
    match store(
        dict,
        index,
        subindex,
        done.complete_access,
        &done.data,
        state,
    ) {
        Ok(()) => out.sdo(&SdoResponse::DownloadSegment { toggle }),
        Err(code) => out.abort(index, subindex, code),
    }
}

fn ack(index: u16, subindex: u8) -> SdoResponse<'static> {
    // Bit 4 is reserved in this response (spec-notes §coe.sdo), so complete access is not echoed.
    SdoResponse::InitiateDownload {
        index,
        subindex,
        complete_access: false,
    }
}

fn store(
    dict: &mut dyn Dictionary,
    index: u16,
    subindex: u8,
    complete_access: bool,
    data: &[u8],
    state: AlState,
) -> Result<(), AbortCode> {
    if complete_access {
        complete::write(dict, index, subindex, data, state)
    } else {
        dict.write(index, subindex, data, state)
    }
}

/// An expedited value without size indication carries 4 bytes; the object's size decides
/// how many count (CiA 301), so a 2-byte entry takes the first 2.
fn unsized_value<'a>(dict: &dyn Dictionary, index: u16, subindex: u8, value: &'a [u8]) -> &'a [u8] {
    match dict.entry(index, subindex) {
        Ok(info) if !info.is_variable_length() => &value[..value.len().min(info.fixed_len())],
        _ => value,
    }
}

/// Checks a segmented download before accepting its first frame, so the client learns
/// of a missing object, a read-only entry or a wrong size at once rather than after all
/// segments, and no buffer is grown beyond what the entry can hold.
fn precheck(
    dict: &dyn Dictionary,
    index: u16,
    subindex: u8,
    complete_access: bool,
    expected: usize,
    state: AlState,
) -> Result<(), AbortCode> {
    if complete_access {
        let max = complete::max_len(dict, index, subindex)?;
        return if expected > max {
            Err(AbortCode::LengthMismatch)
        } else {
            Ok(())
        };
    }
    let info = dict.entry(index, subindex)?;
    check_write(info.access, state)?;
    if info.is_variable_length() {
        if expected > info.max_len {
            return Err(AbortCode::LengthTooHigh);
        }
    } else if expected > info.fixed_len() {
        return Err(AbortCode::LengthTooHigh);
    } else if expected < info.fixed_len() {
        return Err(AbortCode::LengthTooLow);
    }
    Ok(())
}
