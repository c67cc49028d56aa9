//! ecatd's configuration precedence (file, then `ECATD_*` environment, then flags) as
//! `--print-config` shows it, and the shutdown on SIGTERM: event streams closed, every slave
//! in INIT (read back from the segment on veth), exit 0 within the deadline, also when the
//! signal comes during the start-up scan.

use crate::server_support;

use std::process::Command;
use std::time::{Duration, Instant};

use server_support::streaming::Streaming;
use server_support::{Ecatd, bin_dir, grpcurl_path};

#[test]
fn flags_win_over_environment_over_file() {
    let file = std::env::temp_dir().join(format!("ecatd-lifecycle-{}.toml", std::process::id()));
    std::fs::write(
        &file,
        "grpc_listen = \"127.0.0.1:1111\"\nhttp_listen = \"127.0.0.1:2222\"\nlog = \"debug\"\n",
    )
    .unwrap();
    let output = Command::new(bin_dir().join("ecatd"))
        .args([
            "--config",
            file.to_str().unwrap(),
            "--http-listen",
            "127.0.0.1:4444",
            "--simulate",
            "--print-config",
        ])
        .env("ECATD_GRPC_LISTEN", "127.0.0.1:3333")
        .env("ECATD_HTTP_LISTEN", "127.0.0.1:5555")
        .output()
        .unwrap();
    std::fs::remove_file(&file).unwrap();
    assert!(output.status.success());
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(
        text.contains("grpc_listen = \"127.0.0.1:3333\""),
        "environment over file:\n{text}"
    );
    assert!(
        text.contains("http_listen = \"127.0.0.1:4444\""),
        "flag over environment:\n{text}"
    );
    assert!(
        text.contains("log = \"debug\""),
        "file over default:\n{text}"
    );
    assert!(text.contains("[segment.simulate]"), "{text}");
}

#[test]
fn human_log_lines_have_no_colour_codes_off_a_terminal() {
    let mut child = Command::new(bin_dir().join("ecatd"))
        .args(["--simulate", "--no-gateway", "--log-format", "human"])
        .args([
            "--grpc-listen",
            "127.0.0.1:0",
            "--http-listen",
            "127.0.0.1:0",
        ])
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    // Up to the `listening` line (or the end, should ecatd stop first).
    let lines: Vec<String> = std::io::BufRead::lines(stderr)
        .map_while(Result::ok)
        .scan(false, |seen, line| {
            (!*seen).then(|| {
                *seen = line.contains("listening");
                line
            })
        })
        .collect();
    let _ = child.kill();
    let _ = child.wait();
    assert!(
        lines.iter().any(|l| l.contains("listening")),
        "no listening line:\n{}",
        lines.join("\n")
    );
    assert!(
        lines.iter().all(|l| !l.contains('\u{1b}')),
        "escape codes in a piped log:\n{}",
        lines.join("\n")
    );
}

#[test]
fn bad_configuration_is_refused() {
    let output = Command::new(bin_dir().join("ecatd"))
        .args(["--config", "/nonexistent/ecatd.toml", "--print-config"])
        .output()
        .unwrap();
    assert_eq!(
        output.status.code(),
        Some(i32::from(server::exit::CONFIGURATION))
    );
    assert!(String::from_utf8_lossy(&output.stderr).contains("/nonexistent/ecatd.toml"));
}

/// The worker threads of ecatd's API runtime, as its (JSON) `listening` line says.
fn api_threads(ecatd: &Ecatd) -> u64 {
    let log = ecatd.log();
    log.lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|v| v["fields"]["message"] == "listening")
        .and_then(|v| v["fields"]["api_threads"].as_u64())
        .unwrap_or_else(|| panic!("no listening line with api_threads in\n{log}"))
}

