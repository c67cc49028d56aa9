//! SDO upload and download (ETG.1000.6 §5.6.2, spec-notes §coe.sdo, §coe.ca), run by the slave's owner task.
//!
//! Answers are matched to the transfer (index and subindex for initiate responses and
//! aborts, the toggle bit for segments); a CoE answer that does not fit is a late one of an earlier request and is
//! skipped (counted as unexpected), never taken for this transfer's. A transfer given up
//! half-way — the caller went away, the deadline passed, the slave broke the protocol — is
//! aborted towards the slave with an SDO abort, so the slave's SDO server is idle again
//! for the next request.

use crate::mailbox::engine::exchange::Exchange;
use crate::mailbox::engine::job::{BoxFuture, call_for};
use crate::mailbox::engine::report::Subject;
use crate::mailbox::engine::slave::SlaveMailbox;
use crate::mailbox::error::{MailboxError, Result};
use crate::wire::coe::sdo::{SdoFrame, max_initiate_data, max_segment_data};
use crate::wire::coe::{AbortCode, CoeRepr, SdoPayload, SdoRequest, SdoResponse};
use crate::wire::mailbox::MailboxType;

use super::send_coe;

/// The object a transfer addresses.
#[derive(Debug, Clone, Copy)]
struct Target {
    index: u16,
    subindex: u8,
    complete_access: bool,
}

impl Target {
    /// Whether an initiate response for `index:subindex` answers this transfer. Complete
    /// access names the object; stacks differ in the subindex they echo then.
    fn answered_by(&self, index: u16, subindex: u8) -> bool {
        index == self.index && (self.complete_access || subindex == self.subindex)
    }

    /// Whether an abort for `index:subindex` ends this transfer: one for its object, or
    /// one that names no object at all (index 0, which no transfer addresses; some stacks
    /// send that during segments).
    fn owns_abort(&self, index: u16, subindex: u8) -> bool {
        self.answered_by(index, subindex) || (index == 0 && subindex == 0)
    }

    fn subject(&self) -> Subject {
        Subject::Object {
            index: self.index,
            subindex: self.subindex,
        }
    }

    fn abort_error(&self, code: AbortCode) -> MailboxError {
        MailboxError::SdoAbort {
            index: self.index,
            subindex: self.subindex,
            code,
        }
    }
}

async fn send_request(x: &mut Exchange, request: SdoRequest<'_>) -> Result<()> {
    send_coe(x, &CoeRepr::SdoRequest(request)).await
}

