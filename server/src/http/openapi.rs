//! The OpenAPI 3 document of the REST API, served at `/api/v1/openapi.json`: this frame
//! (description, schemas, bearer authentication) and the paths of the router that serves
//! them ([`super::router`] builds both from the handlers' annotations).

use utoipa::OpenApi;

use super::error::ErrorBody;
use super::rest;
use crate::service::gateway::{
    GatewayFailuresView, GatewayStatsView, GatewayView, LatencyBucketView, LatencyView,
};
use crate::service::{
    EmergencyView, EntryView, EventView, IdentityView, IpView, ObjectView, RedundancyView,
    SlaveView, VoeView,
};

/// The document's frame; the paths come from the router.
#[derive(OpenApi)]
#[openapi(
    info(title = "ecatd REST API", description = "EtherCAT master management: slaves, states, CoE, SoE, FoE, VoE, EoE, registers, SII and the ETG.8200 mailbox gateway. Slaves are named `3` (position), `#1004` (station, `%231004` in a path) or `@0x777` (alias)."),
    components(schemas(
        SlaveView, IdentityView, EventView, EmergencyView, IpView, ObjectView, EntryView, VoeView,
        ErrorBody, rest::Data, rest::coe::Upload, rest::coe::SdoWrite, rest::slaves::StateBody,
        rest::sii::AliasBody, rest::slaves::RescanBody, rest::coe::ObjectList, rest::voe::VoeBody, rest::Done,
        GatewayView, GatewayStatsView, GatewayFailuresView, LatencyView, LatencyBucketView,
        RedundancyView,
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
pub fn json(document: &utoipa::openapi::OpenApi) -> String {
    document.to_pretty_json().unwrap_or_else(|_| "{}".into())
}
