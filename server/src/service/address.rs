//! The one syntax for naming a slave, shared by gRPC, REST and the `ecat` command line:
//! `3` (ring position), `#1004` or `#0x3ec` (station address), `@0x777` (alias).

use master_core::master::SlaveAddress;

use super::error::ApiError;

/// Parses a slave name; see the [module documentation](self).
pub fn parse_slave(text: &str) -> Result<SlaveAddress, ApiError> {
    let text = text.trim();
    let (make, digits): (fn(u16) -> SlaveAddress, &str) = if let Some(rest) = text.strip_prefix('#')
    {
        (SlaveAddress::Station, rest)
    } else if let Some(rest) = text.strip_prefix('@') {
        (SlaveAddress::Alias, rest)
    } else {
        (SlaveAddress::Position, text)
    };
    let value = parse_u16(digits).ok_or_else(|| {
        ApiError::invalid(format!(
            "bad slave name {text:?}: use a position (3), a station (#1004, #0x3ec) or an alias (@0x777)"
        ))
    })?;
    Ok(make(value))
}

fn parse_u16(digits: &str) -> Option<u16> {
    match digits
        .strip_prefix("0x")
        .or_else(|| digits.strip_prefix("0X"))
    {
        Some(hex) => u16::from_str_radix(hex, 16).ok(),
        None => digits.parse().ok(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_form_parses() {
        assert_eq!(parse_slave("3").unwrap(), SlaveAddress::Position(3));
        assert_eq!(parse_slave("0x10").unwrap(), SlaveAddress::Position(16));
        assert_eq!(parse_slave("#1004").unwrap(), SlaveAddress::Station(1004));
        assert_eq!(parse_slave("#0x3ec").unwrap(), SlaveAddress::Station(0x3ec));
        assert_eq!(parse_slave("@0x777").unwrap(), SlaveAddress::Alias(0x777));
        assert_eq!(parse_slave(" @5 ").unwrap(), SlaveAddress::Alias(5));
    }

    #[test]
    fn junk_is_refused() {
        for bad in ["", "#", "@", "x3", "70000", "#0xg", "-1", "3.0"] {
            assert!(parse_slave(bad).is_err(), "{bad:?} accepted");
        }
    }
}
