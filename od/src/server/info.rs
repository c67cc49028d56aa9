//! SDO Information (spec-notes §coe.info): OD lists, object and entry descriptions, and the SDO
//! Info error for anything the server cannot answer.

use ecat_wire::coe::AbortCode;
use ecat_wire::coe::info::entry::{ENTRY_RESPONSE_FIXED_LEN, value_len};
use ecat_wire::coe::info::object::OBJECT_DESCRIPTION_FIXED_LEN;
use ecat_wire::coe::info::{
    EntryDescription, ObjectDescription, OdList, OdListType, SDO_INFO_HEADER_LEN, SdoInfoFrame,
    SdoInfoRepr, SdoInfoService, UNIT_TYPE_LEN, ValueInfo,
};
use ecat_wire::error::WireError;

use super::super::dictionary::Dictionary;
use super::reply::Replies;

/// The lists a type-0 request counts, in answer order.
const COUNTED_LISTS: [OdListType; 5] = [
    OdListType::All,
    OdListType::RxPdoMappable,
    OdListType::TxPdoMappable,
    OdListType::Backup,
    OdListType::Settings,
];

/// Serves an SDO Information request; `false` if it is too short for its header.
pub(super) fn serve(dict: &dyn Dictionary, request: &[u8], out: &mut Replies<'_>) -> bool {
    let Ok(frame) = SdoInfoFrame::new_checked(request) else {
        return false;
    };
    match SdoInfoRepr::parse(&frame).map(|r| r.service) {
        Ok(SdoInfoService::OdListRequest { list_type }) => od_list(dict, list_type, out),
        Ok(SdoInfoService::ObjectDescriptionRequest { index }) => object(dict, index, out),
        Ok(SdoInfoService::EntryDescriptionRequest {
            index,
            subindex,
            value_info,
        }) => entry(dict, index, subindex, value_info, out),
        Err(WireError::Truncated { .. }) => out.info_error(AbortCode::LengthTooLow),
        // Responses, errors and unknown opcodes are nothing a client asks a server.
        _ => out.info_error(AbortCode::UnknownCommand),
    }
    true
}

fn words_to_bytes(words: &[u16]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// Get OD List: the list type, then the indices (or, for type 0, the five counts),
/// fragmented when longer than SM1 holds; the list type heads only the first fragment
/// because fragments split the service data.
fn od_list(dict: &dyn Dictionary, list_type: OdListType, out: &mut Replies<'_>) {
    let mut words = vec![u16::from(list_type)];
    match list_type {
        OdListType::Lengths => {
            for list in COUNTED_LISTS {
                let n = dict.indices(list).len();
                words.push(u16::try_from(n).unwrap_or(u16::MAX));
            }
        }
        OdListType::Unknown(_) => return out.info_error(AbortCode::UnsupportedAccess),
        list => words.extend(dict.indices(list)),
    }
    let bytes = words_to_bytes(&words);
    out.info(SdoInfoService::OdListResponse(OdList(&bytes)));
}

/// The longest prefix of `name` that fits in `room` bytes, cut on a character boundary.
fn cut(name: &str, room: usize) -> &[u8] {
    let mut end = name.len().min(room);
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    &name.as_bytes()[..end]
}

/// Get Object Description, in one message: the name is cut to what SM1 holds.
///
/// Descriptions are never fragmented: clients such as SOEM and IgH read them from a single
/// message, and a continuation fragment of a description is not a description by itself
/// (the codec could not parse it). Only OD lists are fragmented.
fn object(dict: &dyn Dictionary, index: u16, out: &mut Replies<'_>) {
    let Some(info) = dict.object(index) else {
        return out.info_error(AbortCode::ObjectDoesNotExist);
    };
    let fixed = SDO_INFO_HEADER_LEN + OBJECT_DESCRIPTION_FIXED_LEN;
    let Some(room) = out.capacity().checked_sub(fixed) else {
        return out.info_error(AbortCode::ObjectTooLong);
    };
    out.info(SdoInfoService::ObjectDescriptionResponse(
        ObjectDescription {
            index,
            data_type: info.data_type,
            max_subindex: info.max_subindex,
            object_code: info.object_code,
            name: cut(&info.name, room),
        },
    ));
}

/// Get Entry Description, in one message like the object description. The value-info
/// byte of the answer keeps the requested bits 0-2 and those of bits 3-6 whose value the
/// entry declares: a client reads the optional fields by the answer's bits, so absent
/// values are left out rather than invented (likewise all of them when they would not fit
/// SM1). Default/minimum/maximum are padded with zeros to ⌈bit length / 8⌉ bytes (strings
/// shorter than their maximum). The name is cut to what is left.
fn entry(
    dict: &dyn Dictionary,
    index: u16,
    subindex: u8,
    requested: ValueInfo,
    out: &mut Replies<'_>,
) {
    let info = match dict.entry(index, subindex) {
        Ok(info) => info,
        Err(code) => return out.info_error(code),
    };
    let n = value_len(info.bit_length);
    let padded = |bit: u8, v: Option<&[u8]>| -> Option<Vec<u8>> {
        let v = v.filter(|_| requested.contains(bit))?;
        let mut v = v.to_vec();
        v.resize(n, 0);
        Some(v)
    };
    let mut default = padded(ValueInfo::DEFAULT, info.default.as_deref());
    let mut minimum = padded(ValueInfo::MINIMUM, info.minimum.as_deref());
    let mut maximum = padded(ValueInfo::MAXIMUM, info.maximum.as_deref());
    let mut unit_type = info
        .unit
        .filter(|_| requested.contains(ValueInfo::UNIT_TYPE));
    let fixed = SDO_INFO_HEADER_LEN + ENTRY_RESPONSE_FIXED_LEN;
    let optional_len = |unit: Option<u32>, values: [&Option<Vec<u8>>; 3]| {
        unit.map_or(0, |_| UNIT_TYPE_LEN)
            + values
                .iter()
                .map(|v| v.as_ref().map_or(0, Vec::len))
                .sum::<usize>()
    };
    if fixed + optional_len(unit_type, [&default, &minimum, &maximum]) > out.capacity() {
        (default, minimum, maximum, unit_type) = (None, None, None, None);
    }
    let Some(room) = out.capacity().checked_sub(fixed) else {
        return out.info_error(AbortCode::ObjectTooLong);
    };
    let optional = optional_len(unit_type, [&default, &minimum, &maximum]);
    let mut bits = requested.0 & (ValueInfo::ACCESS | ValueInfo::CATEGORY | ValueInfo::MAPPABLE);
    for (present, bit) in [
        (unit_type.is_some(), ValueInfo::UNIT_TYPE),
        (default.is_some(), ValueInfo::DEFAULT),
        (minimum.is_some(), ValueInfo::MINIMUM),
        (maximum.is_some(), ValueInfo::MAXIMUM),
    ] {
        if present {
            bits |= bit;
        }
    }
    out.info(SdoInfoService::EntryDescriptionResponse(EntryDescription {
        index,
        subindex,
        value_info: ValueInfo(bits),
        data_type: info.data_type,
        bit_length: info.bit_length,
        access: info.access,
        unit_type,
        default: default.as_deref(),
        minimum: minimum.as_deref(),
        maximum: maximum.as_deref(),
        description: cut(&info.name, room - optional),
    }));
}
