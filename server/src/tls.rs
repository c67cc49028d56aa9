//! Optional TLS for both APIs (`[tls]` / `--tls-cert`, `--tls-key`): rustls with the ring
//! provider, on both sides through one listener type that finishes each handshake in its own
//! task (bounded in number and time, so a slow client cannot hold up the others) and hands
//! the server only connections whose handshake succeeded.
//!
//! The certificate is chosen per handshake from [`TlsFiles`]' current one, which
//! [`TlsFiles::reload`] swaps (SIGHUP): new connections get the new certificate, established
//! ones keep theirs, and a certificate that does not load leaves the current one in place.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, PoisonError, RwLock};
use std::time::Duration;

use tokio::net::{TcpListener, TcpStream};
use tokio::task::JoinSet;
use tokio_rustls::TlsAcceptor;
use tokio_rustls::rustls::ServerConfig;
use tokio_rustls::rustls::crypto::ring;
use tokio_rustls::rustls::pki_types::pem::PemObject;
use tokio_rustls::rustls::pki_types::{CertificateDer, PrivateKeyDer};
use tokio_rustls::rustls::server::{ClientHello, ResolvesServerCert};
use tokio_rustls::rustls::sign::CertifiedKey;
use tokio_rustls::server::TlsStream;

use crate::config::TlsSettings;

/// Handshakes under way at once; connections beyond are closed at once.
const MAX_HANDSHAKES: usize = 64;
/// Time a client has to finish its handshake.
const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(10);

/// The certificate new handshakes get; swapped whole on reload.
#[derive(Debug)]
struct CurrentCert(RwLock<Arc<CertifiedKey>>);

impl ResolvesServerCert for CurrentCert {
    fn resolve(&self, _hello: ClientHello<'_>) -> Option<Arc<CertifiedKey>> {
        Some(Arc::clone(
            &self.0.read().unwrap_or_else(PoisonError::into_inner),
        ))
    }
}

/// The certificate chain and key named by the settings, read at start and again on
/// [`TlsFiles::reload`]. Clones share the current certificate.
#[derive(Clone)]
pub struct TlsFiles {
    cert: PathBuf,
    key: PathBuf,
    current: Arc<CurrentCert>,
}

impl std::fmt::Debug for TlsFiles {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TlsFiles")
            .field("cert", &self.cert)
            .field("key", &self.key)
            .finish_non_exhaustive()
    }
}

fn read(path: &std::path::Path, what: &str) -> Result<Vec<u8>, String> {
    std::fs::read(path).map_err(|err| format!("cannot read TLS {what} {}: {err}", path.display()))
}

impl TlsFiles {
    /// Reads and checks the PEM files named by `settings` (the key must belong to the
    /// certificate): a bad pair fails at start, not at the first connection.
    pub fn load(settings: &TlsSettings) -> Result<TlsFiles, String> {
        let certified = certified(&settings.cert, &settings.key)?;
        Ok(TlsFiles {
            cert: settings.cert.clone(),
            key: settings.key.clone(),
            current: Arc::new(CurrentCert(RwLock::new(Arc::new(certified)))),
        })
    }

    /// Reads the same files again and, if they hold a valid certificate and its key, serves
    /// them to every new connection (established ones keep the certificate they got). On
    /// error the certificate in use stays.
    pub fn reload(&self) -> Result<(), String> {
        let certified = certified(&self.cert, &self.key)?;
        *self
            .current
            .0
            .write()
            .unwrap_or_else(PoisonError::into_inner) = Arc::new(certified);
        Ok(())
    }

    /// The gRPC side's acceptor (`h2` only, as gRPC needs).
    pub fn grpc(&self) -> Result<TlsAcceptor, String> {
        self.acceptor(vec![b"h2".to_vec()])
    }

    /// The HTTP side's acceptor (HTTP/2 and HTTP/1.1 offered through ALPN).
    pub fn http(&self) -> Result<TlsAcceptor, String> {
        self.acceptor(vec![b"h2".to_vec(), b"http/1.1".to_vec()])
    }

    fn acceptor(&self, alpn: Vec<Vec<u8>>) -> Result<TlsAcceptor, String> {
        let resolver: Arc<dyn ResolvesServerCert> = self.current.clone();
        let mut config = ServerConfig::builder_with_provider(Arc::new(ring::default_provider()))
            .with_safe_default_protocol_versions()
            .map_err(|err| format!("TLS: {err}"))?
            .with_no_client_auth()
            .with_cert_resolver(resolver);
        config.alpn_protocols = alpn;
        Ok(TlsAcceptor::from(Arc::new(config)))
    }
}

/// The certificate chain of `cert` with the key of `key`, checked to belong together.
fn certified(cert: &std::path::Path, key: &std::path::Path) -> Result<CertifiedKey, String> {
    let cert_pem = read(cert, "certificate")?;
    let key_pem = read(key, "key")?;
    let certs = CertificateDer::pem_slice_iter(&cert_pem)
        .collect::<Result<Vec<_>, _>>()
        .map_err(|err| format!("TLS certificate: {err}"))?;
    if certs.is_empty() {
        return Err("TLS certificate: no certificate in the file".into());
    }
    let key = PrivateKeyDer::from_pem_slice(&key_pem).map_err(|err| format!("TLS key: {err}"))?;
    CertifiedKey::from_der(certs, key, &ring::default_provider())
        .map_err(|err| format!("TLS certificate and key: {err}"))
}

type Handshake = Option<(TlsStream<TcpStream>, SocketAddr)>;

/// A TCP listener whose connections the server (axum, or tonic through
/// [`TlsListener::into_incoming`]) gets after their TLS handshake.
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

impl TlsListener {
    /// The accepted connections as a stream for tonic's `serve_with_incoming`: a task
    /// accepts and hands each connection over through a small bounded queue; it ends
    /// when the stream is dropped.
    pub fn into_incoming(
        mut self,
    ) -> tokio_stream::wrappers::ReceiverStream<Result<TlsStream<TcpStream>, std::io::Error>> {
        use axum::serve::Listener;
        let (tx, rx) = tokio::sync::mpsc::channel(8);
        tokio::spawn(async move {
            loop {
                tokio::select! {
                    (io, _) = self.accept() => {
                        if tx.send(Ok(io)).await.is_err() {
                            return;
                        }
                    }
                    () = tx.closed() => return,
                }
            }
        });
        tokio_stream::wrappers::ReceiverStream::new(rx)
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
                        // Nagle off: a reply goes out in several small writes (HTTP/2
                        // HEADERS, DATA, trailers) that must not wait for the client's ACK.
                        let _ = stream.set_nodelay(true);
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
