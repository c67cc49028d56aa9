//! The connection settings and, once a command needs it, the gRPC connection (commands
//! such as `completion` never connect).

use std::path::PathBuf;

use proto::v1 as pb;

use crate::client::{Clients, connect};
use crate::failure::Failure;
use crate::parse::failed;

/// One invocation's connection.
pub struct Session {
    address: String,
    token: Option<String>,
    tls_ca: Option<PathBuf>,
    clients: Option<Clients>,
    json: bool,
}

impl Session {
    /// Not connected yet.
    pub fn new(address: String, token: Option<String>, tls_ca: Option<PathBuf>) -> Session {
        Session {
            address,
            token,
            tls_ca,
            clients: None,
            json: false,
        }
    }

    /// Sets whether the output is JSON (`--json`), for commands that print as they go.
    pub fn set_json(&mut self, json: bool) {
        self.json = json;
    }

    /// Whether the output is JSON: a command that prints as it goes (a stream) prints JSON
    /// lines itself.
    pub fn json(&self) -> bool {
        self.json
    }

    /// The gRPC clients, connecting on the first call.
    pub async fn clients(&mut self) -> Result<&mut Clients, Failure> {
        if self.clients.is_none() {
            let clients =
                connect(&self.address, self.token.as_deref(), self.tls_ca.as_deref()).await?;
            self.clients = Some(clients);
        }
        Ok(self.clients.as_mut().expect("connected just above"))
    }

    /// The slaves ecatd knows, in ring order.
    pub async fn slaves(&mut self) -> Result<Vec<pb::Slave>, Failure> {
        Ok(self
            .clients()
            .await?
            .bus
            .list_slaves(pb::ListSlavesRequest {})
            .await
            .map_err(failed)?
            .into_inner()
            .slaves)
    }

    /// The address given.
    pub fn address(&self) -> &str {
        &self.address
    }
}
