//! `ecat domains` and `ecat data`: the process image by domain. IgH's domains are ecatd's
//! slave groups (each its own share of the image, logical address and LRW): `domains` lists
//! each with its logical base address, size, working counter (last/expected) and slaves,
//! `-v` adds its entries and data; `data` writes the image bytes to standard output as IgH
//! does (`--hex` for a hex dump).

use proto::v1 as pb;
use serde_json::{Value, json};

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, bytes, out};
use crate::parse::{failed, num};
use crate::session::Session;

/// `ecat domains`.
#[derive(Debug, clap::Args)]
pub struct Domains {
    /// Only this domain (group number).
    #[arg(short = 'd', long = "domain")]
    pub domain: Option<String>,
    /// Entries and data too.
    #[arg(short = 'v', long)]
    pub verbose: bool,
}

/// `ecat data`.
#[derive(Debug, clap::Args)]
pub struct Data {
    /// Only this domain (group number); every domain, in order, when absent.
    #[arg(short = 'd', long = "domain")]
    pub domain: Option<String>,
    /// A hex dump (16 bytes a line, with the logical address) instead of raw bytes.
    #[arg(long)]
    pub hex: bool,
}

async fn domains(session: &mut Session, only: Option<&str>) -> Result<Vec<pb::Domain>, Failure> {
    let only: Option<u32> = only.map(|d| num(d, "domain")).transpose()?;
    let all = session
        .clients()
        .await?
        .bus
        .list_domains(pb::ListDomainsRequest {})
        .await
        .map_err(failed)?
        .into_inner()
        .domains;
    match only {
        None => Ok(all),
        Some(index) => {
            let count = all.len();
            let one: Vec<_> = all.into_iter().filter(|d| d.index == index).collect();
            if one.is_empty() {
                return Err(format!(
                    "no domain {index}: the segment has {count} (0..={})",
                    count.saturating_sub(1)
                )
                .into());
            }
            Ok(one)
        }
    }
}

fn dump(d: &pb::Domain, indent: &str) -> Vec<String> {
    d.data
        .chunks(16)
        .enumerate()
        .map(|(line, chunk)| {
            let hex: Vec<String> = chunk.iter().map(|b| format!("{b:02x}")).collect();
            format!(
                "{indent}0x{:08x}: {}",
                d.logical_address as usize + line * 16,
                hex.join(" ")
            )
        })
        .collect()
}

fn domain_json(d: &pb::Domain) -> Value {
    json!({
        "index": d.index,
        "logical_address": d.logical_address,
        "size": d.size,
        "expected_wkc": d.expected_wkc,
        "last_wkc": d.last_wkc,
        "wrong_wkc": d.wrong_wkc,
        "period_ns": d.period_ns,
        "slaves": d.slaves,
        "entries": d.entries.iter().map(|e| json!({
            "position": e.position,
            "pdo_index": e.pdo_index,
            "index": e.index,
            "subindex": e.subindex,
            "bit_length": e.bit_length,
            "bit_offset": e.bit_offset,
            "output": e.output,
            "name": e.name,
        })).collect::<Vec<_>>(),
        "data": hex::encode(&d.data),
    })
}

impl Run for Domains {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let list = domains(session, self.domain.as_deref()).await?;
        let mut human = Vec::new();
        for d in &list {
            let slaves: Vec<String> = d.slaves.iter().map(u32::to_string).collect();
            let period = if d.period_ns == 0 {
                String::new()
            } else {
                format!(", Period {} us", d.period_ns / 1000)
            };
            human.push(format!(
                "Domain{}: LogBaseAddr 0x{:08x}, Size {:>3}, WorkingCounter {}/{}, Slaves {}{period}",
                d.index,
                d.logical_address,
                d.size,
                d.last_wkc,
                d.expected_wkc,
                if slaves.is_empty() {
                    "-".to_owned()
                } else {
                    slaves.join(",")
                }
            ));
            if self.verbose {
                for e in &d.entries {
                    let address = u64::from(d.logical_address) * 8 + u64::from(e.bit_offset);
                    human.push(format!(
                        "  Slave {}, {} 0x{:04x}: 0x{:04x}:{:02x}, LogAddr 0x{:08x}.{}, {:>2} bit, {}",
                        e.position,
                        if e.output { "RxPdo" } else { "TxPdo" },
                        e.pdo_index,
                        e.index,
                        e.subindex,
                        address / 8,
                        address % 8,
                        e.bit_length,
                        e.name
                    ));
                }
                human.extend(dump(d, "  "));
            }
        }
        Ok(out(
            Value::Array(list.iter().map(domain_json).collect()),
            human.join("\n"),
        ))
    }
}

impl Run for Data {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let list = domains(session, self.domain.as_deref()).await?;
        let json = Value::Array(
            list.iter()
                .map(|d| json!({"index": d.index, "logical_address": d.logical_address, "data": hex::encode(&d.data)}))
                .collect(),
        );
        if self.hex {
            let lines: Vec<String> = list.iter().flat_map(|d| dump(d, "")).collect();
            return Ok(out(json, lines.join("\n")));
        }
        Ok(bytes(json, list.into_iter().flat_map(|d| d.data).collect()))
    }
}
