//! What can go wrong when attached to ecatd.

use std::fmt;

/// An error of the application interface.
#[derive(Debug)]
pub enum Error {
    /// The socket or a kernel call failed.
    Io(std::io::Error),
    /// ecatd refused the request, with its reason (e.g. `owned pid=12 uid=0`).
    Refused(String),
    /// ecatd sent something this library does not understand, or a region that is not one.
    Protocol(String),
    /// No cycle completed within the time given.
    Timeout,
    /// A new layout generation replaced the one this program attached to: attach again.
    LayoutChanged(u32),
    /// The watchdog (or ecatd) took the outputs back; claim again to own them.
    Watchdog,
    /// ecatd closed the connection (it stopped, or detached this program).
    Closed,
    /// The layout has no such entry.
    NoSuchEntry {
        /// Ring position asked for.
        slave: u16,
        /// Index asked for.
        index: u16,
        /// Subindex asked for.
        subindex: u8,
    },
    /// The entry is an input: only outputs can be written.
    NotOutput,
    /// The value does not fit the entry's type and bits.
    OutOfRange(i64),
    /// Commit without owning the outputs.
    NotOwner,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Io(err) => write!(f, "{err}"),
            Error::Refused(reason) => write!(f, "refused by ecatd: {reason}"),
            Error::Protocol(what) => write!(f, "protocol error: {what}"),
            Error::Timeout => f.write_str("no cycle within the timeout"),
            Error::LayoutChanged(generation) => {
                write!(f, "layout changed (generation {generation}): attach again")
            }
            Error::Watchdog => f.write_str("the outputs were taken back (watchdog): claim again"),
            Error::Closed => f.write_str("ecatd closed the connection"),
            Error::NoSuchEntry {
                slave,
                index,
                subindex,
            } => write!(
                f,
                "slave {slave} maps no entry 0x{index:04X}:{subindex:02X}"
            ),
            Error::NotOutput => f.write_str("the entry is an input"),
            Error::OutOfRange(value) => write!(f, "{value} does not fit the entry"),
            Error::NotOwner => f.write_str("this program does not own the outputs: claim first"),
        }
    }
}

impl std::error::Error for Error {}

impl From<std::io::Error> for Error {
    fn from(err: std::io::Error) -> Error {
        Error::Io(err)
    }
}
