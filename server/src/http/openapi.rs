//! The OpenAPI 3 document of the REST API, generated from the handlers' annotations and
//! served at `/api/v1/openapi.json`.

use utoipa::OpenApi;

use super::error::{ErrorBody, ErrorInfo};
use super::{gateway, rest};
use crate::service::gateway::{
    GatewayFailuresView, GatewayStatsView, GatewayView, LatencyBucketView, LatencyView,
};
use crate::service::{
    EmergencyView, EntryView, EventView, IdentityView, IpView, ObjectView, SlaveView, VoeView,
};

/// The document.
#[derive(OpenApi)]
#[openapi(
    info(title = "ecatd REST API", description = "EtherCAT master management: slaves, states, CoE, SoE, FoE, VoE, EoE, registers, SII and the ETG.8200 mailbox gateway. Slaves are named `3` (position), `#1004` (station, `%231004` in a path) or `@0x777` (alias)."),
    paths(
        rest::list_slaves, rest::get_slave, rest::request_state, rest::rescan, rest::events,
        rest::read_register, rest::write_register, rest::read_sii, rest::write_sii, rest::set_alias,
        rest::coe_upload, rest::coe_download, rest::coe_object_list, rest::coe_object, rest::coe_entry,
        rest::soe_read, rest::soe_write, rest::foe_read, rest::foe_write, rest::voe,
        rest::eoe_get_ip, rest::eoe_set_ip,
        gateway::get_gateway, gateway::start_gateway, gateway::stop_gateway,
    ),
    components(schemas(
        SlaveView, IdentityView, EventView, EmergencyView, IpView, ObjectView, EntryView, VoeView,
        ErrorBody, ErrorInfo, rest::Data, rest::Upload, rest::SdoWrite, rest::StateBody, rest::AliasBody,
        rest::RescanBody, rest::ObjectList, rest::VoeBody, rest::Done,
        GatewayView, GatewayStatsView, GatewayFailuresView, LatencyView, LatencyBucketView,
    )),
    modifiers(&BearerAuth),
    security(("bearer" = []))
)]
pub struct ApiDoc;

struct BearerAuth;

impl utoipa::Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "bearer",
            SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
        );
    }
}

/// The document as JSON.
pub fn json() -> String {
    ApiDoc::openapi()
        .to_pretty_json()
        .unwrap_or_else(|_| "{}".into())
}
