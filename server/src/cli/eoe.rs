//! `ecat eoe`: the EoE interfaces ecatd made, IgH-style (interface, MAC, state, slave,
//! frames and bytes each way, drops, reassembly errors), or JSON (the field names of
//! `ecat.v1.EoeInterface`).

use proto::v1 as pb;
use serde_json::{Value, json};

use crate::Run;
use crate::client::Clients;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::failed;
use crate::session::Session;

/// `ecat eoe`.
#[derive(Debug, clap::Args)]
pub struct Eoe {}

impl Run for Eoe {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let (json, human) = run(session.clients().await?).await?;
        Ok(out(json, human))
    }
}

/// Lists the interfaces: JSON and a table.
async fn run(c: &mut Clients) -> Result<(Value, String), Failure> {
    let list = c
        .eoe
        .list_interfaces(pb::ListInterfacesRequest {})
        .await
        .map_err(failed)?
        .into_inner();
    let json = Value::Array(list.interfaces.iter().map(to_json).collect());
    Ok((json, table(&list.interfaces)))
}

fn to_json(i: &pb::EoeInterface) -> Value {
    json!({
        "name": i.name, "mac": i.mac, "state": i.state, "position": i.position,
        "station": i.station, "alias": i.alias, "frames_out": i.frames_out,
        "bytes_out": i.bytes_out, "drops_out": i.drops_out, "frames_in": i.frames_in,
        "bytes_in": i.bytes_in, "drops_in": i.drops_in,
        "reassembly_errors": i.reassembly_errors,
    })
}

fn table(interfaces: &[pb::EoeInterface]) -> String {
    let mut out = format!(
        "{:<10} {:<17} {:<5} {:>5} {:>10} {:>12} {:>6} {:>10} {:>12} {:>6} {:>6}\n",
        "Interface",
        "MAC",
        "State",
        "Slave",
        "TxFrames",
        "TxBytes",
        "TxDrop",
        "RxFrames",
        "RxBytes",
        "RxDrop",
        "RxErr"
    );
    for i in interfaces {
        out.push_str(&format!(
            "{:<10} {:<17} {:<5} {:>5} {:>10} {:>12} {:>6} {:>10} {:>12} {:>6} {:>6}\n",
            i.name,
            i.mac,
            i.state,
            i.position,
            i.frames_out,
            i.bytes_out,
            i.drops_out,
            i.frames_in,
            i.bytes_in,
            i.drops_in,
            i.reassembly_errors
        ));
    }
    if interfaces.is_empty() {
        out.push_str("(no EoE interfaces)\n");
    }
    out
}
