//! `ecat master`, `ecat rescan`, `ecat version`.

use proto::v1 as pb;
use serde_json::json;

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::failed;
use crate::session::Session;

/// `ecat master`.
#[derive(Debug, clap::Args)]
pub struct MasterCmd {}

/// `ecat rescan`.
#[derive(Debug, clap::Args)]
pub struct Rescan {}

/// `ecat version`.
#[derive(Debug, clap::Args)]
pub struct Version {}

fn master_json(m: &pb::GetMasterResponse) -> serde_json::Value {
    json!({
        "version": m.version, "link": m.link, "mac": m.mac, "ready": m.ready,
        "cycle_period_ns": m.cycle_period_ns, "slave_count": m.slave_count,
        "dc_reference": m.dc_reference, "dc_reference_time_ns": m.dc_reference_time_ns,
        "frames_sent": m.frames_sent, "frames_received": m.frames_received,
        "frames_lost": m.frames_lost, "link_errors": m.link_errors,
        "redundancy": m.redundancy.as_ref().map(|r| json!({
            "state": r.state, "break_after": r.break_after, "primary_side": r.primary_side,
            "backup_side": r.backup_side, "ring_slaves": r.ring_slaves,
            "unreachable": r.unreachable, "breaks": r.breaks, "heals": r.heals,
        })),
    })
}

/// The "Redundancy:" block (as IgH's `ethercat master` shows its backup device's state);
/// `off` in one line.
fn redundancy_text(r: Option<&pb::Redundancy>) -> String {
    let Some(r) = r.filter(|r| !r.state.is_empty() && r.state != "off") else {
        return "\n  Redundancy: off".to_owned();
    };
    let mut text = format!("\n  Redundancy:\n    State: {}", r.state);
    if let Some(after) = r.break_after {
        text.push_str(&format!(
            "\n    Break after: {after} slaves ({} on the primary port, {} on the backup port)\n    \
             Unreachable: {}",
            r.primary_side, r.backup_side, r.unreachable
        ));
    } else {
        text.push_str(&format!("\n    Ring slaves: {}", r.ring_slaves));
    }
    text.push_str(&format!(
        "\n    Breaks: {}\n    Heals: {}",
        r.breaks, r.heals
    ));
    text
}

impl Run for MasterCmd {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let m = session
            .clients()
            .await?
            .bus
            .get_master(pb::GetMasterRequest {})
            .await
            .map_err(failed)?
            .into_inner();
        let dc = match m.dc_reference {
            Some(position) => format!(
                "slave {position}, system time {} ns",
                m.dc_reference_time_ns
            ),
            None => "none".to_owned(),
        };
        let human = format!(
            "Master0\n  Phase: {}\n  Slaves: {}\n  Ethernet devices:\n    Main: {} ({})\n      \
             Tx frames:   {}\n      Rx frames:   {}\n      Lost frames: {}\n      \
             Link errors: {}\n  Cycle period: {} us\n  Distributed clocks:\n    \
             Reference clock: {dc}{}\n  ecatd: {}",
            if m.ready { "Operation" } else { "Scanning" },
            m.slave_count,
            m.mac,
            m.link,
            m.frames_sent,
            m.frames_received,
            m.frames_lost,
            m.link_errors,
            m.cycle_period_ns / 1000,
            redundancy_text(m.redundancy.as_ref()),
            m.version,
        );
        Ok(out(master_json(&m), human))
    }
}

impl Run for Rescan {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let r = session
            .clients()
            .await?
            .bus
            .rescan(pb::RescanRequest {})
            .await
            .map_err(failed)?
            .into_inner();
        let mut human = format!("{} slaves", r.slaves.len());
        for failure in &r.failures {
            human.push_str(&format!("\n{failure}"));
        }
        Ok(out(
            json!({"slaves": r.slaves.len(), "failures": r.failures}),
            human,
        ))
    }
}

impl Run for Version {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let client = env!("CARGO_PKG_VERSION");
        // The client's version prints even when ecatd cannot be reached.
        let server = match session.clients().await {
            Ok(c) => match c.bus.get_master(pb::GetMasterRequest {}).await {
                Ok(m) => m.into_inner().version,
                Err(status) => format!("unknown ({})", failed(status)),
            },
            Err(err) => format!("unknown ({err})"),
        };
        Ok(out(
            json!({"client": client, "server": server}),
            format!("ecat {client}\necatd {server}"),
        ))
    }
}
