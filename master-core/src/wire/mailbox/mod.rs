//! The mailbox layer (digest §5): header, error reply, and dispatch by protocol type.

pub mod header;

pub use header::{HEADER_LEN, Mailbox, MailboxHeader, MailboxType};
