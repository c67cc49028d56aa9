//! EoE: the IP parameters of a slave's EoE port, and the interfaces ecatd made.

use axum::extract::State;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::{DONE, Done, Result};
use crate::eoe::InterfaceView;
use crate::http::extract::{Admit, Json, Path};
use crate::input::mac_filter::MacFilterView;
use crate::service::{Core, IpView};
use crate::service::{op, parse_name};

/// The routes, each declared once (method and path come from the handler's annotation).
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new()
        .routes(routes!(eoe_get_ip, eoe_set_ip))
        .routes(routes!(eoe_set_address_filter))
        .routes(routes!(eoe_interfaces))
}

#[utoipa::path(get, path = "/slaves/{slave}/eoe/ip", tag = "eoe",
    params(("slave" = String, Path)), responses((status = 200, body = IpView)))]
/// Reads the EoE IP parameters.
pub async fn eoe_get_ip(
    State(core): State<Core>,
    Path(slave): Path<String>,
) -> Result<Json<IpView>> {
    core.eoe_get_ip(parse_name(&slave)?).await.map(Json)
}

#[utoipa::path(put, path = "/slaves/{slave}/eoe/ip", tag = "eoe", request_body = IpView,
    params(("slave" = String, Path)), responses((status = 200, body = Done)))]
/// Sets the EoE IP parameters.
pub async fn eoe_set_ip(
    Admit(ticket, _): Admit<op::EoeSetIp>,
    State(core): State<Core>,
    Path(slave): Path<String>,
    Json(body): Json<IpView>,
) -> Result<Json<Done>> {
    core.eoe_set_ip(ticket, parse_name(&slave)?, &body)
        .await
        .map(|()| DONE)
}

#[utoipa::path(put, path = "/slaves/{slave}/eoe/filter", tag = "eoe", request_body = MacFilterView,
    params(("slave" = String, Path)), responses((status = 200, body = Done)))]
/// Sets the EoE address filter: which frames the slave passes to its device.
pub async fn eoe_set_address_filter(
    Admit(ticket, _): Admit<op::EoeSetAddressFilter>,
    State(core): State<Core>,
    Path(slave): Path<String>,
    Json(body): Json<MacFilterView>,
) -> Result<Json<Done>> {
    core.eoe_set_address_filter(ticket, parse_name(&slave)?, &body)
        .await
        .map(|()| DONE)
}

#[utoipa::path(get, path = "/eoe/interfaces", tag = "eoe",
    responses((status = 200, body = Vec<InterfaceView>)))]
/// Lists the EoE interfaces: name, MAC, state, slave and counters.
pub async fn eoe_interfaces(State(core): State<Core>) -> Json<Vec<InterfaceView>> {
    Json(core.eoe_interfaces())
}
