//! `ecat.v1.SoeService`, `VoeService` and `EoeService`: one call each into the core.

use proto::v1 as pb;
use proto::v1::eoe_service_server::EoeService;
use proto::v1::soe_service_server::SoeService;
use proto::v1::voe_service_server::VoeService;
use tonic::{Request, Response, Status};

use super::auth::admit;
use super::status::narrow;
use crate::input::soe_value;
use crate::service::{Core, IpView, Operation, parse_name};

/// The SoE, VoE and EoE services over the core.
pub struct Protocols {
    /// The service layer.
    pub core: Core,
}

type Reply<T> = Result<Response<T>, Status>;

#[tonic::async_trait]
impl SoeService for Protocols {
    async fn read(&self, request: Request<pb::SoeReadRequest>) -> Reply<pb::SoeReadResponse> {
        let r = request.get_ref();
        let (data, value) = self
            .core
            .soe_read_as(
                parse_name(&r.slave)?,
                narrow(r.drive, "drive")?,
                narrow(r.idn, "idn")?,
                narrow(r.elements, "elements")?,
                soe_value::parse_type(&r.value_type)?,
            )
            .await?;
        Ok(Response::new(pb::SoeReadResponse {
            data,
            value: value.unwrap_or_default(),
        }))
    }

    async fn write(&self, request: Request<pb::SoeWriteRequest>) -> Reply<pb::SoeWriteResponse> {
        let ticket = admit(&self.core, &request, Operation::SoeWrite)?;
        let r = request.get_ref();
        let data = match soe_value::parse_type(&r.value_type)? {
            Some(ty) => soe_value::encode(ty, &r.value)?,
            None => r.data.clone(),
        };
        self.core
            .soe_write(
                ticket,
                parse_name(&r.slave)?,
                narrow(r.drive, "drive")?,
                narrow(r.idn, "idn")?,
                narrow(r.elements, "elements")?,
                &data,
            )
            .await?;
        Ok(Response::new(pb::SoeWriteResponse {}))
    }
}

#[tonic::async_trait]
impl VoeService for Protocols {
    async fn transfer(&self, request: Request<pb::VoeRequest>) -> Reply<pb::VoeResponse> {
        let ticket = admit(&self.core, &request, Operation::Voe)?;
        let r = request.get_ref();
        let answer = self
            .core
            .voe(
                ticket,
                parse_name(&r.slave)?,
                r.vendor_id,
                narrow(r.vendor_type, "vendor_type")?,
                &r.data,
            )
            .await?;
        Ok(Response::new(pb::VoeResponse {
            vendor_id: answer.vendor_id,
            vendor_type: u32::from(answer.vendor_type),
            data: answer.data,
        }))
    }
}

fn some(text: &str) -> Option<String> {
    (!text.is_empty()).then(|| text.to_owned())
}

#[tonic::async_trait]
impl EoeService for Protocols {
    async fn set_address_filter(
        &self,
        request: Request<pb::SetAddressFilterRequest>,
    ) -> Reply<pb::SetAddressFilterResponse> {
        let ticket = admit(&self.core, &request, Operation::EoeSetAddressFilter)?;
        let r = request.get_ref();
        let view = crate::input::mac_filter::MacFilterView {
            macs: r.macs.clone(),
            masks: r.masks.clone(),
            no_broadcasts: r.no_broadcasts,
        };
        self.core
            .eoe_set_address_filter(ticket, parse_name(&r.slave)?, &view)
            .await?;
        Ok(Response::new(pb::SetAddressFilterResponse {}))
    }

    async fn set_ip(&self, request: Request<pb::SetIpRequest>) -> Reply<pb::SetIpResponse> {
        let ticket = admit(&self.core, &request, Operation::EoeSetIp)?;
        let r = request.get_ref();
        let s = r.settings.clone().unwrap_or_default();
        let view = IpView {
            mac: some(&s.mac),
            ip: some(&s.ip),
            subnet_mask: some(&s.subnet_mask),
            default_gateway: some(&s.default_gateway),
            dns_server: some(&s.dns_server),
            dns_name: some(&s.dns_name),
        };
        self.core
            .eoe_set_ip(ticket, parse_name(&r.slave)?, &view)
            .await?;
        Ok(Response::new(pb::SetIpResponse {}))
    }

    async fn list_interfaces(
        &self,
        _request: Request<pb::ListInterfacesRequest>,
    ) -> Reply<pb::ListInterfacesResponse> {
        let interfaces = self
            .core
            .eoe_interfaces()
            .into_iter()
            .map(|i| pb::EoeInterface {
                name: i.name,
                mac: i.mac,
                state: i.state,
                position: u32::from(i.position),
                station: u32::from(i.station),
                alias: u32::from(i.alias),
                frames_out: i.frames_out,
                bytes_out: i.bytes_out,
                drops_out: i.drops_out,
                frames_in: i.frames_in,
                bytes_in: i.bytes_in,
                drops_in: i.drops_in,
                reassembly_errors: i.reassembly_errors,
            })
            .collect();
        Ok(Response::new(pb::ListInterfacesResponse { interfaces }))
    }

    async fn get_ip(&self, request: Request<pb::GetIpRequest>) -> Reply<pb::IpSettings> {
        let v = self
            .core
            .eoe_get_ip(parse_name(&request.get_ref().slave)?)
            .await?;
        Ok(Response::new(pb::IpSettings {
            mac: v.mac.unwrap_or_default(),
            ip: v.ip.unwrap_or_default(),
            subnet_mask: v.subnet_mask.unwrap_or_default(),
            default_gateway: v.default_gateway.unwrap_or_default(),
            dns_server: v.dns_server.unwrap_or_default(),
            dns_name: v.dns_name.unwrap_or_default(),
        }))
    }
}