/// Waits for the next SDO response and hands it to `accept`; answers `accept` declines
/// (`None`) are skipped as stale. An abort is taken in either CoE service and with any
/// low command bits (ETG.1000.6 §5.6.2.7), if it names this transfer's object.
async fn await_response<T>(
    x: &mut Exchange,
    target: &Target,
    mut accept: impl FnMut(&SdoResponse<'_>) -> Option<Result<T>>,
) -> Result<T> {
    loop {
        let reply = x.receive(MailboxType::Coe).await?;
        let data = reply.data()?;
        let Ok(frame) = SdoFrame::new_checked(data) else {
            x.count_unexpected(MailboxType::Coe);
            continue;
        };
        if let Some((index, subindex, code)) = frame.any_abort() {
            if target.owns_abort(index, subindex) {
                return Err(target.abort_error(code));
            }
            x.count_unexpected(MailboxType::Coe);
            continue;
        }
        match SdoResponse::parse(&frame) {
            Ok(response) => match accept(&response) {
                Some(result) => {
                    // An answer that belongs to the transfer: it moved on (with progress
                    // deadlines the next exchange gets a whole window).
                    x.progressed();
                    return result;
                }
                None => x.count_unexpected(MailboxType::Coe),
            },
            // Not an SDO response (an SDO Information answer, a PDO): not ours.
            Err(_) => x.count_unexpected(MailboxType::Coe),
        }
    }
}

/// Tells the slave to drop the transfer (no answer comes to an abort).
async fn abort(x: &mut Exchange, target: &Target, code: AbortCode) {
    let request = SdoRequest::Abort {
        index: target.index,
        subindex: target.subindex,
        code,
    };
    let _ = send_request(x, request).await;
}

/// Passes on the result of a transfer's later phase; if it failed other than by the
/// slave's own abort or mailbox error (the caller went away, the deadline passed, the
/// slave broke the protocol), first aborts the transfer towards the slave.
async fn guarded<T>(x: &mut Exchange, target: &Target, result: Result<T>) -> Result<T> {
    match &result {
        Err(MailboxError::SdoAbort { .. } | MailboxError::Mailbox(_)) | Ok(_) => {}
        Err(err) => {
            let code = match err {
                MailboxError::Timeout { .. } => AbortCode::Timeout,
                MailboxError::TooLarge { .. } => AbortCode::OutOfMemory,
                MailboxError::Protocol { .. } => AbortCode::UnknownCommand,
                _ => AbortCode::GeneralError,
            };
            abort(x, target, code).await;
        }
    }
    result
}

/// A whole upload.
async fn upload(x: &mut Exchange, target: Target) -> Result<Vec<u8>> {
    let limit = x.config().max_value_len;
    send_request(
        x,
        SdoRequest::InitiateUpload {
            index: target.index,
            subindex: target.subindex,
            complete_access: target.complete_access,
        },
    )
    .await?;
    let first = await_response(x, &target, |response| match *response {
        SdoResponse::InitiateUpload {
            index,
            subindex,
            payload,
            ..
        } if target.answered_by(index, subindex) => Some(Ok(match payload {
            SdoPayload::Expedited(value) => (value.to_vec(), None, true),
            SdoPayload::Normal {
                complete_size,
                data,
            } => (data.to_vec(), Some(complete_size as usize), false),
            SdoPayload::SizeUnspecified { data } => (data.to_vec(), None, false),
        })),
        _ => None,
    })
    .await?;
    let (mut value, total, done) = first;
    if done {
        return Ok(value);
    }
    if let Some(total) = total
        && total > limit
    {
        let err = MailboxError::TooLarge {
            what: "SDO upload",
            size: total,
            limit,
        };
        return guarded(x, &target, Err(err)).await;
    }
    if total == Some(value.len()) {
        return Ok(value);
    }
    let segments = upload_segments(x, &target, &mut value, total, limit).await;
    guarded(x, &target, segments).await.map(|()| value)
}

async fn upload_segments(
    x: &mut Exchange,
    target: &Target,
    value: &mut Vec<u8>,
    total: Option<usize>,
    limit: usize,
) -> Result<()> {
    let mut toggle = false;
    loop {
        if x.cancelled() {
            return Err(MailboxError::Cancelled);
        }
        send_request(x, SdoRequest::UploadSegment { toggle }).await?;
        let last = await_response(x, target, |response| match *response {
            SdoResponse::UploadSegment {
                toggle: echoed,
                last,
                data,
            } if echoed == toggle => {
                let size = value.len() + data.len();
                if size > total.unwrap_or(limit).min(limit) {
                    return Some(Err(MailboxError::TooLarge {
                        what: "SDO upload",
                        size,
                        limit: total.unwrap_or(limit).min(limit),
                    }));
                }
                value.extend_from_slice(data);
                Some(Ok(last))
            }
            _ => None,
        })
        .await?;
        if last {
            break;
        }
        toggle = !toggle;
    }
    match total {
        Some(total) if total != value.len() => {
            Err(x.violation("the segments do not add up to the announced size"))
        }
        _ => Ok(()),
    }
}

/// A whole download.
async fn download(x: &mut Exchange, target: Target, data: &[u8]) -> Result<()> {
    let expedited = !target.complete_access && (1..=4).contains(&data.len());
    let first = if expedited {
        data.len()
    } else {
        data.len().min(max_initiate_data(x.write_size()))
    };
    let payload = if expedited {
        SdoPayload::Expedited(data)
    } else {
        let complete_size = u32::try_from(data.len()).map_err(|_| MailboxError::TooLarge {
            what: "SDO download",
            size: data.len(),
            limit: u32::MAX as usize,
        })?;
        SdoPayload::Normal {
            complete_size,
            data: &data[..first],
        }
    };
    send_request(
        x,
        SdoRequest::InitiateDownload {
            index: target.index,
            subindex: target.subindex,
            complete_access: target.complete_access,
            payload,
        },
    )
    .await?;
    await_response(x, &target, |response| match *response {
        SdoResponse::InitiateDownload {
            index, subindex, ..
        } if target.answered_by(index, subindex) => Some(Ok(())),
        _ => None,
    })
    .await?;
    if first == data.len() {
        return Ok(());
    }
    let segments = download_segments(x, &target, &data[first..]).await;
    guarded(x, &target, segments).await
}

async fn download_segments(x: &mut Exchange, target: &Target, mut rest: &[u8]) -> Result<()> {
    let chunk = max_segment_data(x.write_size());
    if chunk == 0 {
        return Err(x.violation("the receive mailbox cannot carry a segment"));
    }
    let mut toggle = false;
    while !rest.is_empty() {
        if x.cancelled() {
            return Err(MailboxError::Cancelled);
        }
        let (now, later) = rest.split_at(rest.len().min(chunk));
        let request = SdoRequest::DownloadSegment {
            toggle,
            last: later.is_empty(),
            data: now,
        };
        send_request(x, request).await?;
        await_response(x, target, |response| match *response {
            SdoResponse::DownloadSegment { toggle: echoed } if echoed == toggle => Some(Ok(())),
            _ => None,
        })
        .await?;
        rest = later;
        toggle = !toggle;
    }
    Ok(())
}

impl SlaveMailbox {
    /// SDO upload (read) of `index:subindex`: expedited, normal or segmented, whatever the
    /// slave answers, up to [`MailboxConfig::max_value_len`](crate::mailbox::MailboxConfig::max_value_len) bytes.
    pub async fn sdo_upload(&self, index: u16, subindex: u8) -> Result<Vec<u8>> {
        self.upload_with(index, subindex, false).await
    }

    /// SDO upload of a whole object with complete access (spec-notes §coe.ca): `subindex` 0
    /// includes subindex 0 (padded to 16 bits), 1 starts at subindex 1.
    pub async fn sdo_upload_complete(&self, index: u16, subindex: u8) -> Result<Vec<u8>> {
        self.upload_with(index, subindex, true).await
    }

    async fn upload_with(&self, index: u16, subindex: u8, ca: bool) -> Result<Vec<u8>> {
        let target = Target {
            index,
            subindex,
            complete_access: ca,
        };
        call_for(
            self,
            Some(MailboxType::Coe),
            target.subject(),
            move |x| -> BoxFuture<'_, _> { Box::pin(upload(x, target)) },
        )
        .await
    }

    /// SDO download (write) of `data` to `index:subindex`: expedited for 1 to 4 bytes,
    /// otherwise normal with as many segments as needed.
    pub async fn sdo_download(&self, index: u16, subindex: u8, data: &[u8]) -> Result<()> {
        self.download_with(index, subindex, data, false).await
    }

    /// SDO download of a whole object with complete access (ETG.1000.6, spec-notes §coe.ca).
    pub async fn sdo_download_complete(&self, index: u16, subindex: u8, data: &[u8]) -> Result<()> {
        self.download_with(index, subindex, data, true).await
    }

    async fn download_with(&self, index: u16, subindex: u8, data: &[u8], ca: bool) -> Result<()> {
        let target = Target {
            index,
            subindex,
            complete_access: ca,
        };
        let data = data.to_vec();
        call_for(
            self,
            Some(MailboxType::Coe),
            target.subject(),
            move |x| -> BoxFuture<'_, _> {
                Box::pin(async move { download(x, target, &data).await })
            },
        )
        .await
    }
}
