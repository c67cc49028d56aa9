//! The bus at a glance: frame and cycle counters and the cyclic exchange's timing, for the
//! dashboard's bus view (the same numbers `/metrics` exports, as one JSON document).

use master_core::bus::BusStatsSnapshot;
use master_core::master::{CycleStats, CycleTiming};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::Core;
use super::gateway::LatencyView;

/// Frame counters, the cyclic exchange's counters and its timing, since start-up.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct BusView {
    /// Frames handed to the link (cyclic and acyclic, retries included).
    pub frames_sent: u64,
    /// Returned frames matched to a frame in flight.
    pub frames_received: u64,
    /// Frames that did not come back before their deadline.
    pub frames_lost: u64,
    /// Replies whose working counter was not the expected one.
    pub wkc_mismatches: u64,
    /// Errors the link returned.
    pub link_errors: u64,
    /// Process-data exchanges that came back.
    pub cycles_completed: u64,
    /// Process-data exchanges lost.
    pub cycles_lost: u64,
    /// Exchanges that came back with a working counter other than expected.
    pub cycles_wrong_wkc: u64,
    /// Cycles started a whole period or more late.
    pub cycles_late: u64,
    /// Working counter of the last exchange.
    pub last_wkc: u16,
    /// Working counter the exchange should have.
    pub expected_wkc: u16,
    /// Size of the process image, bytes.
    pub image_bytes: u64,
    /// The configured cycle period, microseconds (0: no cyclic exchange).
    pub period_us: u64,
    /// Time between the starts of consecutive cycles.
    pub cycle_time: LatencyView,
    /// How far each cycle time was from the period.
    pub jitter: LatencyView,
    /// Cyclic frame round trip.
    pub round_trip: LatencyView,
}

impl BusView {
    fn new(bus: &BusStatsSnapshot, cycle: &CycleStats, timing: &CycleTiming) -> BusView {
        BusView {
            frames_sent: bus.frames_sent,
            frames_received: bus.frames_received,
            frames_lost: bus.frames_lost,
            wkc_mismatches: bus.wkc_mismatches,
            link_errors: bus.link_errors,
            cycles_completed: cycle.completed,
            cycles_lost: cycle.lost,
            cycles_wrong_wkc: cycle.wrong_wkc,
            cycles_late: cycle.late,
            last_wkc: cycle.last_wkc,
            expected_wkc: cycle.expected_wkc,
            image_bytes: u64::try_from(cycle.image_len).unwrap_or(u64::MAX),
            period_us: u64::try_from(timing.period.as_micros()).unwrap_or(u64::MAX),
            cycle_time: LatencyView::from(&timing.cycle_time),
            jitter: LatencyView::from(&timing.jitter),
            round_trip: LatencyView::from(&timing.round_trip),
        }
    }
}

impl Core {
    /// The bus's counters and timing now.
    pub fn bus(&self) -> BusView {
        let master = self.master();
        BusView::new(
            &master.bus_stats(),
            &master.cycle_stats(),
            &master.cycle_timing(),
        )
    }
}
