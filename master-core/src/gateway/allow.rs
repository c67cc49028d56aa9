//! The client allowlist: networks in CIDR notation (`127.0.0.0/8`, `::1/128`,
//! `192.168.10.0/24`).
//!
//! A prefix match is all the gateway needs, so this small type stands in for a network
//! crate. Each allowed network carries a [`GatewayRole`] ([`AllowedNet`]): what its clients
//! may do through the gateway.

use core::fmt;
use core::str::FromStr;
use std::net::IpAddr;

/// One network of allowed clients: an address and a prefix length.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ClientNet {
    address: IpAddr,
    prefix: u8,
}

/// Why a network does not parse.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ClientNetError {
    /// The part before `/` is not an IP address.
    #[error("not an IP address: {0:?}")]
    Address(String),
    /// The prefix length is not a number within the address's bits.
    #[error("bad prefix length: {0:?}")]
    Prefix(String),
    /// The role is neither `read` nor `write`.
    #[error("bad role {0:?} (read or write)")]
    Role(String),
}

/// What the clients of an allowed network may do through the gateway.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum GatewayRole {
    /// Uploads, SDO Information, SoE reads, FoE reads, master-dictionary reads.
    Read,
    /// Everything, writes included.
    Write,
}

impl GatewayRole {
    /// `read` or `write`.
    pub fn name(self) -> &'static str {
        match self {
            GatewayRole::Read => "read",
            GatewayRole::Write => "write",
        }
    }
}

impl FromStr for GatewayRole {
    type Err = ClientNetError;

    fn from_str(s: &str) -> Result<GatewayRole, ClientNetError> {
        match s.trim() {
            "read" => Ok(GatewayRole::Read),
            "write" => Ok(GatewayRole::Write),
            other => Err(ClientNetError::Role(other.to_owned())),
        }
    }
}

/// One allowlist entry: a client network and its role.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AllowedNet {
    /// The clients.
    pub net: ClientNet,
    /// What they may do.
    pub role: GatewayRole,
}

impl AllowedNet {
    /// `net` with `role`.
    pub fn new(net: ClientNet, role: GatewayRole) -> AllowedNet {
        AllowedNet { net, role }
    }

    /// Every network of `nets` with `role`.
    pub fn all(nets: Vec<ClientNet>, role: GatewayRole) -> Vec<AllowedNet> {
        nets.into_iter()
            .map(|net| AllowedNet { net, role })
            .collect()
    }
}

impl fmt::Display for AllowedNet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}", self.net, self.role.name())
    }
}

impl ClientNet {
    /// A network of `address` with `prefix` leading bits; `None` if the prefix is longer
    /// than the address (32 for IPv4, 128 for IPv6).
    pub fn new(address: IpAddr, prefix: u8) -> Option<ClientNet> {
        (prefix <= max_prefix(address)).then_some(ClientNet { address, prefix })
    }

    /// Exactly one host.
    pub fn host(address: IpAddr) -> ClientNet {
        ClientNet {
            address,
            prefix: max_prefix(address),
        }
    }

    /// IPv4 and IPv6 loopback (`127.0.0.0/8`, `::1/128`): the default allowlist.
    pub fn loopback() -> Vec<ClientNet> {
        vec![
            ClientNet {
                address: IpAddr::from([127, 0, 0, 0]),
                prefix: 8,
            },
            ClientNet::host(IpAddr::from([0u16, 0, 0, 0, 0, 0, 0, 1])),
        ]
    }

    /// Every address of both families (`0.0.0.0/0`, `::/0`).
    pub fn any() -> Vec<ClientNet> {
        vec![
            ClientNet {
                address: IpAddr::from([0, 0, 0, 0]),
                prefix: 0,
            },
            ClientNet {
                address: IpAddr::from([0u16; 8]),
                prefix: 0,
            },
        ]
    }

    /// Whether every address of this network is a loopback address (inside `127.0.0.0/8`
    /// or exactly `::1`).
    pub fn is_loopback(&self) -> bool {
        match self.address {
            IpAddr::V4(v4) => self.prefix >= 8 && v4.octets()[0] == 127,
            IpAddr::V6(v6) => {
                self.prefix == 128
                    && (v6.is_loopback() || v6.to_ipv4_mapped().is_some_and(|a| a.is_loopback()))
            }
        }
    }

