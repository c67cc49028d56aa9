//! ENI import (ETG.2100, EtherCAT Network Information): the cycle time, the slaves with
//! identity and position, their process data (SyncManager PDO assignment and PDO
//! mappings), their CoE and SoE InitCmds with transitions, and their DC settings become
//! the same configuration as `[bus] cycle` and `[[slave]]` entries. What ecatd does not
//! use is listed (element paths with counts) for one log line.

mod reader;

use std::path::Path;
use std::time::Duration;

use roxmltree::{Document, Node};

use super::slaves::{AssignEntry, DcEntry, EntryEntry, PdoEntry, SlaveEntry, StartupEntry};
use reader::Reader;

/// What an ENI file says, as configuration.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Eni {
    /// `Config/Cyclic/CycleTime` (µs in the file).
    pub cycle: Option<Duration>,
    /// One entry per `Config/Slave`, by position.
    pub slaves: Vec<SlaveEntry>,
    /// Elements not used: `path: count`.
    pub unused: Vec<String>,
}

/// Reads and converts the ENI file `path`.
pub fn load(path: &Path) -> Result<Eni, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|err| format!("cannot read ENI {}: {err}", path.display()))?;
    parse(&text, &path.display().to_string())
}

/// Converts ENI text; `file` names it in messages.
pub fn parse(text: &str, file: &str) -> Result<Eni, String> {
    let doc = Document::parse(text).map_err(|err| format!("{file}: not XML: {err}"))?;
    let r = Reader::new(&doc, file.to_owned());
    let root = doc.root_element();
    if root.tag_name().name() != "EtherCATConfig" {
        return Err(r.error(root, "the root element of an ENI is <EtherCATConfig>"));
    }
    let config = r
        .child(root, "Config")
        .ok_or_else(|| r.error(root, "<Config> is missing"))?;
    let cycle = match r.child(config, "Cyclic") {
        Some(cyclic) => r.number(cyclic, "CycleTime")?.map(Duration::from_micros),
        None => None,
    };
    let mut slaves = Vec::new();
    for (order, slave) in r.children(config, "Slave").into_iter().enumerate() {
        slaves.push(read_slave(&r, slave, order)?);
    }
    if slaves.is_empty() {
        return Err(r.error(config, "no <Slave>"));
    }
    let unused = r
        .unused()
        .into_iter()
        .map(|(path, count)| format!("{path} ({count})"))
        .collect();
    Ok(Eni {
        cycle,
        slaves,
        unused,
    })
}

fn read_slave(r: &Reader<'_, '_>, slave: Node<'_, '_>, order: usize) -> Result<SlaveEntry, String> {
    let info = r
        .child(slave, "Info")
        .ok_or_else(|| r.error(slave, "<Info> is missing"))?;
    let name = r.text(info, "Name");
    // Auto-increment addresses count down from 0: position p is -p.
    let position = match r.number(info, "AutoIncAddr")? {
        Some(raw) => {
            let raw =
                u16::try_from(raw).map_err(|_| r.error(info, "<AutoIncAddr> out of range"))?;
            0u16.wrapping_sub(raw)
        }
        None => u16::try_from(order).map_err(|_| r.error(slave, "too many slaves"))?,
    };
    let vendor_id: u32 = r.required(info, "VendorId")?;
    let product_code: u32 = r.required(info, "ProductCode")?;
    let revision: Option<u32> = r
        .number(info, "RevisionNo")?
        .map(|v| u32::try_from(v).map_err(|_| r.error(info, "<RevisionNo> out of range")))
        .transpose()?;
    let mut entry = SlaveEntry {
        name,
        position: Some(position),
        vendor_id: Some(vendor_id),
        product_code: Some(product_code),
        revision,
        ..SlaveEntry::default()
    };
    let mailbox = r.child(slave, "Mailbox");
    let coe = mailbox.and_then(|m| r.child(m, "CoE"));
    if let (Some(_), Some(pd)) = (coe, r.child(slave, "ProcessData")) {
        entry.pdo_assign = read_process_data(r, pd)?;
    }
    let assigned: Vec<u8> = entry.pdo_assign.iter().map(|a| a.sm).collect();
    if let Some(coe) = coe {
        entry.startup.extend(read_coe_cmds(r, coe, &assigned)?);
    }
    if let Some(soe) = mailbox.and_then(|m| r.child(m, "SoE")) {
        entry.startup.extend(read_soe_cmds(r, soe)?);
    }
    if let Some(dc) = r.child(slave, "DC") {
        entry.dc = read_dc(r, dc)?;
    }
    Ok(entry)
}

/// `ProcessData/Sm2|Sm3/Pdo` (the assignment, in order) with the `RxPdo`/`TxPdo` of each
/// (the mapping; a `Fixed` PDO keeps the slave's own).
fn read_process_data(r: &Reader<'_, '_>, pd: Node<'_, '_>) -> Result<Vec<AssignEntry>, String> {
    let mut assigns = Vec::new();
    for (sm, tag, kind) in [(2u8, "Sm2", "RxPdo"), (3, "Sm3", "TxPdo")] {
        let Some(node) = r.child(pd, tag) else {
            continue;
        };
        let definitions = r.children(pd, kind);
        let mut pdos = Vec::new();
        for p in r.children(node, "Pdo") {
            r.use_all(p);
            let text = p.text().unwrap_or("").trim();
            let index = reader::parse_number(text)
                .and_then(|v| u16::try_from(v).ok())
                .ok_or_else(|| r.error(p, format!("{text:?} is not a PDO index")))?;
            let definition = definitions.iter().find(|d| {
                d.children()
                    .find(|c| c.tag_name().name() == "Index")
                    .and_then(|c| c.text())
                    .and_then(reader::parse_number)
                    == Some(u64::from(index))
            });
            let entries = match definition {
                Some(d) => read_mapping(r, *d)?,
                None => None,
            };
            pdos.push(PdoEntry { index, entries });
        }
        assigns.push(AssignEntry { sm, pdos });
    }
    Ok(assigns)
}

