//! A dictionary that computes its values when read — the shape of the master's ETG.1510
//! dictionary — served by the same SDO server through the `Dictionary` trait alone.

use crate::od_support;

use std::borrow::Cow;

use master_core::od::access::{check_read, check_write};
use master_core::od::check::check_value;
use master_core::od::{DictEntryInfo, DictObjectInfo, Dictionary, StaticDictionary};
use master_core::wire::coe::info::{OdListType, SdoInfoService, ValueInfo};
use master_core::wire::coe::{AbortCode, DataType, ObjectAccess, ObjectCode};
use master_core::wire::register::AlState;
use od_support::*;

/// 0xF120-like diagnosis RECORD: :01 a frame counter that advances on every read, :02 a
/// writable u16, :03 missing (gap), :10 a BOOLEAN.
#[derive(Default)]
struct Live {
    frames: u32,
    setting: u16,
    flag: bool,
    writes: Vec<(u8, Vec<u8>)>,
}

const INDEX: u16 = 0xF120;

impl Live {
    fn info(&self, subindex: u8) -> Result<DictEntryInfo<'static>, AbortCode> {
        let (name, data_type, bits, access) = match subindex {
            0 => (
                "Number of entries",
                DataType::Unsigned8,
                8,
                ObjectAccess::RO,
            ),
            1 => ("Cyclic frames", DataType::Unsigned32, 32, ObjectAccess::RO),
            2 => ("Setting", DataType::Unsigned16, 16, ObjectAccess::RW),
            16 => ("Flag", DataType::Boolean, 1, ObjectAccess::RW),
            3..=15 => return Err(AbortCode::TransferFailed),
            _ => return Err(AbortCode::SubindexDoesNotExist),
        };
        Ok(DictEntryInfo {
            index: INDEX,
            subindex,
            name: Cow::Borrowed(name),
            data_type,
            bit_length: bits,
            max_len: usize::from(bits).div_ceil(8),
            access,
            unit: None,
            default: None,
            minimum: None,
            maximum: (subindex == 2).then(|| Cow::Owned(1000u16.to_le_bytes().to_vec())),
        })
    }
}

impl Dictionary for Live {
    fn indices(&self, list: OdListType) -> Vec<u16> {
        match list {
            OdListType::All => vec![INDEX],
            _ => Vec::new(),
        }
    }

    fn object(&self, index: u16) -> Option<DictObjectInfo<'_>> {
        (index == INDEX).then(|| DictObjectInfo {
            index,
            name: Cow::Borrowed("Master diag data"),
            object_code: ObjectCode::Record,
            data_type: DataType::from(0),
            max_subindex: 16,
        })
    }

    fn entry(&self, index: u16, subindex: u8) -> Result<DictEntryInfo<'_>, AbortCode> {
        if index != INDEX {
            return Err(AbortCode::ObjectDoesNotExist);
        }
        self.info(subindex)
    }

    fn read(
        &mut self,
        index: u16,
        subindex: u8,
        state: AlState,
        out: &mut Vec<u8>,
    ) -> Result<(), AbortCode> {
        check_read(self.entry(index, subindex)?.access, state)?;
        match subindex {
            0 => out.push(16),
            1 => {
                self.frames += 1;
                out.extend(self.frames.to_le_bytes());
            }
            2 => out.extend(self.setting.to_le_bytes()),
            _ => out.push(u8::from(self.flag)),
        }
        Ok(())
    }

    fn write(
        &mut self,
        index: u16,
        subindex: u8,
        data: &[u8],
        state: AlState,
    ) -> Result<(), AbortCode> {
        let info = self.entry(index, subindex)?;
        check_write(info.access, state)?;
        check_value(&info, data)?;
        match subindex {
            2 => self.setting = u16::from_le_bytes([data[0], data[1]]),
            _ => self.flag = data[0] != 0,
        }
        self.writes.push((subindex, data.to_vec()));
        Ok(())
    }
}

/// Serves `request` against `live` and returns the replies.
fn serve(live: &mut Live, request: &[u8]) -> Vec<Vec<u8>> {
    // The client helper owns a StaticDictionary; drive the server directly here.
    let mut server = master_core::od::SdoServer::new();
    let ctx = master_core::od::ServerContext::new(128, AlState::Op);
    let mut replies = Vec::new();
    server.handle(live, request, ctx, &mut |r: &[u8]| replies.push(r.to_vec()));
    replies
}

