//! The ESC and SII details of one slave for `slaves -v` and `graph`: the ESC information
//! block 0x0000-0x0009 (ETG.1000.4, spec-notes §esc.info), DL status 0x0110 (ETG.1000.4,
//! spec-notes §esc.dl) and the mailbox words 0x0014-0x001C of the SII (ETG.2010,
//! spec-notes §sii.fixed).

use master_core::wire::register::dl::DlStatus;
use proto::v1 as pb;
use serde_json::{Value, json};

use crate::client::Clients;
use crate::failure::Failure;
use crate::parse::failed;

/// What `slaves -v` prints below the identity, and its JSON.
pub struct Details {
    /// Text lines, each ending in a newline.
    pub text: String,
    /// The same as JSON.
    pub json: Value,
    /// Per port: implemented, link, loop closed, communication.
    pub ports: Vec<Port>,
}

/// One port of the ESC.
#[derive(Debug, Clone, Copy)]
pub struct Port {
    /// Port descriptor 0x0007: "N/A", "N/C", "EBUS", "MII".
    pub kind: &'static str,
    /// Physical link.
    pub link: bool,
    /// Loop closed.
    pub loop_closed: bool,
    /// Communication established.
    pub communication: bool,
}

/// Reads a register block of `slave`.
pub async fn register(
    c: &mut Clients,
    slave: &str,
    address: u32,
    length: u32,
) -> Result<Vec<u8>, Failure> {
    Ok(c.bus
        .read_register(pb::ReadRegisterRequest {
            slave: slave.to_owned(),
            address,
            length,
        })
        .await
        .map_err(failed)?
        .into_inner()
        .data)
}

/// Reads the details of `s`.
pub async fn details(c: &mut Clients, s: &pb::Slave) -> Result<Details, Failure> {
    let name = format!("pos:{}", s.position);
    let info = register(c, &name, 0x0000, 10).await?;
    let dl = register(c, &name, 0x0110, 2).await?;
    let (Some(info), Some(dl)) = (info.get(..10), dl.get(..2)) else {
        return Err(format!("slave {}: short register read", s.position).into());
    };
    let status = DlStatus::decode(u16::from_le_bytes([dl[0], dl[1]]));
    let features = u16::from_le_bytes([info[8], info[9]]);
    let ports: Vec<Port> = (0..4)
        .map(|n| {
            let p = status.ports[n];
            Port {
                kind: match (info[7] >> (2 * n)) & 3 {
                    0 => "N/A",
                    1 => "N/C",
                    2 => "EBUS",
                    _ => "MII",
                },
                link: p.link,
                loop_closed: p.loop_closed,
                communication: p.communication,
            }
        })
        .collect();
    let dc = features & 0x0004 != 0;
    let dc64 = features & 0x0008 != 0;
    let mut text = format!(
        "ESC:\n  Type: 0x{:02x}, revision 0x{:02x}, build 0x{:04x}\n  \
         FMMUs: {}, SyncManagers: {}, RAM: {} KiB\n\
         DL information:\n  FMMU bit operation: {}\n  Distributed clocks: {}\n\
         Port  Type  Link  Loop    Signal\n",
        info[0],
        info[1],
        u16::from_le_bytes([info[2], info[3]]),
        info[4],
        info[5],
        info[6],
        if features & 0x0001 == 0 { "yes" } else { "no" },
        match (dc, dc64) {
            (false, _) => "no",
            (true, true) => "yes, 64 bit",
            (true, false) => "yes, 32 bit",
        },
    );
    for (n, p) in ports.iter().enumerate() {
        text.push_str(&format!(
            "   {n}  {:<4}  {:<4}  {:<6}  {}\n",
            p.kind,
            if p.link { "up" } else { "down" },
            if p.loop_closed { "closed" } else { "open" },
            if p.communication { "yes" } else { "no" },
        ));
    }
    let mailboxes = mailboxes(c, &name, s).await?;
    text.push_str(&mailboxes.0);
    let json = json!({
        "type": info[0], "revision": info[1], "build": u16::from_le_bytes([info[2], info[3]]),
        "fmmus": info[4], "sync_managers": info[5], "ram_kib": info[6],
        "dc": dc, "dc_64bit": dc64,
        "ports": ports.iter().map(|p| json!({"type": p.kind, "link": p.link,
            "loop_closed": p.loop_closed, "communication": p.communication})).collect::<Vec<_>>(),
        "mailboxes": mailboxes.1,
    });
    Ok(Details { text, json, ports })
}

/// The mailbox lines from the SII's words 0x0014-0x001C.
async fn mailboxes(c: &mut Clients, name: &str, s: &pb::Slave) -> Result<(String, Value), Failure> {
    let sii = c
        .bus
        .read_sii(pb::ReadSiiRequest {
            slave: name.to_owned(),
        })
        .await
        .map_err(failed)?
        .into_inner()
        .data;
    let word = |w: usize| {
        sii.get(2 * w..2 * w + 2)
            .map_or(0, |b| u16::from_le_bytes([b[0], b[1]]))
    };
    let protocols = if s.mailbox_protocols.is_empty() {
        "none".to_owned()
    } else {
        s.mailbox_protocols.join(", ")
    };
    let text = format!(
        "Mailboxes:\n  Bootstrap RX: 0x{:04x}/{}, TX: 0x{:04x}/{}\n  \
         Standard  RX: 0x{:04x}/{}, TX: 0x{:04x}/{}\n  Supported protocols: {protocols}\n",
        word(0x14),
        word(0x15),
        word(0x16),
        word(0x17),
        word(0x18),
        word(0x19),
        word(0x1A),
        word(0x1B),
    );
    let json = json!({
        "bootstrap": {"rx": [word(0x14), word(0x15)], "tx": [word(0x16), word(0x17)]},
        "standard": {"rx": [word(0x18), word(0x19)], "tx": [word(0x1A), word(0x1B)]},
        "protocols": s.mailbox_protocols,
    });
    Ok((text, json))
}
