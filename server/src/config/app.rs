//! `[app]`: the application interface, where a control program in another process attaches
//! to the cycle (docs/application.md).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// The most attachments `max_clients` allows (each costs an eventfd write per cycle on the
/// bus thread).
pub const MAX_CLIENTS: usize = 64;

/// What ecatd does when the owner's watchdog runs out, besides the safe outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OnWatchdog {
    /// Nothing more: the slaves stay in their state with the safe outputs.
    #[default]
    Keep,
    /// Request SAFEOP for every slave with outputs.
    Safeop,
}

/// The safe value of one output entry (`[[app.safe_output]]`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SafeOutput {
    /// The slave, in the common syntax (`3`, `pos:3`, `station:1004`).
    pub slave: String,
    /// Object index of the output entry.
    pub index: u16,
    /// Its subindex.
    pub subindex: u8,
    /// The value (an integer within the entry's type).
    pub value: i64,
}

/// The application interface's settings.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AppSettings {
    /// Serve the application interface at all.
    pub enabled: bool,
    /// The Unix socket programs attach to; absent: `$RUNTIME_DIRECTORY/app.sock`, else
    /// `/run/ecatd/app.sock` as root, else `$XDG_RUNTIME_DIR/ecatd/app.sock`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub socket: Option<PathBuf>,
    /// The socket's permission bits, octal (who may attach).
    pub mode: String,
    /// The socket's group, a name or a number; absent: ecatd's own.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
    /// Cycles the owner may go without a commit before the safe outputs.
    pub watchdog: u32,
    /// What else happens when the watchdog runs out.
    pub on_watchdog: OnWatchdog,
    /// Attachments at once, the owner and monitors together.
    pub max_clients: usize,
    /// Safe values of output entries (every other output's is zero).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub safe_output: Vec<SafeOutput>,
}

impl Default for AppSettings {
    fn default() -> AppSettings {
        AppSettings {
            enabled: true,
            socket: None,
            mode: "0660".into(),
            group: None,
            watchdog: 10,
            on_watchdog: OnWatchdog::Keep,
            max_clients: 16,
            safe_output: Vec::new(),
        }
    }
}

impl AppSettings {
    /// Refuses settings that cannot work.
    pub fn check(&self) -> Result<(), String> {
        self.mode_bits()?;
        if self.watchdog == 0 {
            return Err("[app] watchdog must be at least 1 cycle".into());
        }
        if !(1..=MAX_CLIENTS).contains(&self.max_clients) {
            return Err(format!(
                "[app] max_clients = {} must be 1..={MAX_CLIENTS}",
                self.max_clients
            ));
        }
        Ok(())
    }

    /// The socket's mode as a number.
    pub fn mode_bits(&self) -> Result<u32, String> {
        u32::from_str_radix(self.mode.trim_start_matches("0o"), 8)
            .ok()
            .filter(|m| *m <= 0o777)
            .ok_or_else(|| format!("[app] mode = {:?} is not octal permission bits", self.mode))
    }

    /// The socket to serve: the configured one, else the default for a process of `uid`
    /// with the given runtime directories.
    pub fn socket_path(
        &self,
        uid: u32,
        runtime_directory: Option<std::ffi::OsString>,
        xdg_runtime_dir: Option<std::ffi::OsString>,
    ) -> PathBuf {
        if let Some(path) = &self.socket {
            return path.clone();
        }
        if let Some(dir) = runtime_directory {
            return PathBuf::from(dir).join("app.sock");
        }
        match xdg_runtime_dir {
            Some(dir) if uid != 0 => PathBuf::from(dir).join("ecatd").join("app.sock"),
            _ => PathBuf::from("/run/ecatd/app.sock"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_socket_follows_the_service_and_the_user() {
        let s = AppSettings::default();
        assert_eq!(
            s.socket_path(0, Some("/run/ecatd".into()), None),
            PathBuf::from("/run/ecatd/app.sock")
        );
        assert_eq!(
            s.socket_path(0, None, Some("/run/user/0".into())),
            PathBuf::from("/run/ecatd/app.sock")
        );
        assert_eq!(
            s.socket_path(1000, None, Some("/run/user/1000".into())),
            PathBuf::from("/run/user/1000/ecatd/app.sock")
        );
        let given = AppSettings {
            socket: Some("/tmp/a.sock".into()),
            ..AppSettings::default()
        };
        assert_eq!(
            given.socket_path(0, Some("/x".into()), None),
            PathBuf::from("/tmp/a.sock")
        );
    }

    #[test]
    fn bad_settings_are_refused_with_the_setting_named() {
        let bad_mode = AppSettings {
            mode: "rw-rw----".into(),
            ..AppSettings::default()
        };
        assert!(bad_mode.check().unwrap_err().contains("mode"));
        let no_watchdog = AppSettings {
            watchdog: 0,
            ..AppSettings::default()
        };
        assert!(no_watchdog.check().unwrap_err().contains("watchdog"));
        let many = AppSettings {
            max_clients: 65,
            ..AppSettings::default()
        };
        assert!(many.check().unwrap_err().contains("max_clients"));
        assert_eq!(AppSettings::default().mode_bits(), Ok(0o660));
        let parsed: AppSettings = toml::from_str(
            "watchdog = 5\non_watchdog = \"safeop\"\n[[safe_output]]\nslave = \"pos:1\"\nindex = 0x7000\nsubindex = 1\nvalue = 1\n",
        )
        .unwrap();
        assert_eq!(parsed.on_watchdog, OnWatchdog::Safeop);
        assert_eq!(parsed.safe_output[0].index, 0x7000);
    }
}
