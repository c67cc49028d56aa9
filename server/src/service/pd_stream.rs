//! What a stream of process-data values needs, whichever API serves it: the interval rules
//! (not below the cycle period nor [`MIN_INTERVAL`], so that a stream never asks for values
//! faster than cycles complete nor sends more than a hundred messages a second) and the
//! entries that changed between two reads.

use std::time::Duration;

use super::process_data::{PdValueView, ProcessDataView};
use super::{ApiError, Core, Result};

/// The shortest interval a stream may ask for.
pub const MIN_INTERVAL: Duration = Duration::from_millis(10);

/// The interval of a stream that asks for none (the cycle period if that is longer).
pub const DEFAULT_INTERVAL: Duration = Duration::from_millis(100);

impl Core {
    /// The interval a process-data stream runs at: `requested`, or [`DEFAULT_INTERVAL`]
    /// (the cycle period if that is longer) when none is; refused (`interval`) below the
    /// cycle period or [`MIN_INTERVAL`].
    pub fn pd_stream_interval(&self, requested: Option<Duration>) -> Result<Duration> {
        check_interval(self.master.cycle_timing().period, requested)
    }
}

fn check_interval(period: Duration, requested: Option<Duration>) -> Result<Duration> {
    let interval = requested.unwrap_or(DEFAULT_INTERVAL.max(period));
    if interval < period || interval < MIN_INTERVAL {
        return Err(ApiError::invalid_field(
            "interval",
            format!(
                "interval {} is below the cycle ({}) or {}",
                humantime::format_duration(interval),
                humantime::format_duration(period),
                humantime::format_duration(MIN_INTERVAL)
            ),
        ));
    }
    Ok(interval)
}

/// What a stream sent last, to send only what changed since.
#[derive(Debug, Default)]
pub struct PdChanges {
    last: Option<Vec<PdValueView>>,
}

impl PdChanges {
    /// `view` with only the entries whose bits or force changed since the last call (every
    /// entry the first time); `None` when nothing changed.
    pub fn next(&mut self, view: ProcessDataView) -> Option<ProcessDataView> {
        let changed: Vec<PdValueView> = match &self.last {
            None => view.values.clone(),
            Some(before) => view
                .values
                .iter()
                .filter(|v| {
                    !before
                        .iter()
                        .any(|b| b.entry == v.entry && b.raw == v.raw && b.forced_by == v.forced_by)
                })
                .cloned()
                .collect(),
        };
        let first = self.last.is_none();
        self.last = Some(view.values.clone());
        (first || !changed.is_empty()).then_some(ProcessDataView {
            values: changed,
            ..view
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::process_data::{PdEntryView, PdValue};
    use super::*;

    #[test]
    fn the_interval_is_neither_below_the_cycle_nor_below_10_ms() {
        let ms = Duration::from_millis;
        assert_eq!(check_interval(ms(1), None).unwrap(), ms(100));
        assert_eq!(check_interval(ms(250), None).unwrap(), ms(250));
        assert_eq!(check_interval(ms(1), Some(ms(10))).unwrap(), ms(10));
        let below = check_interval(ms(20), Some(ms(15))).unwrap_err();
        assert_eq!(below.field, Some("interval"));
        assert_eq!(
            below.message,
            "interval 15ms is below the cycle (20ms) or 10ms"
        );
        assert!(check_interval(ms(1), Some(ms(5))).is_err());
    }

    fn view(cycle: u64, values: &[(u16, u8)]) -> ProcessDataView {
        ProcessDataView {
            cycle,
            wkc: 3,
            expected_wkc: 3,
            values: values
                .iter()
                .map(|&(index, raw)| PdValueView {
                    entry: PdEntryView {
                        slave: 0,
                        station: 1001,
                        pdo: 0x1A00,
                        index,
                        subindex: 0,
                        name: String::new(),
                        data_type: String::new(),
                        bit_offset: 0,
                        bit_length: 8,
                        direction: "in",
                    },
                    value: PdValue::Uint(u64::from(raw)),
                    raw: vec![raw],
                    forced_by: None,
                })
                .collect(),
        }
    }

    #[test]
    fn every_entry_first_then_only_the_changed_ones_and_nothing_without_a_change() {
        let mut changes = PdChanges::default();
        let first = changes.next(view(1, &[(1, 0), (2, 0)])).unwrap();
        assert_eq!(first.values.len(), 2);
        assert!(changes.next(view(2, &[(1, 0), (2, 0)])).is_none());
        let changed = changes.next(view(3, &[(1, 0), (2, 7)])).unwrap();
        assert_eq!(changed.cycle, 3);
        assert_eq!(changed.values.len(), 1);
        assert_eq!(changed.values[0].entry.index, 2);
    }
}
