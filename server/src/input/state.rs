//! AL states as callers write them: `INIT`, `PREOP`, `BOOT`, `SAFEOP`, `OP`, in any case,
//! with or without a dash (`pre-op`, `Safe_Op`). The names are master-core's
//! ([`AlState::name`]); this file only reads them.

use master_core::wire::register::AlState;

use crate::error::ApiError;

/// The state `name` names.
pub fn parse_state(name: &str) -> Result<AlState, ApiError> {
    let wanted = name.to_ascii_uppercase().replace(['-', '_'], "");
    AlState::ALL
        .into_iter()
        .find(|state| state.name() == wanted)
        .ok_or_else(|| {
            ApiError::invalid_field(
                "state",
                format!("unknown AL state {name:?}: use INIT, PREOP, BOOT, SAFEOP or OP"),
            )
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_and_its_spellings_parse_and_nothing_else_does() {
        for state in AlState::ALL {
            assert_eq!(parse_state(state.name()).unwrap(), state);
            assert_eq!(parse_state(&state.name().to_lowercase()).unwrap(), state);
        }
        assert_eq!(parse_state("Pre-Op").unwrap(), AlState::PreOp);
        assert_eq!(parse_state("safe_op").unwrap(), AlState::SafeOp);
        for bad in ["", "unknown", "PREOPS", "0x8", "OPERATIONAL"] {
            let err = parse_state(bad).unwrap_err();
            assert_eq!(
                err.kind,
                crate::error::ErrorKind::InvalidArgument,
                "{bad:?}"
            );
        }
    }
}
