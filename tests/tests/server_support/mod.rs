//! Running `ecatd --simulate` for the server tests: the binary built fresh, free loopback
//! ports (port 0, the bound ports read from ecatd's JSON "listening" log line), readiness by
//! polling `/readyz` with a deadline, SIGTERM on drop; and the real clients: grpcurl from the
//! venv `scripts/test` makes, curl.

#![allow(dead_code)]

pub mod gateway_client;
pub mod streaming;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::mpsc;
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// Numbers the application sockets of the ecatds this test binary starts.
static NEXT_SOCKET: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// How long ecatd may take to come up (build excluded) or go down.
const DEADLINE: Duration = Duration::from_secs(30);

/// The workspace root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Builds `ecatd` and `ecat` (once per test binary) with the cargo running the tests and
/// returns the directory holding them. The tests crate cannot depend on a binary of another
/// package, so it asks cargo, which also makes sure the binaries are current. An optimised
/// caller (a benchmark) gets release binaries: timing an unoptimised ecatd measures the
/// compiler's debug code, not the server.
pub fn bin_dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let release: &[&str] = if cfg!(debug_assertions) {
            &[]
        } else {
            &["--release"]
        };
        let output = Command::new(cargo)
            .args([
                "build",
                "-p",
                "server",
                "--bins",
                "--message-format",
                "json",
            ])
            .args(release)
            .current_dir(root())
            .output()
            .expect("cargo runs");
        assert!(
            output.status.success(),
            "building ecatd failed:\n{}",
            String::from_utf8_lossy(&output.stderr)
        );
        let stdout = String::from_utf8_lossy(&output.stdout);
        let exe = stdout
            .lines()
            .filter_map(|line| serde_json::from_str::<serde_json::Value>(line).ok())
            .find_map(|v| {
                let exe = v.get("executable")?.as_str()?;
                exe.ends_with("/ecatd").then(|| PathBuf::from(exe))
            })
            .expect("cargo names the ecatd executable");
        exe.parent()
            .expect("the executable has a directory")
            .to_path_buf()
    })
}

/// Whether this test binary runs ecatd on a real interface: the `server_veth` binary compiles
/// the suites of `server` again (`#[path]`), and in it ecatd runs `--iface` on a veth pair whose
/// other end is `ecat-sim` in its own namespace, serving the same topology as `--simulate`.
pub fn on_veth() -> bool {
    env!("CARGO_CRATE_NAME").ends_with("_veth")
}

/// The simulated segment behind an `ecatd --iface` (see [`on_veth`]).
struct VethSegment {
    // Dropped in this order: the simulator, then its namespace and the veth pair.
    sim: ecat_tests::sim_process::SimProcess,
    rig: ecat_tests::rig::HostRig,
    /// The newest output report read per terminal (`outputs POSITION HEX`): ecat-sim
    /// reports a change once, and a wait that read it must not make the next wait for the
    /// same state think it has never been seen.
    outputs: std::collections::HashMap<u16, String>,
}

/// A running `ecatd`, stopped with SIGTERM on drop.
pub struct Ecatd {
    child: Option<Child>,
    veth: Option<VethSegment>,
    /// gRPC address (`127.0.0.1:port`).
    pub grpc: String,
    /// HTTP base URL (`http://127.0.0.1:port`).
    pub http: String,
    log: Arc<Mutex<Vec<String>>>,
}

impl Ecatd {
    /// Starts `ecatd --simulate` with `extra` flags, on free loopback ports, and waits until
    /// it is ready.
    pub fn start(extra: &[&str]) -> Ecatd {
        Ecatd::start_with(&["--simulate"], extra)
    }

    /// Starts `ecatd` with `segment` flags and `extra` flags; waits until ready.
    ///
    /// In the `*_veth` binaries ([`on_veth`]) `--simulate [TOPOLOGY]` becomes `ecat-sim
    /// [--topology TOPOLOGY]` on a veth pair and ecatd runs `--iface` on its other end.
    pub fn start_with(segment: &[&str], extra: &[&str]) -> Ecatd {
        let mut ecatd = Ecatd::start_listening(segment, extra);
        ecatd.wait_ready(Instant::now() + DEADLINE);
        ecatd
    }

    /// [`Ecatd::start_with`] that returns as soon as ecatd listens, before its start-up
    /// scan ends (to stop it during the scan).
    pub fn start_listening(segment: &[&str], extra: &[&str]) -> Ecatd {
        Ecatd::spawn(segment, extra, None, &[])
    }

