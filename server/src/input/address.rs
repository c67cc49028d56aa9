//! The one syntax for naming a slave, shared by gRPC, REST, `[[watch]]` and the `ecat`
//! command line. Numbers are decimal or `0x` hex everywhere.
//!
//! | form | meaning |
//! |---|---|
//! | `3`, `pos:3` | ring position |
//! | `station:1004`, `#1004`, `#0x3ec` | configured station address |
//! | `alias:0x777`, `@0x777` | configured station alias |
//! | `alias:0x777+2`, `@0x777+2`, `0x777:2` | the slave 2 positions after the one with alias 0x777 (IgH's `alias:relpos`) |
//!
//! The prefixed forms need no URL escaping in REST paths (`#` does: `%23`).

use master_core::master::{SlaveAddress, SlaveInfo};

use crate::error::ApiError;

/// A parsed slave name: an address the master resolves itself, or IgH's `alias:relpos`,
/// resolved against the last scan ([`SlaveName::resolve`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlaveName {
    /// Position, station or alias.
    Address(SlaveAddress),
    /// `offset` positions after the slave with `alias`.
    AliasOffset {
        /// The alias of the reference slave.
        alias: u16,
        /// Positions after it.
        offset: u16,
    },
}

impl SlaveName {
    /// The master's address of the named slave; `slaves` is the last scan, needed only for
    /// `alias:relpos`.
    pub fn resolve(
        self,
        slaves: impl FnOnce() -> Vec<SlaveInfo>,
    ) -> Result<SlaveAddress, ApiError> {
        match self {
            SlaveName::Address(address) => Ok(address),
            SlaveName::AliasOffset { alias, offset } => {
                let slaves = slaves();
                let base = slaves
                    .iter()
                    .find(|s| alias != 0 && s.alias == alias)
                    .ok_or_else(|| {
                        ApiError::unknown_slave(format!("no slave has alias {alias:#06x}"))
                    })?;
                let position = base
                    .position
                    .checked_add(offset)
                    .filter(|p| slaves.iter().any(|s| s.position == *p))
                    .ok_or_else(|| {
                        ApiError::unknown_slave(format!(
                            "no slave {offset} positions after alias {alias:#06x}"
                        ))
                    })?;
                Ok(SlaveAddress::Position(position))
            }
        }
    }
}

/// The name in the syntax it was parsed from (positions plain, `station:`, `alias:`), for
/// audit lines and messages.
impl std::fmt::Display for SlaveName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SlaveName::Address(SlaveAddress::Position(p)) => write!(f, "{p}"),
            SlaveName::Address(SlaveAddress::Station(s)) => write!(f, "station:{s}"),
            SlaveName::Address(SlaveAddress::Alias(a)) => write!(f, "alias:{a:#06x}"),
            SlaveName::AliasOffset { alias, offset } => write!(f, "alias:{alias:#06x}+{offset}"),
        }
    }
}

impl std::str::FromStr for SlaveName {
    type Err = ApiError;

    fn from_str(text: &str) -> Result<SlaveName, ApiError> {
        parse_name(text)
    }
}

fn bad(text: &str) -> ApiError {
    ApiError::invalid_field(
        "slave",
        format!(
            "bad slave name {text:?}: use pos:3 (or 3), station:1004 (or #1004), alias:0x777 \
             (or @0x777) or alias:0x777+2 (or 0x777:2)"
        ),
    )
}

/// Parses a slave name; see the [module documentation](self).
pub fn parse_name(text: &str) -> Result<SlaveName, ApiError> {
    let text = text.trim();
    let number = |digits: &str| parse_u16(digits.trim()).ok_or_else(|| bad(text));
    let alias = |rest: &str| -> Result<SlaveName, ApiError> {
        match rest.split_once('+') {
            Some((alias, offset)) => Ok(alias_offset(number(alias)?, number(offset)?)),
            None => Ok(SlaveName::Address(SlaveAddress::Alias(number(rest)?))),
        }
    };
    if let Some(rest) = text.strip_prefix("pos:") {
        Ok(SlaveName::Address(SlaveAddress::Position(number(rest)?)))
    } else if let Some(rest) = text
        .strip_prefix("station:")
        .or_else(|| text.strip_prefix('#'))
    {
        Ok(SlaveName::Address(SlaveAddress::Station(number(rest)?)))
    } else if let Some(rest) = text
        .strip_prefix("alias:")
        .or_else(|| text.strip_prefix('@'))
    {
        alias(rest)
    } else if let Some((alias, offset)) = text.split_once(':') {
        Ok(alias_offset(number(alias)?, number(offset)?))
    } else {
        Ok(SlaveName::Address(SlaveAddress::Position(number(text)?)))
    }
}

