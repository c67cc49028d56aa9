//! The Python masters (pysoem, kickcat) from the venv `scripts/test` installs.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::netns::NetNs;

/// The variable naming the venv's python (`scripts/test` exports it).
pub const PYTHON_VAR: &str = "ECATD_PYTHON";

/// Where `scripts/test` puts the venv, relative to the workspace root.
pub const DEFAULT_VENV_PYTHON: &str = "target/pyenv/bin/python";

/// The python that has pysoem and kickcat: `$ECATD_PYTHON`, else the venv `scripts/test`
/// makes under `target/pyenv`.
///
/// # Panics
/// If neither exists, with a message that says how to install it.
pub fn python() -> PathBuf {
    let path = match std::env::var_os(PYTHON_VAR) {
        Some(p) => PathBuf::from(p),
        None => Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("..")
            .join(DEFAULT_VENV_PYTHON),
    };
    assert!(
        path.is_file(),
        "no Python with pysoem and kickcat at {}: run scripts/test (it creates the venv \
         target/pyenv with the pinned versions and exports {PYTHON_VAR}), or set {PYTHON_VAR}",
        path.display()
    );
    path
}

/// The path of a check script in `tests/py/`.
pub fn script(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("py").join(name)
}

/// Runs `tests/py/<name> <args>` inside `ns` and parses the last line of its stdout as
/// JSON (the libraries may print their own lines before it).
///
/// # Panics
/// If the script fails or prints no JSON, with its output.
pub fn run_script(ns: &NetNs, name: &str, args: &[&str]) -> serde_json::Value {
    let output = Command::new("ip")
        .args(["netns", "exec", ns.name()])
        .arg(python())
        .arg(script(name))
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {name} through `ip netns exec`: {e}"));
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "{name} failed ({}):\nstdout:\n{stdout}\nstderr:\n{stderr}",
        output.status
    );
    let last = stdout
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("");
    serde_json::from_str(last)
        .unwrap_or_else(|e| panic!("{name} printed no JSON ({e}):\n{stdout}\nstderr:\n{stderr}"))
}
