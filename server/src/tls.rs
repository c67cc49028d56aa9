//! Optional TLS for both APIs (`[tls]` / `--tls-cert`, `--tls-key`): rustls with the ring
//! provider. gRPC uses tonic's own TLS; HTTP gets a listener that finishes each handshake in
//! its own task (bounded in number and time, so a slow client cannot hold up the others)
//! and hands axum only connections whose handshake succeeded.

use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use tokio::net::{TcpListener, TcpStream};
use tokio::task::JoinSet;
use tokio_rustls::TlsAcceptor;
use tokio_rustls::rustls::ServerConfig;
use tokio_rustls::rustls::crypto::ring;
use tokio_rustls::rustls::pki_types::pem::PemObject;
use tokio_rustls::rustls::pki_types::{CertificateDer, PrivateKeyDer};
use tokio_rustls::server::TlsStream;

use crate::config::TlsSettings;

/// Handshakes under way at once; connections beyond are closed at once.
const MAX_HANDSHAKES: usize = 64;
/// Time a client has to finish its handshake.
const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(10);

/// The certificate chain and key, read once at start.
#[derive(Clone)]
pub struct TlsFiles {
    cert_pem: Vec<u8>,
    key_pem: Vec<u8>,
}

fn read(path: &Path, what: &str) -> Result<Vec<u8>, String> {
    std::fs::read(path).map_err(|err| format!("cannot read TLS {what} {}: {err}", path.display()))
}

impl TlsFiles {
    /// Reads and checks the PEM files named by `settings`.
    pub fn load(settings: &TlsSettings) -> Result<TlsFiles, String> {
        let files = TlsFiles {
            cert_pem: read(&settings.cert, "certificate")?,
            key_pem: read(&settings.key, "key")?,
        };
        // Fail at start, not at the first connection.
        files.rustls(Vec::new())?;
        Ok(files)
    }

    /// tonic's configuration (it negotiates `h2` itself).
    pub fn grpc(&self) -> tonic::transport::ServerTlsConfig {
        tonic::transport::ServerTlsConfig::new().identity(tonic::transport::Identity::from_pem(
            &self.cert_pem,
            &self.key_pem,
        ))
    }

    /// The HTTP side's acceptor (HTTP/2 and HTTP/1.1 offered through ALPN).
    pub fn http(&self) -> Result<TlsAcceptor, String> {
        Ok(TlsAcceptor::from(Arc::new(
            self.rustls(vec![b"h2".to_vec(), b"http/1.1".to_vec()])?,
        )))
    }

    fn rustls(&self, alpn: Vec<Vec<u8>>) -> Result<ServerConfig, String> {
        let certs = CertificateDer::pem_slice_iter(&self.cert_pem)
            .collect::<Result<Vec<_>, _>>()
            .map_err(|err| format!("TLS certificate: {err}"))?;
        if certs.is_empty() {
            return Err("TLS certificate: no certificate in the file".into());
        }
        let key = PrivateKeyDer::from_pem_slice(&self.key_pem)
            .map_err(|err| format!("TLS key: {err}"))?;
        let mut config = ServerConfig::builder_with_provider(Arc::new(ring::default_provider()))
            .with_safe_default_protocol_versions()
            .map_err(|err| format!("TLS: {err}"))?
            .with_no_client_auth()
            .with_single_cert(certs, key)
            .map_err(|err| format!("TLS certificate and key: {err}"))?;
        config.alpn_protocols = alpn;
        Ok(config)
    }
}

type Handshake = Option<(TlsStream<TcpStream>, SocketAddr)>;

/// A TCP listener whose connections axum gets after their TLS handshake.
pub struct TlsListener {
    tcp: TcpListener,
    acceptor: TlsAcceptor,
    handshakes: JoinSet<Handshake>,
}

impl TlsListener {
    /// TLS on `tcp` with `acceptor`.
    pub fn new(tcp: TcpListener, acceptor: TlsAcceptor) -> TlsListener {
        TlsListener {
            tcp,
            acceptor,
            handshakes: JoinSet::new(),
        }
    }
}

impl axum::serve::Listener for TlsListener {
    type Io = TlsStream<TcpStream>;
    type Addr = SocketAddr;

    async fn accept(&mut self) -> (Self::Io, Self::Addr) {
        loop {
            // Both branches are cancel-safe: the state lives in `self`.
            tokio::select! {
                accepted = self.tcp.accept() => match accepted {
                    Ok((stream, peer)) => {
                        if self.handshakes.len() >= MAX_HANDSHAKES {
                            tracing::debug!(%peer, "TLS handshakes at their limit; connection closed");
                            continue;
                        }
                        let acceptor = self.acceptor.clone();
                        self.handshakes.spawn(async move {
                            match tokio::time::timeout(HANDSHAKE_TIMEOUT, acceptor.accept(stream)).await {
                                Ok(Ok(tls)) => Some((tls, peer)),
                                Ok(Err(err)) => {
                                    tracing::debug!(%peer, %err, "TLS handshake failed");
                                    None
                                }
                                Err(_) => {
                                    tracing::debug!(%peer, "TLS handshake timed out");
                                    None
                                }
                            }
                        });
                    }
                    Err(err) => {
                        // Out of file descriptors and the like: back off instead of spinning
                        // (axum's own listener does the same).
                        tracing::warn!(%err, "HTTP accept failed");
                        tokio::time::sleep(Duration::from_millis(100)).await;
                    }
                },
                Some(done) = self.handshakes.join_next(), if !self.handshakes.is_empty() => {
                    if let Ok(Some(connection)) = done {
                        return connection;
                    }
                }
            }
        }
    }

    fn local_addr(&self) -> std::io::Result<Self::Addr> {
        self.tcp.local_addr()
    }
}
