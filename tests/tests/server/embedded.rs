//! ecatd's servers embedded in a control program (`server/examples/embedded.rs`, built
//! here with cargo): the program owns the master and runs its own cycle hook (DO8 outputs
//! follow DI8 inputs), and serves REST, gRPC and the gateway through `server::embed`. The
//! test checks the slaves in OP, an SDO upload over REST and gRPC, that the program's hook
//! runs every cycle and its outputs reach the simulated DO8, and a clean exit on SIGTERM
//! with the slaves in INIT.

use crate::server_support;

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::Value;
use server_support::{curl, root};
use sim::topology::{SIM_VENDOR_ID, Topology};

/// How long the program may take to come up (build excluded), or to show what is waited for.
const DEADLINE: Duration = Duration::from_secs(30);
/// Its shutdown budget (the default `shutdown_timeout_ms`) and a margin to see the exit.
const SHUTDOWN: Duration = Duration::from_secs(8);

/// Builds the example with the cargo running the tests (an optimised test run gets an
/// optimised example, as `server_support::bin_dir` does for ecatd) and returns its path.
fn example() -> PathBuf {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let release: &[&str] = if cfg!(debug_assertions) {
        &[]
    } else {
        &["--release"]
    };
    let output = Command::new(cargo)
        .args(["build", "-p", "server", "--example", "embedded"])
        .args(["--message-format", "json"])
        .args(release)
        .current_dir(root())
        .output()
        .expect("cargo runs");
    assert!(
        output.status.success(),
        "building the example failed:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout)
        .lines()
        .filter_map(|line| serde_json::from_str::<Value>(line).ok())
        .find_map(|v| {
            let exe = v.get("executable")?.as_str()?;
            exe.ends_with("/examples/embedded")
                .then(|| PathBuf::from(exe))
        })
        .expect("cargo names the example's executable")
}

/// The running example; killed on drop if a test failed before it exited.
struct Program {
    child: Option<Child>,
    /// Its JSON log lines so far, in order.
    log: Arc<Mutex<Vec<Value>>>,
}

impl Program {
    fn start(args: &[&str]) -> Program {
        let mut child = Command::new(example())
            .args([
                "--http-listen",
                "127.0.0.1:0",
                "--grpc-listen",
                "127.0.0.1:0",
            ])
            .args(["--gateway-listen", "127.0.0.1:0", "--log-format", "json"])
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("the example starts");
        let stderr = child.stderr.take().expect("stderr is piped");
        let log = Arc::new(Mutex::new(Vec::new()));
        let keep = Arc::clone(&log);
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                let v = serde_json::from_str(&line).unwrap_or(Value::String(line));
                keep.lock().unwrap().push(v);
            }
        });
        Program {
            child: Some(child),
            log,
        }
    }

    /// The first log line whose message is `message` and that `accept`s, once logged.
    fn wait_line(&mut self, message: &str, accept: impl Fn(&Value) -> bool) -> Value {
        let deadline = Instant::now() + DEADLINE;
        loop {
            let found = self
                .log
                .lock()
                .unwrap()
                .iter()
                .find(|v| v["fields"]["message"] == message && accept(v))
                .cloned();
            if let Some(line) = found {
                return line;
            }
            self.assert_running();
            assert!(
                Instant::now() < deadline,
                "no {message:?} line:\n{}",
                self.log_text()
            );
            // Poll interval of the log check; the loop ends on the line or the deadline.
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn assert_running(&mut self) {
        if let Some(Ok(Some(status))) = self.child.as_mut().map(Child::try_wait) {
            panic!("the example exited ({status}):\n{}", self.log_text());
        }
    }

    fn log_text(&self) -> String {
        let lines = self.log.lock().unwrap();
        lines
            .iter()
            .map(Value::to_string)
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// Sends SIGTERM; the exit status, or `None` if the program had to be killed.
    fn terminate(&mut self, patience: Duration) -> Option<std::process::ExitStatus> {
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
}

impl Drop for Program {
    fn drop(&mut self) {
        if let Some(mut child) = self.child.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// `GET base + path`: the status and the JSON body (the body as a string if it is none).
fn get(base: &str, path: &str) -> (u16, Value) {
    let (status, body) = curl(&["-s", &format!("{base}{path}")]);
    (
        status,
        serde_json::from_str(&body).unwrap_or(Value::String(body)),
    )
}

/// Polls `GET base + path` until `done` accepts the answer (panics at the deadline).
fn poll(base: &str, path: &str, done: impl Fn(u16, &Value) -> bool) -> Value {
    let deadline = Instant::now() + DEADLINE;
    loop {
        let (status, body) = get(base, path);
        if done(status, &body) {
            return body;
        }
        assert!(Instant::now() < deadline, "{path}: {status} {body}");
        // Poll interval; the loop ends on the answer or the deadline.
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Uploads 0x1018:01 of the slave at `position` over gRPC.
fn grpc_upload(addr: &str, position: u16) -> Vec<u8> {
    use proto::v1::UploadRequest;
    use proto::v1::coe_service_client::CoeServiceClient;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime");
    runtime.block_on(async {
        let mut client = CoeServiceClient::connect(format!("http://{addr}"))
            .await
            .expect("gRPC connects");
        let request = UploadRequest {
            slave: position.to_string(),
            index: 0x1018,
            subindex: 1,
            ..UploadRequest::default()
        };
        client
            .upload(request)
            .await
            .expect("upload")
            .into_inner()
            .data
    })
}

#[test]
fn an_embedding_program_serves_the_apis_over_its_own_master_and_cycle() {
    // The simulated switch on DI8 input 3: the program's hook copies it to DO8 output 3.
    let mut program = Program::start(&["--switch", "3"]);
    let listening = program.wait_line("listening", |_| true);
    let http = format!("http://{}", listening["fields"]["http"].as_str().unwrap());
    let grpc = listening["fields"]["grpc"].as_str().unwrap().to_owned();
    poll(&http, "/readyz", |status, _| status == 200);
    program.wait_line("mailbox gateway serving", |_| true);

    let topology = Topology::default_segment();
    let (status, slaves) = get(&http, "/api/v1/slaves");
    assert_eq!(status, 200, "{slaves}");
    let slaves = slaves.as_array().expect("a list of slaves");
    assert_eq!(slaves.len(), topology.slaves.len(), "{slaves:?}");
    assert!(slaves.iter().all(|s| s["state"] == "OP"), "{slaves:?}");

    let vendor: String = SIM_VENDOR_ID
        .to_le_bytes()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let (status, upload) = get(&http, "/api/v1/slaves/0/coe/sdo/0x1018/1");
    assert_eq!(
        (status, upload["data"].as_str()),
        (200, Some(vendor.as_str()))
    );
    assert_eq!(grpc_upload(&grpc, 0), SIM_VENDOR_ID.to_le_bytes());

    // The program's own cycle: its count grows with the cycles (1 ms each)...
    program.wait_line("mirror running", |v| {
        v["fields"]["cycles"].as_u64().is_some_and(|n| n > 100)
    });
    // ...and what it writes reaches the DO8's terminals (nothing else in the process
    // writes outputs: the application interface is off).
    poll(&http, "/api/v1/slaves/1/sim/outputs", |status, body| {
        status == 200 && body["outputs"] == "04"
    });

    let exit = program.terminate(SHUTDOWN);
    let log = program.log_text();
    let exit = exit.unwrap_or_else(|| panic!("the example did not exit in time:\n{log}"));
    assert_eq!(exit.code(), Some(0), "{log}");
    let safe = program.wait_line("slaves in the safe state", |_| true);
    assert_eq!(safe["fields"]["slaves"], topology.slaves.len(), "{safe}");
    assert_eq!(safe["fields"]["state"], "INIT", "{safe}");
}
