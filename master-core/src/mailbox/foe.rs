//! FoE client (spec-notes §foe): files of any size to and from a slave, with BUSY phases,
//! password, the slave's errors with its own code and text, and progress reports.
//!
//! On BUSY the last message is sent again (a WRQ, or the DATA packet the slave is not
//! ready for), after [`MailboxConfig::poll_interval`](crate::mailbox::MailboxConfig::poll_interval).
//! A transfer given up half-way (the caller went away, the deadline passed, a wrong packet
//! number) is ended towards the slave with an FoE ERROR (ETG.1000.6, spec-notes §foe),
//! so the slave is ready for the next transfer. With progress deadlines
//! ([`SlaveMailbox::with_progress_deadlines`]) each ACK, DATA and BUSY starts a new window.

use std::sync::Arc;

use crate::mailbox::engine::exchange::Exchange;
use crate::mailbox::engine::job::{BoxFuture, call_for};
use crate::mailbox::engine::report::Subject;
use crate::mailbox::engine::slave::SlaveMailbox;
use crate::mailbox::error::{MailboxError, Result};
use crate::wire::Emit;
use crate::wire::foe::{self, FoeError, FoePacket, FoeRepr};
use crate::wire::mailbox::MailboxType;

/// How a transfer went so far, reported to [`FoeOptions::progress`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FoeProgress {
    /// File bytes acknowledged (write) or received (read); `total` is known for writes.
    Transferred {
        /// Bytes so far.
        bytes: usize,
        /// Size of the file, when known.
        total: Option<usize>,
    },
    /// The slave is busy (erasing, programming): `done` of `entire`, with its text.
    Busy {
        /// Progress done.
        done: u16,
        /// Progress total.
        entire: u16,
        /// The slave's text.
        text: String,
    },
}

/// Options of an FoE transfer.
#[derive(Clone, Default)]
pub struct FoeOptions {
    /// Password (0 = none).
    pub password: u32,
    /// Called on the engine's thread after each packet and each BUSY; keep it short.
    pub progress: Option<Arc<dyn Fn(FoeProgress) + Send + Sync>>,
}

impl std::fmt::Debug for FoeOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FoeOptions")
            .field("password", &self.password)
            .field("progress", &self.progress.is_some())
            .finish()
    }
}

impl FoeOptions {
    fn report(&self, progress: FoeProgress) {
        if let Some(report) = &self.progress {
            report(progress);
        }
    }
}

async fn send_foe(x: &mut Exchange, repr: &FoeRepr<'_>) -> Result<()> {
    x.send(MailboxType::Foe, |buf| repr.emit_into(buf)).await
}

/// The next FoE message from the slave, owned.
enum Answer {
    Ack(u32),
    Data(u32, Vec<u8>),
    Busy(u16, u16, String),
}

async fn receive_foe(x: &mut Exchange) -> Result<Answer> {
    loop {
        let reply = x.receive(MailboxType::Foe).await?;
        let parsed = FoePacket::new_checked(reply.data()?).and_then(|p| FoeRepr::parse(&p));
        let text = |t: &[u8]| String::from_utf8_lossy(t).into_owned();
        match parsed {
            Ok(FoeRepr::Ack { packet }) => return Ok(Answer::Ack(packet)),
            Ok(FoeRepr::Data { packet, data }) => return Ok(Answer::Data(packet, data.to_vec())),
            Ok(FoeRepr::Busy {
                done,
                entire,
                text: t,
            }) => {
                return Ok(Answer::Busy(done, entire, text(t)));
            }
            Ok(FoeRepr::Error { code, text: t }) => {
                return Err(MailboxError::Foe {
                    code,
                    text: text(t),
                });
            }
            _ => x.count_unexpected(MailboxType::Foe),
        }
    }
}

/// Ends a transfer towards the slave after `result` failed on the master's side.
async fn guarded<T>(x: &mut Exchange, result: Result<T>) -> Result<T> {
    if let Err(err) = &result
        && !matches!(err, MailboxError::Foe { .. } | MailboxError::Mailbox(_))
    {
        let (code, why): (FoeError, &[u8]) = match err {
            MailboxError::TooLarge { .. } => (FoeError::DiskFull, b"file too large for the master"),
            MailboxError::Protocol { .. } => (FoeError::PacketNumberWrong, b"unexpected packet"),
            _ => (FoeError::NotDefined, b"transfer ended by the master"),
        };
        let _ = send_foe(x, &FoeRepr::Error { code, text: why }).await;
    }
    result
}

async fn write(x: &mut Exchange, name: &[u8], data: &[u8], options: &FoeOptions) -> Result<()> {
    let maxdata = foe::max_data(x.write_size());
    if maxdata == 0 {
        return Err(x.violation("the receive mailbox cannot carry FoE data"));
    }
    let request = FoeRepr::WriteRequest {
        password: options.password,
        file_name: name,
    };
    send_foe(x, &request).await?;
    let result = write_packets(x, &request, data, maxdata, options).await;
    guarded(x, result).await
}

