//! The `[[tokens]]` entries: who may call the APIs, with which role, and where each secret
//! comes from. Checking a caller against them is [`crate::security`]'s job.

use serde::{Deserialize, Serialize};

/// What a token may do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Read-only calls.
    Read,
    /// Everything.
    Write,
}

/// The shortest secret ecatd accepts: shorter ones are guessable by trying.
pub const MIN_SECRET_LEN: usize = 16;

/// One configured token. The secret comes from exactly one of `token` (in the file),
/// `secret_file` (a file holding it; trailing newline ignored) or `secret_env` (an
/// environment variable).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Token {
    /// Who holds it (shows in the audit log; the secret never does).
    pub name: String,
    /// The secret, when given in the configuration itself.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub token: String,
    /// A file holding the secret.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub secret_file: Option<std::path::PathBuf>,
    /// An environment variable holding the secret.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub secret_env: Option<String>,
    /// Its role.
    pub role: Role,
}

impl Token {
    /// Fills `token` from its file or environment variable and checks the secret: exactly
    /// one source, at least [`MIN_SECRET_LEN`] characters. Errors name the token, never
    /// its secret.
    pub fn resolve(&mut self) -> Result<(), String> {
        let name = &self.name;
        let sources = usize::from(!self.token.is_empty())
            + usize::from(self.secret_file.is_some())
            + usize::from(self.secret_env.is_some());
        if sources > 1 {
            return Err(format!(
                "token {name:?}: give only one of token, secret_file and secret_env"
            ));
        }
        if let Some(path) = &self.secret_file {
            let text = std::fs::read_to_string(path).map_err(|err| {
                format!(
                    "token {name:?}: cannot read its secret_file {}: {err}",
                    path.display()
                )
            })?;
            self.token = text.trim_end_matches(['\n', '\r']).to_owned();
        } else if let Some(var) = &self.secret_env {
            self.token = std::env::var(var).map_err(|err| {
                format!("token {name:?}: environment variable {var} of its secret_env: {err}")
            })?;
        }
        if self.token.is_empty() {
            return Err(format!(
                "token {name:?} has an empty secret; give it token, secret_file or secret_env"
            ));
        }
        let len = self.token.chars().count();
        if len < MIN_SECRET_LEN {
            return Err(format!(
                "token {name:?} is too short ({len} characters); use at least {MIN_SECRET_LEN}"
            ));
        }
        Ok(())
    }
}
