//! EoE IP parameters between their text forms (dotted quads, colon MAC) and the mailbox
//! engine's [`IpSettings`].

use std::net::Ipv4Addr;

use master_core::mailbox::IpSettings;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::error::ApiError;

/// IP parameters of a slave's EoE port; absent fields are left as they are.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct IpView {
    /// MAC address, `aa:bb:cc:dd:ee:ff`.
    pub mac: Option<String>,
    /// IPv4 address.
    pub ip: Option<String>,
    /// Subnet mask.
    pub subnet_mask: Option<String>,
    /// Default gateway.
    pub default_gateway: Option<String>,
    /// DNS server.
    pub dns_server: Option<String>,
    /// DNS name.
    pub dns_name: Option<String>,
}

/// Parses the text forms; empty strings count as absent.
pub fn to_settings(view: &IpView) -> Result<IpSettings, ApiError> {
    let addr = |value: &Option<String>,
                field: &'static str,
                what: &str|
     -> Result<Option<Ipv4Addr>, ApiError> {
        match value.as_deref().filter(|s| !s.is_empty()) {
            None => Ok(None),
            Some(text) => text
                .parse()
                .map(Some)
                .map_err(|_| ApiError::invalid_field(field, format!("bad {what} {text:?}"))),
        }
    };
    let mac = match view.mac.as_deref().filter(|s| !s.is_empty()) {
        None => None,
        Some(text) => Some(parse_mac(text).map_err(|err| ApiError::invalid_field("mac", err))?),
    };
    Ok(IpSettings {
        mac,
        ip: addr(&view.ip, "ip", "IP address")?,
        subnet_mask: addr(&view.subnet_mask, "subnet_mask", "subnet mask")?,
        default_gateway: addr(&view.default_gateway, "default_gateway", "default gateway")?,
        dns_server: addr(&view.dns_server, "dns_server", "DNS server")?,
        dns_name: view.dns_name.clone().filter(|s| !s.is_empty()),
    })
}

/// The text forms of `settings`.
pub fn from_settings(settings: &IpSettings) -> IpView {
    let text = |a: Option<Ipv4Addr>| a.map(|a| a.to_string());
    IpView {
        mac: settings.mac.map(|m| {
            m.iter()
                .map(|b| format!("{b:02x}"))
                .collect::<Vec<_>>()
                .join(":")
        }),
        ip: text(settings.ip),
        subnet_mask: text(settings.subnet_mask),
        default_gateway: text(settings.default_gateway),
        dns_server: text(settings.dns_server),
        dns_name: settings.dns_name.clone(),
    }
}

/// A MAC address as `aa:bb:cc:dd:ee:ff` (or with `-`).
pub fn parse_mac(text: &str) -> Result<[u8; 6], String> {
    let bad = || format!("bad MAC address {text:?}");
    let mut mac = [0u8; 6];
    let mut parts = text.split([':', '-']);
    for byte in &mut mac {
        let part = parts.next().ok_or_else(bad)?;
        if part.len() != 2 {
            return Err(bad());
        }
        *byte = u8::from_str_radix(part, 16).map_err(|_| bad())?;
    }
    if parts.next().is_some() {
        return Err(bad());
    }
    Ok(mac)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_refusals() {
        let view = IpView {
            mac: Some("02:00:00:00:00:2a".into()),
            ip: Some("192.168.9.2".into()),
            subnet_mask: Some("255.255.255.0".into()),
            ..IpView::default()
        };
        let settings = to_settings(&view).unwrap();
        assert_eq!(settings.mac, Some([2, 0, 0, 0, 0, 0x2a]));
        assert_eq!(settings.ip, Some(Ipv4Addr::new(192, 168, 9, 2)));
        assert_eq!(from_settings(&settings), view);
        for bad in ["02:00", "02:00:00:00:00:2a:00", "zz:00:00:00:00:00"] {
            let view = IpView {
                mac: Some(bad.into()),
                ..IpView::default()
            };
            assert!(to_settings(&view).is_err(), "{bad}");
        }
        let view = IpView {
            ip: Some("300.1.1.1".into()),
            ..IpView::default()
        };
        assert!(to_settings(&view).is_err());
    }
}