    /// [`Ecatd::start_with`] with `env` added to ecatd's environment (what a service
    /// manager such as systemd passes, e.g. `NOTIFY_SOCKET`).
    pub fn start_with_env(segment: &[&str], extra: &[&str], env: &[(&str, &str)]) -> Ecatd {
        let mut ecatd = Ecatd::spawn(segment, extra, None, env);
        ecatd.wait_ready(Instant::now() + DEADLINE);
        ecatd
    }

    /// [`Ecatd::start_with`] with `setup` run in ecatd's process between fork and exec:
    /// what a service manager sets before it starts a service (resource limits,
    /// capabilities, scheduling). `setup` must only make system calls (no allocation, no
    /// locks: the child of a threaded process).
    pub fn start_prepared(
        segment: &[&str],
        extra: &[&str],
        setup: Box<dyn FnMut() -> std::io::Result<()> + Send + Sync>,
    ) -> Ecatd {
        let mut ecatd = Ecatd::spawn(segment, extra, Some(setup), &[]);
        ecatd.wait_ready(Instant::now() + DEADLINE);
        ecatd
    }

    fn spawn(
        segment: &[&str],
        extra: &[&str],
        setup: Option<Box<dyn FnMut() -> std::io::Result<()> + Send + Sync>>,
        env: &[(&str, &str)],
    ) -> Ecatd {
        let veth = (on_veth() && segment.first() == Some(&"--simulate")).then(|| {
            let rig = ecat_tests::rig::HostRig::new();
            // `--simulate [TOPOLOGY] [ECAT-SIM OPTIONS]`: options such as `--loss` or
            // `--pcap` go to ecat-sim.
            let (file, options) = match segment.get(1) {
                Some(file) if !file.starts_with("--") => (Some(*file), &segment[2..]),
                _ => (None, segment.get(1..).unwrap_or_default()),
            };
            let mut topology: Vec<&str> = file.map_or_else(Vec::new, |f| vec!["--topology", f]);
            topology.extend_from_slice(options);
            // With `--control`, so that tests can reach the slaves' physical side.
            let sim = ecat_tests::sim_process::SimProcess::start_controlled(
                &rig.sim,
                ecat_tests::rig::SIM_IFACE,
                &topology,
            );
            VethSegment {
                sim,
                rig,
                outputs: std::collections::HashMap::new(),
            }
        });
        let iface;
        let segment: &[&str] = match &veth {
            Some(v) => {
                iface = ["--iface", v.rig.master_iface.as_str()];
                &iface
            }
            None => segment,
        };
        // The gateway on a free port too, so that tests can run side by side (unless the
        // test chooses where).
        let gateway: &[&str] =
            if extra.contains(&"--no-gateway") || extra.contains(&"--gateway-listen") {
                &[]
            } else {
                &["--gateway-listen", "127.0.0.1:0"]
            };
        let mut command = Command::new(bin_dir().join("ecatd"));
        if let Some(setup) = setup {
            use std::os::unix::process::CommandExt;
            // SAFETY: the caller's `setup` only makes system calls (its contract above),
            // which is what may run between fork and exec.
            unsafe { command.pre_exec(setup) };
        }
        // Its own application socket, so that ecatds of tests running side by side do not
        // meet at the default one (unless the test chooses where).
        let app_socket = std::env::temp_dir().join(format!(
            "ecatd-test-{}-{}.sock",
            std::process::id(),
            NEXT_SOCKET.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        ));
        let app: Vec<String> = if extra.contains(&"--app-socket") {
            Vec::new()
        } else {
            vec!["--app-socket".into(), app_socket.display().to_string()]
        };
        let mut child = command
            .envs(env.iter().copied())
            .args(segment)
            .args(gateway)
            .args(&app)
            .args([
                "--grpc-listen",
                "127.0.0.1:0",
                "--http-listen",
                "127.0.0.1:0",
            ])
            .args(["--log-format", "json"])
            // A test that reads debug lines gives its own filter.
            .args(if extra.contains(&"--log") {
                &[][..]
            } else {
                &["--log", "info"][..]
            })
            .args(extra)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("ecatd starts");
        let stderr = child.stderr.take().expect("stderr is piped");
        let log = Arc::new(Mutex::new(Vec::new()));
        let (tx, rx) = mpsc::channel();
        let keep = Arc::clone(&log);
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if let Ok(v) = serde_json::from_str::<serde_json::Value>(&line) {
                    let _ = tx.send(v);
                }
                keep.lock().unwrap().push(line);
            }
        });
        let deadline = Instant::now() + DEADLINE;
        let listening = loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match rx.recv_timeout(left) {
                Ok(v) if v["fields"]["message"] == "listening" => break v,
                Ok(_) => continue,
                Err(_) => {
                    let _ = child.kill();
                    panic!(
                        "ecatd did not report its ports:\n{}",
                        log.lock().unwrap().join("\n")
                    );
                }
            }
        };
        let field = |name: &str| {
            listening["fields"][name]
                .as_str()
                .expect("address field")
                .to_owned()
        };
        // With TLS (`--tls-cert`) the HTTP side speaks HTTPS.
        let scheme = if listening["fields"]["tls"] == true {
            "https"
        } else {
            "http"
        };
        Ecatd {
            veth,
            grpc: field("grpc"),
            http: format!("{scheme}://{}", field("http")),
            child: Some(child),
            log,
        }
    }

    fn wait_ready(&mut self, deadline: Instant) {
        let url = format!("{}/readyz", self.http);
        loop {
            // Readiness only: the TLS test checks the certificate itself.
            let (status, _) = curl(&["-s", "-k", &url]);
            if status == 200 {
                return;
            }
            if Instant::now() > deadline {
                panic!("ecatd not ready in time:\n{}", self.log());
            }
            if let Some(Ok(Some(status))) = self.child.as_mut().map(Child::try_wait) {
                panic!("ecatd exited ({status}):\n{}", self.log());
            }
            // Poll interval of the readiness check (not a synchronisation by time: the loop
            // ends on the condition or the deadline).
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// The address the mailbox gateway serves on, from ecatd's log (it starts before
    /// ecatd reports ready; the log reader may lag a little behind).
    pub fn gateway_addr(&self) -> std::net::SocketAddr {
        let lines = self.log_until("mailbox gateway serving");
        let line = lines
            .last()
            .expect("log_until returns the line it waited for");
        line["fields"]["gateway"]
            .as_str()
            .and_then(|addr| addr.parse().ok())
            .unwrap_or_else(|| panic!("no gateway address in {line}"))
    }

    /// Raises a CoE emergency on the simulated slave at `position`: through the
    /// `--simulate`-only REST route, or on veth through `ecat-sim --control`. Returns the
    /// refusal (HTTP status and body, or ecat-sim's error line) if it was refused.
    pub fn raise_emergency(
        &mut self,
        position: u16,
        code: u16,
        register: u8,
        data: [u8; 5],
    ) -> Result<(), String> {
        let hex: String = data.iter().map(|b| format!("{b:02x}")).collect();
        if let Some(veth) = &mut self.veth {
            return veth
                .sim
                .try_command(&format!("emergency {position} {code:x} {register:x} {hex}"));
        }
        let body =
            format!(r#"{{"error_code": {code}, "error_register": {register}, "data": "{hex}"}}"#);
        let (status, text) = post_json(
            &format!("{}/api/v1/slaves/{position}/sim/emergency", self.http),
            &body,
        );
        if status == 200 {
            Ok(())
        } else {
            Err(format!("{status} {text}"))
        }
    }

    /// Waits until the simulated digital output terminal at `position` shows `expected` on
    /// its physical outputs: through the `--simulate`-only REST route, or on veth through
    /// `ecat-sim --control`'s output reports. Panics at the deadline with what it showed.
    pub fn wait_sim_outputs(&mut self, position: u16, expected: &[u8], patience: Duration) {
        let want = expected
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect::<String>();
        if let Some(veth) = &mut self.veth {
            // The reports come on every change: the newest one about the terminal is its
            // state now, older ones (kept back by earlier waits) are history.
            let prefix = format!("ecat-sim: outputs {position} ");
            let mut now = veth.outputs.get(&position).cloned();
            while let Some(line) = veth
                .sim
                .wait_line(Duration::ZERO, |l| l.starts_with(&prefix))
            {
                now = Some(line);
            }
            let deadline = Instant::now() + patience;
            while now.as_deref().and_then(|l| l.strip_prefix(&prefix)) != Some(want.as_str()) {
                let left = deadline.saturating_duration_since(Instant::now());
                now = Some(
                    veth.sim
                        .wait_line(left, |l| l.starts_with(&prefix))
                        .unwrap_or_else(|| {
                            panic!("slave {position}'s outputs are {now:?}, not {want}")
                        }),
                );
            }
            if let Some(line) = now {
                veth.outputs.insert(position, line);
            }
            return;
        }
        let deadline = Instant::now() + patience;
        let url = format!("{}/api/v1/slaves/{position}/sim/outputs", self.http);
        loop {
            let (status, body) = curl(&["-s", &url]);
            assert_eq!(status, 200, "{body}");
            let shown: serde_json::Value = serde_json::from_str(&body).expect("JSON");
            if shown["outputs"] == want.as_str() {
                return;
            }
            assert!(
                Instant::now() < deadline,
                "slave {position}'s outputs are {shown}, not {want}"
            );
            // Poll interval of the outputs check; the loop ends on the value or the deadline.
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// On veth ([`on_veth`]): takes the simulator's end of the veth pair down (`up` false)
    /// or up again, as a cut cable would, with `ip link set` in the simulator's namespace.
    pub fn set_sim_link(&self, up: bool) {
        let veth = self
            .veth
            .as_ref()
            .expect("a link to cut exists on veth only");
        let state = if up { "up" } else { "down" };
        veth.rig
            .sim
            .ip(&["link", "set", "dev", ecat_tests::rig::SIM_IFACE, state]);
        if up {
            // Both ends carry frames again (the master's end lost its carrier meanwhile).
            veth.rig.sim.wait_until_ready(ecat_tests::rig::SIM_IFACE);
            ecat_tests::netns::wait_link_ready(None, &veth.rig.master_iface);
        }
    }

    /// On veth ([`on_veth`]), once ecatd has stopped: stops ecat-sim with SIGTERM, so that
    /// what it writes at the end (a `--pcap` capture) is complete on disk.
    pub fn stop_sim(&mut self) {
        assert!(self.child.is_none(), "stop ecatd first");
        if let Some(veth) = &mut self.veth {
            assert!(
                veth.sim.stop().success(),
                "ecat-sim failed:\n{}",
                veth.sim.stderr()
            );
        }
    }

    /// ecatd's process id (0 once stopped).
    pub fn pid(&self) -> u32 {
        self.child.as_ref().map_or(0, Child::id)
    }

    /// Everything ecatd logged so far.
    pub fn log(&self) -> String {
        self.log.lock().unwrap().join("\n")
    }

    /// Waits until `found` returns something for ecatd's log lines so far (the log reader
    /// gets a line a little after ecatd wrote it); panics naming `what` at the deadline.
    pub fn wait_on_log<T>(&self, what: &str, found: impl Fn(&[String]) -> Option<T>) -> T {
        let deadline = Instant::now() + DEADLINE;
        loop {
            // A copy, so that `found` may read the log again without the lock held.
            let lines = self.log.lock().unwrap().clone();
            if let Some(value) = found(&lines) {
                return value;
            }
            assert!(
                Instant::now() < deadline,
                "ecatd did not log {what}:\n{}",
                self.log()
            );
            // Poll interval of the log check; the loop ends on the condition or the deadline.
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// The JSON log lines ecatd wrote up to and including the first whose message is
    /// `message`, once the log reader has seen it (panics at the deadline). Lines are kept
    /// in the order ecatd wrote them, so what is not among them was not logged before it.
    pub fn log_until(&self, message: &str) -> Vec<serde_json::Value> {
        self.wait_on_log(&format!("{message:?}"), |log| {
            let lines: Vec<serde_json::Value> = log
                .iter()
                .filter_map(|line| serde_json::from_str(line).ok())
                .collect();
            let at = lines
                .iter()
                .position(|v| v["fields"]["message"] == message)?;
            Some(lines[..=at].to_vec())
        })
    }

    /// Waits until ecatd's log holds `text` (panics at the deadline): a line written
    /// after the call it follows has answered (an audit line) reaches the log reader a
    /// little later.
    pub fn wait_log(&self, text: &str) {
        self.wait_on_log(&format!("{text:?}"), |log| {
            log.join("\n").contains(text).then_some(())
        });
    }

    /// Sends SIGTERM and waits for the exit; returns whether it exited with success.
    pub fn stop(&mut self) -> bool {
        self.terminate(DEADLINE)
            .is_some_and(|status| status.success())
    }

    /// Sends SIGTERM and waits up to `patience` for the exit: its status, or `None` if
    /// ecatd had to be killed (or was already stopped).
    pub fn terminate(&mut self, patience: Duration) -> Option<std::process::ExitStatus> {
        let mut child = self.child.take()?;
        // SAFETY: `kill` on our own child's pid, which has not been reaped yet.
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
        let deadline = Instant::now() + patience;
        loop {
            match child.try_wait() {
                Ok(Some(status)) => return Some(status),
                // Poll interval of the exit check; the loop ends on the exit or the deadline.
                Ok(None) if Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(20));
                }
                _ => {
                    let _ = child.kill();
                    let _ = child.wait();
                    return None;
                }
            }
        }
    }

    /// On veth ([`on_veth`]), once ecatd has exited: the AL status (0x0130) of every slave
    /// as the segment reports it now, read with a master of the test's own on the same
    /// interface, by ring position. `None` with the in-process simulator (it ended with
    /// ecatd).
    pub fn segment_al_states(&self) -> Option<Vec<u16>> {
        use master_core::bus::{Bus, BusConfig, DatagramRequest};
        use master_core::link::{RawSocket, RawSocketOptions};
        let veth = self.veth.as_ref()?;
        assert!(
            self.child.is_none(),
            "read the segment once ecatd has exited"
        );
        let socket = RawSocket::open(&veth.rig.master_iface, RawSocketOptions::default())
            .expect("raw socket on the master's end");
        let (bus, thread) = Bus::start(socket, BusConfig::default()).expect("bus starts");
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .build()
            .expect("runtime");
        let states = runtime.block_on(async {
            let mut states = Vec::new();
            for position in 0u16..256 {
                // APRD addresses by ring position: the slave at `position` answers alone.
                let request = DatagramRequest::aprd(position, 0x0130, 2).expect_wkc(1);
                match bus.submit(request).await {
                    Ok(reply) => states.push(u16::from_le_bytes([reply.data[0], reply.data[1]])),
                    Err(_) => break,
                }
            }
            states
        });
        bus.shutdown();
        let _ = thread.join();
        Some(states)
    }
}

impl Drop for Ecatd {
    fn drop(&mut self) {
        self.stop();
        // A failing test on veth also wants to know what the simulator saw.
        if let Some(veth) = &self.veth
            && std::thread::panicking()
        {
            eprintln!("ecat-sim's stderr:\n{}", veth.sim.stderr());
        }
    }
}

/// The venv's bin directory (`$ECATD_PYTHON`'s, else `target/pyenv/bin`).
pub fn venv_bin() -> PathBuf {
    match std::env::var_os("ECATD_PYTHON") {
        Some(python) => PathBuf::from(python)
            .parent()
            .expect("python has a directory")
            .to_path_buf(),
        None => root().join("target/pyenv/bin"),
    }
}

/// grpcurl from the venv.
pub fn grpcurl_path() -> PathBuf {
    let path = venv_bin().join("grpcurl");
    assert!(
        path.is_file(),
        "no grpcurl at {}: run scripts/test (it installs tests/py/requirements.txt into target/pyenv)",
        path.display()
    );
    path
}

/// Runs `grpcurl -plaintext <args>`: stdout, after checking it succeeded.
pub fn grpcurl(args: &[&str]) -> String {
    let output: Output = Command::new(grpcurl_path())
        .arg("-plaintext")
        .args(args)
        .output()
        .expect("grpcurl runs");
    assert!(
        output.status.success(),
        "grpcurl {args:?} failed:\n{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// Calls `method` with the JSON `body` through grpcurl; the JSON answer, or the failure's
/// code and message.
pub fn call(
    addr: &str,
    headers: &[&str],
    method: &str,
    body: &str,
) -> Result<serde_json::Value, (String, String)> {
    call_status(addr, headers, method, body).map_err(|status| {
        (
            status["code"]
                .as_u64()
                .map(|c| c.to_string())
                .unwrap_or_default(),
            status["message"].as_str().unwrap_or_default().to_owned(),
        )
    })
}

/// Like [`call`], but a failure is grpcurl's whole status as JSON (code, message, details).
pub fn call_status(
    addr: &str,
    headers: &[&str],
    method: &str,
    body: &str,
) -> Result<serde_json::Value, serde_json::Value> {
    let mut args: Vec<&str> = vec!["-format-error", "-d", body];
    for h in headers {
        args.push("-H");
        args.push(h);
    }
    let output = Command::new(grpcurl_path())
        .arg("-plaintext")
        .args(&args)
        .arg(addr)
        .arg(method)
        .output()
        .expect("grpcurl runs");
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    if output.status.success() {
        return Ok(serde_json::from_str(&stdout)
            .unwrap_or_else(|e| panic!("grpcurl output {stdout:?}: {e}")));
    }
    // With -format-error grpcurl writes the status as JSON to stderr.
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    Err(serde_json::Deserializer::from_str(&stderr)
        .into_iter::<serde_json::Value>()
        .next()
        .and_then(Result::ok)
        .unwrap_or_else(|| panic!("grpcurl failed without an error: {stdout}{stderr}")))
}

/// Runs curl with `args` and appends `-w %{http_code}`: the status and the body. It sends
/// `X-Ecat-Client` as a non-browser client does (ecatd refuses a write that a web form could
/// send); [`curl_as_browser`] does not.
pub fn curl(args: &[&str]) -> (u16, String) {
    let mut with_header = vec!["-H", "X-Ecat-Client: tests"];
    with_header.extend_from_slice(args);
    curl_as_browser(&with_header)
}

/// `POST url` with the JSON `body` through [`curl`]: the status and the body.
pub fn post_json(url: &str, body: &str) -> (u16, String) {
    curl(&[
        "-s",
        "-X",
        "POST",
        "-H",
        "content-type: application/json",
        "-d",
        body,
        url,
    ])
}

/// Runs `ecat --address http://GRPC <args>` to its end.
pub fn ecat_output(grpc: &str, args: &[&str]) -> Output {
    Command::new(bin_dir().join("ecat"))
        .args(["--address", &format!("http://{grpc}")])
        .args(args)
        .output()
        .expect("ecat runs")
}

/// Runs `ecat --address http://GRPC <args>` and returns its standard output, after checking
/// it succeeded.
pub fn ecat_ok(grpc: &str, args: &[&str]) -> String {
    let output = ecat_output(grpc, args);
    assert!(
        output.status.success(),
        "ecat {args:?} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// [`curl`] without the `X-Ecat-Client` header: what a page in a browser could send.
pub fn curl_as_browser(args: &[&str]) -> (u16, String) {
    let output = Command::new("curl")
        .args(args)
        .args(["-w", "\n%{http_code}"])
        .output()
        .expect("curl runs");
    let text = String::from_utf8_lossy(&output.stdout).into_owned();
    let (body, code) = text.rsplit_once('\n').unwrap_or(("", "0"));
    (code.trim().parse().unwrap_or(0), body.to_owned())
}

/// Standard base64 (grpcurl's JSON form of `bytes`). The tests crate has no base64
/// dependency and its manifest belongs to another part of the project, so this small codec
/// lives with the test support.
pub mod b64 {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

    /// Encodes with padding.
    pub fn encode(data: &[u8]) -> String {
        let mut out = String::new();
        for chunk in data.chunks(3) {
            let b = [
                chunk[0],
                *chunk.get(1).unwrap_or(&0),
                *chunk.get(2).unwrap_or(&0),
            ];
            let n = u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
            for i in 0..4 {
                if i <= chunk.len() {
                    out.push(ALPHABET[(n >> (18 - 6 * i) & 63) as usize] as char);
                } else {
                    out.push('=');
                }
            }
        }
        out
    }

    /// Decodes padded or unpadded base64; panics on anything else (test input only).
    pub fn decode(text: &str) -> Vec<u8> {
        let mut out = Vec::new();
        let (mut acc, mut bits) = (0u32, 0u32);
        for c in text.bytes().filter(|&c| c != b'=') {
            let v = ALPHABET
                .iter()
                .position(|&a| a == c)
                .expect("base64 character") as u32;
            acc = acc << 6 | v;
            bits += 6;
            if bits >= 8 {
                bits -= 8;
                out.push((acc >> bits) as u8);
            }
        }
        out
    }

    #[test]
    fn round_trip() {
        for len in 0..10 {
            let data: Vec<u8> = (0..len).map(|i| (i * 37) as u8).collect();
            assert_eq!(decode(&encode(&data)), data);
        }
        assert_eq!(encode(b"ab"), "YWI=");
    }
}

/// Runs `ecatd <args>` expecting it to exit by itself (a refused start); kills it and
/// panics if it is still running at the deadline. Returns the exit status and stderr.
pub fn run_to_exit(args: &[&str]) -> (std::process::ExitStatus, String) {
    let mut child = Command::new(bin_dir().join("ecatd"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ecatd starts");
    let deadline = Instant::now() + DEADLINE;
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait works") {
            break status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("ecatd {args:?} kept running");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut stderr = String::new();
    use std::io::Read;
    let _ = child
        .stderr
        .take()
        .expect("piped")
        .read_to_string(&mut stderr);
    (status, stderr)
}
