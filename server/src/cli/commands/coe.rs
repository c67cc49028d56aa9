//! CoE commands: `upload`, `download`, `sdos`. Value types take IgH's names
//! (`uint16`, `int32`, `float`, `double`, `string`, `octet_string`) and ours (`u16`, `f32`,
//! `hex`).

use master_core::wire::coe::DataType;
use proto::v1 as pb;
use serde_json::{Value, json};

use crate::Run;
use crate::client::Clients;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::{failed, num, typed, unhex};
use crate::select::Selection;
use crate::session::Session;

/// `ecat upload`.
#[derive(Debug, clap::Args)]
pub struct Upload {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// Object index.
    pub index: String,
    /// Subindex.
    pub subindex: String,
    /// Value type: auto (from the slave's SDO Information) or a type name (`uint32`,
    /// `int16`, `float`, `double`, `string`, `octet_string`, `u32`, `hex`, ...).
    #[arg(long = "type", short = 't', default_value = "auto")]
    pub ty: String,
    /// Complete access.
    #[arg(long)]
    pub complete: bool,
}

/// `ecat download`.
#[derive(Debug, clap::Args)]
pub struct Download {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// Object index.
    pub index: String,
    /// Subindex.
    pub subindex: String,
    /// The value, as `--type` says (hex bytes with `--complete`).
    pub value: String,
    /// Value type: auto (from the slave's SDO Information) or a type name.
    #[arg(long = "type", short = 't', default_value = "auto")]
    pub ty: String,
    /// Complete access.
    #[arg(long)]
    pub complete: bool,
}

/// `ecat sdos`.
#[derive(Debug, clap::Args)]
pub struct Sdos {
    /// The slave (every slave with CoE when none is selected, each under IgH's
    /// `=== Master 0, Slave N ===` when there are several).
    #[command(flatten)]
    pub select: Selection,
    /// Objects only, without their entries (IgH's `-q`).
    #[arg(short, long)]
    pub quiet: bool,
}

/// IgH's name of a CoE data type (`uint32`, `float`, ...).
fn igh_type(code: u32) -> String {
    let Ok(code) = u16::try_from(code) else {
        return format!("type 0x{code:x}");
    };
    match DataType::from(code) {
        DataType::Boolean => "bool".into(),
        DataType::Integer8 => "int8".into(),
        DataType::Integer16 => "int16".into(),
        DataType::Integer32 => "int32".into(),
        DataType::Integer64 => "int64".into(),
        DataType::Unsigned8 => "uint8".into(),
        DataType::Unsigned16 => "uint16".into(),
        DataType::Unsigned32 => "uint32".into(),
        DataType::Unsigned64 => "uint64".into(),
        DataType::Real32 => "float".into(),
        DataType::Real64 => "double".into(),
        DataType::VisibleString => "string".into(),
        DataType::OctetString => "octet_string".into(),
        DataType::UnicodeString => "unicode_string".into(),
        other => other.name().to_ascii_lowercase(),
    }
}

/// IgH's access column: `r`/`w` or `-` for PREOP, SAFEOP and OP (the object access word of
/// Get Entry Description: bits 0-2 read, 3-5 write; ETG.1000.6, spec-notes §coe.info).
fn access(bits: u32) -> String {
    (0..3)
        .flat_map(|state| {
            [
                if bits & (1 << state) != 0 { 'r' } else { '-' },
                if bits & (1 << (state + 3)) != 0 {
                    'w'
                } else {
                    '-'
                },
            ]
        })
        .collect()
}

/// The type to ask the server for: the named one, or for `auto` the one the slave's SDO
/// Information names (so that integers can be printed as IgH does); `auto` again when the
/// slave cannot say.
async fn resolve_type(c: &mut Clients, slave: &str, index: u32, subindex: u32, ty: &str) -> String {
    if ty != "auto" {
        return ty.to_owned();
    }
    match c
        .coe
        .entry_description(pb::EntryDescriptionRequest {
            slave: slave.to_owned(),
            index,
            subindex,
        })
        .await
    {
        Ok(entry) => {
            let name = igh_type(entry.into_inner().data_type);
            if typed(&name).is_ok() {
                name
            } else {
                "auto".into()
            }
        }
        Err(_) => "auto".into(),
    }
}

/// IgH's upload line: `0x002a 42` for an integer, the value alone otherwise.
fn igh_value(ty: &str, data: &[u8], value: &str) -> String {
    use server::input::value::ValueType::*;
    match typed(ty) {
        Ok(Bool | U8 | U16 | U32 | U64 | I8 | I16 | I32 | I64) if !data.is_empty() => {
            let hex: std::string::String = data.iter().rev().map(|b| format!("{b:02x}")).collect();
            format!("0x{hex} {value}")
        }
        _ => value.to_owned(),
    }
}

