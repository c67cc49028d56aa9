//! Durations in the configuration, written the way people write them (`"1ms"`,
//! `"250us"`, `"2s"`), through `humantime-serde`; and their whole-nanosecond arithmetic.

use std::time::Duration;

pub use humantime_serde::{deserialize, serialize};

/// `d` as text, the way the configuration writes it (`"500us"`).
pub fn show(d: Duration) -> String {
    humantime_serde::re::humantime::format_duration(d).to_string()
}

/// `d` in nanoseconds, saturated.
pub fn nanos(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

/// Whether `period` is a whole, non-zero multiple of `cycle`.
pub fn is_multiple(period: Duration, cycle: Duration) -> bool {
    let (period, cycle) = (nanos(period), nanos(cycle));
    cycle > 0 && period >= cycle && period % cycle == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_read_and_print_as_written() {
        #[derive(serde::Deserialize, serde::Serialize)]
        struct T {
            #[serde(with = "super")]
            d: Duration,
        }
        let t: T = toml::from_str("d = \"250us\"").unwrap();
        assert_eq!(t.d, Duration::from_micros(250));
        assert_eq!(show(t.d), "250us");
        assert!(toml::from_str::<T>("d = \"250 parsecs\"").is_err());
        assert!(toml::from_str::<T>("d = 250").is_err());
        assert!(is_multiple(
            Duration::from_millis(2),
            Duration::from_micros(500)
        ));
        assert!(!is_multiple(
            Duration::from_micros(750),
            Duration::from_micros(500)
        ));
        assert!(!is_multiple(
            Duration::from_micros(250),
            Duration::from_micros(500)
        ));
    }
}
