//! How `ecatd` ends, as its exit code says to a service manager (documented in
//! `docs/operations.md`, "Exit codes"; `deploy/systemd/ecatd.service` does not restart on
//! the codes a restart cannot mend).

use std::fmt;
use std::process::ExitCode;

/// A command line clap refused (clap's own code).
pub const USAGE: u8 = 2;
/// The configuration is wrong: a bad file or flag, a missing segment, a configuration that
/// does not fit the segment found (`EX_CONFIG` of sysexits.h).
pub const CONFIGURATION: u8 = 78;
/// Anything else that stopped the start or the run: a port taken, an interface missing.
pub const FAILURE: u8 = 1;

/// Why ecatd did not start or stopped with an error.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Failure {
    /// A configuration error: restarting with the same configuration fails the same way.
    Configuration(String),
    /// A failure a restart may mend.
    Runtime(String),
}

impl Failure {
    /// The process exit code of this failure.
    pub fn exit_code(&self) -> ExitCode {
        ExitCode::from(match self {
            Failure::Configuration(_) => CONFIGURATION,
            Failure::Runtime(_) => FAILURE,
        })
    }

    /// Marks a failure as the configuration's.
    pub fn configuration(message: impl Into<String>) -> Failure {
        Failure::Configuration(message.into())
    }
}

impl From<String> for Failure {
    fn from(message: String) -> Failure {
        Failure::Runtime(message)
    }
}

impl From<&str> for Failure {
    fn from(message: &str) -> Failure {
        Failure::Runtime(message.to_owned())
    }
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Failure::Configuration(message) | Failure::Runtime(message) => f.write_str(message),
        }
    }
}

impl std::error::Error for Failure {}
