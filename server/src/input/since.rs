//! A point in time as callers write it for "since": a UTC time in RFC 3339
//! (`2026-11-29T07:00:00Z`, fractions and offsets as RFC 3339 allows) or a span back from
//! now in humantime's units (`90s`, `10m`, `2h`, `1day`).

use std::time::SystemTime;

use crate::error::ApiError;

/// The time `text` names, `now` being the present (for a span back from it).
pub fn parse_since(text: &str, now: SystemTime) -> Result<SystemTime, ApiError> {
    let text = text.trim();
    if let Ok(at) = humantime::parse_rfc3339_weak(text) {
        return Ok(at);
    }
    humantime::parse_duration(text)
        .ok()
        .and_then(|back| now.checked_sub(back))
        .ok_or_else(|| {
            ApiError::invalid_field(
                "since",
                format!("since {text:?}: give a time (2026-11-29T07:00:00Z) or a span back (10m)"),
            )
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn a_time_or_a_span_back_and_nothing_else() {
        let now = humantime::parse_rfc3339("2026-11-29T07:00:00Z").unwrap();
        assert_eq!(
            parse_since("2026-11-29T06:00:00Z", now).unwrap(),
            now - Duration::from_secs(3600)
        );
        assert_eq!(
            parse_since(" 10m ", now).unwrap(),
            now - Duration::from_secs(600)
        );
        for bad in ["", "yesterday", "10 parsecs", "2026-13-01T00:00:00Z"] {
            let err = parse_since(bad, now).unwrap_err();
            assert_eq!(err.field, Some("since"), "{bad:?}");
        }
    }
}
