//! Gateway sessions: a client in the middle of a multi-message transfer with a slave
//! (segmented SDO, FoE, fragmented SoE write) holds that slave until the transfer ends or
//! the client stays silent for the session timeout. Other clients' requests to the slave
//! wait meanwhile (up to their own deadline), so two transfers never interleave on one
//! slave — the slave's SDO server, FoE and SoE state exist once per slave.
//!
//! A client also holds the slave while one of its messages is being exchanged, so that
//! of two clients starting transfers at the same moment one goes first and the other
//! waits, instead of both initiating and the second silently replacing the first.
//!
//! The lock on the table is never held across an await: waiting is done on a `Notify`
//! registered before the table is looked at, so no release is missed. Each slave's waiters
//! have their own `Notify` (one of [`SHARDS`], by station address): with many clients
//! queued on many slaves, the release of one slave wakes the clients waiting for it, not
//! every waiting client (which cost each request as many wake-ups as clients waited).

use std::collections::HashMap;
use std::net::SocketAddr;
use std::pin::pin;
use std::sync::{Mutex, PoisonError};
use std::time::Duration;

use tokio::sync::Notify;
use tokio::time::Instant;

use super::transfer::Transfer;

#[derive(Debug, Clone, Copy)]
struct Held {
    client: SocketAddr,
    /// The transfer the client is in; `None` while its first message is exchanged.
    transfer: Option<Transfer>,
    expires: Instant,
}

/// How many `Notify`s the waiters are spread over, by station address: stations that
/// share one wake each other's waiters, who look again and wait on.
const SHARDS: usize = 64;

/// Who holds which slave (by station address).
#[derive(Debug)]
pub(crate) struct Sessions {
    held: Mutex<HashMap<u16, Held>>,
    released: [Notify; SHARDS],
}

impl Default for Sessions {
    fn default() -> Sessions {
        Sessions {
            held: Mutex::default(),
            released: std::array::from_fn(|_| Notify::new()),
        }
    }
}

impl Sessions {
    /// What a release of `station` notifies.
    fn released(&self, station: u16) -> &Notify {
        &self.released[usize::from(station) % SHARDS]
    }

    /// Waits until `client` may talk to `station` (no one else holds it, or their hold ran
    /// out), holds it for `client` until `deadline` (the end of its exchange; see
    /// [`Self::update`]) and returns the transfer `client` is in with it, if any. `Err(())`
    /// if `deadline` passes first.
    pub async fn enter(
        &self,
        station: u16,
        client: SocketAddr,
        deadline: Instant,
    ) -> Result<Option<Transfer>, ()> {
        loop {
            let mut released = pin!(self.released(station).notified());
            released.as_mut().enable();
            let wait_until = {
                let mut held = self.held.lock().unwrap_or_else(PoisonError::into_inner);
                let now = Instant::now();
                match held.get(&station).copied() {
                    Some(h) if h.client != client && h.expires > now => {
                        if now >= deadline {
                            return Err(());
                        }
                        h.expires.min(deadline)
                    }
                    other => {
                        // Free, expired, or already this client's.
                        let transfer = other
                            .filter(|h| h.client == client)
                            .and_then(|h| h.transfer);
                        held.insert(
                            station,
                            Held {
                                client,
                                transfer,
                                expires: deadline,
                            },
                        );
                        return Ok(transfer);
                    }
                }
            };
            tokio::select! {
                _ = released => {}
                _ = tokio::time::sleep_until(wait_until) => {}
            }
        }
    }

    /// Records the transfer `client` is in with `station` after a message (`None`: it
    /// ended, the slave is free). Only the holder (or anyone, when free) changes it.
    pub fn update(
        &self,
        station: u16,
        client: SocketAddr,
        transfer: Option<Transfer>,
        timeout: Duration,
    ) {
        let mut held = self.held.lock().unwrap_or_else(PoisonError::into_inner);
        let mine = held.get(&station).is_none_or(|h| h.client == client);
        if !mine {
            return;
        }
        match transfer {
            Some(transfer) => {
                held.insert(
                    station,
                    Held {
                        client,
                        transfer: Some(transfer),
                        expires: Instant::now() + timeout,
                    },
                );
            }
            None => {
                if held.remove(&station).is_some() {
                    drop(held);
                    self.released(station).notify_waiters();
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(port: u16) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], port))
    }

