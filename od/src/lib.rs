//! The CoE object dictionary and the SDO server that answers mailbox requests against it.
//!
//! One server for two users: every simulated CoE slave, and the master's own ETG.1510
//! dictionary (mailbox gateway address 0). Neither is known here.
//!
//! - [`object`]: the model — [`Object`]s (VAR/ARRAY/RECORD) of [`Entry`]s, values as CoE
//!   bytes;
//! - [`dictionary`]: the [`Dictionary`] trait the server works against;
//! - [`static_dictionary`], [`builder`], [`standard`], [`hooks`]: an in-memory dictionary,
//!   declared in code, with the standard objects and write hooks;
//! - [`access`], [`check`]: access rights per AL state and value checks (abort codes);
//! - [`value`]: typed values ⇄ bytes by data type;
//! - [`packing`]: the complete-access image (strings at their declared length);
//! - [`server`]: [`SdoServer`], the per-client SDO / SDO Information state machine;
//! - [`emergency`]: emergency messages for the owner to post.

pub mod access;
pub mod builder;
pub mod check;
pub mod dictionary;
pub mod emergency;
pub mod hooks;
pub mod object;
pub mod packing;
pub mod server;
pub mod standard;
pub mod static_dictionary;
pub mod value;

pub use builder::{BuildError, DictionaryBuilder, ObjectBuilder};
pub use dictionary::{DictEntryInfo, DictObjectInfo, Dictionary, EntryWrite};
pub use hooks::{WriteEvent, WriteHook};
pub use object::{Entry, Object};
pub use server::{MIN_MAILBOX_SIZE, Outcome, SdoServer, ServerContext};
pub use standard::{Identity, PdoEntry, SmType};
pub use static_dictionary::{OdError, StaticDictionary};
pub use value::{DecodeValue, EncodeValue, ValueError};
