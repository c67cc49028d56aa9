//! A streaming client (curl on the SSE route, grpcurl on `WatchEvents`, a slow request) whose
//! stdout lines are collected on a thread as they come; killed on drop.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long [`Streaming::wait_for`] waits for its condition.
const DEADLINE: Duration = Duration::from_secs(20);

/// A client process whose stdout lines are collected as they come; killed on drop.
pub struct Streaming {
    child: Child,
    lines: Arc<Mutex<Vec<String>>>,
}

impl Streaming {
    /// Spawns `command` with its stdout piped to the collecting thread.
    pub fn start(command: &mut Command) -> Streaming {
        let mut child = command
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("the client starts");
        let stdout = child.stdout.take().expect("piped");
        let lines = Arc::new(Mutex::new(Vec::new()));
        let keep = Arc::clone(&lines);
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                keep.lock().unwrap().push(line);
            }
        });
        Streaming { child, lines }
    }

    /// The output so far.
    pub fn text(&self) -> String {
        self.lines.lock().unwrap().join("\n")
    }

    /// Waits until `found` returns something for the output so far; panics naming `what`
    /// at the deadline.
    pub fn wait_for<T>(&self, what: &str, found: impl Fn(&str) -> Option<T>) -> T {
        let deadline = Instant::now() + DEADLINE;
        loop {
            if let Some(value) = found(&self.text()) {
                return value;
            }
            assert!(
                Instant::now() < deadline,
                "no {what} in time; output so far:\n{}",
                self.text()
            );
            // Poll interval of the output check; the loop ends on the condition or the
            // deadline.
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Waits until a line contains `wanted`.
    pub fn wait_for_line(&self, wanted: &str) {
        self.wait_for(&format!("{wanted:?}"), |t| t.contains(wanted).then_some(()));
    }

    /// Whether the client has ended (its stream closed) by `deadline`.
    pub fn ended_by(&mut self, deadline: Instant) -> bool {
        loop {
            if let Ok(Some(_)) = self.child.try_wait() {
                return true;
            }
            if Instant::now() > deadline {
                return false;
            }
            // Poll interval of the exit check; the loop ends on the exit or the deadline.
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Streaming {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
