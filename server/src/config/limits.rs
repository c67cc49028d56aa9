//! `[limits]`: how long and how many connections the HTTP and gRPC servers keep. Without
//! them a client that opens connections and sends nothing (or half a request line) holds
//! memory for ever, before any token is checked.

use std::time::Duration;

use serde::{Deserialize, Serialize};

/// The most connections `max_connections` may allow (each costs a task, buffers and a file
/// descriptor; a limit above the process's descriptors would only move the failure).
pub const MAX_CONNECTIONS: usize = 65_536;

/// Connection limits of the HTTP server (REST, dashboard, metrics) and the gRPC server, each
/// counted on its own.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LimitSettings {
    /// Time a connection has to send a whole request head: from its accept to its first
    /// request (HTTP/2 and gRPC: the preface and the first request's headers), and for
    /// HTTP/1.1 again from the end of each answer to the next request's head (hyper starts
    /// the timer whenever it waits for a head, so it also ends idle kept-alive connections).
    #[serde(with = "humantime_serde")]
    pub header_read_timeout: Duration,
    /// Time a connection may stay open with no request in flight once it has made one, and
    /// time a response may wait for the client to read it (writes making no progress).
    #[serde(with = "humantime_serde")]
    pub idle_timeout: Duration,
    /// Connections open at once, per server; beyond, a new connection is refused (HTTP: 503
    /// and closed; gRPC: closed).
    pub max_connections: usize,
    /// Connections open at once from one client IP address, per server.
    pub max_connections_per_peer: usize,
    /// HTTP/2 (and so gRPC): a PING after this long without frames from the client.
    #[serde(with = "humantime_serde")]
    pub keepalive_interval: Duration,
    /// HTTP/2: a PING not answered within this closes the connection (a peer that vanished
    /// without closing, a cable pulled).
    #[serde(with = "humantime_serde")]
    pub keepalive_timeout: Duration,
}

impl Default for LimitSettings {
    fn default() -> LimitSettings {
        LimitSettings {
            header_read_timeout: Duration::from_secs(10),
            idle_timeout: Duration::from_secs(60),
            max_connections: 1024,
            max_connections_per_peer: 64,
            keepalive_interval: Duration::from_secs(30),
            keepalive_timeout: Duration::from_secs(10),
        }
    }
}

impl LimitSettings {
    /// Refuses limits that would switch a protection off or make the servers unusable.
    pub fn check(&self) -> Result<(), String> {
        let within = |name: &str, value: Duration, min: Duration, max: Duration| {
            if (min..=max).contains(&value) {
                Ok(())
            } else {
                Err(format!(
                    "[limits] {name} = {:?} must be {:?} to {:?}",
                    super::duration::show(value),
                    super::duration::show(min),
                    super::duration::show(max),
                ))
            }
        };
        let ms = Duration::from_millis;
        let hours = |h: u64| Duration::from_secs(h * 3600);
        within(
            "header_read_timeout",
            self.header_read_timeout,
            ms(100),
            hours(1),
        )?;
        within("idle_timeout", self.idle_timeout, ms(100), hours(24))?;
        within(
            "keepalive_interval",
            self.keepalive_interval,
            Duration::from_secs(1),
            hours(24),
        )?;
        within(
            "keepalive_timeout",
            self.keepalive_timeout,
            ms(100),
            hours(1),
        )?;
        if !(1..=MAX_CONNECTIONS).contains(&self.max_connections) {
            return Err(format!(
                "[limits] max_connections = {} must be 1 to {MAX_CONNECTIONS}",
                self.max_connections
            ));
        }
        if !(1..=self.max_connections).contains(&self.max_connections_per_peer) {
            return Err(format!(
                "[limits] max_connections_per_peer = {} must be 1 to max_connections ({})",
                self.max_connections_per_peer, self.max_connections
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<LimitSettings, String> {
        toml::from_str(text).map_err(|err| err.to_string())
    }

    #[test]
    fn defaults_bound_every_connection() {
        let limits = parse("").unwrap();
        assert_eq!(limits, LimitSettings::default());
        assert_eq!(limits.header_read_timeout, Duration::from_secs(10));
        assert_eq!(limits.idle_timeout, Duration::from_secs(60));
        assert_eq!(limits.max_connections, 1024);
        assert_eq!(limits.max_connections_per_peer, 64);
        assert_eq!(limits.keepalive_interval, Duration::from_secs(30));
        assert_eq!(limits.keepalive_timeout, Duration::from_secs(10));
        assert!(limits.check().is_ok());
    }

    #[test]
    fn settings_parse_as_written() {
        let limits = parse(
            "header_read_timeout = \"1s\"\nidle_timeout = \"2s\"\nmax_connections = 50\nmax_connections_per_peer = 10\nkeepalive_interval = \"5s\"\nkeepalive_timeout = \"500ms\"\n",
        )
        .unwrap();
        assert_eq!(limits.header_read_timeout, Duration::from_secs(1));
        assert_eq!(limits.idle_timeout, Duration::from_secs(2));
        assert_eq!(limits.max_connections, 50);
        assert_eq!(limits.max_connections_per_peer, 10);
        assert_eq!(limits.keepalive_interval, Duration::from_secs(5));
        assert_eq!(limits.keepalive_timeout, Duration::from_millis(500));
        assert!(limits.check().is_ok());
        // Printed (`--print-config`) as written, and read back the same.
        let text = toml::to_string(&limits).unwrap();
        assert!(text.contains("header_read_timeout = \"1s\""), "{text}");
        assert_eq!(parse(&text).unwrap(), limits);
    }

    #[test]
    fn bad_limits_are_refused_by_name() {
        for (text, name) in [
            ("header_read_timeout = \"0s\"", "header_read_timeout"),
            ("header_read_timeout = \"2h\"", "header_read_timeout"),
            ("idle_timeout = \"10ms\"", "idle_timeout"),
            ("keepalive_interval = \"100ms\"", "keepalive_interval"),
            ("keepalive_timeout = \"0s\"", "keepalive_timeout"),
            ("max_connections = 0", "max_connections"),
            ("max_connections = 70000", "max_connections"),
            ("max_connections_per_peer = 0", "max_connections_per_peer"),
            (
                "max_connections = 10\nmax_connections_per_peer = 11",
                "max_connections_per_peer",
            ),
        ] {
            let err = parse(text).unwrap().check().unwrap_err();
            assert!(
                err.starts_with(&format!("[limits] {name} = ")),
                "{text}: {err}"
            );
        }
        // Not a duration, not a number, not a key: refused when the file is read.
        for text in [
            "idle_timeout = 60",
            "idle_timeout = \"a minute\"",
            "max_connections = -1",
            "max_conections = 10",
        ] {
            assert!(parse(text).is_err(), "{text}");
        }
    }
}
