//! How the gateway is set up: where it listens, who may talk to it, how much it takes on.

use std::net::{IpAddr, Ipv4Addr};
use std::time::Duration;

use crate::master_od::MasterIdentity;

use super::allow::{AllowedNet, ClientNet, GatewayRole};

/// The ETG.8200 UDP port, 0x88A4.
pub const DEFAULT_PORT: u16 = 0x88A4;

/// The port of master number `master_number` (1-based): 34980 for master 1, 34981 for
/// master 2, and so on (0 counts as 1; saturating at 65535).
pub fn port_for_master(master_number: u16) -> u16 {
    DEFAULT_PORT.saturating_add(master_number.saturating_sub(1))
}

/// Settings of a [`MailboxGateway`](super::MailboxGateway). Changes take effect at the next
/// start.
///
/// Use struct update syntax: `GatewayConfig { strict: true, ..GatewayConfig::default() }`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GatewayConfig {
    /// Address the UDP socket binds to. Default `0.0.0.0` (every interface; who may talk is
    /// decided by [`Self::allow`]).
    pub bind: IpAddr,
    /// Port to bind; `None`: [`port_for_master`] of [`Self::master_number`]. `Some(0)` lets
    /// the system choose.
    pub port: Option<u16>,
    /// This master's number (1-based) when several run on one host. Default 1.
    pub master_number: u16,
    /// If the port is taken, bind a free one chosen by the system instead of failing (the
    /// port actually bound is reported by [`MailboxGateway::port`](super::MailboxGateway::port)).
    /// Default true.
    pub fallback: bool,
    /// Clients allowed to send requests, each network with its role (a client in several
    /// gets the highest); datagrams from others are dropped and counted. A `read` client's
    /// writes are refused with the protocol's access error. Default: loopback, `write`.
    pub allow: Vec<AllowedNet>,
    /// Strict ETG.8200: the gateway itself never answers with an error (unknown slave,
    /// unsupported protocol, busy, timeout); such requests get no reply. Errors from the
    /// slaves and from the master's dictionary still reach the client. Default false.
    pub strict: bool,
    /// Requests being worked on at once, over all clients; beyond it a request is answered
    /// "busy". Default 256.
    pub max_in_flight: usize,
    /// Requests being worked on at once for one client host (IP address, whatever the
    /// port). Default 16.
    pub max_in_flight_per_client: usize,
    /// Longest a forwarded request may take (queueing at the slave and its whole exchange).
    /// Default 5 s.
    pub request_timeout: Duration,
    /// How long a client's multi-message transfer (segmented SDO, FoE, fragmented SoE write)
    /// holds a slave for it after its last message; other clients' requests to that slave
    /// wait meanwhile. Default 3 s (the usual client timeout).
    pub session_timeout: Duration,
    /// Mailbox size the master's own dictionary (address 0) answers with: replies longer
    /// than this are segmented. Default 1024 bytes (header included).
    pub master_mailbox_size: u16,
    /// Identity the master's dictionary reports (0x1000-0x1018).
    pub identity: MasterIdentity,
    /// Also serve TCP (optional in ETG.8200) on the port the UDP socket bound, same
    /// address: each connection carries a stream of gateway messages delimited by the
    /// EtherCAT header's length. Default false.
    pub tcp: bool,
    /// TCP connections served at once; more are closed as soon as they are accepted.
    /// Default 16.
    pub max_tcp_connections: usize,
    /// A TCP connection that sends nothing (or stops in the middle of a message) for this
    /// long is closed. Default 60 s.
    pub tcp_idle_timeout: Duration,
    /// How long after its answer a UDP request repeated by the same client (same bytes,
    /// counter 1-7, nothing else sent in between) is answered from the stored reply instead
    /// of being executed again. Zero: never. Default 1 s.
    pub retry_window: Duration,
    /// Clients whose last request and reply are kept for repeats; beyond it the oldest is
    /// forgotten. Default 1024.
    pub max_retry_clients: usize,
    /// UDP receive workers, each a thread with its own socket on the gateway's port: the
    /// kernel gives each client (address and port) to one of them, so one client's
    /// requests stay in order while several clients are served on several cores. Sessions,
    /// caps and stored replies are shared by all. Default: [`default_workers`]; 0 counts
    /// as 1. Not used while the bus thread serves UDP ([`Self::on_bus_thread`]).
    pub workers: usize,
    /// Serve UDP from the bus thread (one socket, waited on beside the link), where the bus
    /// can (a link with a file descriptor to wait on, and a bus that sleeps: not
    /// [`WaitMode::BusyPoll`](crate::bus::WaitMode::BusyPoll)); else from [`Self::workers`].
    /// A request then wakes no thread but the bus's: on 2 cores, 64 clients read 1.1-2.1
    /// times as fast, at 35-45 % less of ecatd's CPU per read (docs/performance.md). Its
    /// cost is the requests' work on the bus thread, between frames and never when the
    /// next cycle is due. TCP, the dictionary's tracker and the timers stay on one worker.
    /// Default: on.
    pub on_bus_thread: bool,
}

