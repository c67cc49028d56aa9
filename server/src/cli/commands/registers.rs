//! ESC register commands: `reg_read`, `reg_write` (IgH's arguments: offset, then a length
//! or the data; `--type` for a typed value), `reg_rdwr` (IgH has no such command: here it is
//! the ESC's combined read/write, one FPRW datagram that writes the data and returns what was
//! there before, ETG.1000.4 §5.4.3), `alias`, and `crc` (the error counters 0x0300-0x0313
//! of every slave as IgH's table: ETG.1000.4, spec-notes §esc.errors).

use master_core::wire::register::error_counters::{ERROR_COUNTERS_LEN, ErrorCounters};
use proto::v1 as pb;
use serde_json::{Value, json};
use server::input::value::ValueType;

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::{failed, num, typed, unhex};
use crate::select::Selection;
use crate::session::Session;

/// `ecat reg_read`.
#[derive(Debug, clap::Args)]
pub struct RegRead {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// Register address.
    pub address: String,
    /// Bytes (default 1, or the size of `--type`).
    pub length: Option<String>,
    /// Show the value as this type (`uint16`, `int32`, `u8`, `string`, ... as `upload`);
    /// raw hex without it.
    #[arg(long = "type", short = 't')]
    pub ty: Option<String>,
}

/// `ecat reg_write`.
#[derive(Debug, clap::Args)]
pub struct RegWrite {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// Register address.
    pub address: String,
    /// Data: hex bytes, or a value of `--type`.
    pub data: String,
    /// The type of DATA (`uint16`, `int32`, ...); hex bytes without it.
    #[arg(long = "type", short = 't')]
    pub ty: Option<String>,
}

/// `ecat reg_rdwr`: write and read back in one FPRW datagram.
#[derive(Debug, clap::Args)]
pub struct RegRdwr {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// Register address.
    pub address: String,
    /// Data written: hex bytes, or a value of `--type`; as many bytes are read.
    pub data: String,
    /// The type of DATA and of the value read (`uint16`, ...); hex bytes without it.
    #[arg(long = "type", short = 't')]
    pub ty: Option<String>,
}

/// Register data from the command line: a value of `ty`, or hex bytes.
fn register_data(data: &str, ty: Option<&str>) -> Result<Vec<u8>, Failure> {
    match ty {
        Some(ty) => server::input::value::encode(typed(ty)?, data).map_err(|e| e.message.into()),
        None => Ok(unhex(data)?),
    }
}

/// Bytes of a value of `ty`; `None` for strings and raw bytes.
fn type_size(ty: ValueType) -> Option<u32> {
    Some(match ty {
        ValueType::Bool | ValueType::U8 | ValueType::I8 => 1,
        ValueType::U16 | ValueType::I16 => 2,
        ValueType::U32 | ValueType::I32 | ValueType::F32 => 4,
        ValueType::U64 | ValueType::I64 | ValueType::F64 => 8,
        ValueType::String | ValueType::Hex => return None,
    })
}

/// Register bytes as the command prints them: the value of `ty`, or hex (`0x` and the
/// bytes in address order, as IgH prints raw registers).
fn show(data: &[u8], ty: Option<&str>) -> Result<(serde_json::Value, String), Failure> {
    match ty {
        Some(ty) => {
            let ty = typed(ty)?;
            let value = server::input::value::decode(ty, data).map_err(|e| e.message)?;
            Ok((json!({"data": hex::encode(data), "value": value}), value))
        }
        None => Ok((
            json!({"data": hex::encode(data)}),
            data.iter()
                .map(|b| format!("0x{b:02x}"))
                .collect::<Vec<_>>()
                .join(" "),
        )),
    }
}

/// `ecat alias`.
#[derive(Debug, clap::Args)]
pub struct Alias {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// The new alias.
    #[arg(value_name = "ALIAS")]
    pub new_alias: String,
}

/// `ecat crc`.
#[derive(Debug, clap::Args)]
pub struct Crc {}

