//! Exactly-once answers to repeated UDP requests. A client whose reply was lost sends the
//! same datagram again; forwarded again, a download or an FoE write would run twice, since
//! the gateway gives every request a fresh engine counter. The gateway applies the rule a
//! slave applies to its own mailbox (ETG.1000.4 §5.6, mailbox counter: a message with the
//! counter of the previous one is a repeat): a request byte for byte equal to the same
//! client's previous request (same address, same counter 1-7), arriving within the window
//! after that request was answered, gets the stored reply and is not executed again. Counter
//! 0, other bytes, or any other request of the client in between make it new, so a tool
//! polling one object with cycling counters is never served a stale value. A repeat that
//! comes while the original is still being worked on is dropped: the original's answer goes
//! to the same address. "Busy" and "no answer in time" are not final answers: they are not
//! kept, and a repeat runs.
//!
//! Memory is bounded: one request and its reply per client (address and port), replies
//! larger than [`MAX_STORED`] are not kept (a repeat of such a request, an SDO Information
//! list say, is a read and runs again harmlessly), and at most `max_clients` clients, the one
//! answered longest ago forgotten first.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

/// Most bytes of reply datagrams kept for one client.
pub(crate) const MAX_STORED: usize = 16 * 1024;

/// What to do with a request.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Check {
    /// Execute it; hand its replies to [`Retries::finish`] with this ticket (`None`: not
    /// kept, counter 0 or repeats off).
    New(Option<u64>),
    /// A repeat: send these datagrams again.
    Repeat(Vec<Vec<u8>>),
    /// A repeat of a request still being worked on: drop it.
    InFlight,
}

#[derive(Debug)]
enum State {
    InFlight(u64),
    Done(Vec<Vec<u8>>),
}

#[derive(Debug)]
struct Entry {
    request: Box<[u8]>,
    /// When the request arrived, then when it was answered.
    at: Instant,
    state: State,
}

#[derive(Debug, Default)]
struct Inner {
    entries: HashMap<SocketAddr, Entry>,
    next: u64,
}

/// The last request and reply of each client.
#[derive(Debug)]
pub(crate) struct Retries {
    window: Duration,
    max_clients: usize,
    inner: Mutex<Inner>,
}

impl Retries {
    /// Repeats within `window` after the answer are answered from the store; at most
    /// `max_clients` clients are remembered.
    pub fn new(window: Duration, max_clients: usize) -> Retries {
        Retries {
            window,
            max_clients: max_clients.max(1),
            inner: Mutex::default(),
        }
    }

    /// Looks at a request of `client` (the whole gateway message `request`, mailbox
    /// `counter`) arriving `now`.
    pub fn check(&self, client: SocketAddr, request: &[u8], counter: u8, now: Instant) -> Check {
        if self.window.is_zero() {
            return Check::New(None);
        }
        let mut inner = self.inner.lock().unwrap_or_else(PoisonError::into_inner);
        if counter != 0
            && let Some(entry) = inner.entries.get(&client)
            && *entry.request == *request
        {
            match &entry.state {
                State::InFlight(_) => return Check::InFlight,
                State::Done(replies) if now.saturating_duration_since(entry.at) <= self.window => {
                    return Check::Repeat(replies.clone());
                }
                State::Done(_) => {}
            }
        }
        if counter == 0 {
            // Never a repeat, and whatever came before is no longer the previous request.
            inner.entries.remove(&client);
            return Check::New(None);
        }
        if !inner.entries.contains_key(&client) && inner.entries.len() >= self.max_clients {
            let oldest = inner
                .entries
                .iter()
                .min_by_key(|(_, e)| e.at)
                .map(|(k, _)| *k);
            if let Some(oldest) = oldest {
                inner.entries.remove(&oldest);
            }
        }
        inner.next = inner.next.wrapping_add(1);
        let ticket = inner.next;
        inner.entries.insert(
            client,
            Entry {
                request: request.into(),
                at: now,
                state: State::InFlight(ticket),
            },
        );
        Check::New(Some(ticket))
    }

