//! The scheduling ecatd gets as `deploy/systemd/ecatd.service` starts it: no real-time
//! policy for the process, only a limit (`LimitRTPRIO=`) under which the bus thread takes
//! the `[bus] rt_priority` of `deploy/ecatd.toml.example` for itself, every other thread
//! staying ordinary. ecatd is started with what a service manager would set between fork
//! and exec, and its threads are read back from `/proc`. Also: what ecatd says when the
//! priority is not granted, and when it is started real-time as a whole (the unit's old
//! `CPUSchedulingPolicy=fifo`).
//!
//! Needs root, as the whole suite does. The priority is granted here by root's
//! `CAP_SYS_NICE`, not by `RLIMIT_RTPRIO` as under the unit: raising that limit needs
//! `CAP_SYS_RESOURCE`, which the machines this suite runs on do not give root. That an
//! unprivileged thread may take `SCHED_FIFO` up to its `RLIMIT_RTPRIO` is the kernel's
//! rule (`sched(7)`); what is tested of the unit is that it sets the limit at or above the
//! example's priority and no real-time policy.

use crate::server_support;

use std::path::PathBuf;

use server_support::{Ecatd, curl, root};

/// `SCHED_OTHER` and `SCHED_FIFO` as `/proc/PID/task/TID/stat` reports a policy.
const SCHED_OTHER: u32 = 0;
const SCHED_FIFO: u32 = 1;

/// `CAP_SYS_NICE` (`linux/capability.h`; the libc crate does not name capabilities).
const CAP_SYS_NICE: libc::c_ulong = 23;

/// A configuration file for one test, removed on drop.
struct ConfigFile(PathBuf);

impl ConfigFile {
    fn new(name: &str, text: &str) -> ConfigFile {
        let path =
            std::env::temp_dir().join(format!("ecatd-sched-{}-{name}.toml", std::process::id()));
        std::fs::write(&path, text).expect("write the configuration");
        ConfigFile(path)
    }

    fn arg(&self) -> &str {
        self.0.to_str().expect("UTF-8 path")
    }
}

impl Drop for ConfigFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// The unit's lines that are not comments.
fn unit_settings() -> Vec<String> {
    let unit = std::fs::read_to_string(root().join("deploy/systemd/ecatd.service"))
        .expect("deploy/systemd/ecatd.service");
    unit.lines()
        .map(str::trim)
        .filter(|line| !line.is_empty() && !line.starts_with('#'))
        .map(str::to_owned)
        .collect()
}

/// The unit's `LimitRTPRIO=`.
fn unit_rtprio_limit() -> u64 {
    unit_settings()
        .iter()
        .find_map(|line| line.strip_prefix("LimitRTPRIO="))
        .expect("the unit sets LimitRTPRIO=")
        .parse()
        .expect("LimitRTPRIO= is a number")
}

/// The example configuration's `[bus] rt_priority`.
fn example_rt_priority() -> u64 {
    let text = std::fs::read_to_string(root().join("deploy/ecatd.toml.example"))
        .expect("deploy/ecatd.toml.example");
    let example: toml::Table = text.parse().expect("the example is TOML");
    example["bus"]["rt_priority"]
        .as_integer()
        .expect("the example sets [bus] rt_priority") as u64
}

/// Runs in ecatd's process before exec: no `CAP_SYS_NICE` (dropped from the bounding set,
/// so a root exec does not regain it) and `RLIMIT_RTPRIO` = `rtprio` (lowered only: see
/// the top), as systemd's `CapabilityBoundingSet=` without it and `LimitRTPRIO=` leave a
/// service.
fn without_sys_nice(rtprio: u64) -> Box<dyn FnMut() -> std::io::Result<()> + Send + Sync> {
    Box::new(move || {
        let limit = libc::rlimit {
            rlim_cur: rtprio,
            rlim_max: rtprio,
        };
        // SAFETY: plain system calls on the calling (child) process with valid arguments;
        // nothing is allocated or locked between fork and exec.
        unsafe {
            if libc::prctl(libc::PR_CAPBSET_DROP, CAP_SYS_NICE, 0, 0, 0) != 0
                || libc::setrlimit(libc::RLIMIT_RTPRIO, &limit) != 0
            {
                return Err(std::io::Error::last_os_error());
            }
        }
        Ok(())
    })
}

/// Every thread of process `pid`: its name, scheduling policy and real-time priority
/// (fields 41 and 40 of `/proc/PID/task/TID/stat`).
fn threads(pid: u32) -> Vec<(String, u32, u32)> {
    let tasks = std::fs::read_dir(format!("/proc/{pid}/task")).expect("ecatd's threads");
    let mut found = Vec::new();
    for task in tasks.flatten() {
        let Ok(stat) = std::fs::read_to_string(task.path().join("stat")) else {
            continue; // a thread that ended meanwhile
        };
        // The name is in parentheses and may hold spaces: the fields count from after it,
        // where field 3 (the state) is the first.
        let (name, rest) = stat
            .split_once(" (")
            .and_then(|(_, rest)| rest.rsplit_once(") "))
            .expect("stat's name field");
        let fields: Vec<&str> = rest.split_whitespace().collect();
        let field = |n: usize| fields[n - 3].parse::<u32>().expect("a number");
        found.push((name.to_owned(), field(41), field(40)));
    }
    found
}

