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

/// Who makes a call, and what it is: for the log lines of a call that failed.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Call {
    /// Token name of the caller (`anonymous` on loopback without tokens).
    pub caller: String,
    /// The call (`GET /slaves/0/foe/fw.bin`, `/ecat.v1.FoeService/Read`, ...).
    pub operation: String,
}

/// What one call notes: its caller once authenticated, and the write it made.
#[derive(Debug, Default)]
struct Notes {
    caller: Option<Call>,
    write: Option<Write>,
}

type Slot = Arc<Mutex<Notes>>;

tokio::task_local! {
    static CALL: Slot;
}

/// What a finished call noted.
#[derive(Debug, Default)]
pub struct Noted {
    /// Its caller, once authenticated.
    pub caller: Option<Call>,
    /// The write it made.
    pub write: Option<Write>,
}

/// Runs `call` with a slot for the write it may note; returns its output and the write.
pub async fn scoped<F: Future>(call: F) -> (F::Output, Option<Write>) {
    let (output, noted) = Scope::default().run(call).await;
    (output, noted.write)
}

/// The slot of one call, opened before the call is made: a tower service that
/// authenticates in `call` itself (tonic's interceptors) notes its caller while the call's
/// future is made ([`Scope::make`]), before it runs ([`Scope::run`]).
#[derive(Debug, Default)]
pub struct Scope(Slot);

impl Scope {
    /// Runs `make`, which makes the call's future, inside the slot.
    pub fn make<F>(&self, make: impl FnOnce() -> F) -> F {
        CALL.sync_scope(Arc::clone(&self.0), make)
    }

    /// Runs `call` inside the slot; its output and all it noted.
    pub async fn run<F: Future>(self, call: F) -> (F::Output, Noted) {
        let output = CALL.scope(Arc::clone(&self.0), call).await;
        let notes = std::mem::take(&mut *self.0.lock().unwrap_or_else(|e| e.into_inner()));
        (
            output,
            Noted {
                caller: notes.caller,
                write: notes.write,
            },
        )
    }
}

/// `task` with the current call's caller, for a task the call spawns (a streamed answer):
/// task-locals do not cross `tokio::spawn`. Writes it notes stay its own.
pub fn carry<F: Future>(task: F) -> impl Future<Output = F::Output> {
    let notes = Notes {
        caller: caller(),
        write: None,
    };
    CALL.scope(Arc::new(Mutex::new(notes)), task)
}

fn with_notes(update: impl FnOnce(&mut Notes)) {
    let _ = CALL.try_with(|slot| update(&mut slot.lock().unwrap_or_else(|e| e.into_inner())));
}

fn with_slot(update: impl FnOnce(&mut Option<Write>)) {
    with_notes(|notes| update(&mut notes.write));
}

/// Notes who makes the current call (the authentication layers, once they know).
pub fn note_caller(name: &str, operation: &str) {
    with_notes(|notes| {
        notes.caller = Some(Call {
            caller: name.into(),
            operation: operation.into(),
        });
    });
}

/// Who makes the current call, if a transport noted it.
pub fn caller() -> Option<Call> {
    CALL.try_with(|slot| {
        slot.lock()
            .unwrap_or_else(|e| e.into_inner())
            .caller
            .clone()
    })
    .ok()
    .flatten()
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
        note_caller("eng", "x");
        assert_eq!(caller(), None);
    }

    #[tokio::test]
    async fn a_call_knows_its_caller_even_noted_while_the_call_is_made() {
        let scope = Scope::default();
        let call = scope.make(|| {
            // As an interceptor does, before the call's future runs.
            note_caller("scada", "/ecat.v1.FoeService/Read");
            async { caller() }
        });
        let (seen, noted) = scope.run(call).await;
        assert_eq!(
            seen,
            Some(Call {
                caller: "scada".into(),
                operation: "/ecat.v1.FoeService/Read".into()
            })
        );
        assert_eq!(noted.caller, seen);
        assert!(noted.write.is_none());
    }
}
