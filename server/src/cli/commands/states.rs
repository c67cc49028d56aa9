//! `ecat states STATE`: for the selected slave, or every slave when none is selected (as
//! IgH does).

use proto::v1 as pb;
use serde_json::Value;

use super::slaves::slave_json;
use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::{failed, state};
use crate::select::Selection;
use crate::session::Session;

/// `ecat states`.
#[derive(Debug, clap::Args)]
pub struct States {
    /// The slave (all when none is selected).
    #[command(flatten)]
    pub select: Selection,
    /// The state.
    pub state: String,
}

impl Run for States {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let target = state(&self.state)? as i32;
        let c = session.clients().await?;
        let slaves = match self.select.given()? {
            Some(s) => vec![s],
            None => c
                .bus
                .list_slaves(pb::ListSlavesRequest {})
                .await
                .map_err(failed)?
                .into_inner()
                .slaves
                .iter()
                .map(|s| s.position.to_string())
                .collect(),
        };
        let mut done = Vec::new();
        for slave in slaves {
            let r = c
                .bus
                .request_state(pb::RequestStateRequest {
                    slave,
                    state: target,
                })
                .await
                .map_err(failed)?
                .into_inner();
            done.extend(r.slave.as_ref().map(slave_json));
        }
        let human = done
            .iter()
            .map(|s| format!("{} {}", s["position"], s["state"].as_str().unwrap_or("")))
            .collect::<Vec<_>>()
            .join("\n");
        Ok(out(Value::Array(done), human))
    }
}
