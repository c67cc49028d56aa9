//! SDO upload (read): expedited for 1-4 bytes, normal when the value fits one mailbox,
//! segmented otherwise (ETG.1000.6, spec-notes §coe.sdo).

use ecat_wire::coe::sdo_payload::SdoPayload;
use ecat_wire::coe::sdo_response::SdoResponse;
use ecat_wire::coe::{AbortCode, max_initiate_data, max_segment_data};
use ecat_wire::mailbox::HEADER_LEN;

use super::super::dictionary::Dictionary;
use super::reply::Replies;
use super::{ServerContext, Transfer, complete};

/// A segmented upload in progress: the value as read at the initiate (a snapshot, so the
/// client gets one consistent value), how much has been sent, the toggle expected next.
#[derive(Debug)]
pub(super) struct Upload {
    index: u16,
    subindex: u8,
    data: Vec<u8>,
    sent: usize,
    toggle: bool,
}

/// Most bytes of expedited data.
const EXPEDITED_MAX: usize = 4;

/// Initiate upload request: read the value and answer with as much as fits.
pub(super) fn initiate(
    transfer: &mut Transfer,
    dict: &mut dyn Dictionary,
    index: u16,
    subindex: u8,
    complete_access: bool,
    ctx: ServerContext,
    out: &mut Replies<'_>,
) {
    let mut data = Vec::new();
    let read = if complete_access {
        complete::read(dict, index, subindex, ctx.state, &mut data)
    } else {
        dict.read(index, subindex, ctx.state, &mut data)
    };
    if let Err(code) = read {
        return out.abort(index, subindex, code);
    }
    let Ok(complete_size) = u32::try_from(data.len()) else {
        return out.abort(index, subindex, AbortCode::ObjectTooLong);
    };
    let first = max_initiate_data(out.capacity() + HEADER_LEN);
    let payload = if (1..=EXPEDITED_MAX).contains(&data.len()) {
        SdoPayload::Expedited(&data)
    } else {
        SdoPayload::Normal {
            complete_size,
            data: &data[..data.len().min(first)],
        }
    };
    out.sdo(&SdoResponse::InitiateUpload {
        index,
        subindex,
        complete_access,
        payload,
    });
    if data.len() > EXPEDITED_MAX && data.len() > first {
        *transfer = Transfer::Upload(Upload {
            index,
            subindex,
            data,
            sent: first,
            toggle: false,
        });
    }
}

/// Upload segment request: the next piece, echoing the toggle.
pub(super) fn segment(transfer: &mut Transfer, toggle: bool, out: &mut Replies<'_>) {
    let Transfer::Upload(up) = transfer else {
        *transfer = Transfer::Idle;
        return out.abort(0, 0, AbortCode::UnknownCommand);
    };
    if toggle != up.toggle {
        let (index, subindex) = (up.index, up.subindex);
        *transfer = Transfer::Idle;
        return out.abort(index, subindex, AbortCode::ToggleBit);
    }
    let rest = up.data.get(up.sent..).unwrap_or(&[]);
    let n = rest
        .len()
        .min(max_segment_data(out.capacity() + HEADER_LEN));
    let last = n == rest.len();
    out.sdo(&SdoResponse::UploadSegment {
        toggle,
        last,
        data: &rest[..n],
    });
    up.sent += n;
    up.toggle = !up.toggle;
    if last {
        *transfer = Transfer::Idle;
    }
}
