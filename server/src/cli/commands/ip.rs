//! `ecat ip`: show the EoE IP parameters, or set them. IgH's syntax is keyword/value pairs
//! (`ecat ip -p 4 addr 192.168.10.5/24 default 192.168.10.1`: `link MAC`, `addr
//! IPv4[/prefix]`, `default GATEWAY`, `dns IPv4`, `name HOSTNAME`); the options (`--ip`,
//! `--mask`, ...) say the same. Without either it shows them.

use std::net::Ipv4Addr;

use ipnet::Ipv4Net;
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
    /// IP address, with a prefix length if wanted (`10.77.0.2/24` sets the mask too).
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
    /// IgH's keyword/value pairs: `link MAC`, `addr IPv4[/PREFIX]`, `default GATEWAY`,
    /// `dns IPv4`, `name HOSTNAME`.
    #[arg(value_name = "KEYWORD VALUE")]
    pub pairs: Vec<String>,
}

/// The settings the command line gives, as the API takes them (empty: unchanged).
#[derive(Debug, Default, PartialEq, Eq)]
struct Settings {
    mac: Option<String>,
    ip: Option<String>,
    mask: Option<String>,
    gateway: Option<String>,
    dns: Option<String>,
    name: Option<String>,
}

impl Settings {
    /// Sets one parameter, refusing it twice (`addr` and `--ip`).
    fn set(slot: &mut Option<String>, what: &str, value: String) -> Result<(), String> {
        if slot.is_some() {
            return Err(format!("ip: the {what} is given twice"));
        }
        *slot = Some(value);
        Ok(())
    }

    /// An address with an optional prefix length: the address, and the mask the prefix
    /// gives.
    fn address(&mut self, text: &str) -> Result<(), String> {
        if text.contains('/') {
            let net: Ipv4Net = text.parse().map_err(|_| {
                format!("ip: {text:?} is not an IPv4 address with a prefix (192.168.10.5/24)")
            })?;
            Settings::set(&mut self.ip, "address", net.addr().to_string())?;
            Settings::set(&mut self.mask, "subnet mask", net.netmask().to_string())
        } else {
            Settings::set(&mut self.ip, "address", ipv4(text, "address")?)
        }
    }

    fn is_empty(&self) -> bool {
        *self == Settings::default()
    }
}

/// An IPv4 address, checked here so that a typo is a usage error before anything is sent.
fn ipv4(text: &str, what: &str) -> Result<String, String> {
    text.parse::<Ipv4Addr>()
        .map(|a| a.to_string())
        .map_err(|_| format!("ip: {text:?} is not an IPv4 {what}"))
}

impl Ip {
    /// The settings of the options and of IgH's pairs together.
    fn settings(&self) -> Result<Settings, String> {
        let mut s = Settings::default();
        if let Some(ip) = &self.ip {
            s.address(ip)?;
        }
        if let Some(mask) = &self.mask {
            Settings::set(&mut s.mask, "subnet mask", ipv4(mask, "subnet mask")?)?;
        }
        if let Some(gateway) = &self.gateway {
            Settings::set(&mut s.gateway, "gateway", ipv4(gateway, "gateway")?)?;
        }
        if let Some(dns) = &self.dns {
            Settings::set(&mut s.dns, "DNS server", ipv4(dns, "DNS server")?)?;
        }
        if let Some(name) = &self.name {
            Settings::set(&mut s.name, "name", name.clone())?;
        }
        if let Some(mac) = &self.mac {
            Settings::set(&mut s.mac, "MAC address", mac.clone())?;
        }
        let mut pairs = self.pairs.iter();
        while let Some(keyword) = pairs.next() {
            let value = pairs
                .next()
                .ok_or_else(|| format!("ip: {keyword:?} needs a value"))?;
            match keyword.to_ascii_lowercase().as_str() {
                "link" => Settings::set(&mut s.mac, "MAC address", value.clone())?,
                "addr" => s.address(value)?,
                "default" => Settings::set(&mut s.gateway, "gateway", ipv4(value, "gateway")?)?,
                "dns" => Settings::set(&mut s.dns, "DNS server", ipv4(value, "DNS server")?)?,
                "name" => Settings::set(&mut s.name, "name", value.clone())?,
                _ => {
                    return Err(format!(
                        "ip: unknown keyword {keyword:?} (link, addr, default, dns, name)"
                    ));
                }
            }
        }
        Ok(s)
    }
}

impl Run for Ip {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let settings = self.settings()?;
        let slave = self.select.one(session, "ip").await?;
        let c = session.clients().await?;
        if !settings.is_empty() {
            let settings = pb::IpSettings {
                mac: settings.mac.unwrap_or_default(),
                ip: settings.ip.unwrap_or_default(),
                subnet_mask: settings.mask.unwrap_or_default(),
                default_gateway: settings.gateway.unwrap_or_default(),
                dns_server: settings.dns.unwrap_or_default(),
                dns_name: settings.name.unwrap_or_default(),
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

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::Settings;
    use crate::{Cli, Command};

    fn settings(args: &[&str]) -> Result<Settings, String> {
        let mut all = vec!["ecat", "ip", "-p", "4"];
        all.extend_from_slice(args);
        match Cli::try_parse_from(all)
            .expect("the command line parses")
            .command
        {
            Command::Ip(ip) => ip.settings(),
            other => panic!("not ip: {other:?}"),
        }
    }

    #[test]
    fn igh_pairs_and_options_give_the_same_settings() {
        let pairs = settings(&["addr", "192.168.10.5/24", "default", "192.168.10.1"]).unwrap();
        let options = settings(&["--ip", "192.168.10.5/24", "--gateway", "192.168.10.1"]).unwrap();
        assert_eq!(pairs, options);
        assert_eq!(pairs.ip.as_deref(), Some("192.168.10.5"));
        assert_eq!(pairs.mask.as_deref(), Some("255.255.255.0"));
        let all = settings(&[
            "link",
            "02:00:00:00:00:04",
            "addr",
            "10.0.0.2",
            "dns",
            "10.0.0.53",
            "name",
            "drive",
        ])
        .unwrap();
        assert_eq!(all.mac.as_deref(), Some("02:00:00:00:00:04"));
        assert_eq!(all.mask, None, "no prefix, no mask");
        assert_eq!(all.dns.as_deref(), Some("10.0.0.53"));
        assert_eq!(all.name.as_deref(), Some("drive"));
    }

    #[test]
    fn bad_pairs_are_refused() {
        for args in [
            &["addr"][..],
            &["addr", "192.168.10.5/33"],
            &["addr", "300.1.1.1"],
            &["gateway", "10.0.0.1"],
            &["addr", "10.0.0.2/8", "--mask", "255.0.0.0"],
            &["addr", "10.0.0.2", "--ip", "10.0.0.3"],
        ] {
            assert!(settings(args).is_err(), "{args:?}");
        }
    }
}
