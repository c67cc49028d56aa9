//! The IP parameter body of Set IP parameter requests (type 2) and Get IP parameter
//! responses (type 7), ETG.1000.6, spec-notes §eoe.
//!
//! ```text
//! u32 flags: bit 0 MAC, 1 IP, 2 subnet mask, 3 default gateway, 4 DNS server, 5 DNS name
//! then, for each flag set and in this order: MAC (6), IP (4), mask (4), gateway (4),
//! DNS server (4), DNS name (32, NUL-padded ASCII)
//! ```
//!
//! IPv4 addresses are little-endian u32s of the numeric address: 192.168.1.10 is sent as
//! `0a 01 a8 c0` (SOEM, SOES, IgH and Wireshark agree).

use core::fmt;
use std::net::Ipv4Addr;

use crate::error::{Result, WireError, need, room};
use crate::field;

mod flags {
    pub const MAC: u32 = 1 << 0;
    pub const IP: u32 = 1 << 1;
    pub const SUBNET: u32 = 1 << 2;
    pub const GATEWAY: u32 = 1 << 3;
    pub const DNS_SERVER: u32 = 1 << 4;
    pub const DNS_NAME: u32 = 1 << 5;
    pub const ALL: u32 = 0x3F;
}

mod fixed {
    //! Offsets of IgH's / Wireshark's fixed layout (every field present, absent ones zero).
    pub const MAC: usize = 4;
    pub const IP: usize = 10;
    pub const SUBNET: usize = 14;
    pub const GATEWAY: usize = 18;
    pub const DNS_SERVER: usize = 22;
    pub const DNS_NAME: usize = 26;
}

/// Size of the flags field.
pub const FLAGS_LEN: usize = 4;
/// Size of a MAC address.
pub const MAC_LEN: usize = 6;
/// Size of an IPv4 address.
pub const IPV4_LEN: usize = 4;
/// Size of the DNS name field.
pub const DNS_NAME_LEN: usize = 32;
/// Size of the fixed layout: 4 + 6 + 4 × 4 + 32 = 58 bytes.
pub const FIXED_LEN: usize = FLAGS_LEN + MAC_LEN + 4 * IPV4_LEN + DNS_NAME_LEN;

/// The IP parameters; `None` = flag clear, field absent.
///
/// The DNS name is NUL-padded ASCII on the wire: parse cuts it at the first NUL, so emit
/// refuses a name containing NUL (parse could not give it back) or longer than 32 bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct IpParameters<'a> {
    /// MAC address (normal byte order).
    pub mac: Option<[u8; 6]>,
    /// IP address.
    pub ip: Option<Ipv4Addr>,
    /// Subnet mask.
    pub subnet_mask: Option<Ipv4Addr>,
    /// Default gateway.
    pub default_gateway: Option<Ipv4Addr>,
    /// DNS server.
    pub dns_server: Option<Ipv4Addr>,
    /// DNS name (ASCII, at most 32 bytes).
    pub dns_name: Option<&'a [u8]>,
}

fn ipv4_at(body: &[u8], at: usize) -> Ipv4Addr {
    // Little-endian u32 of the numeric value (see module docs).
    Ipv4Addr::from(field::u32_le(body, at))
}

fn mac_at(body: &[u8], at: usize) -> [u8; 6] {
    let mut mac = [0u8; 6];
    mac.copy_from_slice(&body[at..at + MAC_LEN]);
    mac
}

fn name_at(body: &[u8], at: usize) -> &[u8] {
    let name = &body[at..at + DNS_NAME_LEN];
    let end = name.iter().position(|&b| b == 0).unwrap_or(name.len());
    &name[..end]
}

impl<'a> IpParameters<'a> {
    /// The flags word for the fields present.
    pub fn flags(&self) -> u32 {
        let f = |present: bool, bit: u32| if present { bit } else { 0 };
        f(self.mac.is_some(), flags::MAC)
            | f(self.ip.is_some(), flags::IP)
            | f(self.subnet_mask.is_some(), flags::SUBNET)
            | f(self.default_gateway.is_some(), flags::GATEWAY)
            | f(self.dns_server.is_some(), flags::DNS_SERVER)
            | f(self.dns_name.is_some(), flags::DNS_NAME)
    }

    fn packed_len(flag_bits: u32) -> usize {
        let f = |bit: u32, len: usize| if flag_bits & bit != 0 { len } else { 0 };
        FLAGS_LEN
            + f(flags::MAC, MAC_LEN)
            + f(flags::IP, IPV4_LEN)
            + f(flags::SUBNET, IPV4_LEN)
            + f(flags::GATEWAY, IPV4_LEN)
            + f(flags::DNS_SERVER, IPV4_LEN)
            + f(flags::DNS_NAME, DNS_NAME_LEN)
    }