fn read_mapping(r: &Reader<'_, '_>, pdo: Node<'_, '_>) -> Result<Option<Vec<EntryEntry>>, String> {
    r.use_all(pdo);
    if matches!(pdo.attribute("Fixed"), Some("1" | "true")) {
        return Ok(None);
    }
    let mut entries = Vec::new();
    for e in pdo
        .children()
        .filter(|c| c.is_element() && c.tag_name().name() == "Entry")
    {
        entries.push(EntryEntry {
            index: r.required(e, "Index")?,
            subindex: r
                .number(e, "SubIndex")?
                .unwrap_or(0)
                .try_into()
                .map_err(|_| r.error(e, "<SubIndex> out of range"))?,
            bits: r.required(e, "BitLen")?,
        });
    }
    Ok(Some(entries))
}

/// Whether a CoE InitCmd writes what the SyncManagers' PDO assignment already writes.
fn pdo_object(index: u16, assigned: &[u8]) -> bool {
    let sm_of = match index {
        0x1C12 | 0x1600..=0x17FF => 2,
        0x1C13 | 0x1A00..=0x1BFF => 3,
        _ => return false,
    };
    assigned.contains(&sm_of)
}

fn read_coe_cmds(
    r: &Reader<'_, '_>,
    coe: Node<'_, '_>,
    assigned: &[u8],
) -> Result<Vec<StartupEntry>, String> {
    let Some(cmds) = r.child(coe, "InitCmds") else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for cmd in r.children(cmds, "InitCmd") {
        // Only downloads (Ccs 1) are start-up writes; uploads stay listed as unused.
        let ccs = cmd
            .children()
            .find(|c| c.tag_name().name() == "Ccs")
            .and_then(|c| c.text())
            .and_then(reader::parse_number)
            .unwrap_or(1);
        if ccs != 1 {
            r.used_off(cmd);
            continue;
        }
        let index: u16 = r.required(cmd, "Index")?;
        let subindex: u8 = r.required(cmd, "SubIndex")?;
        let transition = r
            .text(cmd, "Transition")
            .ok_or_else(|| r.error(cmd, "<Transition> is missing"))?;
        let data = r
            .text(cmd, "Data")
            .ok_or_else(|| r.error(cmd, "<Data> is missing"))?;
        let comment = r.text(cmd, "Comment").filter(|c| !c.is_empty());
        let complete_access = matches!(cmd.attribute("CompleteAccess"), Some("1" | "true"));
        r.use_all(cmd);
        if pdo_object(index, assigned) {
            continue;
        }
        let entry = StartupEntry {
            transition,
            index: Some(index),
            subindex: Some(subindex),
            complete_access,
            idn: None,
            drive: None,
            value: None,
            data_type: None,
            data: Some(data),
            comment,
        };
        entry.command().map_err(|err| r.error(cmd, err))?;
        out.push(entry);
    }
    Ok(out)
}

fn read_soe_cmds(r: &Reader<'_, '_>, soe: Node<'_, '_>) -> Result<Vec<StartupEntry>, String> {
    let Some(cmds) = r.child(soe, "InitCmds") else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for cmd in r.children(cmds, "InitCmd") {
        let idn: u16 = r.required(cmd, "IDN")?;
        let drive: u8 = r
            .number(cmd, "DriveNo")?
            .unwrap_or(0)
            .try_into()
            .map_err(|_| r.error(cmd, "<DriveNo> out of range"))?;
        let transition = r
            .text(cmd, "Transition")
            .ok_or_else(|| r.error(cmd, "<Transition> is missing"))?;
        let data = r
            .text(cmd, "Data")
            .ok_or_else(|| r.error(cmd, "<Data> is missing"))?;
        let comment = r.text(cmd, "Comment").filter(|c| !c.is_empty());
        r.use_all(cmd);
        let entry = StartupEntry {
            transition,
            index: None,
            subindex: None,
            complete_access: false,
            idn: Some(super::slaves::IdnText::Number(idn)),
            drive: Some(drive),
            value: None,
            data_type: None,
            data: Some(data),
            comment,
        };
        entry.command().map_err(|err| r.error(cmd, err))?;
        out.push(entry);
    }
    Ok(out)
}

/// `DC/CycleTime0` (ns; 0 or absent: no SYNC0), `CycleTime1`, `ShiftTime0`/`ShiftTime`,
/// `ShiftTime1`.
fn read_dc(r: &Reader<'_, '_>, dc: Node<'_, '_>) -> Result<Option<DcEntry>, String> {
    let ns = |name: &str| -> Result<Option<Duration>, String> {
        Ok(r.number(dc, name)?
            .filter(|&v| v > 0)
            .map(Duration::from_nanos))
    };
    let Some(sync0) = ns("CycleTime0")? else {
        return Ok(None);
    };
    let shift0 = match ns("ShiftTime0")? {
        Some(shift) => Some(shift),
        None => ns("ShiftTime")?,
    };
    Ok(Some(DcEntry {
        enabled: true,
        sync0_cycle: Some(sync0),
        sync0_shift: shift0,
        sync1_cycle: ns("CycleTime1")?,
        sync1_shift: ns("ShiftTime1")?,
    }))
}

#[cfg(test)]
mod tests;
