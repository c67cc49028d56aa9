//! The `[eoe]` section of ecatd's configuration: how the EoE interfaces are named and what
//! each slave's interface gets at every bring-up.
//!
//! ```toml
//! [eoe]
//! name_scheme = "alias"     # eoe<m>a<alias> when the slave has an alias, else eoe<m>s<pos>
//! master_index = 0          # <m>
//!
//! [[eoe.slave]]
//! slave = "0"               # any slave name the API takes: 3, #0x1001, @7
//! mac = "02:00:00:00:00:10" # the interface's MAC (default 02:NIC:NIC:NIC:RP:RP)
//! ip = "10.7.0.2"           # sent with Set IP at every bring-up (ETG.1000.6 §5.7)
//! subnet_mask = "255.255.255.0"
//! host_address = "10.7.0.1/24"  # put on the interface, or:
//! bridge = "eoebr0"         # joined (the bridge must exist)
//! ```

use std::net::Ipv4Addr;

use master_core::mailbox::IpSettings;
use master_core::master::SlaveAddress;
use serde::{Deserialize, Serialize};

use crate::input::address::parse_slave;
use crate::input::ip::{IpView, to_settings};

/// How interfaces are named (as IgH's master names them).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NameScheme {
    /// `eoe<m>s<position>` always.
    Position,
    /// `eoe<m>a<alias>` for a slave with an alias, `eoe<m>s<position>` otherwise.
    #[default]
    Alias,
}

/// The `[eoe]` section.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EoeSettings {
    /// Whether ecatd makes interfaces at all (default: yes).
    pub enabled: bool,
    /// The naming scheme.
    pub name_scheme: NameScheme,
    /// `<m>` in the names: the master's number less one.
    pub master_index: u16,
    /// Per-slave settings.
    #[serde(rename = "slave")]
    pub slaves: Vec<EoeSlaveSettings>,
}

impl Default for EoeSettings {
    fn default() -> EoeSettings {
        EoeSettings {
            enabled: true,
            name_scheme: NameScheme::default(),
            master_index: 0,
            slaves: Vec::new(),
        }
    }
}

/// One `[[eoe.slave]]` entry.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EoeSlaveSettings {
    /// The slave, as the API names it (`3`, `#0x1001`, `@7`).
    pub slave: String,
    /// The interface's MAC address (default `02:NIC:NIC:NIC:RP:RP`).
    pub mac: Option<String>,
    /// The slave's MAC address (Set IP).
    pub slave_mac: Option<String>,
    /// The slave's IPv4 address (Set IP).
    pub ip: Option<String>,
    /// Its subnet mask (Set IP).
    pub subnet_mask: Option<String>,
    /// Its default gateway (Set IP).
    pub default_gateway: Option<String>,
    /// Its DNS server (Set IP).
    pub dns_server: Option<String>,
    /// Its DNS name (Set IP).
    pub dns_name: Option<String>,
    /// `a.b.c.d/prefix` put on the interface each time it is made.
    pub host_address: Option<String>,
    /// A bridge the interface joins each time it is made.
    pub bridge: Option<String>,
}

/// A checked `[[eoe.slave]]` entry.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SlavePlan {
    /// The slave.
    pub address: SlaveAddress,
    /// The interface's MAC, if configured.
    pub mac: Option<[u8; 6]>,
    /// What Set IP sends; `None` = nothing configured, no Set IP.
    pub ip: Option<IpSettings>,
    /// The host's address on the interface.
    pub host_address: Option<(Ipv4Addr, u8)>,
    /// The bridge to join.
    pub bridge: Option<String>,
}

impl EoeSettings {
    /// Checks every entry; the error names the bad one.
    pub fn plans(&self) -> Result<Vec<SlavePlan>, String> {
        self.slaves.iter().map(EoeSlaveSettings::plan).collect()
    }

    /// Checks the section (at start-up).
    pub fn check(&self) -> Result<(), String> {
        let plans = self.plans()?;
        for (i, plan) in plans.iter().enumerate() {
            if plans[..i].iter().any(|p| p.address == plan.address) {
                return Err(format!(
                    "[[eoe.slave]]: slave {:?} twice",
                    self.slaves[i].slave
                ));
            }
        }
        Ok(())
    }
}

