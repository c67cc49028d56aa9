//! `ecat config`: the configuration ecatd runs with (IgH's `ethercat config`): the cycle,
//! the expected slaves with their PDOs, DC and start-up commands, the groups, as TOML in
//! the configuration file's keys; `--json` gives `{ "toml": ..., "eni": ... }`.

use proto::v1 as pb;
use serde_json::{Value, json};

use crate::Run;
use crate::client::Clients;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::failed;
use crate::session::Session;

/// `ecat config`.
#[derive(Debug, clap::Args)]
pub struct Config {}

impl Run for Config {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let (json, human) = run(session.clients().await?).await?;
        Ok(out(json, human))
    }
}

/// Asks ecatd for its effective configuration: as JSON and as text.
async fn run(c: &mut Clients) -> Result<(Value, String), Failure> {
    let config = c
        .bus
        .get_config(pb::GetConfigRequest {})
        .await
        .map_err(failed)?
        .into_inner();
    let human = if config.eni.is_empty() {
        config.toml.clone()
    } else {
        format!(
            "# slaves and cycle from the ENI file {}\n{}",
            config.eni, config.toml
        )
    };
    Ok((json!({ "toml": config.toml, "eni": config.eni }), human))
}
