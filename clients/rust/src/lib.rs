//! A control program's side of ecatd's application interface (docs/application.md): attach
//! over the Unix socket, follow the cycle through the shared process image, own the outputs
//! and commit them whole.
//!
//! ```no_run
//! use ecat_app::{App, Direction};
//! # fn main() -> Result<(), ecat_app::Error> {
//! let mut app = App::connect(None, false)?;
//! let input = app.entry(2, 0x6000, 1)?;
//! let output = app.entry(1, 0x7000, 1)?;
//! app.claim()?;
//! loop {
//!     app.wait(std::time::Duration::from_secs(1))?;
//!     let value = app.read(&input);
//!     app.write(&output, value)?;
//!     app.commit()?;
//! #   break;
//! }
//! # Ok(()) }
//! ```
//!
//! The layout of the shared memory (`shm`) and the socket's lines (`protocol`) are defined
//! here once; ecatd's server uses the same definitions.

mod client;
pub mod entry;
mod error;
pub mod fd_passing;
pub mod protocol;
pub mod shm;

pub use client::App;
pub use entry::{Direction, Entry};
pub use error::Error;

/// The socket ecatd serves when it is run as a system service, and where a program
/// attaches when it names none and `$ECAT_APP_SOCKET` is not set.
pub const SYSTEM_SOCKET: &str = "/run/ecatd/app.sock";

/// The socket a program attaches to when it names none: `$ECAT_APP_SOCKET`, else
/// [`SYSTEM_SOCKET`].
pub fn default_socket() -> std::path::PathBuf {
    std::env::var_os("ECAT_APP_SOCKET").map_or_else(|| SYSTEM_SOCKET.into(), Into::into)
}
