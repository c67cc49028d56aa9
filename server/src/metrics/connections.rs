//! The API servers' connections (`[limits]`): `ecat_api_connections`,
//! `ecat_api_connections_refused_total` and `ecat_api_connections_timed_out_total`, by server.

use prometheus::proto::{MetricFamily, MetricType};

use super::family::Family;
use crate::connections::ServerStats;

/// The families of both servers.
pub fn collect(stats: &ServerStats) -> Vec<Option<MetricFamily>> {
    let servers = [("http", stats.http.counts()), ("grpc", stats.grpc.counts())];
    let mut open = Family::new(
        "ecat_api_connections",
        "Connections open to the API server.",
        MetricType::GAUGE,
    );
    let mut refused = Family::new(
        "ecat_api_connections_refused_total",
        "Connections refused at accept by a [limits] connection limit.",
        MetricType::COUNTER,
    );
    let mut timed_out = Family::new(
        "ecat_api_connections_timed_out_total",
        "Connections the server closed: no request head in time, idle, or a stalled write.",
        MetricType::COUNTER,
    );
    for (server, counts) in servers {
        open = open.gauge(&[("server", server)], counts.open as f64);
        for (reason, n) in [
            ("max_connections", counts.refused_total),
            ("max_connections_per_peer", counts.refused_peer),
        ] {
            refused = refused.counter(&[("server", server), ("reason", reason)], n as f64);
        }
        for (reason, n) in [
            ("header_read", counts.header_read),
            ("idle", counts.idle),
            ("write_stall", counts.write_stall),
        ] {
            timed_out = timed_out.counter(&[("server", server), ("reason", reason)], n as f64);
        }
    }
    vec![open.done(), refused.done(), timed_out.done()]
}
