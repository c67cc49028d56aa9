//! The outcome half of the audit trail: every write leaves one line on the `audit` target
//! with the caller, the operation, its target, the value's size and SHA-256 prefix (when
//! the write carries a value) and the outcome (`done` or the error).
//!
//! The write check ([`crate::security::authorize_write`]) notes who writes what in the
//! slot of the call in progress ([`scoped`]); the transport that opened the slot logs the
//! line once the call has its answer, so a handler cannot forget it.

use std::future::Future;
use std::sync::{Arc, Mutex};

use sha2::{Digest, Sha256};

/// Hex digits of the SHA-256 digest shown: enough to tell two values apart in a log.
const DIGEST_PREFIX: usize = 16;

/// A write noted during a call.
#[derive(Debug, Clone, Default)]
pub struct Write {
    /// Token name of the caller.
    pub caller: String,
    /// What is written (`foe_write`, `PUT /slaves/3/coe/sdo/0x2001/0`, ...).
    pub operation: String,
    /// The slave, file or object written.
    pub target: String,
    /// Size and digest prefix of the value, when the write carries one.
    pub value: Option<(usize, String)>,
}

type Slot = Arc<Mutex<Option<Write>>>;

tokio::task_local! {
    static CALL: Slot;
}

/// Runs `call` with a slot for the write it may note; returns its output and the write.
pub async fn scoped<F: Future>(call: F) -> (F::Output, Option<Write>) {
    let slot = Slot::default();
    let output = CALL.scope(Arc::clone(&slot), call).await;
    let write = slot.lock().unwrap_or_else(|e| e.into_inner()).take();
    (output, write)
}

fn with_slot(update: impl FnOnce(&mut Option<Write>)) {
    let _ = CALL.try_with(|slot| update(&mut slot.lock().unwrap_or_else(|e| e.into_inner())));
}

/// Notes an authorised write in the current call's slot (no slot: nothing to do).
pub fn note(caller: &str, operation: &str, target: &str) {
    with_slot(|slot| {
        let value = slot.take().and_then(|w| w.value);
        *slot = Some(Write {
            caller: caller.into(),
            operation: operation.into(),
            target: target.into(),
            value,
        });
    });
}

/// Notes the value the current call writes (size and digest prefix).
pub fn note_value(data: &[u8]) {
    note_described(describe(data));
}

/// Notes the size and SHA-256 prefix of a value hashed elsewhere (a request body read as it
/// streams), as [`note_value`] does.
pub fn note_described(value: (usize, String)) {
    with_slot(|slot| slot.get_or_insert_with(Write::default).value = Some(value));
}

/// Size and SHA-256 prefix of a value from its running hash.
pub fn describe_hashed(len: usize, hash: Sha256) -> (usize, String) {
    let digest = hex::encode(hash.finalize());
    (len, digest[..DIGEST_PREFIX].to_owned())
}

/// Size and SHA-256 prefix of `data`.
pub fn describe(data: &[u8]) -> (usize, String) {
    let digest = hex::encode(Sha256::digest(data));
    (data.len(), digest[..DIGEST_PREFIX].to_owned())
}

/// Logs the audit line of a finished write: `Ok` for done, `Err` with the error's text.
pub fn outcome(write: &Write, result: Result<(), &str>) {
    let outcome = match result {
        Ok(()) => "done".to_owned(),
        Err(err) => format!("error: {err}"),
    };
    let (size, sha256) = match &write.value {
        Some((size, digest)) => (Some(*size), Some(digest.as_str())),
        None => (None, None),
    };
    tracing::info!(
        target: "audit",
        caller = %write.caller,
        operation = %write.operation,
        target = %write.target,
        size,
        sha256,
        outcome = %outcome,
        "write finished"
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn a_call_notes_its_write_and_value() {
        let ((), write) = scoped(async {
            note_value(b"abc");
            note("eng", "foe_write", "3 fw.bin");
        })
        .await;
        let write = write.unwrap();
        assert_eq!(write.caller, "eng");
        assert_eq!(write.target, "3 fw.bin");
        // SHA-256("abc") = ba7816bf8f01cfea...
        assert_eq!(write.value, Some((3, "ba7816bf8f01cfea".into())));
        let ((), none) = scoped(async {}).await;
        assert!(none.is_none());
        // Outside a call, noting is harmless.
        note("eng", "x", "y");
    }
}