    /// Parses the body that follows the EoE header.
    ///
    /// The packed layout (SOEM/SOES) is the norm; a body of exactly 58 bytes with fewer than
    /// all six flags is read in IgH's fixed layout instead (spec-notes §eoe — with all six flags
    /// both layouts are the same bytes). Bytes after the packed fields are ignored. Flag
    /// bits above bit 5 are ignored (Wireshark names bit 16 "append timestamp"; no source
    /// sends it).
    pub fn parse_body(body: &'a [u8]) -> Result<Self> {
        need("EoE IP parameters", body, FLAGS_LEN)?;
        let bits = field::u32_le(body, 0) & flags::ALL;
        let has = |bit: u32| bits & bit != 0;
        if body.len() == FIXED_LEN && bits != flags::ALL {
            return Ok(IpParameters {
                mac: has(flags::MAC).then(|| mac_at(body, fixed::MAC)),
                ip: has(flags::IP).then(|| ipv4_at(body, fixed::IP)),
                subnet_mask: has(flags::SUBNET).then(|| ipv4_at(body, fixed::SUBNET)),
                default_gateway: has(flags::GATEWAY).then(|| ipv4_at(body, fixed::GATEWAY)),
                dns_server: has(flags::DNS_SERVER).then(|| ipv4_at(body, fixed::DNS_SERVER)),
                dns_name: has(flags::DNS_NAME).then(|| name_at(body, fixed::DNS_NAME)),
            });
        }
        need("EoE IP parameters", body, Self::packed_len(bits))?;
        let mut at = FLAGS_LEN;
        let mut take = |bit: u32, len: usize| {
            let here = at;
            if has(bit) {
                at += len;
            }
            has(bit).then_some(here)
        };
        let mac = take(flags::MAC, MAC_LEN).map(|o| mac_at(body, o));
        let ip = take(flags::IP, IPV4_LEN).map(|o| ipv4_at(body, o));
        let subnet_mask = take(flags::SUBNET, IPV4_LEN).map(|o| ipv4_at(body, o));
        let default_gateway = take(flags::GATEWAY, IPV4_LEN).map(|o| ipv4_at(body, o));
        let dns_server = take(flags::DNS_SERVER, IPV4_LEN).map(|o| ipv4_at(body, o));
        let dns_name = take(flags::DNS_NAME, DNS_NAME_LEN).map(|o| name_at(body, o));
        Ok(IpParameters {
            mac,
            ip,
            subnet_mask,
            default_gateway,
            dns_server,
            dns_name,
        })
    }

    /// Bytes of the packed body.
    pub fn buffer_len(&self) -> usize {
        Self::packed_len(self.flags())
    }

    /// Writes the packed body into the start of `body`; refuses a DNS name longer than 32
    /// bytes or containing NUL (writing nothing).
    pub fn emit_body(&self, body: &mut [u8]) -> Result<()> {
        room("EoE IP parameters", body, self.buffer_len())?;
        if let Some(name) = self.dns_name {
            if name.len() > DNS_NAME_LEN {
                return Err(WireError::BadLength {
                    what: "EoE DNS name",
                    declared: name.len(),
                    available: DNS_NAME_LEN,
                });
            }
            if name.contains(&0) {
                return Err(WireError::Invalid {
                    what: "EoE DNS name",
                    reason: "contains NUL",
                });
            }
        }
        field::set_u32_le(body, 0, self.flags());
        let mut at = FLAGS_LEN;
        if let Some(mac) = self.mac {
            body[at..at + MAC_LEN].copy_from_slice(&mac);
            at += MAC_LEN;
        }
        for ip in [
            self.ip,
            self.subnet_mask,
            self.default_gateway,
            self.dns_server,
        ]
        .into_iter()
        .flatten()
        {
            field::set_u32_le(body, at, u32::from(ip));
            at += IPV4_LEN;
        }
        if let Some(name) = self.dns_name {
            let slot = &mut body[at..at + DNS_NAME_LEN];
            slot.fill(0);
            slot[..name.len()].copy_from_slice(name);
        }
        Ok(())
    }
}

impl fmt::Display for IpParameters<'_> {
    /// `mac=.. ip=.. mask=.. gw=.. dns=.. name=".."`, only the fields present.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut sep = "";
        if let Some(m) = self.mac {
            write!(
                f,
                "mac={:02x}:{:02x}:{:02x}:{:02x}:{:02x}:{:02x}",
                m[0], m[1], m[2], m[3], m[4], m[5]
            )?;
            sep = " ";
        }
        for (label, ip) in [
            ("ip", self.ip),
            ("mask", self.subnet_mask),
            ("gw", self.default_gateway),
            ("dns", self.dns_server),
        ] {
            if let Some(ip) = ip {
                write!(f, "{sep}{label}={ip}")?;
                sep = " ";
            }
        }
        if let Some(name) = self.dns_name {
            write!(f, "{sep}name=")?;
            crate::foe::fmt_ascii(f, name)?;
        }
        Ok(())
    }
}
