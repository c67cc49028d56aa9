//! `ecat ip`: show the EoE IP parameters, or set them when any option is given.

use proto::v1 as pb;
use serde_json::json;

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::failed;
use crate::select::Selection;
use crate::session::Session;

/// `ecat ip`.
#[derive(Debug, clap::Args)]
pub struct Ip {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// IP address.
    #[arg(long)]
    pub ip: Option<String>,
    /// Subnet mask.
    #[arg(long)]
    pub mask: Option<String>,
    /// Default gateway.
    #[arg(long)]
    pub gateway: Option<String>,
    /// DNS server.
    #[arg(long)]
    pub dns: Option<String>,
    /// DNS name.
    #[arg(long)]
    pub name: Option<String>,
    /// MAC address.
    #[arg(long)]
    pub mac: Option<String>,
}

impl Run for Ip {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let setting = [
            &self.ip,
            &self.mask,
            &self.gateway,
            &self.dns,
            &self.name,
            &self.mac,
        ]
        .iter()
        .any(|o| o.is_some());
        let slave = self.select.one(session, "ip").await?;
        let c = session.clients().await?;
        if setting {
            let settings = pb::IpSettings {
                mac: self.mac.unwrap_or_default(),
                ip: self.ip.unwrap_or_default(),
                subnet_mask: self.mask.unwrap_or_default(),
                default_gateway: self.gateway.unwrap_or_default(),
                dns_server: self.dns.unwrap_or_default(),
                dns_name: self.name.unwrap_or_default(),
            };
            c.eoe
                .set_ip(pb::SetIpRequest {
                    slave,
                    settings: Some(settings),
                })
                .await
                .map_err(failed)?;
            return Ok(out(json!({"ok": true}), ""));
        }
        let s = c
            .eoe
            .get_ip(pb::GetIpRequest { slave })
            .await
            .map_err(failed)?
            .into_inner();
        let json = json!({"mac": s.mac, "ip": s.ip, "subnet_mask": s.subnet_mask,
            "default_gateway": s.default_gateway, "dns_server": s.dns_server, "dns_name": s.dns_name});
        let human = [
            ("MAC", &s.mac),
            ("IP", &s.ip),
            ("mask", &s.subnet_mask),
            ("gateway", &s.default_gateway),
            ("DNS", &s.dns_server),
            ("name", &s.dns_name),
        ]
        .iter()
        .filter(|(_, v)| !v.is_empty())
        .map(|(k, v)| format!("{k}: {v}"))
        .collect::<Vec<_>>()
        .join("\n");
        Ok(out(json, human))
    }
}
