//! Forwarding one message to one slave through the mailbox engine: the engine's counter
//! replaces the client's (so nothing is ever dropped as a repeat), the slave's session is
//! taken for multi-message transfers, and the slave's answers come back in order.

use std::net::SocketAddr;

use tokio::time::Instant;

use crate::mailbox::{MailboxError, SlaveMailbox};
use crate::wire::mailbox::{HEADER_LEN, Mailbox, MailboxHeader, MailboxType};

use super::answer::Fault;
use super::plan::{self, Expect, Sizes, data_of};
use super::session::Sessions;

/// Most messages a slave may send for one request (SDO Information lists of large
/// dictionaries come in a few dozen fragments).
const MAX_FOLLOW_UPS: usize = 1024;

/// What a forward needs besides the message.
pub(crate) struct Forward<'a> {
    pub sessions: Option<&'a Sessions>,
    pub client: SocketAddr,
    pub deadline: Instant,
    pub session_timeout: std::time::Duration,
}

fn fault_of(err: &MailboxError) -> Fault {
    match err {
        MailboxError::Timeout { .. } => Fault::Timeout,
        MailboxError::QueueFull(_) => Fault::Busy,
        MailboxError::TooLarge { .. } => Fault::Oversized,
        MailboxError::Unsupported { .. } => Fault::Unsupported,
        MailboxError::UnknownSlave(_) => Fault::UnknownAddress,
        _ => Fault::Other,
    }
}

/// A mailbox message of `mailbox_type` carrying `data` (the engine sets counter and
/// address).
fn message(mailbox_type: MailboxType, data: &[u8]) -> Result<Vec<u8>, Fault> {
    let header = MailboxHeader {
        length: u16::try_from(data.len()).map_err(|_| Fault::Oversized)?,
        address: 0,
        channel: 0,
        priority: 0,
        mailbox_type,
        counter: 0,
    };
    let mut out = vec![0u8; HEADER_LEN + data.len()];
    header
        .emit(&mut Mailbox::new_unchecked(&mut out[..]))
        .map_err(|_| Fault::Other)?;
    out[HEADER_LEN..].copy_from_slice(data);
    Ok(out)
}

/// The type of a message from the slave.
fn type_of(message: &[u8]) -> Option<MailboxType> {
    Mailbox::new_checked(message)
        .and_then(|m| MailboxHeader::parse(&m))
        .ok()
        .map(|h| h.mailbox_type)
}

/// Sends `data` (mailbox data of `mailbox_type`) to the slave and returns its answers
/// (whole mailbox messages; none for a message that gets no answer).
pub(crate) async fn forward(
    f: &Forward<'_>,
    mailbox: &SlaveMailbox,
    mailbox_type: MailboxType,
    data: &[u8],
) -> Result<Vec<Vec<u8>>, Fault> {
    let station = mailbox.station();
    let message = message(mailbox_type, data)?;
    let transfer = match f.sessions {
        Some(sessions) => sessions
            .enter(station, f.client, f.deadline)
            .await
            .map_err(|()| Fault::Busy)?,
        None => None,
    };
    // From here on every way out updates the session (the slave is held for us).
    let left = f.deadline.saturating_duration_since(Instant::now());
    if left.is_zero() {
        if let Some(sessions) = f.sessions {
            sessions.update(station, f.client, None, f.session_timeout);
        }
        return Err(Fault::Timeout);
    }
    let mb = mailbox.with_timeout(left);
    let result = match plan::expect(mailbox_type, data, transfer) {
        Expect::Reply => mb.raw(&message).await.map(|reply| vec![reply]),
        Expect::Replies(follows) => mb.raw_replies(&message, follows, MAX_FOLLOW_UPS).await,
        Expect::Nothing => mb.raw_send(&message).await.map(|()| Vec::new()),
    };
    let sizes = Sizes {
        write: usize::from(mailbox.config().write.len),
        read: usize::from(mailbox.config().read.len),
    };
    match result {
        Ok(replies) => {
            if let Some(sessions) = f.sessions {
                let first = replies
                    .first()
                    .and_then(|m| Some((type_of(m)?, data_of(m))));
                let next = plan::after(mailbox_type, data, first, transfer, sizes);
                sessions.update(station, f.client, next, f.session_timeout);
            }
            Ok(replies)
        }
        Err(err) => {
            // The transfer is broken either way: the slave is free for others.
            if let Some(sessions) = f.sessions {
                sessions.update(station, f.client, None, f.session_timeout);
            }
            Err(fault_of(&err))
        }
    }
}
