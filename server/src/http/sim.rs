//! The simulator's debug route, registered only when ecatd runs `--simulate`:
//! `POST /api/v1/slaves/{slave}/sim/emergency` raises a CoE emergency on a simulated slave,
//! which then arrives on the event streams like one from real hardware;
//! `GET /api/v1/slaves/{slave}/sim/outputs` reads a simulated digital output terminal's
//! physical outputs (`{"outputs": "hex"}`), what a probe on its terminals would show;
//! `POST /api/v1/sim/ring` cuts a cable of a simulated ring, kills a slave on it or heals it
//! (`{"action":"break","cable":3}`, `{"action":"kill","position":2}`, `{"action":"heal"}`;
//! docs/redundancy.md). Not part of the OpenAPI document: they do not exist on a real
//! segment.

use axum::Router;
use axum::extract::State;
use axum::routing::{get, post};
use serde::Deserialize;

use super::rest::Done;
use crate::http::extract::{Admit, Json, Path};
use crate::service::{ApiError, Core, Operation, op, parse_name};
use crate::sim_hooks::{RingCut, SimHooks};

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
        .route("/sim/ring", post(ring))
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
        .ok_or_else(|| ApiError::invalid_field("data", "data must be 5 bytes, hex"))?;
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

/// What to do to the simulated ring: `action` is `break` (with `cable`), `kill` (with
/// `position`) or `heal`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RingBody {
    /// `break`, `kill` or `heal`.
    pub action: String,
    /// The cable to cut (`break`): 0 is the master's primary cable, `k` the cable after
    /// `k` slaves, the slave count the cable back into the backup port.
    pub cable: Option<u16>,
    /// The ring position of the slave to switch off (`kill`).
    pub position: Option<u16>,
}

impl RingBody {
    /// The cut asked for; the field at fault otherwise.
    fn cut(&self) -> Result<RingCut, ApiError> {
        let unexpected = |field: &'static str| {
            ApiError::invalid_field(
                field,
                format!("{field} does not go with action {:?}", self.action),
            )
        };
        match self.action.as_str() {
            "break" => {
                if self.position.is_some() {
                    return Err(unexpected("position"));
                }
                let cable = self
                    .cable
                    .ok_or_else(|| ApiError::invalid_field("cable", "break needs a cable"))?;
                Ok(RingCut::Break { cable })
            }
            "kill" => {
                if self.cable.is_some() {
                    return Err(unexpected("cable"));
                }
                let position = self
                    .position
                    .ok_or_else(|| ApiError::invalid_field("position", "kill needs a position"))?;
                Ok(RingCut::Kill { position })
            }
            "heal" => match (self.cable, self.position) {
                (Some(_), _) => Err(unexpected("cable")),
                (_, Some(_)) => Err(unexpected("position")),
                (None, None) => Ok(RingCut::Heal),
            },
            other => Err(ApiError::invalid_field(
                "action",
                format!("unknown action {other:?}: break, kill or heal"),
            )),
        }
    }
}

async fn ring(
    Admit(mut ticket, _): Admit<op::SimRing>,
    State(SimState { hooks, .. }): State<SimState>,
    Json(body): Json<RingBody>,
) -> Result<Json<Done>, ApiError> {
    // The simulator's hooks are no part of the core: the ticket is used here.
    let target = match (body.cable, body.position) {
        (Some(cable), _) => format!("ring: {} cable {cable}", body.action),
        (_, Some(position)) => format!("ring: {} position {position}", body.action),
        (None, None) => format!("ring: {}", body.action),
    };
    ticket.check(Operation::SimRing, target)?;
    ticket.finish(
        body.cut()
            .and_then(|cut| hooks.ring(cut))
            .map(|()| Json(Done { ok: true })),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn body(text: &str) -> RingBody {
        serde_json::from_str(text).expect("a ring body")
    }

    #[test]
    fn ring_bodies_name_the_cut_or_the_field_at_fault() {
        assert_eq!(
            body(r#"{"action":"break","cable":3}"#).cut(),
            Ok(RingCut::Break { cable: 3 })
        );
        assert_eq!(
            body(r#"{"action":"kill","position":2}"#).cut(),
            Ok(RingCut::Kill { position: 2 })
        );
        assert_eq!(body(r#"{"action":"heal"}"#).cut(), Ok(RingCut::Heal));
        for (text, field) in [
            (r#"{"action":"cut","cable":3}"#, "action"),
            (r#"{"action":"break"}"#, "cable"),
            (r#"{"action":"kill","cable":1}"#, "cable"),
            (r#"{"action":"heal","position":1}"#, "position"),
        ] {
            let refused = body(text).cut().unwrap_err();
            assert_eq!(
                (refused.kind.http(), refused.field),
                (400, Some(field)),
                "{text}"
            );
        }
        assert!(serde_json::from_str::<RingBody>(r#"{"action":"heal","extra":1}"#).is_err());
    }
}
