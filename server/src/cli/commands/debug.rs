//! `ecat debug [LEVEL|FILTER]`: ecatd's runtime log filter, shown without an argument and
//! replaced with one. IgH's levels are taken as they are (`0` info, `1` debug, `2` trace);
//! anything else is a `tracing` filter (`warn`, `info,master_core::bus=debug`).

use proto::v1 as pb;
use serde_json::json;

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::failed;
use crate::session::Session;

/// `ecat debug`.
#[derive(Debug, clap::Args)]
pub struct Debug {
    /// The new filter: IgH's level (0, 1, 2) or a filter (`debug`,
    /// `info,master_core::bus=trace`); without it, the filter in force is printed.
    pub filter: Option<String>,
}

/// IgH's debug level as a filter.
fn from_level(text: &str) -> &str {
    match text.trim() {
        "0" => "info",
        "1" => "debug",
        "2" => "trace",
        other => other,
    }
}

impl Run for Debug {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let bus = &mut session.clients().await?.bus;
        let filter = match self.filter {
            None => {
                bus.get_log_filter(pb::GetLogFilterRequest {})
                    .await
                    .map_err(failed)?
                    .into_inner()
                    .filter
            }
            Some(filter) => {
                bus.set_log_filter(pb::SetLogFilterRequest {
                    filter: from_level(&filter).to_owned(),
                })
                .await
                .map_err(failed)?
                .into_inner()
                .filter
            }
        };
        Ok(out(json!({"filter": filter}), filter))
    }
}