#[test]
fn the_api_runtime_has_the_configured_threads_one_by_default() {
    let ecatd = Ecatd::start(&[]);
    assert_eq!(api_threads(&ecatd), 1);
    drop(ecatd);
    let file = std::env::temp_dir().join(format!("ecatd-threads-{}.toml", std::process::id()));
    std::fs::write(&file, "api_threads = 3\n").unwrap();
    let ecatd = Ecatd::start(&["--config", file.to_str().unwrap()]);
    assert_eq!(api_threads(&ecatd), 3);
    drop(ecatd);
    std::fs::write(&file, "api_threads = 0\n").unwrap();
    let output = Command::new(bin_dir().join("ecatd"))
        .args([
            "--config",
            file.to_str().unwrap(),
            "--simulate",
            "--print-config",
        ])
        .output()
        .unwrap();
    std::fs::remove_file(&file).unwrap();
    assert_eq!(
        output.status.code(),
        Some(i32::from(server::exit::CONFIGURATION))
    );
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("api_threads must be 1 to 64, not 0"),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// Threads of process `pid` whose name starts with `prefix`, once there are `want` of them
/// (a thread names itself as it starts), within a deadline.
fn expect_threads(pid: u32, prefix: &str, want: usize) {
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let names: Vec<String> = std::fs::read_dir(format!("/proc/{pid}/task"))
            .unwrap()
            .filter_map(|task| std::fs::read_to_string(task.ok()?.path().join("comm")).ok())
            .map(|name| name.trim().to_string())
            .collect();
        let count = names.iter().filter(|n| n.starts_with(prefix)).count();
        if count == want {
            return;
        }
        assert!(
            Instant::now() < deadline,
            "want {want} threads {prefix}*: {names:?}"
        );
        std::thread::yield_now();
    }
}

#[test]
fn the_gateway_has_the_configured_receive_workers() {
    let serving = gateway_serving("[gateway]\non_bus_thread = false\nworkers = 3\n", 3);
    assert_eq!(serving["fields"]["workers"], 3, "{serving}");
    assert_eq!(serving["fields"]["on_bus_thread"], false, "{serving}");
}

/// By default the bus thread serves the gateway's UDP socket (the simulator's link and the
/// raw socket can both be waited on): one worker is left, for TCP and the timers.
#[test]
fn by_default_the_bus_thread_serves_the_gateway() {
    let serving = gateway_serving("[gateway]\nworkers = 3\n", 1);
    assert_eq!(serving["fields"]["on_bus_thread"], true, "{serving}");
}

/// Starts ecatd with `config`, expects `threads` gateway threads, and returns its
/// "mailbox gateway serving" log line.
fn gateway_serving(config: &str, threads: usize) -> serde_json::Value {
    let file = std::env::temp_dir().join(format!(
        "ecatd-gw-workers-{}-{threads}.toml",
        std::process::id()
    ));
    std::fs::write(&file, config).unwrap();
    let ecatd = Ecatd::start(&["--config", file.to_str().unwrap()]);
    std::fs::remove_file(&file).unwrap();
    let log = ecatd.log();
    let serving = log
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|v| v["fields"]["message"] == "mailbox gateway serving")
        .unwrap_or_else(|| panic!("no gateway line in\n{log}"));
    expect_threads(ecatd.pid(), "ecat-gateway-", threads);
    serving
}

/// The whole shutdown's budget (ecatd's default `shutdown_timeout_ms`) and a margin for the
/// process to start its exit and the test to see it.
const SHUTDOWN: Duration = Duration::from_secs(5);
const MARGIN: Duration = Duration::from_secs(3);

/// AL status INIT and SAFEOP, no error indication (ETG.1000.6 §5.3.2, spec-notes §al).
const INIT: (u16, &str) = (0x0001, "INIT");
const SAFEOP: (u16, &str) = (0x0004, "SAFEOP");

/// Sends SIGTERM, checks that ecatd exits 0 within the shutdown budget and that every slave
/// is in the given state (AL status, name) afterwards: on veth read back from the segment, with the
/// in-process simulator as ecatd confirmed it by broadcast read (its own log).
fn terminate_and_check(ecatd: &mut Ecatd, slaves: usize, (status, name): (u16, &str)) {
    let sent = Instant::now();
    let exit = ecatd.terminate(SHUTDOWN + MARGIN);
    let took = sent.elapsed();
    let log = ecatd.log();
    let exit = exit.unwrap_or_else(|| panic!("ecatd did not exit in time:\n{log}"));
    assert_eq!(exit.code(), Some(0), "{log}");
    assert!(took < SHUTDOWN + MARGIN, "{took:?}\n{log}");
    let shutting = log.find("shutting down").expect("a shutdown line");
    let safe = log
        .find("slaves in the safe state")
        .unwrap_or_else(|| panic!("no safe-state confirmation:\n{log}"));
    let stopped = log.find("\"stopped\"").expect("a stopped line");
    assert!(shutting < safe && safe < stopped, "{log}");
    assert!(log.contains("SIGTERM"), "{log}");
    if let Some(states) = ecatd.segment_al_states() {
        assert_eq!(states, vec![status; slaves], "AL status by position\n{log}");
    } else {
        let line = log
            .lines()
            .find(|l| l.contains("slaves in the safe state"))
            .unwrap();
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        assert_eq!(v["fields"]["slaves"], slaves, "{line}");
        assert_eq!(v["fields"]["state"], name, "{line}");
    }
}

