//! `ecat-sim` as a child process inside a network namespace, stopped on drop.

use std::collections::VecDeque;
use std::io::Write;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::sync::OnceLock;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use crate::netns::NetNs;

/// How long the simulator may take to say it is ready; far more than it needs.
pub const READY_PATIENCE: Duration = Duration::from_secs(30);

/// How long it may take to stop after SIGTERM.
pub const STOP_PATIENCE: Duration = Duration::from_secs(10);

/// The line `ecat-sim` prints on stdout once it answers frames.
pub const READY_PREFIX: &str = "ecat-sim: ready on ";

/// The `ecat-sim` binary of this workspace, built (once per test process) with the profile
/// the tests were built with, so the tests never run a stale simulator.
///
/// # Panics
/// If cargo cannot build it.
pub fn ecat_sim_binary() -> &'static Path {
    static BINARY: OnceLock<PathBuf> = OnceLock::new();
    BINARY.get_or_init(|| {
        let exe = std::env::current_exe().expect("path of the test executable");
        // target/<profile>/deps/<test> → target/<profile>
        let profile_dir = exe
            .parent()
            .and_then(Path::parent)
            .expect("test executable inside target/<profile>/deps")
            .to_path_buf();
        let profile = match profile_dir.file_name().and_then(|n| n.to_str()) {
            Some("debug") | None => "dev".to_owned(),
            Some(other) => other.to_owned(),
        };
        let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("../Cargo.toml");
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
        let output = Command::new(&cargo)
            .arg("build")
            .arg("--manifest-path")
            .arg(&manifest)
            .args(["-p", "sim", "--bin", "ecat-sim", "--profile", &profile])
            .output()
            .unwrap_or_else(|e| panic!("cannot run {cargo} to build ecat-sim: {e}"));
        assert!(
            output.status.success(),
            "building ecat-sim failed:\n{}",
            String::from_utf8_lossy(&output.stderr)
        );
        let binary = profile_dir.join("ecat-sim");
        assert!(
            binary.is_file(),
            "{} missing after the build",
            binary.display()
        );
        binary
    })
}

/// A running `ecat-sim`. Dropping it kills the process if it still runs.
#[derive(Debug)]
pub struct SimProcess {
    child: Child,
    /// What it printed before the ready line (one line per emulated slave, and more).
    pub banner: Vec<String>,
    stderr_path: PathBuf,
    /// Lines printed after the ready line, as the reader thread hands them over.
    lines: mpsc::Receiver<String>,
    /// Lines taken off `lines` while looking for another one.
    backlog: VecDeque<String>,
    /// Its stdin, with `--control`.
    stdin: Option<ChildStdin>,
}

impl SimProcess {
    /// Starts `ecat-sim --iface <iface> <extra>` inside `ns` and waits for its ready line.
    ///
    /// # Panics
    /// If it cannot start, or exits or stays silent instead of becoming ready.
    pub fn start(ns: &NetNs, iface: &str, extra: &[&str]) -> SimProcess {
        SimProcess::spawn(ns, iface, extra, false)
    }

    /// Like [`SimProcess::start`], with `--control`: [`SimProcess::command`] drives the
    /// terminals' inputs and emergencies, [`SimProcess::wait_line`] sees their outputs.
    ///
    /// # Panics
    /// As [`SimProcess::start`].
    pub fn start_controlled(ns: &NetNs, iface: &str, extra: &[&str]) -> SimProcess {
        SimProcess::spawn(ns, iface, extra, true)
    }

