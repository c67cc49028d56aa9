//! The simulator's debug route, registered only when ecatd runs `--simulate`:
//! `POST /api/v1/slaves/{slave}/sim/emergency` raises a CoE emergency on a simulated slave,
//! which then arrives on the event streams like one from real hardware;
//! `GET /api/v1/slaves/{slave}/sim/outputs` reads a simulated digital output terminal's
//! physical outputs (`{"outputs": "hex"}`), what a probe on its terminals would show. Not part of the
//! OpenAPI document: it does not exist on a real segment.

use axum::Router;
use axum::extract::State;
use axum::routing::{get, post};
use serde::Deserialize;

use super::rest::Done;
use crate::http::extract::{Admit, Json, Path};
use crate::service::{ApiError, Core, Operation, op, parse_name};
use crate::sim_hooks::SimHooks;

/// What the route needs: the core (to name slaves) and the simulator's hooks.
#[derive(Clone)]
struct SimState {
    core: Core,
    hooks: SimHooks,
}

impl axum::extract::FromRef<SimState> for Core {
    fn from_ref(state: &SimState) -> Core {
        state.core.clone()
    }
}

/// The emergency to raise.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EmergencyBody {
    /// CiA 301 error code.
    pub error_code: u16,
    /// Error register (object 0x1001).
    pub error_register: u8,
    /// The five manufacturer-specific bytes, hex.
    pub data: String,
}

/// The route, when ecatd runs the simulator (`hooks` given); otherwise none.
pub fn routes<S: Clone + Send + Sync + 'static>(core: Core, hooks: Option<SimHooks>) -> Router<S> {
    let Some(hooks) = hooks else {
        return Router::new();
    };
    Router::new()
        .route("/slaves/{slave}/sim/emergency", post(raise_emergency))
        .route("/slaves/{slave}/sim/outputs", get(outputs))
        .with_state(SimState { core, hooks })
}

async fn raise_emergency(
    Admit(mut ticket, _): Admit<op::SimEmergency>,
    State(SimState { core, hooks }): State<SimState>,
    Path(slave): Path<String>,
    Json(body): Json<EmergencyBody>,
) -> Result<Json<Done>, ApiError> {
    // The simulator's hooks are no part of the core: the ticket is used here.
    ticket.check(Operation::SimEmergency, &slave)?;
    ticket.finish(emergency(&core, &hooks, &slave, &body))
}

fn emergency(
    core: &Core,
    hooks: &SimHooks,
    slave: &str,
    body: &EmergencyBody,
) -> Result<Json<Done>, ApiError> {
    let data: [u8; 5] = hex::decode(body.data.trim())
        .ok()
        .and_then(|bytes| bytes.try_into().ok())
        .ok_or_else(|| ApiError::invalid("data must be 5 bytes, hex"))?;
    let position = core.get_slave(parse_name(slave)?)?.position;
    hooks.raise_emergency(position, body.error_code, body.error_register, data)?;
    Ok(Json(Done { ok: true }))
}

/// A simulated terminal's physical outputs.
#[derive(Debug, serde::Serialize)]
pub struct OutputsBody {
    /// The output bytes, hex.
    pub outputs: String,
}

async fn outputs(
    State(SimState { core, hooks }): State<SimState>,
    Path(slave): Path<String>,
) -> Result<Json<OutputsBody>, ApiError> {
    let position = core.get_slave(parse_name(&slave)?)?.position;
    Ok(Json(OutputsBody {
        outputs: hex::encode(hooks.outputs(position)?),
    }))
}
