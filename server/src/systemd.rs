//! Telling systemd about ecatd's state (`Type=notify` in `deploy/systemd/ecatd.service`),
//! through the `sd-notify` crate: `READY=1` once the first scan is done and the APIs serve,
//! `STOPPING=1` when the shutdown starts, and `WATCHDOG=1` while the bus thread makes
//! progress (`WatchdogSec=` in the unit). Without `$NOTIFY_SOCKET` (not started by systemd)
//! nothing is sent. The crate connects to a socket path, which is what systemd gives a
//! service (`/run/systemd/notify`); an abstract address (`@name`) is not supported.

use sd_notify::NotifyState;

/// Sends `state` to systemd if it is watching; a failure is logged, never fatal (the
/// service still runs, systemd's start timeout tells the operator).
pub fn notify(state: NotifyState<'_>) {
    if let Err(err) = sd_notify::notify(std::slice::from_ref(&state)) {
        tracing::warn!(%err, state = %state, "cannot notify systemd");
    }
}

/// Starts pinging systemd's watchdog if the unit asked for one (`WatchdogSec=`, seen as
/// `$WATCHDOG_USEC`): twice per period, and only when `progress` moved since the last ping.
/// `progress` counts the bus thread's work (frames sent, cycles run, requests failed);
/// ecatd's own watch submits a frame every 100 ms, so a bus thread that stopped turning
/// stops the pings and systemd restarts the service. A cut cable does not: frames still go
/// out and time out.
pub fn start_watchdog(
    progress: impl Fn() -> u64 + Send + 'static,
) -> Option<tokio::task::JoinHandle<()>> {
    let period = sd_notify::watchdog_enabled()?;
    let every = period / 2;
    tracing::info!(period_ms = period.as_millis() as u64, "systemd watchdog on");
    Some(tokio::spawn(async move {
        let mut pacer = Pacer::new(progress());
        let mut ticks = tokio::time::interval(every);
        ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            ticks.tick().await;
            match pacer.tick(progress()) {
                Beat::Ping => notify(NotifyState::Watchdog),
                Beat::Stalled => {
                    tracing::error!(
                        period_ms = period.as_millis() as u64,
                        "the bus thread made no progress: systemd's watchdog is not pinged"
                    )
                }
                Beat::StillStalled => {}
            }
        }
    }))
}

/// What one look at the bus thread's progress decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Beat {
    /// The bus moved since the last look: ping.
    Ping,
    /// The bus stopped since the last look: no ping, say so once.
    Stalled,
    /// Still no progress: no ping, already said.
    StillStalled,
}

/// The watchdog's decision, apart from the clock so that it can be tested.
#[derive(Debug)]
pub struct Pacer {
    last: u64,
    stalled: bool,
}

impl Pacer {
    /// Starts from the bus's progress counter now.
    pub fn new(progress: u64) -> Pacer {
        Pacer {
            last: progress,
            stalled: false,
        }
    }

    /// One look at the counter.
    pub fn tick(&mut self, progress: u64) -> Beat {
        let moved = progress != self.last;
        self.last = progress;
        match (moved, self.stalled) {
            (true, _) => {
                self.stalled = false;
                Beat::Ping
            }
            (false, false) => {
                self.stalled = true;
                Beat::Stalled
            }
            (false, true) => Beat::StillStalled,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_watchdog_pings_only_while_the_bus_moves_and_says_a_stall_once() {
        let mut pacer = Pacer::new(5);
        assert_eq!(pacer.tick(9), Beat::Ping);
        assert_eq!(pacer.tick(12), Beat::Ping);
        assert_eq!(pacer.tick(12), Beat::Stalled);
        assert_eq!(pacer.tick(12), Beat::StillStalled);
        assert_eq!(pacer.tick(13), Beat::Ping);
        assert_eq!(pacer.tick(13), Beat::Stalled);
    }
}
