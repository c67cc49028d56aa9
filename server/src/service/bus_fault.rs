//! Bus faults as events: the event hub looks at the bus's counters of lost frames, lost
//! cycles and link errors on every look ([`super::events`], five times a second) and
//! publishes `bus_fault` when they start to rise and `bus_recovered` at the first look after
//! which they stood still. So a flapping link gives two events per episode, not one per
//! lost frame, and the counters themselves stay in the metrics.

use master_core::bus::BusStatsSnapshot;

use super::view::EventView;

/// The counters that mean the bus lost something.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Faults {
    frames_lost: u64,
    cycles_lost: u64,
    link_errors: u64,
}

impl Faults {
    fn of(stats: &BusStatsSnapshot) -> Faults {
        Faults {
            frames_lost: stats.frames_lost,
            cycles_lost: stats.cycles_lost,
            link_errors: stats.link_errors,
        }
    }

    fn since(self, before: Faults) -> Faults {
        Faults {
            frames_lost: self.frames_lost.saturating_sub(before.frames_lost),
            cycles_lost: self.cycles_lost.saturating_sub(before.cycles_lost),
            link_errors: self.link_errors.saturating_sub(before.link_errors),
        }
    }

    fn any(self) -> bool {
        self != Faults::default()
    }

    fn words(self) -> String {
        format!(
            "{} frames lost, {} cycles lost, {} link errors",
            self.frames_lost, self.cycles_lost, self.link_errors
        )
    }
}

/// Follows the bus's fault counters from one look to the next.
#[derive(Debug)]
pub struct FaultWatch {
    last: Faults,
    /// The counters when the episode under way started.
    episode: Option<Faults>,
}

impl FaultWatch {
    /// Starts from the counters now (faults before, e.g. of the scan, are not news).
    pub fn new(stats: &BusStatsSnapshot) -> FaultWatch {
        FaultWatch::from(Faults::of(stats))
    }

    fn from(faults: Faults) -> FaultWatch {
        FaultWatch {
            last: faults,
            episode: None,
        }
    }

    /// One look: the event to publish, if an episode starts or ends.
    pub fn look(&mut self, stats: &BusStatsSnapshot) -> Option<EventView> {
        self.step(Faults::of(stats))
    }

    fn step(&mut self, now: Faults) -> Option<EventView> {
        let new = now.since(self.last);
        let before = self.last;
        self.last = now;
        match (new.any(), self.episode) {
            (true, None) => {
                self.episode = Some(before);
                Some(EventView::note(
                    "bus_fault",
                    format!("bus fault: {}", new.words()),
                ))
            }
            (false, Some(start)) => {
                self.episode = None;
                Some(EventView::note(
                    "bus_recovered",
                    format!("bus recovered: {} in all", now.since(start).words()),
                ))
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(frames_lost: u64, link_errors: u64) -> Faults {
        Faults {
            frames_lost,
            cycles_lost: 0,
            link_errors,
        }
    }

    #[test]
    fn an_episode_of_faults_is_one_fault_event_and_one_recovery() {
        let mut watch = FaultWatch::from(stats(5, 0));
        assert_eq!(watch.step(stats(5, 0)), None, "old faults are not news");
        let fault = watch.step(stats(8, 1)).expect("a fault");
        assert_eq!(fault.kind, "bus_fault");
        assert_eq!(
            fault.text,
            "bus fault: 3 frames lost, 0 cycles lost, 1 link errors"
        );
        assert_eq!(watch.step(stats(20, 1)), None, "the same episode");
        let recovered = watch.step(stats(20, 1)).expect("a recovery");
        assert_eq!(recovered.kind, "bus_recovered");
        assert_eq!(
            recovered.text,
            "bus recovered: 15 frames lost, 0 cycles lost, 1 link errors in all"
        );
        assert_eq!(watch.step(stats(20, 1)), None);
    }
}