async fn write_packets(
    x: &mut Exchange,
    request: &FoeRepr<'_>,
    data: &[u8],
    maxdata: usize,
    options: &FoeOptions,
) -> Result<()> {
    // The packet last sent (0 = the WRQ) and the bytes it carried.
    let mut packet: u32 = 0;
    let mut chunk = 0..0;
    loop {
        match receive_foe(x).await? {
            Answer::Ack(acked) if acked == packet => {
                x.progressed();
                options.report(FoeProgress::Transferred {
                    bytes: chunk.end,
                    total: Some(data.len()),
                });
                if packet > 0 && chunk.len() < maxdata {
                    return Ok(());
                }
                if x.cancelled() {
                    return Err(MailboxError::Cancelled);
                }
                packet = packet.checked_add(1).ok_or(MailboxError::TooLarge {
                    what: "FoE file (packets)",
                    size: data.len(),
                    limit: maxdata.saturating_mul(u32::MAX as usize),
                })?;
                chunk = chunk.end..data.len().min(chunk.end + maxdata);
            }
            Answer::Ack(_) => return Err(x.violation("an FoE ACK with the wrong packet number")),
            Answer::Busy(done, entire, text) => {
                x.progressed();
                options.report(FoeProgress::Busy { done, entire, text });
                if x.cancelled() {
                    return Err(MailboxError::Cancelled);
                }
                x.sleep(x.config().poll_interval).await;
                if packet == 0 {
                    send_foe(x, request).await?;
                    continue;
                }
            }
            Answer::Data(..) => return Err(x.violation("FoE DATA during a write")),
        }
        let repr = FoeRepr::Data {
            packet,
            data: &data[chunk.clone()],
        };
        send_foe(x, &repr).await?;
    }
}

async fn read(x: &mut Exchange, name: &[u8], options: &FoeOptions) -> Result<Vec<u8>> {
    let maxdata = foe::max_data(x.read_size());
    let request = FoeRepr::ReadRequest {
        password: options.password,
        file_name: name,
    };
    send_foe(x, &request).await?;
    let mut file = Vec::new();
    let result = read_packets(x, &request, &mut file, maxdata, options).await;
    guarded(x, result).await.map(|()| file)
}

async fn read_packets(
    x: &mut Exchange,
    request: &FoeRepr<'_>,
    file: &mut Vec<u8>,
    maxdata: usize,
    options: &FoeOptions,
) -> Result<()> {
    let limit = x.config().max_file_len;
    // The packet last acknowledged (0 = none yet, the RRQ was the last message).
    let mut acked: u32 = 0;
    loop {
        match receive_foe(x).await? {
            Answer::Data(packet, data) if Some(packet) == acked.checked_add(1) => {
                let size = file.len() + data.len();
                if size > limit {
                    return Err(MailboxError::TooLarge {
                        what: "FoE file",
                        size,
                        limit,
                    });
                }
                file.extend_from_slice(&data);
                acked = packet;
                x.progressed();
                send_foe(x, &FoeRepr::Ack { packet }).await?;
                options.report(FoeProgress::Transferred {
                    bytes: file.len(),
                    total: None,
                });
                if data.len() < maxdata {
                    return Ok(());
                }
                if x.cancelled() {
                    return Err(MailboxError::Cancelled);
                }
            }
            Answer::Data(..) => return Err(x.violation("an FoE DATA packet out of sequence")),
            Answer::Busy(done, entire, text) => {
                x.progressed();
                options.report(FoeProgress::Busy { done, entire, text });
                if x.cancelled() {
                    return Err(MailboxError::Cancelled);
                }
                x.sleep(x.config().poll_interval).await;
                if acked == 0 {
                    send_foe(x, request).await?;
                } else {
                    send_foe(x, &FoeRepr::Ack { packet: acked }).await?;
                }
            }
            Answer::Ack(_) => return Err(x.violation("an FoE ACK during a read")),
        }
    }
}

impl SlaveMailbox {
    /// Writes `data` to the slave's file `name` (ASCII, no NUL). Give the handle a deadline
    /// long enough for the file ([`SlaveMailbox::with_timeout`]), or deadlines that follow
    /// the transfer's progress ([`SlaveMailbox::with_progress_deadlines`]: each ACK and BUSY
    /// restarts the window).
    pub async fn foe_write(&self, name: &str, data: &[u8], options: FoeOptions) -> Result<()> {
        let subject = Subject::File(name.to_string());
        let name = name.as_bytes().to_vec();
        let data = data.to_vec();
        call_for(
            self,
            Some(MailboxType::Foe),
            subject,
            move |x| -> BoxFuture<'_, _> {
                Box::pin(async move { write(x, &name, &data, &options).await })
            },
        )
        .await
    }

    /// Reads the slave's file `name`, up to [`MailboxConfig::max_file_len`](crate::mailbox::MailboxConfig::max_file_len) bytes.
    pub async fn foe_read(&self, name: &str, options: FoeOptions) -> Result<Vec<u8>> {
        let subject = Subject::File(name.to_string());
        let name = name.as_bytes().to_vec();
        call_for(
            self,
            Some(MailboxType::Foe),
            subject,
            move |x| -> BoxFuture<'_, _> {
                Box::pin(async move { read(x, &name, &options).await })
            },
        )
        .await
    }
}
