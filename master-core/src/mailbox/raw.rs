//! Raw mailbox transactions for the ETG.8200 gateway (spec-notes §gateway): one message in, the
//! slave's answer out, with the engine's counter and all the guards of any other request.

use crate::mailbox::engine::exchange::Exchange;
use crate::mailbox::engine::job::{BoxFuture, call_for};
use crate::mailbox::engine::report::Subject;
use crate::mailbox::engine::slave::SlaveMailbox;
use crate::mailbox::error::{MailboxError, Result};
use crate::mailbox::matching::answers;
use crate::wire::mailbox::{HEADER_LEN, Mailbox, MailboxHeader, MailboxType};

/// The type and data of a complete mailbox message.
fn split(message: &[u8]) -> Result<(MailboxType, Vec<u8>)> {
    let header = Mailbox::new_checked(message)
        .and_then(|m| MailboxHeader::parse(&m))
        .map_err(MailboxError::Invalid)?;
    let end = HEADER_LEN + usize::from(header.length);
    Ok((header.mailbox_type, message[HEADER_LEN..end].to_vec()))
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
async fn answer(x: &mut Exchange, mailbox_type: MailboxType, data: &[u8]) -> Result<Vec<u8>> {
    loop {
        let reply = x.receive(mailbox_type).await?;
        if answers(mailbox_type, data, reply.header.mailbox_type, reply.data) {
            return Ok(reply.message.to_vec());
        }
        x.count_unexpected(mailbox_type);
    }
}

/// Whether another message follows the whole message `message`, by `follows`.
fn follows_in(message: &[u8], mailbox_type: MailboxType, follows: fn(&[u8]) -> bool) -> bool {
    match split(message) {
        Ok((ty, data)) => ty == mailbox_type && follows(&data),
        Err(_) => false,
    }
}

impl SlaveMailbox {
    /// Writes one complete mailbox message (header and data; the header's counter is
    /// replaced by the engine's, its address and priority by the master's) and returns
    /// the slave's answer: the next message of the same type that is not unsolicited
    /// (emergencies and EoE frames still go to their own queues) and answers this request
    /// (the same object, segment or IDN: a late answer to an earlier request is dropped and
    /// counted in [`MailboxStats::unexpected`](crate::mailbox::MailboxStats::unexpected)),
    /// or a mailbox error reply.
    pub async fn raw(&self, message: &[u8]) -> Result<Vec<u8>> {
        let (mailbox_type, data) = split(message)?;
        call_for(
            self,
            None,
            Subject::Raw(mailbox_type),
            move |x| -> BoxFuture<'_, _> {
                Box::pin(async move {
                    write(x, mailbox_type, &data).await?;
                    let reply = answer(x, mailbox_type, &data).await?;
                    Ok(reply)
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
        message: &[u8],
        follows: fn(&[u8]) -> bool,
        limit: usize,
    ) -> Result<Vec<Vec<u8>>> {
        let (mailbox_type, data) = split(message)?;
        call_for(
            self,
            None,
            Subject::Raw(mailbox_type),
            move |x| -> BoxFuture<'_, _> {
                Box::pin(async move {
                    write(x, mailbox_type, &data).await?;
                    let first = answer(x, mailbox_type, &data).await?;
                    let mut more = follows_in(&first, mailbox_type, follows);
                    let mut replies = vec![first];
                    loop {
                        if !more || replies.len() >= limit.max(1) {
                            return Ok(replies);
                        }
                        let reply = x.receive(mailbox_type).await?;
                        more = reply.header.mailbox_type == mailbox_type && follows(reply.data);
                        replies.push(reply.message.to_vec());
                    }
                })
            },
        )
        .await
    }

    /// Writes one complete mailbox message that gets no answer (an EoE fragment, an SDO
    /// abort).
    pub async fn raw_send(&self, message: &[u8]) -> Result<()> {
        let (mailbox_type, data) = split(message)?;
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
