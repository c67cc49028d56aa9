//! `ecat.v1.CoeService`: SDO upload and download, SDO Information.

use proto::v1 as pb;
use proto::v1::coe_service_server::CoeService;
use tonic::{Request, Response, Status};

use super::auth::admit;
use super::status::narrow;
use crate::input::value::Typing;
use crate::service::{Core, Operation, SdoPayload, parse_name};

/// The CoE service over the core.
pub struct Coe {
    /// The service layer.
    pub core: Core,
}

type Reply<T> = Result<Response<T>, Status>;

#[tonic::async_trait]
impl CoeService for Coe {
    async fn upload(&self, request: Request<pb::UploadRequest>) -> Reply<pb::UploadResponse> {
        let r = request.get_ref();
        let (index, subindex) = (narrow(r.index, "index")?, narrow(r.subindex, "subindex")?);
        // proto3 has no absent string: an empty `value_type` asks for the bytes only.
        let typing = (!r.value_type.is_empty())
            .then(|| r.value_type.parse::<Typing>())
            .transpose()?;
        let read = self
            .core
            .coe_read(
                parse_name(&r.slave)?,
                index,
                subindex,
                r.complete_access,
                typing,
            )
            .await?;
        Ok(Response::new(pb::UploadResponse {
            data: read.data,
            value: read.value.unwrap_or_default(),
        }))
    }

    async fn download(&self, request: Request<pb::DownloadRequest>) -> Reply<pb::DownloadResponse> {
        let ticket = admit(&self.core, &request, Operation::CoeDownload)?;
        let r = request.get_ref();
        let payload = if r.value_type.is_empty() {
            SdoPayload::Bytes {
                data: &r.data,
                complete: r.complete_access,
            }
        } else {
            SdoPayload::Value {
                text: &r.value,
                typing: r.value_type.parse()?,
                complete: r.complete_access,
            }
        };
        let (index, subindex) = (narrow(r.index, "index")?, narrow(r.subindex, "subindex")?);
        self.core
            .coe_write(ticket, parse_name(&r.slave)?, index, subindex, payload)
            .await?;
        Ok(Response::new(pb::DownloadResponse {}))
    }

    async fn object_list(
        &self,
        request: Request<pb::ObjectListRequest>,
    ) -> Reply<pb::ObjectListResponse> {
        let r = request.get_ref();
        let list = if r.list == 0 {
            1
        } else {
            narrow(r.list, "list")?
        };
        let indices = self
            .core
            .coe_object_list(parse_name(&r.slave)?, list)
            .await?;
        Ok(Response::new(pb::ObjectListResponse {
            indices: indices.into_iter().map(u32::from).collect(),
        }))
    }

    async fn object_description(
        &self,
        request: Request<pb::ObjectDescriptionRequest>,
    ) -> Reply<pb::ObjectDescriptionResponse> {
        let r = request.get_ref();
        let o = self
            .core
            .coe_object(parse_name(&r.slave)?, narrow(r.index, "index")?)
            .await?;
        Ok(Response::new(pb::ObjectDescriptionResponse {
            index: u32::from(o.index),
            data_type: u32::from(o.data_type),
            data_type_name: o.data_type_name,
            max_subindex: u32::from(o.max_subindex),
            object_code: u32::from(o.object_code),
            name: o.name,
        }))
    }

    async fn entry_description(
        &self,
        request: Request<pb::EntryDescriptionRequest>,
    ) -> Reply<pb::EntryDescriptionResponse> {
        let r = request.get_ref();
        let e = self
            .core
            .coe_entry(
                parse_name(&r.slave)?,
                narrow(r.index, "index")?,
                narrow(r.subindex, "subindex")?,
            )
            .await?;
        Ok(Response::new(pb::EntryDescriptionResponse {
            index: u32::from(e.index),
            subindex: u32::from(e.subindex),
            data_type: u32::from(e.data_type),
            data_type_name: e.data_type_name,
            bit_length: u32::from(e.bit_length),
            access: u32::from(e.access),
            description: e.description,
        }))
    }
}
