//! Bearer tokens with read and write roles, shared by gRPC and REST.
//!
//! Without configured tokens every caller may read and write (ecatd then refuses to listen
//! on a non-loopback address unless `--insecure`). With tokens every API call needs one
//! (`authorization: Bearer <token>`); writes and state changes need a write token, which the
//! core checks and audits ([`crate::service::admission`]).
//!
//! This is the transport-neutral half; `grpc::auth` and `http::auth` authenticate every call
//! with it.

use std::sync::{Arc, RwLock};

pub use crate::config::tokens::{MIN_SECRET_LEN, Role, Token};
use crate::error::ApiError;

/// The identity of a request, attached by the authentication layer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Caller {
    /// Token name, or `anonymous` when no tokens are configured.
    pub name: String,
    /// Role.
    pub role: Role,
}

/// The configured tokens. Clones share one set, which [`Tokens::replace`] swaps (SIGHUP).
#[derive(Debug, Clone, Default)]
pub struct Tokens {
    tokens: Arc<RwLock<Arc<Vec<Token>>>>,
}

impl Tokens {
    /// The token set.
    pub fn new(tokens: Vec<Token>) -> Tokens {
        Tokens {
            tokens: Arc::new(RwLock::new(Arc::new(tokens))),
        }
    }

    /// The current set (a snapshot: a reload does not change it under the caller).
    fn current(&self) -> Arc<Vec<Token>> {
        // A panic while holding the lock cannot leave the set half-written (it is swapped
        // whole), so a poisoned lock still holds a valid set.
        Arc::clone(&self.tokens.read().unwrap_or_else(|e| e.into_inner()))
    }

    /// Swaps in a new set for every clone; calls already authenticated keep their caller.
    pub fn replace(&self, tokens: Vec<Token>) {
        *self.tokens.write().unwrap_or_else(|e| e.into_inner()) = Arc::new(tokens);
    }

    /// Whether any token is configured.
    pub fn enabled(&self) -> bool {
        !self.current().is_empty()
    }

    /// How many tokens are configured.
    pub fn len(&self) -> usize {
        self.current().len()
    }

    /// Whether no token is configured.
    pub fn is_empty(&self) -> bool {
        !self.enabled()
    }

    /// Who sends `authorization` (the header's value, if any).
    pub fn authenticate(&self, authorization: Option<&str>) -> Result<Caller, ApiError> {
        let tokens = self.current();
        if tokens.is_empty() {
            return Ok(Caller {
                name: "anonymous".into(),
                role: Role::Write,
            });
        }
        let secret = authorization
            .and_then(|v| {
                v.strip_prefix("Bearer ")
                    .or_else(|| v.strip_prefix("bearer "))
            })
            .map(str::trim)
            .ok_or_else(|| ApiError::unauthenticated("a bearer token is required"))?;
        tokens
            .iter()
            .find(|t| constant_time_eq(t.token.as_bytes(), secret.as_bytes()))
            .map(|t| Caller {
                name: t.name.clone(),
                role: t.role,
            })
            .ok_or_else(|| ApiError::unauthenticated("unknown token"))
    }
}

/// Compares a presented secret with a configured one in time that does not depend on where
/// they differ (`subtle`); only the length shows, which the token rules already bound.
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    use subtle::ConstantTimeEq;
    a.ct_eq(b).into()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tokens() -> Tokens {
        Tokens::new(vec![
            Token {
                name: "r".into(),
                token: "read-secret".into(),
                secret_file: None,
                secret_env: None,
                role: Role::Read,
            },
            Token {
                name: "w".into(),
                token: "write-secret".into(),
                secret_file: None,
                secret_env: None,
                role: Role::Write,
            },
        ])
    }

    #[test]
    fn tokens_name_their_caller_and_role() {
        let t = tokens();
        assert_eq!(t.authenticate(None).unwrap_err().kind.http(), 401);
        assert_eq!(
            t.authenticate(Some("Bearer nope")).unwrap_err().kind.http(),
            401
        );
        let reader = t.authenticate(Some("Bearer read-secret")).unwrap();
        assert_eq!((reader.name.as_str(), reader.role), ("r", Role::Read));
        let writer = t.authenticate(Some("Bearer write-secret")).unwrap();
        assert_eq!((writer.name.as_str(), writer.role), ("w", Role::Write));
        let open = Tokens::default().authenticate(None).unwrap();
        assert_eq!(open.role, Role::Write);
    }
}
