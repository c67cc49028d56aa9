//! Bearer tokens with read and write roles, shared by gRPC and REST.
//!
//! Without configured tokens every caller may read and write (ecatd then refuses to listen
//! on a non-loopback address unless `--insecure`). With tokens every API call needs one
//! (`authorization: Bearer <token>`); writes and state changes need a write token. Every
//! write is logged on the `audit` target with the caller's token name.
//!
//! This is the transport-neutral half; `grpc::auth` and `http::auth` put it in front of
//! their calls.

use serde::{Deserialize, Serialize};

use crate::service::ApiError;

/// What a token may do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Read-only calls.
    Read,
    /// Everything.
    Write,
}

/// One configured token.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Token {
    /// Who holds it (shows in the audit log; the secret never does).
    pub name: String,
    /// The secret.
    pub token: String,
    /// Its role.
    pub role: Role,
}

/// The identity of a request, attached by the authentication layer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Caller {
    /// Token name, or `anonymous` when no tokens are configured.
    pub name: String,
    /// Role.
    pub role: Role,
}

/// The configured tokens.
#[derive(Debug, Clone, Default)]
pub struct Tokens {
    tokens: Vec<Token>,
}

impl Tokens {
    /// The token set.
    pub fn new(tokens: Vec<Token>) -> Tokens {
        Tokens { tokens }
    }

    /// Whether any token is configured.
    pub fn enabled(&self) -> bool {
        !self.tokens.is_empty()
    }

    /// Who sends `authorization` (the header's value, if any).
    pub fn authenticate(&self, authorization: Option<&str>) -> Result<Caller, ApiError> {
        if !self.enabled() {
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
        self.tokens
            .iter()
            .find(|t| constant_time_eq(t.token.as_bytes(), secret.as_bytes()))
            .map(|t| Caller {
                name: t.name.clone(),
                role: t.role,
            })
            .ok_or_else(|| ApiError::unauthenticated("unknown token"))
    }
}

fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// Checks that `caller` may write and logs the audit line for `operation` on `target`.
pub fn authorize_write(
    caller: Option<&Caller>,
    operation: &str,
    target: &str,
) -> Result<(), ApiError> {
    let caller = caller.ok_or_else(|| ApiError::unauthenticated("a bearer token is required"))?;
    if caller.role < Role::Write {
        tracing::warn!(target: "audit", caller = %caller.name, operation, target, "write refused: read-only token");
        return Err(ApiError::permission_denied(format!(
            "{operation} needs a write token"
        )));
    }
    tracing::info!(target: "audit", caller = %caller.name, operation, target, "write");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tokens() -> Tokens {
        Tokens::new(vec![
            Token {
                name: "r".into(),
                token: "read-secret".into(),
                role: Role::Read,
            },
            Token {
                name: "w".into(),
                token: "write-secret".into(),
                role: Role::Write,
            },
        ])
    }

    #[test]
    fn roles_decide() {
        let t = tokens();
        assert_eq!(t.authenticate(None).unwrap_err().kind.http(), 401);
        assert_eq!(
            t.authenticate(Some("Bearer nope")).unwrap_err().kind.http(),
            401
        );
        let reader = t.authenticate(Some("Bearer read-secret")).unwrap();
        assert_eq!(
            authorize_write(Some(&reader), "x", "0")
                .unwrap_err()
                .kind
                .http(),
            403
        );
        let writer = t.authenticate(Some("Bearer write-secret")).unwrap();
        assert!(authorize_write(Some(&writer), "x", "0").is_ok());
        let open = Tokens::default().authenticate(None).unwrap();
        assert_eq!(open.role, Role::Write);
    }
}