    /// Stores the reply datagrams of the request with `ticket`, answered `now` (unless the
    /// client sent another request meanwhile, or they are too large to keep); `None`: the
    /// answer says nothing final (busy, timeout), so a repeat runs again.
    pub fn finish(
        &self,
        client: SocketAddr,
        ticket: u64,
        replies: Option<Vec<Vec<u8>>>,
        now: Instant,
    ) {
        let mut inner = self.inner.lock().unwrap_or_else(PoisonError::into_inner);
        let Some(entry) = inner.entries.get_mut(&client) else {
            return;
        };
        if !matches!(entry.state, State::InFlight(t) if t == ticket) {
            return;
        }
        let Some(replies) = replies.filter(|r| r.iter().map(Vec::len).sum::<usize>() <= MAX_STORED)
        else {
            inner.entries.remove(&client);
            return;
        };
        entry.state = State::Done(replies);
        entry.at = now;
    }

    /// Clients remembered.
    #[cfg(test)]
    fn len(&self) -> usize {
        self.inner
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .entries
            .len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn client(port: u16) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], port))
    }

    #[test]
    fn a_repeat_within_the_window_gets_the_stored_reply() {
        let r = Retries::new(Duration::from_secs(1), 8);
        let t0 = Instant::now();
        let Check::New(Some(ticket)) = r.check(client(1), b"req", 1, t0) else {
            panic!("new")
        };
        assert_eq!(r.check(client(1), b"req", 1, t0), Check::InFlight);
        r.finish(client(1), ticket, Some(vec![b"reply".to_vec()]), t0);
        let later = t0 + Duration::from_millis(900);
        assert_eq!(
            r.check(client(1), b"req", 1, later),
            Check::Repeat(vec![b"reply".to_vec()])
        );
        // Another client, the same bytes: new.
        assert!(matches!(
            r.check(client(2), b"req", 1, later),
            Check::New(Some(_))
        ));
        // After the window: new.
        let after = t0 + Duration::from_millis(1001);
        assert!(matches!(
            r.check(client(1), b"req", 1, after),
            Check::New(Some(_))
        ));
    }

    #[test]
    fn counter_zero_other_bytes_or_a_request_in_between_make_it_new() {
        let r = Retries::new(Duration::from_secs(10), 8);
        let now = Instant::now();
        let done = |bytes: &[u8], counter: u8| {
            if let Check::New(Some(t)) = r.check(client(1), bytes, counter, now) {
                r.finish(client(1), t, Some(vec![bytes.to_vec()]), now);
            }
        };
        done(b"a", 0);
        assert_eq!(r.check(client(1), b"a", 0, now), Check::New(None));
        done(b"a", 1);
        assert!(matches!(
            r.check(client(1), b"b", 1, now),
            Check::New(Some(_))
        ));
        done(b"b", 1);
        done(b"c", 2);
        assert!(matches!(
            r.check(client(1), b"b", 1, now),
            Check::New(Some(_))
        ));
    }

    #[test]
    fn memory_stays_bounded() {
        let r = Retries::new(Duration::from_secs(10), 4);
        let now = Instant::now();
        for port in 0..100 {
            let Check::New(Some(t)) = r.check(client(port), b"x", 1, now) else {
                panic!("new")
            };
            r.finish(client(port), t, Some(vec![vec![0; 10]]), now);
        }
        assert_eq!(r.len(), 4);
        let Check::New(Some(t)) = r.check(client(7), b"big", 1, now) else {
            panic!("new")
        };
        r.finish(client(7), t, Some(vec![vec![0; MAX_STORED + 1]]), now);
        assert!(matches!(
            r.check(client(7), b"big", 1, now),
            Check::New(Some(_))
        ));
        // A busy or timed-out request is not final: its repeat runs.
        let Check::New(Some(t)) = r.check(client(8), b"busy", 1, now) else {
            panic!("new")
        };
        r.finish(client(8), t, None, now);
        assert!(matches!(
            r.check(client(8), b"busy", 1, now),
            Check::New(Some(_))
        ));
    }
}
