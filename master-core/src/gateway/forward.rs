//! Forwarding one message to one slave through the mailbox engine: the engine's counter
//! replaces the client's (so nothing is ever dropped as a repeat), the slave's session is
//! taken for the exchange and kept for multi-message transfers, and the slave's answers
//! come back in order.

use std::net::SocketAddr;

use tokio::time::Instant;

use crate::mailbox::{MailboxError, RawReply, SlaveMailbox};

use super::answer::Fault;
use super::ask::Ask;
use super::session::{Patience, Sessions};
use super::transfer::{Expect, Sizes};

/// Most messages a slave may send for one request (SDO Information lists of large
/// dictionaries come in a few dozen fragments).
const MAX_FOLLOW_UPS: usize = 1024;

/// What a forward needs besides the message.
pub(crate) struct Forward<'a> {
    pub sessions: &'a Sessions,
    /// Whether to wait for another client's transfer with the slave (a request addressed
    /// to it) or be refused at once (a broadcast).
    pub patience: Patience,
    pub client: SocketAddr,
    pub deadline: Instant,
    pub session_timeout: std::time::Duration,
}

fn fault_of(err: &MailboxError) -> Fault {
    match err {
        MailboxError::Timeout { .. } => Fault::Timeout,
        MailboxError::QueueFull(_) | MailboxError::NotSent { .. } => Fault::Busy,
        MailboxError::TooLarge { .. } => Fault::Oversized,
        MailboxError::Unsupported { .. } => Fault::Unsupported,
        MailboxError::UnknownSlave(_) => Fault::UnknownAddress,
        _ => Fault::Other,
    }
}

/// Sends `data` (mailbox data of `ask.ty`, which ask `ask`) to the slave and returns its
/// answers (none for a message that gets no answer). A slave another client holds is
/// [`Fault::Busy`], whether the wait ran out or the patience did not allow one.
pub(crate) async fn forward(
    f: &Forward<'_>,
    mailbox: &SlaveMailbox,
    ask: &Ask,
    data: &[u8],
) -> Result<Vec<RawReply>, Fault> {
    let mailbox_type = ask.ty;
    let station = mailbox.station();
    let open = f
        .sessions
        .enter(station, f.client, f.deadline, f.patience)
        .await
        .map_err(|_| Fault::Busy)?;
    // From here on every way out updates the session (the slave is held for us).
    let left = f.deadline.saturating_duration_since(Instant::now());
    if left.is_zero() {
        f.sessions
            .update(station, f.client, None, f.session_timeout);
        return Err(Fault::Timeout);
    }
    let mb = mailbox.with_timeout(left);
    let result = match ask.expect(open) {
        Expect::Reply => mb.raw(mailbox_type, data).await.map(|reply| vec![reply]),
        Expect::Replies(follows) => {
            mb.raw_replies(mailbox_type, data, follows, MAX_FOLLOW_UPS)
                .await
        }
        Expect::Nothing => mb.raw_send(mailbox_type, data).await.map(|()| Vec::new()),
    };
    let sizes = Sizes {
        write: usize::from(mailbox.config().write.len),
        read: usize::from(mailbox.config().read.len),
    };
    match result {
        Ok(replies) => {
            let first = replies.first().map(|m| (m.mailbox_type(), m.data()));
            let next = ask.after(first, open, sizes);
            f.sessions
                .update(station, f.client, next, f.session_timeout);
            Ok(replies)
        }
        Err(err) => {
            // The transfer is broken either way: the slave is free for others.
            f.sessions
                .update(station, f.client, None, f.session_timeout);
            Err(fault_of(&err))
        }
    }
}
