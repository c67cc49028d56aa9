//! Naming a slave: by ring position, station address or alias (spec-notes §addressing, §sii.alias).

use core::fmt;

/// How a caller names a slave. Resolved against the slaves of the last scan; an address no
/// scanned slave has gives [`MasterError::UnknownSlave`](crate::master::MasterError::UnknownSlave).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SlaveAddress {
    /// Ring position, 0 next to the master.
    Position(u16),
    /// Configured station address (0x0010), as the master assigned it.
    Station(u16),
    /// Configured station alias (0x0012, from SII word 4); 0 means "no alias" and never
    /// resolves.
    Alias(u16),
}

impl fmt::Display for SlaveAddress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SlaveAddress::Position(p) => write!(f, "position {p}"),
            SlaveAddress::Station(s) => write!(f, "station {s:#06x}"),
            SlaveAddress::Alias(a) => write!(f, "alias {a:#06x}"),
        }
    }
}

/// What an address is checked against: (position, station, alias) of each slave.
pub(crate) fn resolve<'a, T: 'a>(
    address: SlaveAddress,
    slaves: impl IntoIterator<Item = (&'a T, u16, u16, u16)>,
) -> Option<&'a T> {
    slaves
        .into_iter()
        .find(|&(_, position, station, alias)| match address {
            SlaveAddress::Position(p) => p == position,
            SlaveAddress::Station(s) => s == station,
            SlaveAddress::Alias(a) => a != 0 && a == alias,
        })
        .map(|(slave, ..)| slave)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolves_each_form_and_never_alias_zero() {
        let slaves = [("a", 0u16, 1001u16, 0u16), ("b", 1, 1002, 0x77)];
        let find = |address| resolve(address, slaves.iter().map(|(n, p, s, a)| (n, *p, *s, *a)));
        assert_eq!(find(SlaveAddress::Position(1)), Some(&"b"));
        assert_eq!(find(SlaveAddress::Station(1001)), Some(&"a"));
        assert_eq!(find(SlaveAddress::Alias(0x77)), Some(&"b"));
        assert_eq!(find(SlaveAddress::Alias(0)), None);
        assert_eq!(find(SlaveAddress::Position(2)), None);
        assert_eq!(SlaveAddress::Station(0x3e9).to_string(), "station 0x03e9");
    }
}
