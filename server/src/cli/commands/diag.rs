//! `ecat diag`: a slave's diagnosis history object 0x10F3 decoded (ETG.1020 §13): the
//! header (maximum messages, newest and newest acknowledged message, new messages
//! available, flags) and every used message slot with its DiagCode, type, text ID, time
//! stamp and parameters, oldest slot first; `*` marks the newest.

use proto::v1 as pb;
use serde_json::json;

use crate::Run;
use crate::client::Clients;
use crate::diag_message::{FIRST_MESSAGE, Message};
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::failed;
use crate::select::Selection;
use crate::session::Session;

/// The diagnosis history object.
const HISTORY: u32 = 0x10F3;

/// `ecat diag`.
#[derive(Debug, clap::Args)]
pub struct Diag {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
}

async fn entry(c: &mut Clients, slave: &str, subindex: u8) -> Result<Vec<u8>, Failure> {
    c.coe
        .upload(pb::UploadRequest {
            slave: slave.to_owned(),
            index: HISTORY,
            subindex: u32::from(subindex),
            complete_access: false,
            value_type: String::new(),
        })
        .await
        .map(|r| r.into_inner().data)
        .map_err(|status| failed(status).context(format!("0x10F3:{subindex:02X}")))
}

fn first_u(data: &[u8]) -> u64 {
    let mut bytes = [0u8; 8];
    let n = data.len().min(8);
    bytes[..n].copy_from_slice(&data[..n]);
    u64::from_le_bytes(bytes)
}

impl Run for Diag {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.one(session, "diag").await?;
        let c = session.clients().await?;
        let highest = first_u(&entry(c, &slave, 0).await?) as u8;
        if highest < FIRST_MESSAGE - 1 {
            return Err(format!(
                "slave {slave}: 0x10F3 has {highest} entries, not a diagnosis history"
            )
            .into());
        }
        let max = first_u(&entry(c, &slave, 1).await?);
        let newest = first_u(&entry(c, &slave, 2).await?) as u8;
        let acknowledged = first_u(&entry(c, &slave, 3).await?) as u8;
        let new_available = first_u(&entry(c, &slave, 4).await?) != 0;
        let flags = first_u(&entry(c, &slave, 5).await?) as u16;
        let mut human = vec![
            format!(
                "Diagnosis history of slave {slave}: {max} message slots, newest 0x{newest:02x}, \
                 acknowledged 0x{acknowledged:02x}, {}",
                if new_available {
                    "new messages available"
                } else {
                    "no new messages"
                }
            ),
            format!("Flags 0x{flags:04x}"),
            format!(
                "  {:<4} {:<7} {:<10} {:<6} {:>20}  Parameters",
                "Sub", "Type", "Code", "TextID", "Time (ns)"
            ),
        ];
        let mut messages = Vec::new();
        for subindex in FIRST_MESSAGE..=highest {
            let data = entry(c, &slave, subindex).await?;
            let Some(m) =
                Message::decode(&data).map_err(|err| format!("0x10F3:{subindex:02X}: {err}"))?
            else {
                continue;
            };
            let params: Vec<String> = m
                .params
                .iter()
                .map(|p| format!("{} {}", p.kind, p.text))
                .collect();
            human.push(format!(
                "{} 0x{subindex:02x} {:<7} 0x{:08x} 0x{:04x} {:>20}{}  {}",
                if subindex == newest { '*' } else { ' ' },
                m.severity(),
                m.code,
                m.text_id,
                m.time_ns,
                if m.local_time() { " local" } else { "" },
                params.join(", ")
            ));
            messages.push(m.json(subindex));
        }
        Ok(out(
            json!({
                "slave": slave,
                "max_messages": max,
                "newest": newest,
                "newest_acknowledged": acknowledged,
                "new_messages_available": new_available,
                "flags": flags,
                "messages": messages,
            }),
            human.join("\n"),
        ))
    }
}