impl EoeSlaveSettings {
    fn plan(&self) -> Result<SlavePlan, String> {
        let what = |err: String| format!("[[eoe.slave]] {:?}: {err}", self.slave);
        let address = parse_slave(&self.slave).map_err(|e| what(e.message))?;
        let mac = self
            .mac
            .as_deref()
            .map(parse_mac)
            .transpose()
            .map_err(&what)?;
        let view = IpView {
            mac: self.slave_mac.clone(),
            ip: self.ip.clone(),
            subnet_mask: self.subnet_mask.clone(),
            default_gateway: self.default_gateway.clone(),
            dns_server: self.dns_server.clone(),
            dns_name: self.dns_name.clone(),
        };
        let settings = to_settings(&view).map_err(|e| what(e.message))?;
        let ip = (settings != IpSettings::default()).then_some(settings);
        let host_address = self
            .host_address
            .as_deref()
            .map(parse_cidr)
            .transpose()
            .map_err(&what)?;
        if host_address.is_some() && self.bridge.is_some() {
            return Err(what("host_address and bridge exclude each other".into()));
        }
        if let Some(bridge) = &self.bridge
            && (bridge.is_empty() || bridge.len() > master_core::link::netdev::MAX_NAME_LEN)
        {
            return Err(what(format!("bad bridge name {bridge:?}")));
        }
        Ok(SlavePlan {
            address,
            mac,
            ip,
            host_address,
            bridge: self.bridge.clone(),
        })
    }
}

pub use crate::input::ip::parse_mac;

fn parse_cidr(text: &str) -> Result<(Ipv4Addr, u8), String> {
    let bad = || format!("bad host address {text:?}: use a.b.c.d/prefix");
    let (address, prefix) = text.split_once('/').ok_or_else(bad)?;
    let address: Ipv4Addr = address.parse().map_err(|_| bad())?;
    let prefix: u8 = prefix.parse().map_err(|_| bad())?;
    if prefix > 32 {
        return Err(bad());
    }
    Ok((address, prefix))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_section_parses_and_bad_entries_are_named() {
        let text = r#"
            name_scheme = "position"
            [[slave]]
            slave = "@7"
            ip = "10.7.0.2"
            subnet_mask = "255.255.255.0"
            host_address = "10.7.0.1/24"
            mac = "02:00:00:00:00:10"
        "#;
        let settings: EoeSettings = toml::from_str(text).unwrap();
        assert_eq!(settings.name_scheme, NameScheme::Position);
        let plans = settings.plans().unwrap();
        assert_eq!(plans[0].address, SlaveAddress::Alias(7));
        assert_eq!(plans[0].mac, Some([2, 0, 0, 0, 0, 0x10]));
        assert_eq!(
            plans[0].host_address,
            Some((Ipv4Addr::new(10, 7, 0, 1), 24))
        );
        let ip = plans[0].ip.as_ref().unwrap();
        assert_eq!(ip.ip, Some(Ipv4Addr::new(10, 7, 0, 2)));
        assert_eq!(ip.mac, None);

        for (bad, says) in [
            (r#"slave = "x""#, "bad slave name"),
            (
                "slave = \"0\"\nhost_address = \"10.0.0.1\"",
                "a.b.c.d/prefix",
            ),
            (
                "slave = \"0\"\nhost_address = \"10.0.0.1/33\"",
                "a.b.c.d/prefix",
            ),
            ("slave = \"0\"\nip = \"10.0.0\"", "bad IP address"),
            ("slave = \"0\"\nmac = \"02:00\"", "bad MAC"),
            (
                "slave = \"0\"\nbridge = \"br0\"\nhost_address = \"10.0.0.1/24\"",
                "exclude",
            ),
        ] {
            let entry: EoeSlaveSettings = toml::from_str(bad).unwrap();
            let err = entry.plan().unwrap_err();
            assert!(err.contains(says), "{bad}: {err}");
        }
        let twice = EoeSettings {
            slaves: vec![
                EoeSlaveSettings {
                    slave: "0".into(),
                    ..Default::default()
                },
                EoeSlaveSettings {
                    slave: "0".into(),
                    ..Default::default()
                },
            ],
            ..EoeSettings::default()
        };
        assert!(twice.check().unwrap_err().contains("twice"));
    }
}
