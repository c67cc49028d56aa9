//! `ecat soe_read` and `ecat soe_write`: IDNs as `S-0-0011`, `P-0-0100` or a number.

use proto::v1 as pb;
use serde_json::json;
// SoE's own text forms: a string travels with its length header.
use server::input::soe_value::{decode, encode};

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::{failed, idn, typed};
use crate::select::Selection;
use crate::session::Session;

/// `ecat soe_read`.
#[derive(Debug, clap::Args)]
pub struct SoeRead {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// Drive number (IgH's `-d`; default 0).
    #[arg(short = 'd', long, default_value = "0")]
    pub drive: u8,
    /// The IDN: `S-0-0011`, `P-0-0100` or a number (`0x8064`).
    pub idn: String,
    /// Value type (`uint16`, `int32`, `string`, `hex`, ...).
    #[arg(long = "type", short = 't', default_value = "hex")]
    pub ty: String,
}

/// `ecat soe_write`.
#[derive(Debug, clap::Args)]
pub struct SoeWrite {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// Drive number (IgH's `-d`; default 0).
    #[arg(short = 'd', long, default_value = "0")]
    pub drive: u8,
    /// The IDN: `S-0-0011`, `P-0-0100` or a number.
    pub idn: String,
    /// The value.
    pub value: String,
    /// Value type.
    #[arg(long = "type", short = 't', default_value = "hex")]
    pub ty: String,
}

impl Run for SoeRead {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let ty = typed(&self.ty)?;
        let idn = idn(&self.idn)?;
        let slave = self.select.one(session, "soe_read").await?;
        let r = session
            .clients()
            .await?
            .soe
            .read(pb::SoeReadRequest {
                slave,
                drive: u32::from(self.drive),
                idn,
                elements: 0,
                value_type: String::new(),
            })
            .await
            .map_err(failed)?
            .into_inner();
        let value = decode(ty, &r.data).map_err(|e| e.message)?;
        Ok(out(
            json!({"data": hex::encode(&r.data), "value": value}),
            value,
        ))
    }
}

impl Run for SoeWrite {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let data = encode(typed(&self.ty)?, &self.value).map_err(|e| e.message)?;
        let idn = idn(&self.idn)?;
        let slave = self.select.one(session, "soe_write").await?;
        session
            .clients()
            .await?
            .soe
            .write(pb::SoeWriteRequest {
                slave,
                drive: u32::from(self.drive),
                idn,
                elements: 0,
                data,
                value: String::new(),
                value_type: String::new(),
            })
            .await
            .map_err(failed)?;
        Ok(out(json!({"ok": true}), ""))
    }
}