/// `ecat_bus_thread_realtime` from ecatd's `/metrics`.
fn bus_thread_realtime(ecatd: &Ecatd) -> f64 {
    let (status, text) = curl(&["-s", &format!("{}/metrics", ecatd.http)]);
    assert_eq!(status, 200, "{text}");
    text.lines()
        .find_map(|line| line.strip_prefix("ecat_bus_thread_realtime "))
        .expect("ecat_bus_thread_realtime")
        .trim()
        .parse()
        .expect("a number")
}

/// Whether the log up to "ready" has a warning whose message starts with `start`.
fn warned(log: &[serde_json::Value], start: &str) -> Option<serde_json::Value> {
    log.iter()
        .find(|v| {
            v["level"] == "WARN"
                && v["fields"]["message"]
                    .as_str()
                    .is_some_and(|m| m.starts_with(start))
        })
        .cloned()
}

const NOT_GRANTED: &str = "[bus] rt_priority not granted";
const STARTED_REALTIME: &str = "ecatd was started real-time as a whole";

#[test]
fn the_unit_sets_a_limit_for_the_examples_priority_and_no_real_time_policy() {
    assert!(
        !unit_settings()
            .iter()
            .any(|line| line.starts_with("CPUSchedulingPolicy=")),
        "the unit must not make the whole process real-time (see the comment there)"
    );
    let limit = unit_rtprio_limit();
    let priority = example_rt_priority();
    assert!(
        (1..=limit).contains(&priority),
        "the example's rt_priority {priority} is not within the unit's LimitRTPRIO={limit}: \
         the bus thread would not get it"
    );
}

#[test]
fn the_bus_thread_alone_takes_the_examples_real_time_priority() {
    let priority = example_rt_priority();
    let config = ConfigFile::new("granted", &format!("[bus]\nrt_priority = {priority}\n"));
    let ecatd = Ecatd::start_with(&["--simulate"], &["--config", config.arg()]);

    let threads = threads(ecatd.pid());
    let bus: Vec<_> = threads.iter().filter(|t| t.0 == "ecat-bus").collect();
    assert_eq!(
        bus,
        [&("ecat-bus".to_owned(), SCHED_FIFO, priority as u32)],
        "{threads:?}"
    );
    let realtime: Vec<_> = threads
        .iter()
        .filter(|t| t.0 != "ecat-bus" && t.1 != SCHED_OTHER)
        .collect();
    assert!(realtime.is_empty(), "threads not ordinary: {realtime:?}");
    assert!(
        threads.iter().any(|t| t.0.starts_with("tokio")),
        "the API's threads are among them: {threads:?}"
    );
    assert_eq!(bus_thread_realtime(&ecatd), 1.0);
    let log = ecatd.log_until("ready");
    assert_eq!(warned(&log, NOT_GRANTED), None);
    assert_eq!(warned(&log, STARTED_REALTIME), None);
}

#[test]
fn without_the_limit_the_bus_thread_runs_ordinarily_and_ecatd_says_so() {
    let config = ConfigFile::new("nolimit", "[bus]\nrt_priority = 50\n");
    let ecatd = Ecatd::start_prepared(
        &["--simulate"],
        &["--config", config.arg()],
        without_sys_nice(0),
    );

    let threads = threads(ecatd.pid());
    assert!(
        threads.iter().all(|t| t.1 == SCHED_OTHER),
        "every thread ordinary: {threads:?}"
    );
    assert_eq!(bus_thread_realtime(&ecatd), 0.0);
    let log = ecatd.log_until("ready");
    let warning = warned(&log, NOT_GRANTED).expect("the warning before ready");
    assert_eq!(warning["fields"]["asked"], 50, "{warning}");
}

#[test]
fn a_process_started_real_time_as_a_whole_is_told_so() {
    let ecatd = Ecatd::start_prepared(
        &["--simulate"],
        &[],
        Box::new(|| {
            let param = libc::sched_param { sched_priority: 10 };
            // SAFETY: a system call on the calling (child) process with a valid argument.
            match unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) } {
                0 => Ok(()),
                _ => Err(std::io::Error::last_os_error()),
            }
        }),
    );

    // What the warning is about: every thread inherited the policy.
    let threads = threads(ecatd.pid());
    assert!(
        threads.iter().all(|t| (t.1, t.2) == (SCHED_FIFO, 10)),
        "{threads:?}"
    );
    let log = ecatd.log_until("ready");
    let warning = warned(&log, STARTED_REALTIME).expect("the warning before ready");
    assert_eq!(warning["fields"]["policy"], "SCHED_FIFO", "{warning}");
    assert_eq!(warning["fields"]["priority"], 10, "{warning}");
    // Nothing was asked of [bus] rt_priority: nothing to be refused.
    assert_eq!(warned(&log, NOT_GRANTED), None);
}
