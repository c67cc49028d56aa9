//! `ecat gateway [start|stop]`: the mailbox gateway's state and statistics as a table or
//! JSON (the field names of `ecat.v1.GatewayStatus`).

use proto::v1 as pb;
use serde_json::{Value, json};

use crate::Run;
use crate::client::Clients;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::session::Session;

/// `ecat gateway`.
#[derive(Debug, clap::Args)]
pub struct Gateway {
    /// What to do (nothing: show the state).
    #[command(subcommand)]
    pub action: Option<Action>,
}

impl Run for Gateway {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let (json, human) = run(session.clients().await?, self.action).await?;
        Ok(out(json, human))
    }
}

/// What `ecat gateway` does.
#[derive(Debug, Clone, Copy, clap::Subcommand)]
pub enum Action {
    /// Start the gateway (binds its port, or a free one if it is taken).
    Start,
    /// Stop the gateway and release its port.
    Stop,
}

/// Runs `action` (none: show) and returns the gateway's state as JSON and as a table.
pub async fn run(c: &mut Clients, action: Option<Action>) -> Result<(Value, String), Failure> {
    let answer = match action {
        None => c.gateway.get_gateway(pb::GetGatewayRequest {}).await,
        Some(Action::Start) => c.gateway.start_gateway(pb::StartGatewayRequest {}).await,
        Some(Action::Stop) => c.gateway.stop_gateway(pb::StopGatewayRequest {}).await,
    };
    let status = answer
        .map_err(|s| format!("{:?}: {}", s.code(), s.message()))?
        .into_inner();
    Ok((to_json(&status), table(&status)))
}

fn to_json(g: &pb::GatewayStatus) -> Value {
    let s = g.stats.clone().unwrap_or_default();
    let f = s.failures.unwrap_or_default();
    let l = s.latency.unwrap_or_default();
    json!({
        "enabled": g.enabled, "running": g.running, "bound_address": g.bound_address,
        "port": g.port, "configured_address": g.configured_address,
        "master_number": g.master_number, "strict": g.strict, "allow": g.allow,
        "stats": {
            "total_requests": s.total_requests, "forwarded_requests": s.forwarded_requests,
            "failed_requests": s.failed_requests, "coe_count": s.coe_count,
            "soe_count": s.soe_count, "foe_count": s.foe_count, "voe_count": s.voe_count,
            "eoe_count": s.eoe_count, "started_at_ms": s.started_at_ms,
            "in_flight": s.in_flight, "port": s.port,
            "failures": {
                "malformed": f.malformed, "unknown_address": f.unknown_address,
                "unsupported_protocol": f.unsupported_protocol, "timeout": f.timeout,
                "denied": f.denied, "busy": f.busy, "oversized": f.oversized, "other": f.other,
            },
            "latency": {
                "count": l.count, "p50_us": l.p50_us, "p99_us": l.p99_us,
                "buckets": l.buckets.iter()
                    .map(|b| json!({"low_us": b.low_us, "high_us": b.high_us, "count": b.count}))
                    .collect::<Vec<_>>(),
            },
        },
    })
}

fn table(g: &pb::GatewayStatus) -> String {
    if !g.enabled {
        return "gateway      none (ecatd runs with --no-gateway)".into();
    }
    let s = g.stats.clone().unwrap_or_default();
    let f = s.failures.unwrap_or_default();
    let l = s.latency.unwrap_or_default();
    let state = if g.running {
        format!("running on {}", g.bound_address)
    } else {
        "stopped".into()
    };
    let micros = |v: Option<u64>| v.map_or("-".into(), |v| format!("{v} us"));
    [
        format!("gateway      {state}"),
        format!(
            "configured   {} (master {})",
            g.configured_address, g.master_number
        ),
        format!("strict       {}", if g.strict { "yes" } else { "no" }),
        format!("allow        {}", g.allow.join(", ")),
        format!("started      {} ms (Unix)", s.started_at_ms),
        format!(
            "requests     total {}  forwarded {}  failed {}  in flight {}",
            s.total_requests, s.forwarded_requests, s.failed_requests, s.in_flight
        ),
        format!(
            "protocols    CoE {}  SoE {}  FoE {}  VoE {}  EoE {}",
            s.coe_count, s.soe_count, s.foe_count, s.voe_count, s.eoe_count
        ),
        format!(
            "failures     malformed {}  unknown_address {}  unsupported_protocol {}  timeout {}  denied {}  busy {}  oversized {}  other {}",
            f.malformed,
            f.unknown_address,
            f.unsupported_protocol,
            f.timeout,
            f.denied,
            f.busy,
            f.oversized,
            f.other
        ),
        format!(
            "latency      {} requests  p50 {}  p99 {}",
            l.count,
            micros(l.p50_us),
            micros(l.p99_us)
        ),
    ]
    .join("\n")
}
