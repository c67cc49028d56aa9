//! SDO Information (ETG.1000.6 §5.6.3, spec-notes §coe.info): the slave's object dictionary as it describes itself.
//!
//! A long answer comes in fragments (Incomplete set, fragments left counting down); the
//! client keeps reading the send mailbox and concatenates their service data — for an OD
//! list only the first fragment carries the list type.

use crate::mailbox::engine::exchange::Exchange;
use crate::mailbox::engine::job::{BoxFuture, call_for};
use crate::mailbox::engine::report::Subject;
use crate::mailbox::engine::slave::SlaveMailbox;
use crate::mailbox::error::{MailboxError, Result};
use crate::mailbox::matching::describes;
use crate::wire::coe::info::entry::{EntryDescription, ValueInfo};
use crate::wire::coe::info::object::ObjectDescription;
use crate::wire::coe::info::od_list::{OdList, OdListType};
use crate::wire::coe::info::{SdoInfoFrame, SdoInfoOpcode, SdoInfoRepr, SdoInfoService};
use crate::wire::coe::{CoeRepr, CoeService, DataType, ObjectAccess, ObjectCode};
use crate::wire::mailbox::MailboxType;

use super::send_coe;

/// What Get Object Description reports about an object.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObjectInfo {
    /// Object index.
    pub index: u16,
    /// Data type (of the entries, for an ARRAY).
    pub data_type: DataType,
    /// Highest subindex.
    pub max_subindex: u8,
    /// VAR, ARRAY, RECORD, ...
    pub object_code: ObjectCode,
    /// The object's name.
    pub name: String,
}

/// What Get Entry Description reports about one entry.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EntryInfo {
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
    /// Which optional parts are present (the request's value info, echoed).
    pub value_info: u8,
    /// Data type.
    pub data_type: DataType,
    /// Size in bits.
    pub bit_length: u16,
    /// Access and mapping flags.
    pub access: ObjectAccess,
    /// Unit type, if asked for.
    pub unit_type: Option<u32>,
    /// Default value, if asked for.
    pub default: Option<Vec<u8>>,
    /// Minimum value, if asked for.
    pub minimum: Option<Vec<u8>>,
    /// Maximum value, if asked for.
    pub maximum: Option<Vec<u8>>,
    /// The entry's name.
    pub description: String,
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Sends `request` and returns the concatenated service data of the answer `expect`; a
/// first fragment that describes another object than `about` is a late answer to an
/// earlier request, dropped and counted.
async fn info_request(
    x: &mut Exchange,
    request: SdoInfoService<'_>,
    expect: SdoInfoOpcode,
    about: Option<(u16, Option<u8>)>,
) -> Result<Vec<u8>> {
    let repr = CoeRepr::SdoInfo(SdoInfoRepr {
        incomplete: false,
        fragments_left: 0,
        service: request,
    });
    send_coe(x, &repr).await?;
    let limit = x.config().max_value_len;
    let station = x.station();
    let mut collected = Vec::new();
    loop {
        let reply = x.receive(MailboxType::Coe).await?;
        let data = reply.data()?;
        let Ok(frame) = SdoInfoFrame::new_checked(data) else {
            x.count_unexpected(MailboxType::Coe);
            continue;
        };
        if frame.service() != CoeService::SdoInfo {
            x.count_unexpected(MailboxType::Coe);
            continue;
        }
        let opcode = frame.opcode();
        if opcode == SdoInfoOpcode::Error {
            // Some stacks declare a mailbox length of 6 and leave the abort code outside
            // it: still the slave's refusal, only without its reason.
            return Err(match SdoInfoRepr::parse(&frame).map(|info| info.service) {
                Ok(SdoInfoService::Error { code }) => MailboxError::SdoInfo(code),
                _ => MailboxError::SdoInfoAbortMissing { station },
            });
        }
        if opcode != expect || (collected.is_empty() && !describes(frame.data(), about)) {
            x.count_unexpected(MailboxType::Coe);
            continue;
        }
        let size = collected.len() + frame.data().len();
        if size > limit {
            return Err(MailboxError::TooLarge {
                what: "SDO Information answer",
                size,
                limit,
            });
        }
        collected.extend_from_slice(frame.data());
        if !frame.incomplete() {
            return Ok(collected);
        }
    }
}

