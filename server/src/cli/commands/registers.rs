//! ESC register commands: `reg_read`, `reg_write`, `alias`, and `crc` (the error counters
//! 0x0300-0x0313 of every slave as IgH's table: ETG.1000.4, spec-notes §esc.errors).

use master_core::wire::register::error_counters::{ERROR_COUNTERS_LEN, ErrorCounters};
use proto::v1 as pb;
use serde_json::{Value, json};

use crate::Run;
use crate::out::{Out, out};
use crate::parse::{failed, num, unhex};
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
    /// Bytes (default 1).
    #[arg(default_value = "1")]
    pub length: String,
}

/// `ecat reg_write`.
#[derive(Debug, clap::Args)]
pub struct RegWrite {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// Register address.
    pub address: String,
    /// Data, hex.
    pub data: String,
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
    async fn run(self, session: &mut Session) -> Result<Out, String> {
        let slave = self.select.one(session, "reg_read").await?;
        let r = session
            .clients()
            .await?
            .bus
            .read_register(pb::ReadRegisterRequest {
                slave,
                address: num(&self.address, "address")?,
                length: num(&self.length, "length")?,
            })
            .await
            .map_err(failed)?
            .into_inner();
        Ok(out(
            json!({"data": hex::encode(&r.data)}),
            hex::encode(&r.data),
        ))
    }
}

impl Run for RegWrite {
    async fn run(self, session: &mut Session) -> Result<Out, String> {
        let slave = self.select.one(session, "reg_write").await?;
        session
            .clients()
            .await?
            .bus
            .write_register(pb::WriteRegisterRequest {
                slave,
                address: num(&self.address, "address")?,
                data: unhex(&self.data)?,
            })
            .await
            .map_err(failed)?;
        Ok(out(json!({"ok": true}), ""))
    }
}

impl Run for Alias {
    async fn run(self, session: &mut Session) -> Result<Out, String> {
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
    async fn run(self, session: &mut Session) -> Result<Out, String> {
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