#[test]
fn sigterm_with_open_event_streams_reaches_init() {
    let mut ecatd = Ecatd::start(&[]);
    let slaves = sim::topology::Topology::default_segment().slaves.len();
    let mut sse = Streaming::start(Command::new("curl").args([
        "-s",
        "-N",
        "-i",
        "-H",
        "accept: text/event-stream",
        &format!("{}/api/v1/events", ecatd.http),
    ]));
    let mut grpc = Streaming::start(
        Command::new(grpcurl_path())
            .args(["-plaintext", "-v", "-d", "{}", &ecatd.grpc])
            .arg("ecat.v1.BusService/WatchEvents"),
    );
    sse.wait_for_line("HTTP/1.1 200");
    grpc.wait_for_line("Response headers received");
    terminate_and_check(&mut ecatd, slaves, INIT);
    // ecatd closed both streams (the clients ended on their own, not by its exit alone).
    let deadline = Instant::now() + MARGIN;
    assert!(sse.ended_by(deadline), "the SSE stream is still open");
    assert!(
        grpc.ended_by(deadline),
        "the WatchEvents stream is still open"
    );
}

#[test]
fn sigterm_during_the_start_up_scan_reaches_init() {
    // Every mailbox reply 300 ms late: the scan's CoE exchanges take seconds.
    let slow = sim::topology::Topology::default_segment()
        .to_toml()
        .unwrap()
        .replace(
            "hop_delay_ns = 150\n",
            "hop_delay_ns = 150\nresponse_delay_us = 300000\n",
        );
    assert!(slow.contains("response_delay_us"), "{slow}");
    let slaves = sim::topology::Topology::from_toml(&slow)
        .unwrap()
        .slaves
        .len();
    let file = std::env::temp_dir().join(format!("ecatd-slow-scan-{}.toml", std::process::id()));
    std::fs::write(&file, slow).unwrap();
    let mut ecatd = Ecatd::start_listening(&["--simulate", file.to_str().unwrap()], &[]);
    terminate_and_check(&mut ecatd, slaves, INIT);
    std::fs::remove_file(&file).unwrap();
    let log = ecatd.log();
    assert!(
        !log.contains("\"ready\"") && !log.contains("segment scanned"),
        "the signal came after the scan; make it slower:\n{log}"
    );
}

#[test]
fn sigterm_with_safe_state_safeop_leaves_the_slaves_in_safeop() {
    let mut ecatd = Ecatd::start(&["--safe-state", "safeop"]);
    let slaves = sim::topology::Topology::default_segment().slaves.len();
    terminate_and_check(&mut ecatd, slaves, SAFEOP);
}