/// The most receive workers [`GatewayConfig::default`] asks for, however many cores there
/// are: beyond a few, the slaves' mailboxes, not the gateway, limit the requests served.
pub const MAX_DEFAULT_WORKERS: usize = 4;

/// The receive workers a gateway gets by default: one core fewer than are available (the
/// bus thread keeps one to itself), at least 1, at most [`MAX_DEFAULT_WORKERS`]. On two
/// cores one worker served 64 clients 2-50 % more reads per second than two (never fewer,
/// in four alternated runs), at 18 instead of 22-27 µs of ecatd's CPU per request
/// (docs/performance.md): a second worker only competed with the bus thread for the
/// other core.
pub fn default_workers() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    cores.saturating_sub(1).clamp(1, MAX_DEFAULT_WORKERS)
}

impl Default for GatewayConfig {
    fn default() -> GatewayConfig {
        GatewayConfig {
            bind: IpAddr::V4(Ipv4Addr::UNSPECIFIED),
            port: None,
            master_number: 1,
            fallback: true,
            allow: AllowedNet::all(ClientNet::loopback(), GatewayRole::Write),
            strict: false,
            max_in_flight: 256,
            max_in_flight_per_client: 16,
            request_timeout: Duration::from_secs(5),
            session_timeout: Duration::from_secs(3),
            master_mailbox_size: 1024,
            identity: MasterIdentity::default(),
            tcp: false,
            max_tcp_connections: 16,
            tcp_idle_timeout: Duration::from_secs(60),
            retry_window: Duration::from_secs(1),
            max_retry_clients: 1024,
            workers: default_workers(),
            on_bus_thread: true,
        }
    }
}

impl GatewayConfig {
    /// The port the gateway asks for first.
    pub fn wanted_port(&self) -> u16 {
        self.port
            .unwrap_or_else(|| port_for_master(self.master_number))
    }

    /// Whether a client at `ip` may use the gateway.
    pub fn allows(&self, ip: IpAddr) -> bool {
        self.role_of(ip).is_some()
    }

    /// The role of a client at `ip`: the highest of the networks it is in, `None` if none.
    pub fn role_of(&self, ip: IpAddr) -> Option<GatewayRole> {
        self.allow
            .iter()
            .filter(|entry| entry.net.contains(ip))
            .map(|entry| entry.role)
            .max()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ports_follow_the_master_number() {
        assert_eq!(port_for_master(1), 34980);
        assert_eq!(port_for_master(0), 34980);
        assert_eq!(port_for_master(3), 34982);
        let config = GatewayConfig {
            master_number: 2,
            ..GatewayConfig::default()
        };
        assert_eq!(config.wanted_port(), 34981);
        let explicit = GatewayConfig {
            port: Some(4000),
            ..config
        };
        assert_eq!(explicit.wanted_port(), 4000);
    }
}
