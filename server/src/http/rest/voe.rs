//! VoE: one vendor message and its answer.

use axum::extract::State;
use serde::Deserialize;
use utoipa::ToSchema;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::{Result, unhex};
use crate::http::extract::{Admit, Json, Path};
use crate::service::{Core, VoeView};
use crate::service::{op, parse_name};

/// The routes, each declared once (method and path come from the handler's annotation).
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new().routes(routes!(voe))
}

/// A VoE message to send.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct VoeBody {
    /// Vendor id.
    pub vendor_id: u32,
    /// Vendor type.
    pub vendor_type: u16,
    /// Payload, hex.
    pub data: String,
}

#[utoipa::path(post, path = "/slaves/{slave}/voe", tag = "voe", request_body = VoeBody,
    params(("slave" = String, Path)), responses((status = 200, body = VoeView)))]
/// Sends one VoE message and returns the answer.
pub async fn voe(
    Admit(ticket, _): Admit<op::Voe>,
    State(core): State<Core>,
    Path(slave): Path<String>,
    Json(body): Json<VoeBody>,
) -> Result<Json<VoeView>> {
    let answer = core
        .voe(
            ticket,
            parse_name(&slave)?,
            body.vendor_id,
            body.vendor_type,
            &unhex(&body.data)?,
        )
        .await?;
    Ok(Json(VoeView {
        vendor_id: answer.vendor_id,
        vendor_type: answer.vendor_type,
        data: hex::encode(answer.data),
    }))
}