    /// Whether `ip` is in this network. An IPv4 address mapped into IPv6 (`::ffff:a.b.c.d`,
    /// as a dual-stack socket reports it) is compared as IPv4.
    pub fn contains(&self, ip: IpAddr) -> bool {
        let ip = canonical(ip);
        match (self.address, ip) {
            (IpAddr::V4(net), IpAddr::V4(ip)) => {
                same_prefix(&net.octets(), &ip.octets(), self.prefix)
            }
            (IpAddr::V6(net), IpAddr::V6(ip)) => {
                same_prefix(&net.octets(), &ip.octets(), self.prefix)
            }
            _ => false,
        }
    }
}

fn max_prefix(address: IpAddr) -> u8 {
    match address {
        IpAddr::V4(_) => 32,
        IpAddr::V6(_) => 128,
    }
}

fn canonical(ip: IpAddr) -> IpAddr {
    match ip {
        IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(ip, IpAddr::V4),
        v4 => v4,
    }
}

/// Whether the first `prefix` bits of `a` and `b` agree.
fn same_prefix(a: &[u8], b: &[u8], prefix: u8) -> bool {
    let full = usize::from(prefix / 8);
    let rest = prefix % 8;
    if a.iter().zip(b).take(full).any(|(x, y)| x != y) {
        return false;
    }
    if rest == 0 {
        return true;
    }
    let mask = 0xFFu8 << (8 - rest);
    match (a.get(full), b.get(full)) {
        (Some(x), Some(y)) => x & mask == y & mask,
        _ => true,
    }
}

impl FromStr for ClientNet {
    type Err = ClientNetError;

    /// `address/prefix`, or a bare address for one host.
    fn from_str(s: &str) -> Result<ClientNet, ClientNetError> {
        let (addr, prefix) = match s.split_once('/') {
            Some((addr, prefix)) => (addr, Some(prefix)),
            None => (s, None),
        };
        let address: IpAddr = addr
            .trim()
            .parse()
            .map_err(|_| ClientNetError::Address(addr.to_owned()))?;
        match prefix {
            None => Ok(ClientNet::host(address)),
            Some(p) => p
                .trim()
                .parse::<u8>()
                .ok()
                .and_then(|p| ClientNet::new(address, p))
                .ok_or_else(|| ClientNetError::Prefix(p.to_owned())),
        }
    }
}

impl fmt::Display for ClientNet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.address, self.prefix)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn net(s: &str) -> ClientNet {
        s.parse().unwrap()
    }

    fn ip(s: &str) -> IpAddr {
        s.parse().unwrap()
    }

    #[test]
    fn prefixes_match_the_leading_bits() {
        assert!(net("192.168.10.0/24").contains(ip("192.168.10.77")));
        assert!(!net("192.168.10.0/24").contains(ip("192.168.11.1")));
        assert!(net("10.0.0.0/9").contains(ip("10.127.0.1")));
        assert!(!net("10.0.0.0/9").contains(ip("10.128.0.1")));
        assert!(net("0.0.0.0/0").contains(ip("8.8.8.8")));
        assert!(net("fd00::/8").contains(ip("fd12::1")));
        assert!(!net("fd00::/8").contains(ip("fe80::1")));
        assert!(net("10.1.2.3").contains(ip("10.1.2.3")));
        assert!(!net("10.1.2.3").contains(ip("10.1.2.4")));
    }

    #[test]
    fn loopback_default_covers_both_families_and_mapped_v4() {
        let nets = ClientNet::loopback();
        let allowed = |a: &str| nets.iter().any(|n| n.contains(ip(a)));
        assert!(allowed("127.0.0.1"));
        assert!(allowed("127.9.9.9"));
        assert!(allowed("::1"));
        assert!(allowed("::ffff:127.0.0.1"));
        assert!(!allowed("192.168.1.1"));
        assert!(!allowed("::2"));
    }

    #[test]
    fn bad_networks_are_refused() {
        assert!(matches!(
            "10.0.0.0/33".parse::<ClientNet>(),
            Err(ClientNetError::Prefix(_))
        ));
        assert!(matches!(
            "ten/8".parse::<ClientNet>(),
            Err(ClientNetError::Address(_))
        ));
        assert_eq!(net("10.0.0.0/8").to_string(), "10.0.0.0/8");
        assert!("admin".parse::<GatewayRole>().is_err());
    }

    #[test]
    fn loopback_networks_are_told_apart() {
        assert!(net("127.0.0.0/8").is_loopback());
        assert!(net("127.0.0.1").is_loopback());
        assert!(net("::1").is_loopback());
        assert!(!net("0.0.0.0/0").is_loopback());
        assert!(!net("126.0.0.0/7").is_loopback());
        assert!(!net("10.0.0.0/8").is_loopback());
        assert!(!net("::/0").is_loopback());
    }
}
