//! Caps on the requests worked on at once, overall and per client host: a request beyond
//! either is answered "busy" at once instead of queueing without bound. A client counts by
//! its IP address, whatever its ports: a host cannot take more places by opening sockets.

use std::collections::HashMap;
use std::net::{IpAddr, SocketAddr};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use super::stats::Stats;

/// The counts behind the caps.
#[derive(Debug)]
pub(crate) struct Admission {
    max_total: usize,
    max_per_client: usize,
    total: AtomicUsize,
    per_client: Mutex<HashMap<IpAddr, usize>>,
    stats: Arc<Stats>,
}

/// A request admitted; dropping it frees its place.
#[derive(Debug)]
pub(crate) struct Ticket {
    admission: Arc<Admission>,
    client: IpAddr,
}

impl Admission {
    pub fn new(max_total: usize, max_per_client: usize, stats: Arc<Stats>) -> Admission {
        Admission {
            max_total: max_total.max(1),
            max_per_client: max_per_client.max(1),
            total: AtomicUsize::new(0),
            per_client: Mutex::new(HashMap::new()),
            stats,
        }
    }

    /// A place for a request of `client`, or `None` if a cap is reached.
    pub fn admit(self: &Arc<Self>, client: SocketAddr) -> Option<Ticket> {
        let client = host(client);
        let mut per_client = self
            .per_client
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        if self.total.load(Ordering::Relaxed) >= self.max_total {
            return None;
        }
        let mine = per_client.entry(client).or_insert(0);
        if *mine >= self.max_per_client {
            return None;
        }
        *mine += 1;
        self.total.fetch_add(1, Ordering::Relaxed);
        self.stats.in_flight_add();
        Some(Ticket {
            admission: Arc::clone(self),
            client,
        })
    }

    /// Requests admitted and not finished.
    #[cfg(test)]
    pub fn in_flight(&self) -> usize {
        self.total.load(Ordering::Relaxed)
    }
}

/// The host of a client; an IPv4 address mapped into IPv6 counts as IPv4.
fn host(client: SocketAddr) -> IpAddr {
    match client.ip() {
        IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(IpAddr::V6(v6), IpAddr::V4),
        v4 => v4,
    }
}

impl Drop for Ticket {
    fn drop(&mut self) {
        let a = &self.admission;
        let mut per_client = a.per_client.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(n) = per_client.get_mut(&self.client) {
            *n = n.saturating_sub(1);
            if *n == 0 {
                // No entry outlives its client's last request: the map stays small.
                per_client.remove(&self.client);
            }
        }
        a.total.fetch_sub(1, Ordering::Relaxed);
        a.stats.in_flight_sub();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn caps_hold_per_client_and_overall_and_places_come_back() {
        let stats = Arc::new(Stats::default());
        let a = Arc::new(Admission::new(3, 2, Arc::clone(&stats)));
        let c1 = SocketAddr::from(([127, 0, 0, 1], 1));
        let c2 = SocketAddr::from(([127, 0, 0, 2], 2));
        let t1 = a.admit(c1).unwrap();
        let _t2 = a.admit(c1).unwrap();
        assert!(a.admit(c1).is_none(), "per-client cap");
        let _t3 = a.admit(c2).unwrap();
        assert!(a.admit(c2).is_none(), "overall cap");
        assert_eq!(stats.snapshot().in_flight, 3);
        drop(t1);
        assert_eq!(a.in_flight(), 2);
        assert!(a.admit(c1).is_some());
    }

    #[test]
    fn the_cap_counts_per_host_not_per_port() {
        let stats = Arc::new(Stats::default());
        let a = Arc::new(Admission::new(10, 2, stats));
        let _t1 = a.admit(SocketAddr::from(([127, 0, 0, 1], 1))).unwrap();
        let _t2 = a.admit(SocketAddr::from(([127, 0, 0, 1], 2))).unwrap();
        assert!(a.admit(SocketAddr::from(([127, 0, 0, 1], 3))).is_none());
        assert!(a.admit(SocketAddr::from(([127, 0, 0, 2], 3))).is_some());
    }
}
