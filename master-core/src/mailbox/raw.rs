//! Raw mailbox transactions for the ETG.8200 gateway (spec-notes §gateway): the mailbox
//! type and the service data of one request in, the slave's answers out as [`RawReply`]s
//! (header parsed once, here), with the engine's counter and all the guards of any other
//! request.

use crate::mailbox::engine::exchange::{Exchange, Reply};
use crate::mailbox::engine::job::{BoxFuture, call_for};
use crate::mailbox::engine::report::Subject;
use crate::mailbox::engine::slave::SlaveMailbox;
use crate::mailbox::error::{MailboxError, Result};
use crate::mailbox::matching::answers;
use crate::wire::mailbox::{HEADER_LEN, Mailbox, MailboxHeader, MailboxType};

/// One message a slave sent on the raw path: its header, parsed once when it was read,
/// and the message as it came (header and data).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawReply {
    header: MailboxHeader,
    message: Vec<u8>,
}

impl RawReply {
    fn of(reply: &Reply<'_>) -> RawReply {
        RawReply {
            header: reply.header,
            message: reply.message.to_vec(),
        }
    }

    /// A whole message (header and data; bytes beyond the header's length are left out),
    /// or `None` if it has no valid header or is shorter than its header says. For the
    /// gateway's tests and fuzz target, which stand in for a slave.
    pub(crate) fn parse(message: &[u8]) -> Option<RawReply> {
        let header = Mailbox::new_checked(message)
            .and_then(|m| MailboxHeader::parse(&m))
            .ok()?;
        let message = message.get(..HEADER_LEN + usize::from(header.length))?;
        Some(RawReply {
            header,
            message: message.to_vec(),
        })
    }

    /// The header as the slave sent it (its counter, address, channel, priority, type).
    pub fn header(&self) -> &MailboxHeader {
        &self.header
    }

    /// The mailbox type ([`MailboxType::Error`] for a mailbox error reply).
    pub fn mailbox_type(&self) -> MailboxType {
        self.header.mailbox_type
    }

    /// The mailbox data (the header's `length` bytes after it).
    pub fn data(&self) -> &[u8] {
        // `message` ends where the header's length says (Exchange::receive cut it so).
        self.message.get(HEADER_LEN..).unwrap_or_default()
    }

    /// The whole message as the slave sent it (header and data).
    pub fn message(&self) -> &[u8] {
        &self.message
    }
}

async fn write(x: &mut Exchange, mailbox_type: MailboxType, data: &[u8]) -> Result<()> {
    let room = x.write_size().saturating_sub(HEADER_LEN);
    if data.len() > room {
        return Err(MailboxError::TooLarge {
            what: "mailbox message",
            size: data.len(),
            limit: room,
        });
    }
    x.send(mailbox_type, |buf| {
        buf[..data.len()].copy_from_slice(data);
        Ok(data.len())
    })
    .await
}

/// Waits for the slave's answer to the request `data` (of `mailbox_type`) just written:
/// the first message that [`answers`] it. Others (a late answer to an earlier request
/// that timed out, an answer for another object) are dropped and counted as unexpected.
async fn answer(x: &mut Exchange, mailbox_type: MailboxType, data: &[u8]) -> Result<RawReply> {
    loop {
        let reply = x.receive(mailbox_type).await?;
        if answers(mailbox_type, data, reply.header.mailbox_type, reply.data) {
            return Ok(RawReply::of(&reply));
        }
        x.count_unexpected(mailbox_type);
    }
}

impl SlaveMailbox {
    /// Writes one mailbox message of `mailbox_type` carrying `data` (the engine sets the
    /// header: its counter, the master's address and priority) and returns the slave's
    /// answer: the next message of the same type that is not unsolicited (emergencies and
    /// EoE frames still go to their own queues) and answers this request (the same object,
    /// segment or IDN: a late answer to an earlier request is dropped and counted in
    /// [`MailboxStats::unexpected`](crate::mailbox::MailboxStats::unexpected)), or a
    /// mailbox error reply.
    pub async fn raw(&self, mailbox_type: MailboxType, data: &[u8]) -> Result<RawReply> {
        let data = data.to_vec();
        call_for(
            self,
            None,
            Subject::Raw(mailbox_type),
            move |x| -> BoxFuture<'_, _> {
                Box::pin(async move {
                    write(x, mailbox_type, &data).await?;
                    answer(x, mailbox_type, &data).await
                })
            },
        )
        .await
    }

    /// Like [`Self::raw`], for services where the slave answers one message with several
    /// (SDO Information fragments, SoE read fragments): returns the answer and every
    /// message that follows it, in order, while `follows` says of the last one's mailbox
    /// data that another comes (at most `limit` messages in all).
    pub async fn raw_replies(
        &self,
        mailbox_type: MailboxType,
        data: &[u8],
        follows: fn(&[u8]) -> bool,
        limit: usize,
    ) -> Result<Vec<RawReply>> {
        let data = data.to_vec();
        call_for(
            self,
            None,
            Subject::Raw(mailbox_type),
            move |x| -> BoxFuture<'_, _> {
                Box::pin(async move {
                    write(x, mailbox_type, &data).await?;
                    let first = answer(x, mailbox_type, &data).await?;
                    let mut more = first.mailbox_type() == mailbox_type && follows(first.data());
                    let mut replies = vec![first];
                    loop {
                        if !more || replies.len() >= limit.max(1) {
                            return Ok(replies);
                        }
                        let reply = x.receive(mailbox_type).await?;
                        more = reply.header.mailbox_type == mailbox_type && follows(reply.data);
                        replies.push(RawReply::of(&reply));
                    }
                })
            },
        )
        .await
    }

    /// Writes one mailbox message of `mailbox_type` carrying `data` that gets no answer
    /// (an EoE fragment, an SDO abort).
    pub async fn raw_send(&self, mailbox_type: MailboxType, data: &[u8]) -> Result<()> {
        let data = data.to_vec();
        call_for(
            self,
            None,
            Subject::Raw(mailbox_type),
            move |x| -> BoxFuture<'_, _> {
                Box::pin(async move { write(x, mailbox_type, &data).await })
            },
        )
        .await
    }
}