    fn spawn(ns: &NetNs, iface: &str, extra: &[&str], control: bool) -> SimProcess {
        let stderr_path = std::env::temp_dir().join(format!(
            "ecat-sim-{}-{}.stderr",
            std::process::id(),
            ns.name()
        ));
        let stderr = std::fs::File::create(&stderr_path).expect("create the stderr file");
        let mut child = Command::new("ip")
            .args(["netns", "exec", ns.name()])
            .arg(ecat_sim_binary())
            .args(["--iface", iface])
            .args(extra)
            .args(if control { &["--control"][..] } else { &[] })
            .stdin(if control {
                Stdio::piped()
            } else {
                Stdio::null()
            })
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start ecat-sim through `ip netns exec`: {e}"));
        let stdout = child.stdout.take().expect("piped stdout");
        let stdin = child.stdin.take();
        // A reader thread hands over lines, so waiting for the ready line has a deadline.
        let (lines_tx, lines_rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if lines_tx.send(line).is_err() {
                    break;
                }
            }
        });
        let mut process = SimProcess {
            child,
            banner: Vec::new(),
            stderr_path,
            lines: lines_rx,
            backlog: VecDeque::new(),
            stdin,
        };
        let deadline = Instant::now() + READY_PATIENCE;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match process.lines.recv_timeout(left) {
                Ok(line) if line.starts_with(READY_PREFIX) => return process,
                Ok(line) => process.banner.push(line),
                Err(_) => panic!(
                    "ecat-sim did not become ready within {READY_PATIENCE:?}; stdout so far: \
                     {:?}; stderr: {}",
                    process.banner,
                    process.stderr()
                ),
            }
        }
    }

    /// Waits up to `patience` for a line printed after the ready line that satisfies
    /// `wanted`, and returns it; lines passed over stay for later calls.
    pub fn wait_line(
        &mut self,
        patience: Duration,
        mut wanted: impl FnMut(&str) -> bool,
    ) -> Option<String> {
        if let Some(at) = self.backlog.iter().position(|line| wanted(line)) {
            return self.backlog.remove(at);
        }
        let deadline = Instant::now() + patience;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let line = self.lines.recv_timeout(left).ok()?;
            if wanted(&line) {
                return Some(line);
            }
            self.backlog.push_back(line);
        }
    }

    /// Forgets the lines printed so far (to wait for new ones only).
    pub fn clear_lines(&mut self) {
        self.backlog.clear();
        while self.lines.try_recv().is_ok() {}
    }

    /// Sends a `--control` command and waits for its answer.
    ///
    /// # Panics
    /// Without `--control`, or if the simulator refuses the command or does not answer.
    pub fn command(&mut self, command: &str) {
        if let Err(refusal) = self.try_command(command) {
            panic!("{command:?}: {refusal}");
        }
    }

    /// Sends a `--control` command and waits for its answer; `Err` holds a refusal.
    ///
    /// # Panics
    /// Without `--control`, or if the simulator does not answer.
    pub fn try_command(&mut self, command: &str) -> Result<(), String> {
        let stdin = self.stdin.as_mut().expect("started with --control");
        writeln!(stdin, "{command}").expect("write to ecat-sim's stdin");
        stdin.flush().expect("flush ecat-sim's stdin");
        let answer = self
            .wait_line(READY_PATIENCE, |line| {
                line.starts_with("ecat-sim: ok ") || line.starts_with("ecat-sim: error ")
            })
            .unwrap_or_else(|| panic!("ecat-sim did not answer {command:?}"));
        if answer == format!("ecat-sim: ok {command}") {
            Ok(())
        } else {
            Err(answer)
        }
    }

    /// What it wrote to stderr so far.
    pub fn stderr(&self) -> String {
        std::fs::read_to_string(&self.stderr_path).unwrap_or_default()
    }

    /// Stops it with SIGTERM, as an operator would, and returns its exit status.
    ///
    /// # Panics
    /// If it does not exit within [`STOP_PATIENCE`].
    pub fn stop(&mut self) -> ExitStatus {
        let pid = libc::pid_t::try_from(self.child.id()).expect("pid fits pid_t");
        // SAFETY: kill has no memory preconditions; the pid is our own child, not yet
        // reaped (we hold the Child), so it cannot name another process.
        unsafe { libc::kill(pid, libc::SIGTERM) };
        let deadline = Instant::now() + STOP_PATIENCE;
        loop {
            if let Some(status) = self.child.try_wait().expect("wait for ecat-sim") {
                return status;
            }
            assert!(
                Instant::now() < deadline,
                "ecat-sim did not stop within {STOP_PATIENCE:?} of SIGTERM"
            );
            // A bounded poll of the exit status, not a synchronisation sleep.
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

impl Drop for SimProcess {
    fn drop(&mut self) {
        // Never panic here: we may be unwinding from a failed assertion.
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
        let _ = std::fs::remove_file(&self.stderr_path);
    }
}