    #[tokio::test(flavor = "current_thread")]
    async fn a_held_slave_waits_for_the_release_or_the_timeout() {
        let sessions = std::sync::Arc::new(Sessions::default());
        let far = Instant::now() + Duration::from_secs(60);
        assert_eq!(sessions.enter(1, addr(1), far).await, Ok(None));
        sessions.update(1, addr(1), Some(Transfer::Sdo), Duration::from_secs(3));
        assert_eq!(
            sessions.enter(1, addr(1), far).await,
            Ok(Some(Transfer::Sdo))
        );
        // Another client gives up at its own deadline while the hold lasts.
        let soon = Instant::now() + Duration::from_millis(20);
        assert_eq!(sessions.enter(1, addr(2), soon).await, Err(()));
        // A release lets it in at once.
        let waiter = {
            let sessions = std::sync::Arc::clone(&sessions);
            tokio::spawn(async move { sessions.enter(1, addr(2), far).await })
        };
        tokio::task::yield_now().await;
        sessions.update(1, addr(1), None, Duration::from_secs(3));
        assert_eq!(waiter.await.unwrap(), Ok(None));
        // A forgotten hold runs out.
        let hold = Duration::from_millis(30);
        sessions.update(2, addr(1), Some(Transfer::FoeWrite), hold);
        let start = Instant::now();
        assert_eq!(sessions.enter(2, addr(2), far).await, Ok(None));
        assert!(start.elapsed() >= hold);
    }

    /// Counts the wake-ups of the future it is the waker of.
    #[derive(Default)]
    struct Wakes(std::sync::atomic::AtomicUsize);

    impl std::task::Wake for Wakes {
        fn wake(self: std::sync::Arc<Self>) {
            self.0.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        }
    }

    #[tokio::test(flavor = "current_thread")]
    async fn a_release_wakes_the_waiters_of_that_slave_only() {
        use std::future::Future;
        use std::sync::atomic::Ordering;
        let sessions = Sessions::default();
        let far = Instant::now() + Duration::from_secs(60);
        for station in [1, 2] {
            assert_eq!(sessions.enter(station, addr(1), far).await, Ok(None));
        }
        // Client 2 waits for station 2.
        let wakes = std::sync::Arc::new(Wakes::default());
        let waker = std::task::Waker::from(std::sync::Arc::clone(&wakes));
        let mut cx = std::task::Context::from_waker(&waker);
        let mut waiting = pin!(sessions.enter(2, addr(2), far));
        assert!(waiting.as_mut().poll(&mut cx).is_pending());
        sessions.update(1, addr(1), None, Duration::from_secs(3));
        assert_eq!(wakes.0.load(Ordering::SeqCst), 0, "station 1's release");
        sessions.update(2, addr(1), None, Duration::from_secs(3));
        assert_eq!(wakes.0.load(Ordering::SeqCst), 1, "station 2's release");
        assert_eq!(
            waiting.as_mut().poll(&mut cx),
            std::task::Poll::Ready(Ok(None))
        );
    }

    #[tokio::test(flavor = "current_thread")]
    async fn an_exchange_holds_the_slave_until_its_update() {
        let sessions = Sessions::default();
        let far = Instant::now() + Duration::from_secs(60);
        assert_eq!(sessions.enter(7, addr(1), far).await, Ok(None));
        let soon = Instant::now() + Duration::from_millis(20);
        assert_eq!(sessions.enter(7, addr(2), soon).await, Err(()));
        // The same client may go on (a pipelining client).
        assert_eq!(sessions.enter(7, addr(1), far).await, Ok(None));
        sessions.update(7, addr(1), None, Duration::from_secs(3));
        assert_eq!(sessions.enter(7, addr(2), far).await, Ok(None));
    }
}