impl Run for RegRead {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.one(session, "reg_read").await?;
        let length: u32 = match (&self.length, &self.ty) {
            (Some(length), _) => num(length, "length")?,
            (None, Some(ty)) => {
                type_size(typed(ty)?).ok_or_else(|| format!("give a length for type {ty}"))?
            }
            (None, None) => 1,
        };
        let r = session
            .clients()
            .await?
            .bus
            .read_register(pb::ReadRegisterRequest {
                slave,
                address: num(&self.address, "address")?,
                length,
            })
            .await
            .map_err(failed)?
            .into_inner();
        let (json, human) = show(&r.data, self.ty.as_deref())?;
        Ok(out(json, human))
    }
}

impl Run for RegWrite {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.one(session, "reg_write").await?;
        let data = register_data(&self.data, self.ty.as_deref())?;
        session
            .clients()
            .await?
            .bus
            .write_register(pb::WriteRegisterRequest {
                slave,
                address: num(&self.address, "address")?,
                data,
            })
            .await
            .map_err(failed)?;
        Ok(out(json!({"ok": true}), ""))
    }
}

impl Run for RegRdwr {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.one(session, "reg_rdwr").await?;
        let data = register_data(&self.data, self.ty.as_deref())?;
        let r = session
            .clients()
            .await?
            .bus
            .read_write_register(pb::ReadWriteRegisterRequest {
                slave,
                address: num(&self.address, "address")?,
                data,
            })
            .await
            .map_err(failed)?
            .into_inner();
        let (json, human) = show(&r.data, self.ty.as_deref())?;
        Ok(out(json, human))
    }
}

impl Run for Alias {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.one(session, "alias").await?;
        let r = session
            .clients()
            .await?
            .bus
            .set_alias(pb::SetAliasRequest {
                slave,
                alias: num(&self.new_alias, "alias")?,
            })
            .await
            .map_err(failed)?
            .into_inner();
        Ok(out(
            json!({"alias": r.alias}),
            format!("alias 0x{:04x}", r.alias),
        ))
    }
}

impl Run for Crc {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slaves = session.slaves().await?;
        let c = session.clients().await?;
        let mut human = vec![
            "Pos  |CRC A|Phy A|Fwd A|CRC B|Phy B|Fwd B|CRC C|Phy C|Fwd C|CRC D|Phy D|Fwd D|PU |PDI|Lnk A|Lnk B|Lnk C|Lnk D"
                .to_owned(),
        ];
        let mut json = Vec::new();
        for s in &slaves {
            let data = super::esc::register(
                c,
                &format!("pos:{}", s.position),
                0x0300,
                ERROR_COUNTERS_LEN as u32,
            )
            .await?;
            let counters = ErrorCounters::new_checked(&data[..])
                .map_err(|err| format!("slave {}: error counters: {err}", s.position))?;
            let mut line = format!("{:<5}", s.position);
            for port in 0..4 {
                line.push_str(&format!(
                    "|{:>5}|{:>5}|{:>5}",
                    counters.invalid_frame(port),
                    counters.rx_error(port),
                    counters.forwarded_rx_error(port)
                ));
            }
            line.push_str(&format!(
                "|{:>3}|{:>3}",
                counters.processing_unit(),
                counters.pdi()
            ));
            for port in 0..4 {
                line.push_str(&format!("|{:>5}", counters.lost_link(port)));
            }
            human.push(line);
            json.push(json!({
                "position": s.position,
                "invalid_frame": (0..4).map(|p| counters.invalid_frame(p)).collect::<Vec<_>>(),
                "rx_error": (0..4).map(|p| counters.rx_error(p)).collect::<Vec<_>>(),
                "forwarded_rx_error": (0..4).map(|p| counters.forwarded_rx_error(p)).collect::<Vec<_>>(),
                "processing_unit": counters.processing_unit(),
                "pdi": counters.pdi(),
                "lost_link": (0..4).map(|p| counters.lost_link(p)).collect::<Vec<_>>(),
            }));
        }
        Ok(out(Value::Array(json), human.join("\n")))
    }
}