impl Run for Upload {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.one(session, "upload").await?;
        let c = session.clients().await?;
        let index = num(&self.index, "index")?;
        let subindex = num(&self.subindex, "subindex")?;
        let ty = if self.complete {
            self.ty.clone()
        } else {
            resolve_type(c, &slave, index, subindex, &self.ty).await
        };
        let r = c
            .coe
            .upload(pb::UploadRequest {
                slave,
                index,
                subindex,
                complete_access: self.complete,
                value_type: ty.clone(),
            })
            .await
            .map_err(failed)?
            .into_inner();
        let human = igh_value(&ty, &r.data, &r.value);
        Ok(out(
            json!({"data": hex::encode(&r.data), "value": r.value}),
            human,
        ))
    }
}

impl Run for Download {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.one(session, "download").await?;
        let (data, value, value_type) = if self.complete {
            // Complete access takes raw bytes only.
            (unhex(&self.value)?, String::new(), String::new())
        } else {
            (Vec::new(), self.value, self.ty)
        };
        session
            .clients()
            .await?
            .coe
            .download(pb::DownloadRequest {
                slave,
                index: num(&self.index, "index")?,
                subindex: num(&self.subindex, "subindex")?,
                data,
                complete_access: self.complete,
                value,
                value_type,
            })
            .await
            .map_err(failed)?;
        Ok(out(json!({"ok": true}), ""))
    }
}

impl Run for Sdos {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slaves = match self.select.given()? {
            Some(slave) => vec![slave],
            // IgH lists every slave's dictionary; a slave without CoE has none.
            None => session
                .slaves()
                .await?
                .iter()
                .filter(|s| s.mailbox_protocols.iter().any(|p| p == "CoE"))
                .map(|s| s.position.to_string())
                .collect(),
        };
        let headers = slaves.len() > 1;
        let c = session.clients().await?;
        let mut human = Vec::new();
        let mut json = Vec::new();
        for slave in slaves {
            if headers {
                human.push(format!("=== Master 0, Slave {slave} ==="));
            }
            let objects = dictionary(c, &slave, self.quiet, &mut human).await?;
            if !headers {
                return Ok(out(Value::Array(objects), human.join("\n")));
            }
            json.push(json!({"slave": slave.parse::<u32>().ok(), "objects": objects}));
        }
        Ok(out(Value::Array(json), human.join("\n")))
    }
}

/// One slave's dictionary (SDO Information): IgH's lines added to `human`, the objects as
/// JSON returned; `quiet` leaves the entries out.
async fn dictionary(
    c: &mut Clients,
    slave: &str,
    quiet: bool,
    human: &mut Vec<String>,
) -> Result<Vec<Value>, Failure> {
    let list = c
        .coe
        .object_list(pb::ObjectListRequest {
            slave: slave.to_owned(),
            list: 1,
        })
        .await
        .map_err(failed)?
        .into_inner();
    let mut objects = Vec::new();
    for index in list.indices {
        let o = c
            .coe
            .object_description(pb::ObjectDescriptionRequest {
                slave: slave.to_owned(),
                index,
            })
            .await
            .map_err(failed)?
            .into_inner();
        human.push(format!("SDO 0x{:04x}, \"{}\"", o.index, o.name));
        let mut entries = Vec::new();
        if !quiet {
            for subindex in 0..=o.max_subindex {
                // A gap in a record's subindices answers with an abort: not an entry.
                let Ok(e) = c
                    .coe
                    .entry_description(pb::EntryDescriptionRequest {
                        slave: slave.to_owned(),
                        index,
                        subindex,
                    })
                    .await
                else {
                    continue;
                };
                let e = e.into_inner();
                human.push(format!(
                    "  0x{:04x}:{:02x}, {}, {}, {} bit, \"{}\"",
                    e.index,
                    e.subindex,
                    access(e.access),
                    igh_type(e.data_type),
                    e.bit_length,
                    e.description
                ));
                entries.push(json!({"subindex": e.subindex, "access": access(e.access),
                    "data_type": igh_type(e.data_type), "bit_length": e.bit_length,
                    "name": e.description}));
            }
        }
        objects.push(
            json!({"index": o.index, "name": o.name, "data_type": o.data_type_name,
            "max_subindex": o.max_subindex, "entries": entries}),
        );
    }
    Ok(objects)
}
