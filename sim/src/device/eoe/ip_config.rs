//! The IP settings a master gives an EoE slave with Set IP parameter (ETG.1000.6, spec-notes §eoe).

use std::net::Ipv4Addr;

use ecat_wire::eoe::IpParameters;

/// What the slave remembers of Set IP parameter requests; each field is `None` until a
/// request carried it. Get IP parameter answers exactly the fields that are set.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct IpConfig {
    /// The slave's MAC address.
    pub mac: Option<[u8; 6]>,
    /// The slave's IPv4 address.
    pub ip: Option<Ipv4Addr>,
    /// Subnet mask.
    pub subnet_mask: Option<Ipv4Addr>,
    /// Default gateway.
    pub default_gateway: Option<Ipv4Addr>,
    /// DNS server.
    pub dns_server: Option<Ipv4Addr>,
    /// DNS name (at most 32 bytes, no NUL).
    pub dns_name: Option<Vec<u8>>,
    /// The device's own MAC address, burnt in at the factory: the one it answers on until a
    /// Set IP parameter request gives it another (`mac`). Not part of Get IP parameter's
    /// answer, which says what the master set.
    pub factory_mac: Option<[u8; 6]>,
}

/// The factory MAC of the simulated EoE device of the slave at ring `position`:
/// `02:45:43:53:PP:PP` (locally administered, unicast; "ECS" for EtherCAT simulator, then the
/// position, big-endian).
pub fn factory_mac(position: u16) -> [u8; 6] {
    let [high, low] = position.to_be_bytes();
    [0x02, 0x45, 0x43, 0x53, high, low]
}

impl IpConfig {
    /// Takes over every field present in a Set IP parameter request; absent ones stay.
    pub fn apply(&mut self, params: &IpParameters<'_>) {
        if params.mac.is_some() {
            self.mac = params.mac;
        }
        if params.ip.is_some() {
            self.ip = params.ip;
        }
        if params.subnet_mask.is_some() {
            self.subnet_mask = params.subnet_mask;
        }
        if params.default_gateway.is_some() {
            self.default_gateway = params.default_gateway;
        }
        if params.dns_server.is_some() {
            self.dns_server = params.dns_server;
        }
        if let Some(name) = params.dns_name {
            self.dns_name = Some(name.to_vec());
        }
    }

    /// The MAC the device answers on: the one the master set, else its factory MAC.
    pub fn station_mac(&self) -> Option<[u8; 6]> {
        self.mac.or(self.factory_mac)
    }

    /// The settings as the body of a Get IP parameter response.
    pub fn as_params(&self) -> IpParameters<'_> {
        IpParameters {
            mac: self.mac,
            ip: self.ip,
            subnet_mask: self.subnet_mask,
            default_gateway: self.default_gateway,
            dns_server: self.dns_server,
            dns_name: self.dns_name.as_deref(),
        }
    }
}
