//! VoE client (spec-notes §voe): the master only moves the bytes; the meaning is the vendor's.

use crate::mailbox::engine::job::{BoxFuture, call};
use crate::mailbox::engine::slave::SlaveMailbox;
use crate::mailbox::error::Result;
use crate::wire::Emit;
use crate::wire::mailbox::MailboxType;
use crate::wire::voe::{VoePacket, VoeRepr};

/// A VoE message: vendor id, vendor type and data.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VoeMessage {
    /// EtherCAT vendor id of the protocol's owner.
    pub vendor_id: u32,
    /// Vendor-defined message type.
    pub vendor_type: u16,
    /// Vendor data.
    pub data: Vec<u8>,
}

impl SlaveMailbox {
    /// Sends a VoE message and returns the slave's VoE answer.
    pub async fn voe(&self, vendor_id: u32, vendor_type: u16, data: &[u8]) -> Result<VoeMessage> {
        let data = data.to_vec();
        call(self, Some(MailboxType::Voe), move |x| -> BoxFuture<'_, _> {
            Box::pin(async move {
                let request = VoeRepr {
                    vendor_id,
                    vendor_type,
                    data: &data,
                };
                x.send(MailboxType::Voe, |buf| request.emit_into(buf))
                    .await?;
                loop {
                    let reply = x.receive(MailboxType::Voe).await?;
                    let parsed =
                        VoePacket::new_checked(reply.data()?).and_then(|p| VoeRepr::parse(&p));
                    match parsed {
                        Ok(answer) => {
                            return Ok(VoeMessage {
                                vendor_id: answer.vendor_id,
                                vendor_type: answer.vendor_type,
                                data: answer.data.to_vec(),
                            });
                        }
                        Err(_) => x.count_unexpected(MailboxType::Voe),
                    }
                }
            })
        })
        .await
    }
}
