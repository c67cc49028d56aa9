//! A link wrapper that loses, damages and delays frames on purpose, repeatably.
//!
//! The bus must survive a bad cable: lost frames, flipped bits, late replies. Tests wrap a
//! link in a [`FaultInjector`] and compare what it injected ([`FaultInjector::counts`]) with
//! what the master noticed. Every decision comes from one PRNG seeded by the caller, so the
//! same seed, configuration and traffic give the same faults on every run.

use std::collections::VecDeque;
use std::io;
use std::time::{Duration, Instant};

use super::{Link, MAX_FRAME_LEN, Wait};
use ecat_wire::ethernet::HEADER_LEN as ETHERNET_HEADER_LEN;

/// Which faults to inject, as probabilities per frame (0.0 = never, 1.0 = always).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FaultConfig {
    /// Probability that a frame given to `send` silently vanishes instead of being sent.
    pub drop_tx: f64,
    /// Probability that a received frame silently vanishes instead of being returned.
    pub drop_rx: f64,
    /// Probability that a received frame (one that was not dropped) gets one byte changed at
    /// a random offset after the Ethernet header, so that it still reaches the EtherCAT
    /// parser instead of being ignored as foreign traffic.
    pub corrupt: f64,
    /// If set, every received frame is held back this long, counted from the moment the
    /// injector takes it from the inner link, and handed out by a later `recv` once due.
    pub delay: Option<Duration>,
}

/// What a [`FaultInjector`] has done so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FaultCounts {
    /// Frames dropped on the way out.
    pub tx_dropped: u64,
    /// Frames dropped on the way in.
    pub rx_dropped: u64,
    /// Received frames that had a byte changed.
    pub corrupted: u64,
    /// Received frames that were held back by the configured delay.
    pub delayed: u64,
}

/// Wraps a link and injects faults into the frames that pass through it.
///
/// Wrap the end whose traffic should suffer: around the master's link, `drop_tx` loses
/// requests and `drop_rx`/`corrupt`/`delay` affect replies. Delayed frames come out in the
/// order they arrived.
#[derive(Debug)]
pub struct FaultInjector<L: Link> {
    inner: L,
    config: FaultConfig,
    rng: fastrand::Rng,
    counts: FaultCounts,
    /// Delayed frames, oldest first.
    held: VecDeque<Held>,
    /// Buffers of released frames, reused so that holding a frame does not allocate once the
    /// injector has warmed up.
    spare: Vec<Vec<u8>>,
}

#[derive(Debug)]
struct Held {
    due: Instant,
    frame: Vec<u8>,
}

impl<L: Link> FaultInjector<L> {
    /// Wraps `inner`, drawing every fault decision from a PRNG seeded with `seed`.
    pub fn new(inner: L, config: FaultConfig, seed: u64) -> FaultInjector<L> {
        FaultInjector {
            inner,
            config,
            rng: fastrand::Rng::with_seed(seed),
            counts: FaultCounts::default(),
            held: VecDeque::new(),
            spare: Vec::new(),
        }
    }

    /// The faults injected so far.
    pub fn counts(&self) -> FaultCounts {
        self.counts
    }

    /// The current configuration.
    pub fn config(&self) -> FaultConfig {
        self.config
    }

    /// Changes the faults from now on (for example to cut the cable in the middle of a test).
    /// Frames already held keep their due time.
    pub fn set_config(&mut self, config: FaultConfig) {
        self.config = config;
    }

    /// How many received frames are being held back by the delay.
    pub fn held(&self) -> usize {
        self.held.len()
    }

    /// The wrapped link.
    pub fn inner(&self) -> &L {
        &self.inner
    }

    /// The wrapped link, mutably (frames sent through it bypass the injector).
    pub fn inner_mut(&mut self) -> &mut L {
        &mut self.inner
    }

    /// Unwraps the link; frames still held back are lost.
    pub fn into_inner(self) -> L {
        self.inner
    }

    /// Draws one decision that is true with probability `p`.
    fn chance(&mut self, p: f64) -> bool {
        // Drawing even when `p` is 0 keeps the sequence of decisions the same whichever
        // faults are switched on, so changing one probability does not reshuffle the others.
        self.rng.f64() < p
    }

    /// Changes one byte after the Ethernet header; false if the frame has no such byte.
    fn corrupt(&mut self, frame: &mut [u8]) -> bool {
        if frame.len() <= ETHERNET_HEADER_LEN {
            return false;
        }
        let offset = self.rng.usize(ETHERNET_HEADER_LEN..frame.len());
        // XOR with a non-zero value, so the byte really differs from what was sent.
        frame[offset] ^= self.rng.u8(1..=u8::MAX);
        true
    }

    /// Holds a received frame until `due`.
    fn hold(&mut self, frame: &[u8], due: Instant) {
        let mut copy = self
            .spare
            .pop()
            .unwrap_or_else(|| Vec::with_capacity(MAX_FRAME_LEN));
        copy.clear();
        copy.extend_from_slice(frame);
        self.held.push_back(Held { due, frame: copy });
    }

    /// Copies the oldest held frame into `buf` if it is due at `now`.
    fn release_due(&mut self, now: Instant, buf: &mut [u8]) -> Option<usize> {
        if self.held.front()?.due > now {
            return None;
        }
        let Held { frame, .. } = self.held.pop_front()?;
        let len = frame.len().min(buf.len());
        buf[..len].copy_from_slice(&frame[..len]);
        self.spare.push(frame);
        Some(len)
    }
}

impl<L: Link> Link for FaultInjector<L> {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        if self.chance(self.config.drop_tx) {
            self.counts.tx_dropped += 1;
            return Ok(());
        }
        self.inner.send(frame)
    }

    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> io::Result<Option<usize>> {
        loop {
            if let Some(len) = self.release_due(Instant::now(), buf) {
                return Ok(Some(len));
            }
            // Wake up for the next held frame even if the caller would wait longer.
            let inner_wait = match (wait, self.held.front()) {
                (Wait::NoWait, _) => Wait::NoWait,
                (Wait::Until(deadline), Some(next)) => Wait::Until(deadline.min(next.due)),
                (Wait::Until(deadline), None) => Wait::Until(deadline),
            };
            match self.inner.recv(buf, inner_wait)? {
                Some(len) => {
                    if self.chance(self.config.drop_rx) {
                        self.counts.rx_dropped += 1;
                        continue;
                    }
                    if self.chance(self.config.corrupt) && self.corrupt(&mut buf[..len]) {
                        self.counts.corrupted += 1;
                    }
                    if let Some(delay) = self.config.delay {
                        self.hold(&buf[..len], Instant::now() + delay);
                        self.counts.delayed += 1;
                        continue;
                    }
                    return Ok(Some(len));
                }
                None => {
                    let now = Instant::now();
                    let next_due = self.held.front().is_some_and(|next| next.due <= now);
                    if !next_due && wait.expired_at(now) {
                        return Ok(None);
                    }
                }
            }
        }
    }
}