impl SlaveMailbox {
    /// Get OD List: the object indices of `list` (for [`OdListType::Lengths`], the five
    /// list lengths: all, RxPDO-mappable, TxPDO-mappable, backup, settings).
    pub async fn sdo_info_od_list(&self, list: OdListType) -> Result<Vec<u16>> {
        call_for(
            self,
            Some(MailboxType::Coe),
            Subject::None,
            move |x| -> BoxFuture<'_, _> {
                Box::pin(async move {
                    let request = SdoInfoService::OdListRequest { list_type: list };
                    let data =
                        info_request(x, request, SdoInfoOpcode::OdListResponse, None).await?;
                    let Some((answered, rest)) = OdList(&data).first_fragment() else {
                        return Err(x.violation("an OD list without its list type"));
                    };
                    if answered != list {
                        return Err(x.violation("an OD list of another list type"));
                    }
                    Ok(rest.words().collect())
                })
            },
        )
        .await
    }

    /// Get Object Description of `index`.
    pub async fn sdo_info_object(&self, index: u16) -> Result<ObjectInfo> {
        let subject = Subject::Object { index, subindex: 0 };
        call_for(
            self,
            Some(MailboxType::Coe),
            subject,
            move |x| -> BoxFuture<'_, _> {
                Box::pin(async move {
                    let request = SdoInfoService::ObjectDescriptionRequest { index };
                    let about = Some((index, None));
                    let data =
                        info_request(x, request, SdoInfoOpcode::ObjectDescriptionResponse, about)
                            .await?;
                    let object = ObjectDescription::parse(&data)
                        .map_err(|_| x.violation("a short object description"))?;
                    Ok(ObjectInfo {
                        index: object.index,
                        data_type: object.data_type,
                        max_subindex: object.max_subindex,
                        object_code: object.object_code,
                        name: text(object.name),
                    })
                })
            },
        )
        .await
    }

    /// Get Entry Description of `index:subindex`; `value_info` selects the optional parts
    /// ([`ValueInfo`] bits: 0x08 unit type, 0x10 default, 0x20 minimum, 0x40 maximum).
    pub async fn sdo_info_entry(
        &self,
        index: u16,
        subindex: u8,
        value_info: u8,
    ) -> Result<EntryInfo> {
        let subject = Subject::Object { index, subindex };
        call_for(
            self,
            Some(MailboxType::Coe),
            subject,
            move |x| -> BoxFuture<'_, _> {
                Box::pin(async move {
                    let request = SdoInfoService::EntryDescriptionRequest {
                        index,
                        subindex,
                        value_info: ValueInfo(value_info),
                    };
                    let about = Some((index, Some(subindex)));
                    let data =
                        info_request(x, request, SdoInfoOpcode::EntryDescriptionResponse, about)
                            .await?;
                    let entry = EntryDescription::parse(&data)
                        .map_err(|_| x.violation("an entry description shorter than announced"))?;
                    Ok(EntryInfo {
                        index: entry.index,
                        subindex: entry.subindex,
                        value_info: entry.value_info.0,
                        data_type: entry.data_type,
                        bit_length: entry.bit_length,
                        access: entry.access,
                        unit_type: entry.unit_type,
                        default: entry.default.map(<[u8]>::to_vec),
                        minimum: entry.minimum.map(<[u8]>::to_vec),
                        maximum: entry.maximum.map(<[u8]>::to_vec),
                        description: text(entry.description),
                    })
                })
            },
        )
        .await
    }
}
