//! SoE client (ETG.1000.6, spec-notes §soe): reading and writing IDN elements of a servo drive, in
//! fragments when a value does not fit one mailbox message.

use crate::mailbox::engine::exchange::Exchange;
use crate::mailbox::engine::job::{BoxFuture, call_for};
use crate::mailbox::engine::report::Subject;
use crate::mailbox::engine::slave::SlaveMailbox;
use crate::mailbox::error::{MailboxError, Result};
use crate::wire::Emit;
use crate::wire::mailbox::MailboxType;
use crate::wire::soe::{self, ElementFlags, Idn, IdnOrFragments, SoeOpcode, SoePacket, SoeRepr};

async fn send_soe(x: &mut Exchange, repr: &SoeRepr<'_>) -> Result<()> {
    x.send(MailboxType::Soe, |buf| repr.emit_into(buf)).await
}

fn check_drive(drive: u8) -> Result<()> {
    if drive > 7 {
        return Err(MailboxError::Invalid(crate::wire::WireError::Invalid {
            what: "SoE request",
            reason: "drive number above 7",
        }));
    }
    Ok(())
}

async fn read(x: &mut Exchange, drive: u8, idn: Idn, elements: ElementFlags) -> Result<Vec<u8>> {
    let request = SoeRepr {
        opcode: SoeOpcode::ReadRequest,
        drive,
        elements,
        idn_or_fragments: IdnOrFragments::Idn(idn),
        error: None,
        data: &[],
    };
    send_soe(x, &request).await?;
    let limit = x.config().max_value_len;
    let mut value = Vec::new();
    loop {
        let reply = x.receive(MailboxType::Soe).await?;
        let parsed = SoePacket::new_checked(reply.data()?).and_then(|p| SoeRepr::parse(&p));
        let answer = match parsed {
            Ok(answer) if answer.opcode == SoeOpcode::ReadResponse && answer.drive == drive => {
                answer
            }
            _ => {
                x.count_unexpected(MailboxType::Soe);
                continue;
            }
        };
        // A fragment does not name its IDN, only the elements (the response echoes the
        // request's, ETG.1000.6 §5.7); an answer for other elements or another IDN is a late
        // one of an earlier read.
        let last = match answer.idn_or_fragments {
            IdnOrFragments::FragmentsLeft(_) if answer.elements == elements => false,
            IdnOrFragments::Idn(answered) if answered == idn => true,
            _ => {
                x.count_unexpected(MailboxType::Soe);
                continue;
            }
        };
        if let Some(code) = answer.error {
            return Err(MailboxError::Soe { drive, idn, code });
        }
        let size = value.len() + answer.data.len();
        if size > limit {
            return Err(MailboxError::TooLarge {
                what: "SoE value",
                size,
                limit,
            });
        }
        value.extend_from_slice(answer.data);
        if last {
            return Ok(value);
        }
    }
}

async fn write(
    x: &mut Exchange,
    drive: u8,
    idn: Idn,
    elements: ElementFlags,
    data: &[u8],
) -> Result<()> {
    let capacity = soe::fragment_capacity(x.write_size());
    let fragments = soe::fragments(data.len(), capacity).map_err(MailboxError::Invalid)?;
    for fragment in fragments {
        if x.cancelled() {
            // The slave drops the partial value when the next write starts over.
            return Err(MailboxError::Cancelled);
        }
        let request = SoeRepr {
            opcode: SoeOpcode::WriteRequest,
            drive,
            elements,
            idn_or_fragments: match fragment.fragments_left {
                Some(left) => IdnOrFragments::FragmentsLeft(left),
                None => IdnOrFragments::Idn(idn),
            },
            error: None,
            data: data.get(fragment.range).unwrap_or_default(),
        };
        send_soe(x, &request).await?;
    }
    loop {
        let reply = x.receive(MailboxType::Soe).await?;
        let parsed = SoePacket::new_checked(reply.data()?).and_then(|p| SoeRepr::parse(&p));
        match parsed {
            Ok(answer)
                if answer.opcode == SoeOpcode::WriteResponse
                    && answer.drive == drive
                    && answer.idn_or_fragments == IdnOrFragments::Idn(idn) =>
            {
                return match answer.error {
                    Some(code) => Err(MailboxError::Soe { drive, idn, code }),
                    None => Ok(()),
                };
            }
            _ => x.count_unexpected(MailboxType::Soe),
        }
    }
}

impl SlaveMailbox {
    /// Reads the `elements` of IDN `idn` of drive `drive` (0..=7); the slave's data for
    /// them, put together from every fragment. Usually [`ElementFlags::VALUE`].
    pub async fn soe_read(&self, drive: u8, idn: Idn, elements: ElementFlags) -> Result<Vec<u8>> {
        check_drive(drive)?;
        let subject = Subject::Idn { drive, idn };
        call_for(
            self,
            Some(MailboxType::Soe),
            subject,
            move |x| -> BoxFuture<'_, _> { Box::pin(read(x, drive, idn, elements)) },
        )
        .await
    }

    /// Writes `data` to the `elements` of IDN `idn` of drive `drive`, in as many fragments
    /// as the slave's receive mailbox needs.
    pub async fn soe_write(
        &self,
        drive: u8,
        idn: Idn,
        elements: ElementFlags,
        data: &[u8],
    ) -> Result<()> {
        check_drive(drive)?;
        let data = data.to_vec();
        let subject = Subject::Idn { drive, idn };
        call_for(
            self,
            Some(MailboxType::Soe),
            subject,
            move |x| -> BoxFuture<'_, _> {
                Box::pin(async move { write(x, drive, idn, elements, &data).await })
            },
        )
        .await
    }
}
