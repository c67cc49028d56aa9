//! The call in progress: the transport opens a slot for each call ([`Scope`]), its
//! authentication notes the caller there ([`note_caller`]), and whatever the call runs can
//! ask who it is for ([`caller`]): the core's audit lines ([`crate::service::admission`]) and
//! the log line of a failed transfer name it. Also the value digest the audit lines carry
//! ([`describe`]).

use std::future::Future;
use std::sync::{Arc, Mutex};

use sha2::{Digest, Sha256};

/// Hex digits of the SHA-256 digest shown: enough to tell two values apart in a log.
const DIGEST_PREFIX: usize = 16;

/// Who makes a call, and what it is: for the log lines of a call that failed.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Call {
    /// Token name of the caller (`anonymous` on loopback without tokens).
    pub caller: String,
    /// The call (`GET /slaves/0/foe/fw.bin`, `/ecat.v1.FoeService/Read`, ...).
    pub operation: String,
}

/// What one call notes: its caller once authenticated.
#[derive(Debug, Default)]
struct Notes {
    caller: Option<Call>,
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
            },
        )
    }
}

/// `task` with the current call's caller, for a task the call spawns (a streamed answer):
/// task-locals do not cross `tokio::spawn`.
pub fn carry<F: Future>(task: F) -> impl Future<Output = F::Output> {
    let notes = Notes { caller: caller() };
    CALL.scope(Arc::new(Mutex::new(notes)), task)
}

fn with_notes(update: impl FnOnce(&mut Notes)) {
    let _ = CALL.try_with(|slot| update(&mut slot.lock().unwrap_or_else(|e| e.into_inner())));
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

/// Size and SHA-256 prefix of `data`.
pub fn describe(data: &[u8]) -> (usize, String) {
    let digest = hex::encode(Sha256::digest(data));
    (data.len(), digest[..DIGEST_PREFIX].to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_value_is_described_by_its_size_and_digest_prefix() {
        // SHA-256("abc") = ba7816bf8f01cfea...
        assert_eq!(describe(b"abc"), (3, "ba7816bf8f01cfea".into()));
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
        // Outside a call, noting is harmless and nobody is the caller.
        note_caller("eng", "x");
        assert_eq!(caller(), None);
    }
}
