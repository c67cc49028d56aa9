//! `ecat slaves [-v]`: IgH's columns (position, `alias:relpos`, state, `+`/`E`, name; the
//! identity when a slave has no name), and with `-v` a block per slave: identity, ESC, ports
//! and links, DC, mailboxes and protocols, read from the ESC registers and the SII.

use proto::v1 as pb;
use serde_json::{Value, json};

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::{failed, slave_state_text};
use crate::select::Selection;
use crate::session::Session;

/// `ecat slaves`.
#[derive(Debug, clap::Args)]
pub struct Slaves {
    /// Only these slaves.
    #[command(flatten)]
    pub select: Selection,
    /// Details of each slave.
    #[arg(short = 'v', long)]
    pub verbose: bool,
}

/// The JSON of one slave (the fields of `ecat.v1.Slave`).
pub fn slave_json(s: &pb::Slave) -> Value {
    let id = s.identity.unwrap_or_default();
    json!({
        "position": s.position, "station": s.station, "alias": s.alias, "name": s.name,
        "state": slave_state_text(s), "present": s.present, "al_error": s.al_error, "al_status_code": s.al_status_code,
        "al_status_text": s.al_status_text, "mailbox_protocols": s.mailbox_protocols,
        "vendor_id": id.vendor_id, "product_code": id.product_code, "revision": id.revision,
        "serial": id.serial,
    })
}

/// IgH's `alias:relpos` of every slave: the alias of the last slave before it (or itself)
/// that has one, and how many positions after that slave it is.
pub fn alias_relpos(slaves: &[pb::Slave]) -> Vec<(u32, u32)> {
    let mut base = (0u32, 0u32);
    slaves
        .iter()
        .map(|s| {
            if s.alias != 0 {
                base = (s.alias, s.position);
            }
            (base.0, s.position - base.1)
        })
        .collect()
}

/// The slave's name, or its identity when it has none (as IgH prints a nameless slave).
pub fn display_name(s: &pb::Slave) -> String {
    if s.name.is_empty() {
        let id = s.identity.unwrap_or_default();
        format!("0x{:08x}:0x{:08x}", id.vendor_id, id.product_code)
    } else {
        s.name.clone()
    }
}

fn table(slaves: &[pb::Slave], relpos: &[(u32, u32)]) -> String {
    let width = |f: &dyn Fn(usize) -> usize| (0..slaves.len()).map(f).max().unwrap_or(1);
    let pos_w = width(&|i| slaves[i].position.to_string().len());
    let alias_w = width(&|i| relpos[i].0.to_string().len());
    let rel_w = width(&|i| relpos[i].1.to_string().len());
    let state_w = width(&|i| slave_state_text(&slaves[i]).len());
    slaves
        .iter()
        .zip(relpos)
        .map(|(s, (alias, rel))| {
            format!(
                "{:>pos_w$}  {:>alias_w$}:{:<rel_w$}  {:<state_w$}  {}  {}",
                s.position,
                alias,
                rel,
                slave_state_text(s),
                if s.al_error { 'E' } else { '+' },
                display_name(s)
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

impl Run for Slaves {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let all = session.slaves().await?;
        let c = session.clients().await?;
        let relpos = alias_relpos(&all);
        let mut chosen: Vec<usize> = (0..all.len()).collect();
        if let Some(name) = self.select.given()? {
            let one = c
                .bus
                .get_slave(pb::GetSlaveRequest { slave: name })
                .await
                .map_err(failed)?
                .into_inner();
            chosen.retain(|&i| all[i].position == one.position);
        }
        let slaves: Vec<pb::Slave> = chosen.iter().map(|&i| all[i].clone()).collect();
        let relpos: Vec<(u32, u32)> = chosen.iter().map(|&i| relpos[i]).collect();
        if !self.verbose {
            return Ok(out(
                Value::Array(slaves.iter().map(slave_json).collect()),
                table(&slaves, &relpos),
            ));
        }
        let mut json = Vec::new();
        let mut human = Vec::new();
        for (s, rel) in slaves.iter().zip(&relpos) {
            let details = super::esc::details(c, s).await?;
            let mut j = slave_json(s);
            j["esc"] = details.json.clone();
            json.push(j);
            human.push(verbose_block(s, *rel, &details.text));
        }
        Ok(out(Value::Array(json), human.join("\n")))
    }
}

fn verbose_block(s: &pb::Slave, (alias, rel): (u32, u32), details: &str) -> String {
    let id = s.identity.unwrap_or_default();
    let mut text = format!(
        "=== Master 0, Slave {} ===\n\
         Alias: {}\n\
         Relative position: {alias}:{rel}\n\
         Station: {} (0x{:04x})\n\
         State: {}\n\
         Flag: {}\n\
         Identity:\n  \
           Vendor Id:       0x{:08x}\n  \
           Product code:    0x{:08x}\n  \
           Revision number: 0x{:08x}\n  \
           Serial number:   0x{:08x}\n",
        s.position,
        s.alias,
        s.station,
        s.station,
        slave_state_text(s),
        if s.al_error { 'E' } else { '+' },
        id.vendor_id,
        id.product_code,
        id.revision,
        id.serial,
    );
    if s.al_error {
        text.push_str(&format!(
            "AL status code: 0x{:04x} {}\n",
            s.al_status_code, s.al_status_text
        ));
    }
    text.push_str(details);
    text.push_str(&format!("Name: {}", display_name(s)));
    text
}
