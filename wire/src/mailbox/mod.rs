//! The mailbox layer (spec-notes §mbx.header): header, error reply, and messages decoded by protocol type.

pub mod error_reply;
pub mod header;
pub mod message;

pub use error_reply::{ERROR_REPLY_LEN, ErrorReply, ErrorReplyRepr, MailboxErrorCode, error_reply};
pub use header::{HEADER_LEN, Mailbox, MailboxHeader, MailboxType};
pub use message::{MailboxMessage, MailboxPayload};
