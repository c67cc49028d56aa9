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
//! A broadcast is, for each slave, a message of its client like any other, with one
//! difference ([`Patience::ExchangeOnly`]): it waits for another client's single exchange
//! (which ends with its one answer) but not for another client's transfer (which lasts as
//! long as its client keeps sending): that slave is refused at once and answers "busy" in
//! the broadcast's answer, so the transfer is never stepped into and the broadcast's other
//! slaves do not wait for it.
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

/// What a request does about a slave that another client holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Patience {
    /// Waits for any holder, up to its deadline: a request addressed to the slave, whose
    /// client asked for that slave and nothing else.
    AnyHolder,
    /// Waits for another client's single exchange but is refused at once by another
    /// client's transfer: a broadcast, whose other slaves should not wait for a transfer
    /// that may last long, and which must not be carried into the middle of it.
    ExchangeOnly,
}

/// Why [`Sessions::enter`] did not let a client in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Refused {
    /// Another client still held the slave at the deadline.
    Deadline,
    /// Another client holds the slave for a transfer (with [`Patience::ExchangeOnly`]).
    InTransfer,
}

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
    /// [`Self::update`]) and returns the transfer `client` is in with it, if any. Refused
    /// if `deadline` passes first, or at once if `patience` is [`Patience::ExchangeOnly`]
    /// and another client holds the slave for a transfer.
    pub async fn enter(
        &self,
        station: u16,
        client: SocketAddr,
        deadline: Instant,
        patience: Patience,
    ) -> Result<Option<Transfer>, Refused> {
        loop {
            let mut released = pin!(self.released(station).notified());
            released.as_mut().enable();
            let wait_until = {
                let mut held = self.held.lock().unwrap_or_else(PoisonError::into_inner);
                let now = Instant::now();
                match held.get(&station).copied() {
                    Some(h) if h.client != client && h.expires > now => {
                        if patience == Patience::ExchangeOnly && h.transfer.is_some() {
                            return Err(Refused::InTransfer);
                        }
                        if now >= deadline {
                            return Err(Refused::Deadline);
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
    ///
    /// The waiters are woken when the slave is freed and when an exchange turns into a
    /// transfer (a broadcast waiting for that exchange is refused now, not at the
    /// exchange's deadline); not at every message of a transfer, which would wake every
    /// waiter once per segment for nothing.
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
                let previous = held.insert(
                    station,
                    Held {
                        client,
                        transfer: Some(transfer),
                        expires: Instant::now() + timeout,
                    },
                );
                if previous.is_none_or(|h| h.transfer.is_none()) {
                    drop(held);
                    self.released(station).notify_waiters();
                }
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

    const ANY: Patience = Patience::AnyHolder;

    #[tokio::test(flavor = "current_thread")]
    async fn a_held_slave_waits_for_the_release_or_the_timeout() {
        let sessions = std::sync::Arc::new(Sessions::default());
        let far = Instant::now() + Duration::from_secs(60);
        assert_eq!(sessions.enter(1, addr(1), far, ANY).await, Ok(None));
        sessions.update(1, addr(1), Some(Transfer::Sdo), Duration::from_secs(3));
        assert_eq!(
            sessions.enter(1, addr(1), far, ANY).await,
            Ok(Some(Transfer::Sdo))
        );
        // Another client gives up at its own deadline while the hold lasts.
        let soon = Instant::now() + Duration::from_millis(20);
        assert_eq!(
            sessions.enter(1, addr(2), soon, ANY).await,
            Err(Refused::Deadline)
        );
        // A release lets it in at once.
        let waiter = {
            let sessions = std::sync::Arc::clone(&sessions);
            tokio::spawn(async move { sessions.enter(1, addr(2), far, ANY).await })
        };
        tokio::task::yield_now().await;
        sessions.update(1, addr(1), None, Duration::from_secs(3));
        assert_eq!(waiter.await.unwrap(), Ok(None));
        // A forgotten hold runs out.
        let hold = Duration::from_millis(30);
        sessions.update(2, addr(1), Some(Transfer::FoeWrite), hold);
        let start = Instant::now();
        assert_eq!(sessions.enter(2, addr(2), far, ANY).await, Ok(None));
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
            assert_eq!(sessions.enter(station, addr(1), far, ANY).await, Ok(None));
        }
        // Client 2 waits for station 2.
        let wakes = std::sync::Arc::new(Wakes::default());
        let waker = std::task::Waker::from(std::sync::Arc::clone(&wakes));
        let mut cx = std::task::Context::from_waker(&waker);
        let mut waiting = pin!(sessions.enter(2, addr(2), far, ANY));
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
        assert_eq!(sessions.enter(7, addr(1), far, ANY).await, Ok(None));
        let soon = Instant::now() + Duration::from_millis(20);
        assert_eq!(
            sessions.enter(7, addr(2), soon, ANY).await,
            Err(Refused::Deadline)
        );
        // The same client may go on (a pipelining client).
        assert_eq!(sessions.enter(7, addr(1), far, ANY).await, Ok(None));
        sessions.update(7, addr(1), None, Duration::from_secs(3));
        assert_eq!(sessions.enter(7, addr(2), far, ANY).await, Ok(None));
    }

    #[tokio::test(flavor = "current_thread")]
    async fn a_broadcast_waits_for_an_exchange_but_not_for_a_transfer() {
        use std::future::Future;
        const BROADCAST: Patience = Patience::ExchangeOnly;
        let sessions = Sessions::default();
        let far = Instant::now() + Duration::from_secs(60);
        // Client 1 holds station 3 for its first message (an SDO initiate, say).
        assert_eq!(sessions.enter(3, addr(1), far, ANY).await, Ok(None));
        // The broadcast of client 2 waits for that exchange...
        let wakes = std::sync::Arc::new(Wakes::default());
        let waker = std::task::Waker::from(std::sync::Arc::clone(&wakes));
        let mut cx = std::task::Context::from_waker(&waker);
        let mut waiting = pin!(sessions.enter(3, addr(2), far, BROADCAST));
        assert!(waiting.as_mut().poll(&mut cx).is_pending());
        // ...which leaves a transfer open: woken at once and refused, not at `far`.
        sessions.update(3, addr(1), Some(Transfer::Sdo), Duration::from_secs(3));
        assert_eq!(wakes.0.load(std::sync::atomic::Ordering::SeqCst), 1);
        assert_eq!(
            waiting.as_mut().poll(&mut cx),
            std::task::Poll::Ready(Err(Refused::InTransfer))
        );
        // Refused at once while the transfer lasts, and the hold is untouched.
        assert_eq!(
            sessions.enter(3, addr(2), far, BROADCAST).await,
            Err(Refused::InTransfer)
        );
        // The transfer's own client goes on, whatever it sends.
        assert_eq!(
            sessions.enter(3, addr(1), far, BROADCAST).await,
            Ok(Some(Transfer::Sdo))
        );
        sessions.update(3, addr(1), None, Duration::from_secs(3));
        // Free again: the broadcast gets in (and holds the slave for its exchange).
        assert_eq!(sessions.enter(3, addr(2), far, BROADCAST).await, Ok(None));
        let soon = Instant::now() + Duration::from_millis(20);
        assert_eq!(
            sessions.enter(3, addr(1), soon, ANY).await,
            Err(Refused::Deadline)
        );
    }
}
