//! Throwaway network namespaces with veth pairs, for tests that need real Ethernet
//! interfaces without touching the host's network.
//!
//! A test makes a [`NetNs`], adds a veth pair to it, and runs its body in a thread that has
//! entered the namespace ([`NetNs::run_inside`]). Sockets opened there stay in the namespace
//! for their whole life. Dropping the `NetNs`, also while unwinding from a failed assertion,
//! deletes the namespace and with it the interfaces.
//!
//! Needs root (`CAP_SYS_ADMIN` for namespaces, `CAP_NET_RAW` for raw sockets) and the `ip`
//! command from iproute2; without them the test fails with a message saying so.

use std::fs::File;
use std::os::fd::AsRawFd;
use std::path::PathBuf;
use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

/// Tells namespaces of one test process apart (tests run in parallel).
static NEXT_ID: AtomicU32 = AtomicU32::new(0);

/// How long a new interface may take to become ready; far more than it ever needs.
pub const READY_PATIENCE: Duration = Duration::from_secs(10);

/// A named network namespace (`ip netns`), deleted on drop.
#[derive(Debug)]
pub struct NetNs {
    name: String,
}

impl NetNs {
    /// Creates a new, empty namespace named `ecatd-test-<pid>-<n>`.
    ///
    /// # Panics
    /// If the process is not root, `ip` is missing, or the namespace cannot be created.
    pub fn new() -> NetNs {
        require_root();
        let name = format!(
            "ecatd-test-{}-{}",
            std::process::id(),
            NEXT_ID.fetch_add(1, Ordering::Relaxed)
        );
        run_ip(&["netns", "add", &name]);
        // From here on the guard exists, so a later failure still deletes the namespace.
        NetNs { name }
    }

    /// The namespace's name, as `ip netns` shows it.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Runs `ip -n <name> <args>`, panics with its error output if it fails, and returns
    /// what it printed.
    pub fn ip(&self, args: &[&str]) -> String {
        let mut full = vec!["-n", self.name.as_str()];
        full.extend_from_slice(args);
        run_ip(&full)
    }

    /// Adds a veth pair `a` <-> `b` to the namespace, brings both ends up, and returns once
    /// both can carry frames.
    pub fn add_veth_pair(&self, a: &str, b: &str) {
        // Always spell out `name`: `ip link add a ...` would read `a` as `address`.
        self.ip(&["link", "add", "name", a, "type", "veth", "peer", "name", b]);
        self.ip(&["link", "set", "dev", a, "up"]);
        self.ip(&["link", "set", "dev", b, "up"]);
        self.wait_until_ready(a);
        self.wait_until_ready(b);
    }

    /// Waits (at most [`READY_PATIENCE`]) until `device` is up and can transmit.
    ///
    /// `ip link set up` returns before the kernel's link watcher has seen the carrier and
    /// attached the real queueing discipline; until then the device still has the `noop`
    /// qdisc, which silently drops every frame sent through it. A test that sends at once
    /// would then lose its first frames now and then, so wait for both signs of readiness.
    pub fn wait_until_ready(&self, device: &str) {
        wait_link_ready(Some(self), device);
    }

    /// Moves the calling thread into the namespace (other threads stay where they are).
    ///
    /// # Panics
    /// If the namespace cannot be opened or entered.
    pub fn enter_current_thread(&self) {
        let path = self.path();
        let file =
            File::open(&path).unwrap_or_else(|err| panic!("cannot open {}: {err}", path.display()));
        // SAFETY: `file` is an open namespace file for the duration of the call; setns only
        // changes the calling thread's network namespace.
        let result = unsafe { libc::setns(file.as_raw_fd(), libc::CLONE_NEWNET) };
        if result != 0 {
            panic!(
                "cannot enter network namespace {}: {}",
                self.name,
                std::io::Error::last_os_error()
            );
        }
    }

    /// Runs `body` on a new thread inside the namespace and returns its result; a panic in
    /// `body` is passed on unchanged, so the test reports the original assertion.
    pub fn run_inside<T: Send>(&self, body: impl FnOnce() -> T + Send) -> T {
        std::thread::scope(|scope| {
            let handle = scope.spawn(|| {
                self.enter_current_thread();
                body()
            });
            match handle.join() {
                Ok(value) => value,
                Err(panic) => std::panic::resume_unwind(panic),
            }
        })
    }

    /// Where `ip netns` keeps the namespace.
    pub fn path(&self) -> PathBuf {
        PathBuf::from("/run/netns").join(&self.name)
    }
}

impl Drop for NetNs {
    fn drop(&mut self) {
        // Never panic here: we may already be unwinding from a failed assertion.
        match Command::new("ip")
            .args(["netns", "delete", &self.name])
            .output()
        {
            Ok(output) if output.status.success() => {}
            Ok(output) => eprintln!(
                "could not delete network namespace {}: {}",
                self.name,
                String::from_utf8_lossy(&output.stderr).trim()
            ),
            Err(err) => eprintln!("could not delete network namespace {}: {err}", self.name),
        }
    }
}

fn require_root() {
    // SAFETY: geteuid has no preconditions and cannot fail.
    let euid = unsafe { libc::geteuid() };
    assert!(
        euid == 0,
        "this test must run as root (it creates network namespaces and opens raw sockets, \
         which need CAP_SYS_ADMIN and CAP_NET_RAW); CI runs it as root"
    );
}

/// Waits (at most [`READY_PATIENCE`]) until `device` in `netns` (`None`: the calling
/// process's own namespace) is up and can transmit; see [`NetNs::wait_until_ready`].
pub fn wait_link_ready(netns: Option<&NetNs>, device: &str) {
    let deadline = Instant::now() + READY_PATIENCE;
    loop {
        let show = ["-o", "link", "show", "dev", device];
        let state = match netns {
            Some(ns) => ns.ip(&show),
            None => run_ip(&show),
        };
        if state.contains("state UP") && !state.contains("qdisc noop") {
            return;
        }
        // Each check is an `ip` process, which paces this loop by itself.
        assert!(
            Instant::now() < deadline,
            "{device} in {} did not become ready within {READY_PATIENCE:?}: {}",
            netns.map_or("this namespace", NetNs::name),
            state.trim()
        );
    }
}

/// Runs `ip <args>` and returns its output, panicking with a clear message if `ip` is
/// missing or fails.
pub fn run_ip(args: &[&str]) -> String {
    let output = Command::new("ip")
        .args(args)
        .output()
        .unwrap_or_else(|err| {
            panic!("cannot run `ip` ({err}); install iproute2 (apt-get install iproute2)")
        });
    assert!(
        output.status.success(),
        "`ip {}` failed: {}",
        args.join(" "),
        String::from_utf8_lossy(&output.stderr).trim()
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}