fn alias_offset(alias: u16, offset: u16) -> SlaveName {
    // Alias 0 in IgH's `alias:relpos` means "no alias": the position counts from the start.
    match (alias, offset) {
        (0, position) => SlaveName::Address(SlaveAddress::Position(position)),
        (alias, 0) => SlaveName::Address(SlaveAddress::Alias(alias)),
        (alias, offset) => SlaveName::AliasOffset { alias, offset },
    }
}

/// Parses a slave name that needs no scan to resolve (every form but `alias:relpos` with a
/// non-zero offset, which [`parse_name`] and [`SlaveName::resolve`] handle).
pub fn parse_slave(text: &str) -> Result<SlaveAddress, ApiError> {
    match parse_name(text)? {
        SlaveName::Address(address) => Ok(address),
        SlaveName::AliasOffset { .. } => Err(bad(text)),
    }
}

fn parse_u16(digits: &str) -> Option<u16> {
    crate::input::value::parse_number::<u16>(digits, "slave").ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn address(text: &str) -> SlaveAddress {
        match parse_name(text).unwrap() {
            SlaveName::Address(address) => address,
            other => panic!("{text:?} gave {other:?}"),
        }
    }

    #[test]
    fn each_form_parses() {
        assert_eq!(address("3"), SlaveAddress::Position(3));
        assert_eq!(address("0x10"), SlaveAddress::Position(16));
        assert_eq!(address("pos:3"), SlaveAddress::Position(3));
        assert_eq!(address("#1004"), SlaveAddress::Station(1004));
        assert_eq!(address("#0x3ec"), SlaveAddress::Station(0x3ec));
        assert_eq!(address("station:1004"), SlaveAddress::Station(1004));
        assert_eq!(address("@0x777"), SlaveAddress::Alias(0x777));
        assert_eq!(address("alias:0x777"), SlaveAddress::Alias(0x777));
        assert_eq!(address(" @5 "), SlaveAddress::Alias(5));
        assert_eq!(address("0:4"), SlaveAddress::Position(4));
        assert_eq!(address("alias:0x777+0"), SlaveAddress::Alias(0x777));
        assert_eq!(
            parse_name("alias:0x777+2").unwrap(),
            SlaveName::AliasOffset {
                alias: 0x777,
                offset: 2
            }
        );
        assert_eq!(
            parse_name("1911:1").unwrap(),
            SlaveName::AliasOffset {
                alias: 1911,
                offset: 1
            }
        );
    }

    #[test]
    fn a_name_prints_in_a_form_that_parses_back() {
        for text in ["3", "station:1004", "alias:0x0777", "alias:0x0777+2"] {
            let name: SlaveName = text.parse().unwrap();
            assert_eq!(name.to_string(), text);
        }
        assert_eq!(parse_name("#0x3ec").unwrap().to_string(), "station:1004");
    }

    #[test]
    fn junk_is_refused() {
        for bad in [
            "",
            "#",
            "@",
            "x3",
            "70000",
            "#0xg",
            "-1",
            "3.0",
            "pos:",
            "station:x",
            "alias:1+",
            "alias:+1",
            "pos:1+1",
            "1:2:3",
            "foo:3",
        ] {
            assert!(parse_name(bad).is_err(), "{bad:?} accepted");
        }
        let err = parse_name("foo:3").unwrap_err();
        assert_eq!(err.field, Some("slave"));
        assert_eq!(err.kind, crate::error::ErrorKind::InvalidArgument);
    }
}
