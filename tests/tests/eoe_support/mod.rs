//! ecatd in a network namespace of its own, so its EoE interfaces (and every frame the
//! tests send through them) stay there: the process, curl, ping and the interface checks,
//! all run inside that namespace.

#![allow(dead_code)]

use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use ecat_tests::netns::NetNs;

pub mod rig;

/// How long anything in these tests may take to happen.
pub const PATIENCE: Duration = Duration::from_secs(30);

/// A running ecatd in `ns`, on the default ports of that namespace's loopback; killed on
/// drop (before the namespace goes).
pub struct EcatdInNs {
    child: Child,
    /// Its namespace.
    pub ns: NetNs,
    log: std::path::PathBuf,
}

impl EcatdInNs {
    /// Starts `ecatd <args>` in a new namespace (its loopback up) and waits until ready.
    pub fn start(bin_dir: &Path, args: &[&str]) -> EcatdInNs {
        EcatdInNs::start_in(NetNs::new(), bin_dir, args)
    }

    /// Starts `ecatd <args>` in `ns` (its loopback brought up) and waits until ready.
    pub fn start_in(ns: NetNs, bin_dir: &Path, args: &[&str]) -> EcatdInNs {
        ns.ip(&["link", "set", "dev", "lo", "up"]);
        let log = std::env::temp_dir().join(format!("{}-ecatd.log", ns.name()));
        let file = std::fs::File::create(&log).expect("log file");
        let child = Command::new("ip")
            .args(["netns", "exec", ns.name()])
            .arg(bin_dir.join("ecatd"))
            .args(args)
            .args(["--log", "info"])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(file)
            .spawn()
            .expect("ecatd starts");
        let mut ecatd = EcatdInNs { child, ns, log };
        ecatd.wait_until("ecatd ready", |e| e.curl(&["/readyz"]).0 == 200);
        ecatd
    }

    /// ecatd's log so far.
    pub fn log(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// Runs `program args` inside the namespace.
    pub fn run(&self, program: &str, args: &[&str]) -> Output {
        Command::new("ip")
            .args(["netns", "exec", self.ns.name(), program])
            .args(args)
            .output()
            .expect("ip netns exec runs")
    }

    /// curl on ecatd's HTTP API (`path` starting with `/`, then curl options): status and
    /// body.
    pub fn curl(&self, args: &[&str]) -> (u16, String) {
        let (path, rest) = args.split_first().expect("a path");
        let url = format!("http://127.0.0.1:8080{path}");
        let mut full = vec![
            "-s",
            "-H",
            "X-Ecat-Client: tests",
            "-w",
            "\n%{http_code}",
            &url,
        ];
        full.extend_from_slice(rest);
        let out = self.run("curl", &full);
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        let (body, code) = text.rsplit_once('\n').unwrap_or(("", "0"));
        (code.trim().parse().unwrap_or(0), body.to_owned())
    }

    /// The EoE interfaces as `GET /api/v1/eoe/interfaces` lists them.
    pub fn interfaces(&self) -> Vec<serde_json::Value> {
        let (status, body) = self.curl(&["/api/v1/eoe/interfaces"]);
        assert_eq!(status, 200, "{body}");
        serde_json::from_str(&body).expect("a JSON list")
    }

    /// The listed interface `name`, if any.
    pub fn interface(&self, name: &str) -> Option<serde_json::Value> {
        self.interfaces().into_iter().find(|i| i["name"] == name)
    }

    /// `ip -o link show dev <name>` and `ip -o -4 addr show dev <name>`, or `None` without the
    /// interface.
    pub fn link(&self, name: &str) -> Option<(String, String)> {
        let link = self.run("ip", &["-o", "link", "show", "dev", name]);
        if !link.status.success() {
            return None;
        }
        let addr = self.run("ip", &["-o", "-4", "addr", "show", "dev", name]);
        Some((
            String::from_utf8_lossy(&link.stdout).into_owned(),
            String::from_utf8_lossy(&addr.stdout).into_owned(),
        ))
    }

    /// The interface's index (it changes when the interface is made anew).
    pub fn ifindex(&self, name: &str) -> Option<u32> {
        let (link, _) = self.link(name)?;
        link.split(':').next()?.trim().parse().ok()
    }

    /// Whether the interface has its carrier (`LOWER_UP`).
    pub fn carrier(&self, name: &str) -> bool {
        self.link(name)
            .is_some_and(|(link, _)| link.contains("LOWER_UP"))
    }

    /// `ping -c count` to `address`: how many answers came back.
    pub fn ping(&self, address: &str, count: u32, size: u32) -> u32 {
        let out = self.run(
            "ping",
            &[
                "-c",
                &count.to_string(),
                "-i",
                "0.02",
                "-W",
                "2",
                "-s",
                &size.to_string(),
                address,
            ],
        );
        let text = String::from_utf8_lossy(&out.stdout);
        text.lines()
            .find_map(|line| {
                let (_, rest) = line.split_once("transmitted, ")?;
                rest.split_whitespace().next()?.parse().ok()
            })
            .unwrap_or_else(|| panic!("no ping summary:\n{text}"))
    }

    /// Asks for a rescan and waits until interface `name` is made anew (a new index), has
    /// its carrier and `address` (e.g. `10.78.0.1/24`) on it, with no other command.
    pub fn rescan_and_wait_for(&mut self, name: &str, address: &str) {
        let before = self.ifindex(name).expect("the interface's index");
        let (status, body) = self.curl(&["/api/v1/rescan", "-X", "POST"]);
        assert_eq!(status, 200, "{body}");
        self.wait_until(&format!("{name} made anew, up, with {address}"), |e| {
            e.ifindex(name).is_some_and(|i| i != before)
                && e.carrier(name)
                && e.link(name).is_some_and(|(_, addr)| addr.contains(address))
        });
    }

    /// Polls `check` until it holds, panicking with `what` and ecatd's log after
    /// [`PATIENCE`].
    pub fn wait_until(&mut self, what: &str, mut check: impl FnMut(&EcatdInNs) -> bool) {
        let deadline = Instant::now() + PATIENCE;
        loop {
            if check(self) {
                return;
            }
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!("ecatd exited ({status}) before {what}:\n{}", self.log());
            }
            assert!(
                Instant::now() < deadline,
                "timed out waiting for {what}:\n{}",
                self.log()
            );
            // The poll interval of the check (the loop ends on the condition or the deadline).
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for EcatdInNs {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.log);
    }
}

/// The payload the simulated device serves for `GET /<len>` (sim's `tcp_host`).
pub fn payload(len: usize) -> Vec<u8> {
    (0..len as u64)
        .map(sim::device::eoe::tcp_host::payload_byte)
        .collect()
}