#[test]
fn a_second_sigterm_exits_at_once() {
    // Mailbox replies 2 s late: a rescan takes seconds, and the shutdown waits for it (a
    // third of a 60 s budget) unless a second signal cuts it short.
    let slow = sim::topology::Topology::default_segment()
        .to_toml()
        .unwrap()
        .replace(
            "hop_delay_ns = 150\n",
            "hop_delay_ns = 150\nresponse_delay_us = 2000000\n",
        );
    let dir = std::env::temp_dir();
    let topology = dir.join(format!("ecatd-second-signal-{}.toml", std::process::id()));
    let config = dir.join(format!(
        "ecatd-second-signal-{}.conf.toml",
        std::process::id()
    ));
    std::fs::write(&topology, slow).unwrap();
    std::fs::write(&config, "shutdown_timeout_ms = 60000\n").unwrap();
    let mut ecatd = Ecatd::start_with(
        &["--simulate", topology.to_str().unwrap()],
        &["--config", config.to_str().unwrap()],
    );
    let mut rescan = Streaming::start(Command::new("curl").args([
        "-s",
        "-X",
        "POST",
        "-H",
        "X-Ecat-Client: tests",
        &format!("{}/api/v1/rescan", ecatd.http),
    ]));
    // The rescan is under way once the slaves it found before are gone or leave OP.
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let (status, body) =
            server_support::curl(&["-s", &format!("{}/api/v1/slaves", ecatd.http)]);
        let slaves: serde_json::Value = serde_json::from_str(&body).unwrap_or_default();
        let list = slaves["slaves"].as_array().or(slaves.as_array()).cloned();
        if status == 200
            && list.is_some_and(|l| l.is_empty() || l.iter().any(|s| s["state"] != "OP"))
        {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the rescan did not start: {body}"
        );
        // Poll interval of the state check; the loop ends on the condition or the deadline.
        std::thread::sleep(Duration::from_millis(20));
    }
    let pid = ecatd.pid() as libc::pid_t;
    // SAFETY: `kill` on our own child's pid, which has not been reaped yet.
    unsafe { libc::kill(pid, libc::SIGTERM) };
    let deadline = Instant::now() + Duration::from_secs(10);
    while !ecatd.log().contains("shutting down") {
        assert!(Instant::now() < deadline, "no shutdown:\n{}", ecatd.log());
        // Poll interval of the log check; the loop ends on the line or the deadline.
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(!rescan.ended_by(Instant::now()), "the rescan ended already");
    let exit = ecatd.terminate(MARGIN);
    let log = ecatd.log();
    let exit = exit.unwrap_or_else(|| panic!("ecatd did not exit at once:\n{log}"));
    assert_eq!(exit.code(), Some(143), "{log}");
    assert!(log.contains("second signal"), "{log}");
    std::fs::remove_file(&topology).unwrap();
    std::fs::remove_file(&config).unwrap();
}

/// The next datagram systemd's notify socket receives, within a deadline.
fn next_notification(
    socket: &std::os::unix::net::UnixDatagram,
    log: impl Fn() -> String,
) -> String {
    let mut buf = [0u8; 256];
    match socket.recv(&mut buf) {
        Ok(n) => String::from_utf8_lossy(&buf[..n]).trim_end().to_owned(),
        Err(err) => panic!("no notification ({err}):\n{}", log()),
    }
}

#[test]
fn systemd_hears_ready_then_watchdog_pings_while_the_bus_runs_then_stopping() {
    let dir = std::env::temp_dir().join(format!("ecatd-notify-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("notify.sock");
    let socket = std::os::unix::net::UnixDatagram::bind(&path).unwrap();
    socket
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    // A 400 ms watchdog: pings every 200 ms, while the watch keeps the bus busy (100 ms).
    let mut ecatd = Ecatd::start_with_env(
        &["--simulate"],
        &[],
        &[
            ("NOTIFY_SOCKET", path.to_str().unwrap()),
            ("WATCHDOG_USEC", "400000"),
        ],
    );
    assert_eq!(next_notification(&socket, || ecatd.log()), "READY=1");
    for _ in 0..3 {
        assert_eq!(next_notification(&socket, || ecatd.log()), "WATCHDOG=1");
    }
    let exit = ecatd.terminate(SHUTDOWN + MARGIN).expect("ecatd exits");
    assert_eq!(exit.code(), Some(0), "{}", ecatd.log());
    // Pings already in the socket may come first; STOPPING=1 comes, and nothing after it.
    let mut said = Vec::new();
    loop {
        let note = next_notification(&socket, || ecatd.log());
        let stopping = note == "STOPPING=1";
        said.push(note);
        if stopping {
            break;
        }
        assert!(said.len() < 50, "no STOPPING=1 in {said:?}");
    }
    socket
        .set_read_timeout(Some(Duration::from_millis(1)))
        .unwrap();
    let mut buf = [0u8; 64];
    assert!(
        socket.recv(&mut buf).is_err(),
        "a notification after STOPPING=1"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_configuration_error_exits_78_and_a_taken_port_exits_1() {
    let output = Command::new(bin_dir().join("ecatd"))
        .args([
            "--grpc-listen",
            "127.0.0.1:0",
            "--http-listen",
            "127.0.0.1:0",
        ])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(78), "{said}");
    assert!(said.contains("no segment: pass --simulate"), "{said}");
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().to_string();
    let output = Command::new(bin_dir().join("ecatd"))
        .args([
            "--simulate",
            "--grpc-listen",
            &port,
            "--http-listen",
            "127.0.0.1:0",
        ])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{said}");
    assert!(said.contains(&port), "{said}");
}
