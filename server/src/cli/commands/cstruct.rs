//! `ecat cstruct`: each slave's PDO assignment as the C structures IgH's application
//! interface takes (`ecrt.h`: `ec_pdo_entry_info_t`, `ec_pdo_info_t`, `ec_sync_info_t`, the
//! sync list ended by `{0xff}`), to paste into a program written for IgH: the same output
//! as IgH's `ethercat cstruct`. From the layout ecatd keeps (no frame is sent).

use proto::v1 as pb;
use serde_json::{Value, json};

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::failed;
use crate::select::Selection;
use crate::session::Session;

/// `ecat cstruct`.
#[derive(Debug, clap::Args)]
pub struct Cstruct {
    /// The slave (every slave when none is selected).
    #[command(flatten)]
    pub select: Selection,
}

impl Run for Cstruct {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.given()?.unwrap_or_default();
        let slaves = session.slaves().await?;
        let layout = session
            .clients()
            .await?
            .pd
            .get_layout(pb::GetLayoutRequest { slave })
            .await
            .map_err(failed)?
            .into_inner();
        let mut text = Vec::new();
        let mut json = Vec::new();
        for s in &layout.slaves {
            let known = slaves.iter().find(|k| k.position == s.slave);
            text.push(c_source(s, known));
            json.push(json!({"slave": s.slave, "c": text.last()}));
        }
        Ok(out(Value::Array(json), text.join("\n")))
    }
}

/// IgH's direction of a SyncManager from its control byte (bit 2: the master writes).
fn direction(sm: &pb::PdSyncManager) -> &'static str {
    if sm.control_register & 0x04 != 0 {
        "EC_DIR_OUTPUT"
    } else {
        "EC_DIR_INPUT"
    }
}

/// IgH's watchdog mode of a SyncManager from its control byte (bit 6: watchdog trigger).
fn watchdog(sm: &pb::PdSyncManager) -> &'static str {
    if sm.control_register & 0x40 != 0 {
        "EC_WD_ENABLE"
    } else {
        "EC_WD_DISABLE"
    }
}

/// One slave's three arrays, with a comment naming it.
fn c_source(s: &pb::PdSlave, known: Option<&pb::Slave>) -> String {
    let n = s.slave;
    let identity = known.and_then(|k| k.identity).unwrap_or_default();
    let mut c = vec![
        format!(
            "/* Master 0, Slave {n}, \"{}\"",
            known.map_or("", |k| k.name.as_str()).replace("*/", "* /")
        ),
        format!(" * Vendor ID:       0x{:08x}", identity.vendor_id),
        format!(" * Product code:    0x{:08x}", identity.product_code),
        format!(" * Revision number: 0x{:08x}", identity.revision),
        " */".into(),
        String::new(),
    ];
    let pdos: Vec<&pb::Pdo> = s.sync_managers.iter().flat_map(|sm| &sm.pdos).collect();
    let entries: Vec<&pb::PdoEntry> = pdos.iter().flat_map(|pdo| &pdo.entries).collect();
    // C has no empty initialiser lists: a slave without PDOs (or without entries) gets no
    // array, and its syncs point nowhere.
    if !entries.is_empty() {
        c.push(format!("ec_pdo_entry_info_t slave_{n}_pdo_entries[] = {{"));
        for e in &entries {
            let name = comment(&e.name);
            c.push(format!(
                "    {{0x{:04x}, 0x{:02x}, {}}},{name}",
                e.index, e.subindex, e.bit_length
            ));
        }
        c.push("};".into());
        c.push(String::new());
    }
    if !pdos.is_empty() {
        c.push(format!("ec_pdo_info_t slave_{n}_pdos[] = {{"));
        let mut first_entry = 0;
        for pdo in &pdos {
            let entries = if pdo.entries.is_empty() {
                "NULL".to_owned()
            } else {
                format!("slave_{n}_pdo_entries + {first_entry}")
            };
            c.push(format!(
                "    {{0x{:04x}, {}, {entries}}},{}",
                pdo.index,
                pdo.entries.len(),
                comment(&pdo.name)
            ));
            first_entry += pdo.entries.len();
        }
        c.push("};".into());
        c.push(String::new());
    }
    c.push(format!("ec_sync_info_t slave_{n}_syncs[] = {{"));
    let mut first_pdo = 0;
    for sm in &s.sync_managers {
        let list = if sm.pdos.is_empty() {
            "NULL".to_owned()
        } else {
            format!("slave_{n}_pdos + {first_pdo}")
        };
        c.push(format!(
            "    {{{}, {}, {}, {list}, {}}},",
            sm.index,
            direction(sm),
            sm.pdos.len(),
            watchdog(sm)
        ));
        first_pdo += sm.pdos.len();
    }
    c.push("    {0xff}".into());
    c.push("};".into());
    c.push(String::new());
    c.join("\n")
}

/// A name as a C comment (` /* Status */`), none when empty.
fn comment(name: &str) -> String {
    if name.is_empty() {
        String::new()
    } else {
        format!(" /* {} */", name.replace("*/", "* /"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_pdos_and_syncs_point_into_each_other() {
        let entry = |index, subindex, bit_length| pb::PdoEntry {
            index,
            subindex,
            bit_length,
            name: String::new(),
        };
        let slave = pb::PdSlave {
            slave: 2,
            station: 1003,
            sync_managers: vec![
                pb::PdSyncManager {
                    index: 2,
                    control_register: 0x64,
                    pdos: vec![pb::Pdo {
                        index: 0x1600,
                        name: "Out */".into(),
                        entries: vec![entry(0x7000, 1, 1), entry(0, 0, 7)],
                    }],
                    ..Default::default()
                },
                pb::PdSyncManager {
                    index: 3,
                    control_register: 0x20,
                    pdos: vec![pb::Pdo {
                        index: 0x1a00,
                        name: String::new(),
                        entries: vec![entry(0x6000, 1, 16)],
                    }],
                    ..Default::default()
                },
            ],
        };
        let c = c_source(&slave, None);
        assert!(
            c.contains("    {0x7000, 0x01, 1},\n    {0x0000, 0x00, 7},\n    {0x6000, 0x01, 16},"),
            "{c}"
        );
        assert!(
            c.contains("    {0x1600, 2, slave_2_pdo_entries + 0}, /* Out * / */"),
            "{c}"
        );
        assert!(
            c.contains("    {0x1a00, 1, slave_2_pdo_entries + 2},"),
            "{c}"
        );
        assert!(
            c.contains("    {2, EC_DIR_OUTPUT, 1, slave_2_pdos + 0, EC_WD_ENABLE},"),
            "{c}"
        );
        assert!(
            c.contains("    {3, EC_DIR_INPUT, 1, slave_2_pdos + 1, EC_WD_DISABLE},"),
            "{c}"
        );
        assert!(c.contains("    {0xff}\n};"), "{c}");
    }
}
