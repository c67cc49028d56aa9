//! The connection settings and, once a command needs it, the gRPC connection (commands
//! such as `completion` never connect).

use std::path::PathBuf;

use crate::client::{Clients, connect};

/// One invocation's connection.
pub struct Session {
    address: String,
    token: Option<String>,
    tls_ca: Option<PathBuf>,
    clients: Option<Clients>,
}

impl Session {
    /// Not connected yet.
    pub fn new(address: String, token: Option<String>, tls_ca: Option<PathBuf>) -> Session {
        Session {
            address,
            token,
            tls_ca,
            clients: None,
        }
    }

    /// The gRPC clients, connecting on the first call.
    pub async fn clients(&mut self) -> Result<&mut Clients, String> {
        if self.clients.is_none() {
            let clients =
                connect(&self.address, self.token.as_deref(), self.tls_ca.as_deref()).await?;
            self.clients = Some(clients);
        }
        Ok(self.clients.as_mut().expect("connected just above"))
    }

    /// The address given.
    pub fn address(&self) -> &str {
        &self.address
    }
}