/// Under `od` so that `cargo test -p master-core od` selects these tests.
mod od {
    use super::*;
    use master_core::wire::coe::sdo_payload::SdoPayload;
    use master_core::wire::coe::sdo_request::SdoRequest;
    use master_core::wire::coe::sdo_response::SdoResponse;

    fn upload(live: &mut Live, subindex: u8, ca: bool) -> Vec<u8> {
        let replies = serve(
            live,
            &sdo_bytes(&SdoRequest::InitiateUpload {
                index: INDEX,
                subindex,
                complete_access: ca,
            }),
        );
        match sdo_reply(&replies[0]) {
            SdoResponse::InitiateUpload {
                payload: SdoPayload::Expedited(v) | SdoPayload::Normal { data: v, .. },
                ..
            } => v.to_vec(),
            other => panic!("unexpected {other}"),
        }
    }

    #[test]
    fn computed_values_are_read_live() {
        let mut live = Live::default();
        assert_eq!(upload(&mut live, 1, false), 1u32.to_le_bytes());
        assert_eq!(upload(&mut live, 1, false), 2u32.to_le_bytes());
        // Complete access reads every entry once, skipping the gap :03..:0F; the BOOLEAN
        // is packed after the byte-aligned u16.
        let image = upload(&mut live, 0, true);
        assert_eq!(image, [16, 0, 3, 0, 0, 0, 0, 0, 0]);
        let abort = serve(
            &mut live,
            &sdo_bytes(&SdoRequest::InitiateUpload {
                index: INDEX,
                subindex: 5,
                complete_access: false,
            }),
        );
        assert!(matches!(
            sdo_reply(&abort[0]),
            SdoResponse::Abort {
                code: AbortCode::TransferFailed,
                ..
            }
        ));
    }

    #[test]
    fn writes_and_descriptions_come_from_the_trait() {
        let mut live = Live::default();
        let down = |value: &[u8]| {
            sdo_bytes(&SdoRequest::InitiateDownload {
                index: INDEX,
                subindex: 2,
                complete_access: false,
                payload: SdoPayload::Expedited(value),
            })
        };
        let ok = serve(&mut live, &down(&500u16.to_le_bytes()));
        assert!(matches!(
            sdo_reply(&ok[0]),
            SdoResponse::InitiateDownload { .. }
        ));
        assert_eq!(live.setting, 500);
        let too_high = serve(&mut live, &down(&1001u16.to_le_bytes()));
        assert!(matches!(
            sdo_reply(&too_high[0]),
            SdoResponse::Abort {
                code: AbortCode::ValueTooHigh,
                ..
            }
        ));
        // The default complete-access write goes entry by entry through `write`.
        let ca = sdo_bytes(&SdoRequest::InitiateDownload {
            index: INDEX,
            subindex: 1,
            complete_access: true,
            payload: SdoPayload::Normal {
                complete_size: 7,
                data: &[9, 9, 9, 9, 0x34, 0x02, 0x01],
            },
        });
        let replies = serve(&mut live, &ca);
        assert!(matches!(
            sdo_reply(&replies[0]),
            SdoResponse::InitiateDownload { .. }
        ));
        assert_eq!((live.setting, live.flag), (0x0234, true));
        assert_eq!(live.writes.len(), 3);
        let replies = serve(
            &mut live,
            &info_bytes(SdoInfoService::EntryDescriptionRequest {
                index: INDEX,
                subindex: 2,
                value_info: ValueInfo(ValueInfo::MAXIMUM),
            }),
        );
        let SdoInfoService::EntryDescriptionResponse(e) = info_reply(&replies[0]).service else {
            panic!("no description");
        };
        assert_eq!(
            (e.description, e.maximum),
            (&b"Setting"[..], Some(&[0xE8, 0x03][..]))
        );
    }

    #[test]
    fn large_domains_go_beyond_the_16_bit_length() {
        // 20 KiB: more than SDO Information's bit length can say (capped at 0xFFFF bits).
        let data: Vec<u8> = (0..20_480u32).map(|i| (i % 253) as u8).collect();
        let dict = StaticDictionary::builder()
            .bytes(
                0x2100,
                "Big",
                DataType::Domain,
                ObjectAccess::RW,
                Vec::new(),
                20_480,
            )
            .build()
            .unwrap();
        let mut c = Client::with(dict, 256);
        c.download(0x2100, 0, false, &data).unwrap();
        assert_eq!(c.upload(0x2100, 0, false).unwrap(), data);
        assert_eq!(
            c.dict.get_object(0x2100).unwrap().entries[0].bit_length,
            0xFFFF
        );
    }
}
