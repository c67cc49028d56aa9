//! `ecat completion SHELL` and `ecat man`: generated from the clap definitions, so they
//! cannot drift from the commands.

use clap::CommandFactory;
use serde_json::json;

use crate::failure::Failure;
use crate::out::{Out, bytes};
use crate::session::Session;
use crate::{Cli, Run};

/// `ecat completion`.
#[derive(Debug, clap::Args)]
pub struct Completion {
    /// The shell.
    pub shell: clap_complete::Shell,
}

/// `ecat man`.
#[derive(Debug, clap::Args)]
pub struct Man {}

impl Run for Completion {
    async fn run(self, _: &mut Session) -> Result<Out, Failure> {
        let mut script = Vec::new();
        clap_complete::generate(self.shell, &mut Cli::command(), "ecat", &mut script);
        Ok(bytes(
            json!({"shell": self.shell.to_string(), "script": String::from_utf8_lossy(&script)}),
            script,
        ))
    }
}

impl Run for Man {
    async fn run(self, _: &mut Session) -> Result<Out, Failure> {
        let mut page = Vec::new();
        clap_mangen::Man::new(Cli::command())
            .render(&mut page)
            .map_err(|err| format!("man page: {err}"))?;
        Ok(bytes(json!({"roff": String::from_utf8_lossy(&page)}), page))
    }
}
