//! `ecat.v1.FoeService`: file read as a stream of chunks (progress first, then the data),
//! file write from a client stream, with its progress streamed back (`WriteWithProgress`).
//! A client that goes away ends its transfer: the call is dropped, and the engine sends
//! the slave an FoE ERROR.

use std::pin::Pin;
use std::sync::Arc;

use master_core::mailbox::FoeProgress;
use proto::v1 as pb;
use proto::v1::foe_service_server::FoeService;
use tokio::sync::mpsc;
use tokio_stream::wrappers::ReceiverStream;
use tokio_stream::{Stream, StreamExt};
use tonic::{Request, Response, Status, Streaming};

use super::auth::admit;
use crate::service::transfer::PROGRESS_PERIOD;
use crate::service::{ApiError, Core, Operation, SlaveName, parse_name};

/// Largest file a client may write in one call.
pub const MAX_FOE_WRITE: usize = 16 << 20;
/// Data bytes per streamed chunk.
const CHUNK: usize = 64 << 10;
/// Progress and data messages buffered ahead of a slow client.
const QUEUE: usize = 16;

/// The FoE service over the core.
pub struct Foe {
    /// The service layer.
    pub core: Core,
}

type Reply<T> = Result<Response<T>, Status>;

#[tonic::async_trait]
impl FoeService for Foe {
    type ReadStream = Pin<Box<dyn Stream<Item = Result<pb::FoeChunk, Status>> + Send>>;

    async fn read(&self, request: Request<pb::FoeReadRequest>) -> Reply<Self::ReadStream> {
        let r = request.into_inner();
        let slave = parse_name(&r.slave)?;
        let (tx, rx) = mpsc::channel(QUEUE);
        let progress_tx = tx.clone();
        // Progress messages carry no data; a full queue drops them (the data still comes).
        let progress = Arc::new(move |p: FoeProgress| {
            if let FoeProgress::Transferred { bytes, total } = p {
                let _ = progress_tx.try_send(Ok(pb::FoeChunk {
                    data: Vec::new(),
                    transferred: bytes as u64,
                    total: total.map(|t| t as u64),
                }));
            }
        });
        let core = self.core.clone();
        tokio::spawn(crate::audit::carry(async move {
            // The client leaving closes the stream's receiver: the read is dropped then,
            // which ends the transfer towards the slave.
            let read = tokio::select! {
                read = core.foe_read(slave, &r.name, r.password, Some(progress)) => read,
                () = tx.closed() => return,
            };
            match read {
                Ok(data) => {
                    let total = data.len() as u64;
                    let mut sent = 0u64;
                    for piece in data.chunks(CHUNK) {
                        sent += piece.len() as u64;
                        let chunk = pb::FoeChunk {
                            data: piece.to_vec(),
                            transferred: sent,
                            total: Some(total),
                        };
                        if tx.send(Ok(chunk)).await.is_err() {
                            return;
                        }
                    }
                }
                Err(err) => {
                    let _ = tx.send(Err(Status::from(err))).await;
                }
            }
        }));
        Ok(Response::new(Box::pin(ReceiverStream::new(rx))))
    }

    async fn write(
        &self,
        request: Request<Streaming<pb::FoeWriteChunk>>,
    ) -> Reply<pb::FoeWriteResponse> {
        // Admitted before any data is kept.
        let ticket = admit(&self.core, &request, Operation::FoeWrite)?;
        let (slave, name, password, data) = receive_file(request.into_inner()).await?;
        self.core
            .foe_write(ticket, slave, &name, password, &data, None)
            .await?;
        Ok(Response::new(pb::FoeWriteResponse {
            written: data.len() as u64,
        }))
    }

    type WriteWithProgressStream =
        Pin<Box<dyn Stream<Item = Result<pb::WriteWithProgressResponse, Status>> + Send>>;

    async fn write_with_progress(
        &self,
        request: Request<Streaming<pb::WriteWithProgressRequest>>,
    ) -> Reply<Self::WriteWithProgressStream> {
        // Admitted before any data is kept.
        let ticket = admit(&self.core, &request, Operation::FoeWrite)?;
        // The same pieces as Write's, in a message of the method's own name.
        let chunks = request.into_inner().map(|piece| {
            piece.map(|p| pb::FoeWriteChunk {
                slave: p.slave,
                name: p.name,
                password: p.password,
                data: p.data,
            })
        });
        let (slave, name, password, data) = receive_file(chunks).await?;
        let (tx, rx) = mpsc::channel(QUEUE);
        let progress_tx = tx.clone();
        // Progress messages are spaced like the events; a full queue drops one (the next,
        // or the final message, still comes).
        let last = std::sync::Mutex::new(None::<std::time::Instant>);
        let progress = Arc::new(move |p: FoeProgress| {
            let FoeProgress::Transferred { bytes, total } = p else {
                return;
            };
            let now = std::time::Instant::now();
            let mut last = last
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            if last.is_some_and(|at| now.duration_since(at) < PROGRESS_PERIOD) {
                return;
            }
            *last = Some(now);
            let _ = progress_tx.try_send(Ok(pb::WriteWithProgressResponse {
                transferred: bytes as u64,
                total: total.unwrap_or(bytes) as u64,
                done: false,
            }));
        });
        let core = self.core.clone();
        tokio::spawn(crate::audit::carry(async move {
            // The client leaving closes the stream's receiver: the write is dropped then,
            // which ends the transfer towards the slave with an FoE ERROR.
            let written = tokio::select! {
                written = core.foe_write(ticket, slave, &name, password, &data, Some(progress)) => written,
                () = tx.closed() => return,
            };
            let last = match written {
                Ok(()) => Ok(pb::WriteWithProgressResponse {
                    transferred: data.len() as u64,
                    total: data.len() as u64,
                    done: true,
                }),
                Err(err) => Err(Status::from(err)),
            };
            let _ = tx.send(last).await;
        }));
        Ok(Response::new(Box::pin(ReceiverStream::new(rx))))
    }
}

/// Takes a whole file from a write stream: the first chunk names the slave and the file.
async fn receive_file(
    stream: impl Stream<Item = Result<pb::FoeWriteChunk, Status>>,
) -> Result<(SlaveName, String, u32, Vec<u8>), Status> {
    let mut stream = std::pin::pin!(stream);
    let mut target: Option<(SlaveName, String, u32)> = None;
    let mut data = Vec::new();
    while let Some(chunk) = stream.next().await {
        let chunk = chunk?;
        if target.is_none() {
            target = Some((parse_name(&chunk.slave)?, chunk.name, chunk.password));
        }
        if data.len() + chunk.data.len() > MAX_FOE_WRITE {
            return Err(Status::from(ApiError::too_large(format!(
                "FoE write above {MAX_FOE_WRITE} bytes"
            ))));
        }
        data.extend_from_slice(&chunk.data);
    }
    let (slave, name, password) =
        target.ok_or_else(|| Status::from(ApiError::invalid("empty FoE write stream")))?;
    Ok((slave, name, password, data))
}
