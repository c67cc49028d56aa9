//! Caps on the requests worked on at once, overall and per client: a request beyond either
//! is answered "busy" at once instead of queueing without bound.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use super::stats::Stats;

/// The counts behind the caps.
#[derive(Debug)]
pub(crate) struct Admission {
    max_total: usize,
    max_per_client: usize,
    total: AtomicUsize,
    per_client: Mutex<HashMap<SocketAddr, usize>>,
    stats: Arc<Stats>,
}

/// A request admitted; dropping it frees its place.
#[derive(Debug)]
pub(crate) struct Ticket {
    admission: Arc<Admission>,
    client: SocketAddr,
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
        let c2 = SocketAddr::from(([127, 0, 0, 1], 2));
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
}
