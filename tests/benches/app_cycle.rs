//! A control program in its own process on ecatd's cycle (docs/application.md), for each
//! client library (Rust, C, Python) at 1 ms and 250 µs, next to the floor: the same loop in
//! process, as a master-core [`CycleHook`] on the bus thread.
//!
//! ```text
//! cargo bench -p ecat-tests --bench app_cycle
//! APP_CYCLE_SECONDS=60 cargo bench -p ecat-tests --bench app_cycle
//! ```
//!
//! Each row: `ecatd --simulate` (release: `server_support::bin_dir` builds release for an
//! optimised caller) with `[bus] cycle` and `rt_priority = 50`, and the test program's
//! `bench SECONDS` scenario (tests/src/bin/app_program.rs, tests/c/app_program.c,
//! tests/py/app_program.py) run at `SCHED_FIFO` 40 for `APP_CYCLE_SECONDS` (default 10).
//! Every cycle the program reads the DI8, writes the DO8 and commits: the DO8's low nibble
//! tags the commit, its high nibble is the DI8's high nibble plus one. The simulator wires
//! the DO8 to the DI8 within a frame, so the DI8's low nibble in cycle `c` names the commit
//! that frame `c` carried, read from the slot the program copied (no race with the next
//! frame). Per row:
//! - **wake-up latency**: the program's `CLOCK_MONOTONIC` right after its wait returned,
//!   minus the cycle's publication time ecatd stamps into the slot (`published_ns`); p50,
//!   p99 and max;
//! - **turnaround**: for each commit, whether the next frame carried it (as in process),
//!   a later frame (the next cycle's DI8 did not show it), or no frame (the program's next
//!   commit replaced it before a frame was built); a commit whose next cycle the program
//!   missed is counted apart (`after a miss`: that frame or a later one carried it, the
//!   program cannot tell which);
//! - **missed cycles**: gaps in the cycle numbers the program's waits returned;
//! - **steal**: the hypervisor's steal time during the row (`/proc/stat`, all vCPUs),
//!   which no scheduling inside the VM prevents: read misses beside it.
//!
//! The floor rows run the same loop in process on master-core and the in-process
//! simulator (as `ecatd --simulate` opens it), the bus thread at `SCHED_FIFO` 50: the hook
//! stamps the cycle as ecatd's publish does and "wakes" by a direct call, computes in
//! `after_receive` into a pending buffer that the next `before_send` puts into the frame.
//!
//! `APP_CYCLE_CPU=N` pins ecatd's bus thread (`[bus] cpu = N`) and every program to CPU
//! `N`: the program then wakes on the CPU the cycle completed on, with no inter-processor
//! interrupt between them (and runs only when the bus thread sleeps).
//!
//! Needs root (`SCHED_FIFO`), `cc` and `python3` (`ECATD_PYTHON` overrides). Not part of
//! CI: the rows depend on the machine's load.

#![allow(missing_docs)]

#[path = "../tests/server_support/mod.rs"]
mod server_support;

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use master_core::bus::{Bus, BusConfig, ThreadPriority};
use master_core::master::{
    CompletedCycle, CycleHook, Master, MasterConfig, OutgoingImage, SlaveAddress,
};
use serde_json::Value;
use server_support::{Ecatd, root};
use sim::link::InProcessLink;
use sim::topology::{Topology, build};

/// The bus thread's real-time priority (ecatd's `[bus] rt_priority`, and the floor's).
const BUS_PRIORITY: u8 = 50;
/// The control program's `SCHED_FIFO` priority.
const PROGRAM_PRIORITY: libc::c_int = 40;
/// The goal for the wake-up latency's p99, µs.
const WAKE_P99_GOAL_US: f64 = 50.0;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Client {
    Floor,
    Rust,
    C,
    Python,
}

impl Client {
    fn name(self) -> &'static str {
        match self {
            Client::Floor => "in-process floor",
            Client::Rust => "Rust",
            Client::C => "C",
            Client::Python => "Python",
        }
    }
}

/// What one row measured (the JSON line of a program's `bench` scenario).
#[derive(Debug, Clone)]
struct Row {
    client: Client,
    period: Duration,
    cycles: u64,
    missed: u64,
    /// Commits the next frame carried.
    next_frame: u64,
    /// Commits a later frame carried (not the next: the program saw it without them).
    later: u64,
    /// Commits no frame carried (replaced by the next before a frame took them).
    replaced: u64,
    /// Commits whose next cycle the program missed (carried then or later).
    after_miss: u64,
    wake_p50_ns: u64,
    wake_p99_ns: u64,
    wake_max_ns: u64,
    /// Steal time during the row, ms (all vCPUs).
    steal_ms: f64,
    /// The row's wall time.
    wall: Duration,
}

impl Row {
    fn from_json(client: Client, period: Duration, v: &Value) -> Row {
        let n = |key: &str| {
            v[key]
                .as_u64()
                .unwrap_or_else(|| panic!("{client:?}: no {key} in {v}"))
        };
        assert_eq!(
            n("period_ns"),
            period.as_nanos() as u64,
            "{client:?}: ecatd runs another period"
        );
        assert_eq!(n("unstamped"), 0, "ecatd stamps every slot");
        Row {
            client,
            period,
            cycles: n("cycles"),
            missed: n("missed"),
            next_frame: n("next_frame"),
            later: n("later"),
            replaced: n("replaced"),
            after_miss: n("after_miss"),
            wake_p50_ns: n("wake_p50_ns"),
            wake_p99_ns: n("wake_p99_ns"),
            wake_max_ns: n("wake_max_ns"),
            steal_ms: 0.0,
            wall: Duration::ZERO,
        }
    }

    /// Commits whose turnaround the program could tell.
    fn judged(&self) -> u64 {
        self.next_frame + self.later + self.replaced
    }

    /// Commits the program saw were not in the next frame: later, or never.
    fn late(&self) -> u64 {
        self.later + self.replaced
    }

    fn share(&self, count: u64) -> f64 {
        100.0 * count as f64 / self.judged().max(1) as f64
    }

    /// Steal as a share of the CPU time the run had (wall × vCPUs).
    fn steal_percent(&self) -> f64 {
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
        100.0 * self.steal_ms / (self.wall.as_secs_f64() * 1000.0 * cpus).max(1e-9)
    }
}

// --- steal time -------------------------------------------------------------------------

/// The steal time of all vCPUs so far, in clock ticks: the 8th number of `/proc/stat`'s
/// `cpu` line.
fn steal_ticks() -> u64 {
    let stat = std::fs::read_to_string("/proc/stat").expect("/proc/stat");
    stat.lines()
        .find(|l| l.starts_with("cpu "))
        .and_then(|l| l.split_whitespace().nth(8))
        .and_then(|v| v.parse().ok())
        .unwrap_or(0)
}

fn ticks_to_ms(ticks: u64) -> f64 {
    // SAFETY: sysconf only reads a constant.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1);
    ticks as f64 * 1000.0 / hz as f64
}

/// Runs `row`, recording the steal time and wall time it took.
fn measured(row: impl FnOnce() -> Row) -> Row {
    let (steal, start) = (steal_ticks(), Instant::now());
    let mut row = row();
    row.wall = start.elapsed();
    row.steal_ms = ticks_to_ms(steal_ticks().saturating_sub(steal));
    row
}

fn monotonic_ns() -> u64 {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid clock id and a live timespec to fill.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut now) };
    now.tv_sec as u64 * 1_000_000_000 + now.tv_nsec as u64
}

// --- the floor: the same loop in process ---------------------------------------------------

/// The program's loop as a [`CycleHook`]: what the test programs' `bench` scenario does,
/// with the publication and the wake-up one direct call apart.
struct FloorHook {
    /// Byte of the DO8 in the image, byte of the DI8.
    do8: usize,
    di8: usize,
    state: Mutex<FloorState>,
}

#[derive(Default)]
struct FloorState {
    /// The output computed in the last `after_receive`, for the next frame.
    next: Option<u8>,
    /// Record from the next cycle on.
    recording: bool,
    last: Option<u64>,
    first: u64,
    missed: u64,
    commits: u64,
    pending: VecDeque<(u64, u64)>,
    next_frame: u64,
    later: u64,
    replaced: u64,
    after_miss: u64,
    wakes: Vec<u64>,
}

impl CycleHook for FloorHook {
    fn before_send(&self, image: &mut OutgoingImage<'_>) {
        let mut st = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        if let (Some(value), Some(byte)) = (st.next.take(), image.outputs.get_mut(self.do8)) {
            *byte = value;
        }
    }

    fn after_receive(&self, cycle: &CompletedCycle<'_>) {
        // Where ecatd's hook stamps the slot it publishes...
        let published = monotonic_ns();
        let mut st = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        if !st.recording {
            return;
        }
        // ...and the program runs right away: its "wake-up" is this call.
        let now = monotonic_ns();
        st.wakes.push(now - published);
        let c = cycle.cycle;
        let last = st.last.unwrap_or(c - 1);
        if st.last.is_none() {
            st.first = c;
        }
        st.missed += c - last - 1;
        let seen = cycle.inputs.get(self.di8).copied().unwrap_or(0);
        if let Some(at) = st
            .pending
            .iter()
            .position(|&(n, _)| n & 0xF == u64::from(seen & 0xF))
        {
            let made = st.pending[at].1;
            st.replaced += at as u64;
            match (last == made, c == made + 1) {
                (true, true) => st.next_frame += 1,
                (true, false) => st.after_miss += 1,
                (false, _) => st.later += 1,
            }
            st.pending.drain(..=at);
        }
        st.last = Some(c);
        st.commits += 1;
        let value = ((seen >> 4).wrapping_add(1) << 4) | (st.commits & 0xF) as u8;
        st.next = Some(value);
        let commit = st.commits;
        st.pending.push_back((commit, c));
        if st.pending.len() > 8 {
            st.pending.pop_front();
            st.replaced += 1;
        }
    }
}

/// The byte in the image of `index:01..08` of the slave at `position` (one whole byte).
fn channel_byte(master: &Master, position: u16, index: u16) -> usize {
    let entries = master
        .entries(SlaveAddress::Position(position))
        .expect("entries");
    let first = entries
        .iter()
        .find(|e| e.index == index && e.subindex == 1)
        .expect("channel 1 mapped");
    for e in entries.iter().filter(|e| e.index == index) {
        assert_eq!(
            e.bit_offset,
            first.bit_offset + u32::from(e.subindex - 1),
            "channels in one byte"
        );
    }
    assert_eq!(first.bit_offset % 8, 0, "the channels start a byte");
    first.bit_offset as usize / 8
}

fn floor(period: Duration, seconds: u64) -> Row {
    let segment = build(&Topology::default_segment()).expect("segment");
    let (bus, thread) = Bus::start(
        InProcessLink::new(segment),
        BusConfig {
            priority: ThreadPriority::Realtime(BUS_PRIORITY),
            ..BusConfig::default()
        },
    )
    .expect("bus");
    // As `server::segment::open` starts ecatd's master, at the row's period.
    let master = Master::start(
        bus.clone(),
        MasterConfig {
            cycle_period: period,
            ..MasterConfig::default()
        },
    )
    .expect("master");
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .expect("runtime");
    let report = runtime.block_on(master.scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let hook = Arc::new(FloorHook {
        do8: channel_byte(&master, 1, 0x7000),
        di8: channel_byte(&master, 2, 0x6000),
        state: Mutex::new(FloorState {
            wakes: Vec::with_capacity(
                (seconds * 1_000_000_000 / period.as_nanos() as u64) as usize + 4096,
            ),
            ..FloorState::default()
        }),
    });
    let installed: Arc<dyn CycleHook> = hook.clone();
    master.set_cycle_hook(Some(installed));
    // Settle, then record for the run.
    std::thread::sleep(Duration::from_millis(500));
    hook.state
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .recording = true;
    std::thread::sleep(Duration::from_secs(seconds));
    master.set_cycle_hook(None);
    drop(master);
    bus.shutdown();
    let _ = thread.join();
    let mut st = std::mem::take(&mut *hook.state.lock().unwrap_or_else(PoisonError::into_inner));
    st.wakes.sort_unstable();
    let at = |q: f64| st.wakes[((st.wakes.len() - 1) as f64 * q) as usize];
    Row {
        client: Client::Floor,
        period,
        cycles: st.last.unwrap_or(st.first) - st.first,
        missed: st.missed,
        next_frame: st.next_frame,
        later: st.later,
        replaced: st.replaced,
        after_miss: st.after_miss,
        wake_p50_ns: at(0.50),
        wake_p99_ns: at(0.99),
        wake_max_ns: *st.wakes.last().expect("cycles ran"),
        steal_ms: 0.0,
        wall: Duration::ZERO,
    }
}

// --- the programs -------------------------------------------------------------------------

/// The C program, built once from `clients/c` and `tests/c/app_program.c`.
fn c_program() -> PathBuf {
    let dir = root().join("target").join("app-c");
    std::fs::create_dir_all(&dir).expect("target/app-c");
    let exe = dir.join(format!("app_cycle_{}", std::process::id()));
    let status = Command::new("cc")
        .args([
            "-O2",
            "-std=c11",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-pedantic",
        ])
        .arg("-I")
        .arg(root().join("clients/c"))
        .arg("-o")
        .arg(&exe)
        .arg(root().join("tests/c/app_program.c"))
        .arg(root().join("clients/c/ecat_app.c"))
        .status()
        .expect("cc runs");
    assert!(status.success(), "the C client and its program compile");
    exe
}

fn python() -> PathBuf {
    std::env::var_os("ECATD_PYTHON").map_or_else(|| PathBuf::from("python3"), PathBuf::from)
}

/// Runs the `bench` scenario of `client` against `socket` for `seconds`, real-time when
/// `realtime`, pinned to `cpu` if given; its JSON line.
fn run_program(
    client: Client,
    c_exe: &Path,
    socket: &Path,
    seconds: u64,
    realtime: bool,
    cpu: Option<usize>,
) -> Value {
    let mut command = match client {
        Client::Rust => Command::new(env!("CARGO_BIN_EXE_app_program")),
        Client::C => Command::new(c_exe),
        Client::Python => {
            let mut c = Command::new(python());
            c.arg(root().join("tests/py/app_program.py"))
                .env("PYTHONPATH", root().join("clients/python"));
            c
        }
        Client::Floor => unreachable!("the floor runs in process"),
    };
    command
        .arg(socket)
        .arg("bench")
        .arg(seconds.to_string())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    if let Some(cpu) = cpu {
        use std::os::unix::process::CommandExt;
        // SAFETY: `cpu_set_t` is plain data; only system calls between fork and exec.
        unsafe {
            command.pre_exec(move || {
                let mut only: libc::cpu_set_t = std::mem::zeroed();
                libc::CPU_SET(cpu, &mut only);
                if libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &only) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            })
        };
    }
    if realtime {
        ecat_tests::realtime::fifo(&mut command, PROGRAM_PRIORITY);
    }
    let output = command.output().expect("the program runs");
    let stdout = String::from_utf8_lossy(&output.stdout);
    let line = stdout.lines().last().unwrap_or_default();
    let value: Value = serde_json::from_str(line).unwrap_or_else(|_| {
        panic!(
            "{client:?}: not JSON: {stdout}\n{}",
            String::from_utf8_lossy(&output.stderr)
        )
    });
    assert!(
        output.status.success(),
        "{client:?} failed: {value}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    value
}

/// The threads of process `pid` scheduled `SCHED_FIFO` or `SCHED_RR`.
fn realtime_threads(pid: u32) -> usize {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return 0;
    };
    tasks
        .filter_map(Result::ok)
        .filter_map(|t| std::fs::read_to_string(t.path().join("stat")).ok())
        .filter(|stat| {
            // Field 41 (policy), counted after the command's closing parenthesis (field 2).
            let policy = stat
                .rsplit_once(')')
                .and_then(|(_, rest)| rest.split_whitespace().nth(41 - 3))
                .and_then(|p| p.parse::<u32>().ok());
            matches!(policy, Some(1 | 2))
        })
        .count()
}

fn period_text(period: Duration) -> String {
    if period >= Duration::from_millis(1) {
        format!("{} ms", period.as_millis())
    } else {
        format!("{} µs", period.as_micros())
    }
}

fn print_row(r: &Row) {
    let us = |ns: u64| ns as f64 / 1000.0;
    println!(
        "| {} | {} | {:.1} | {:.1} | {:.1} | {:.2} % | {} | {} | {} | {} | {} | {:.0} ms ({:.2} %) |",
        r.client.name(),
        period_text(r.period),
        us(r.wake_p50_ns),
        us(r.wake_p99_ns),
        us(r.wake_max_ns),
        r.share(r.next_frame),
        r.later,
        r.replaced,
        r.after_miss,
        r.missed,
        r.cycles,
        r.steal_ms,
        r.steal_percent(),
    );
}

fn main() {
    let seconds: u64 = std::env::var("APP_CYCLE_SECONDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10)
        .max(1);
    // SAFETY: geteuid only reads the process's credentials.
    let root_user = unsafe { libc::geteuid() } == 0;
    if !root_user {
        eprintln!("not root: the programs run without SCHED_FIFO, ecatd's bus thread too");
    }
    let cpu: Option<usize> = std::env::var("APP_CYCLE_CPU")
        .ok()
        .and_then(|v| v.parse().ok());
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    assert!(
        cpu.is_none_or(|cpu| cpu < cpus),
        "APP_CYCLE_CPU: this machine has CPUs 0..{cpus}"
    );
    let c_exe = c_program();
    let periods = [Duration::from_millis(1), Duration::from_micros(250)];
    let clients = [Client::Rust, Client::C, Client::Python];
    let mut rows = Vec::new();
    let mut bus_rt = Vec::new();
    for period in periods {
        eprintln!("{}: in-process floor, {seconds} s", period_text(period));
        rows.push(measured(|| floor(period, seconds)));
        let dir = std::env::temp_dir().join(format!(
            "ecatd-app-cycle-{}-{}",
            std::process::id(),
            period.as_micros()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("run dir");
        let socket = dir.join("app.sock");
        let config = dir.join("ecatd.toml");
        // A watchdog of a second: a stalled program is counted in its row (missed cycles,
        // late commits) instead of losing the outputs and ending the run.
        let watchdog = (Duration::from_secs(1).as_nanos() / period.as_nanos()).max(10);
        std::fs::write(
            &config,
            format!(
                "[bus]\ncycle = \"{}us\"\nrt_priority = {BUS_PRIORITY}\n{}\n[app]\nwatchdog = {watchdog}\n",
                period.as_micros(),
                cpu.map_or_else(String::new, |cpu| format!("cpu = {cpu}\n")),
            ),
        )
        .expect("config");
        let ecatd = Ecatd::start(&[
            "--app-socket",
            socket.to_str().expect("UTF-8 path"),
            "--config",
            config.to_str().expect("UTF-8 path"),
        ]);
        bus_rt.push((period, realtime_threads(ecatd.pid())));
        for client in clients {
            eprintln!("{}: {}, {seconds} s", period_text(period), client.name());
            // The last program's socket closed: let ecatd end its ownership first.
            std::thread::sleep(Duration::from_secs(1));
            rows.push(measured(|| {
                let value = run_program(client, &c_exe, &socket, seconds, root_user, cpu);
                Row::from_json(client, period, &value)
            }));
        }
        drop(ecatd);
        let _ = std::fs::remove_dir_all(&dir);
    }
    let _ = std::fs::remove_file(&c_exe);

    println!();
    println!(
        "Application interface: ecatd --simulate (release), bus thread SCHED_FIFO {BUS_PRIORITY}, \
         program SCHED_FIFO {PROGRAM_PRIORITY}{}, {seconds} s per row{}",
        if root_user {
            ""
        } else {
            " (NOT granted: not root)"
        },
        cpu.map_or_else(String::new, |cpu| format!(
            "; bus thread and programs pinned to CPU {cpu}"
        )),
    );
    for (period, threads) in &bus_rt {
        println!(
            "ecatd at {}: {threads} real-time thread(s) (the bus thread)",
            period_text(*period)
        );
    }
    println!();
    println!(
        "| client | period | wake p50 µs | wake p99 µs | wake max µs | next frame | later | never | after a miss | missed cycles | cycles | steal |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for period in periods {
        for r in rows.iter().filter(|r| r.period == period) {
            print_row(r);
        }
    }

    println!();
    println!("Goals:");
    let row = |client: Client, period: Duration| {
        rows.iter()
            .find(|r| r.client == client && r.period == period)
            .expect("row")
    };
    // Rust and C carry every commit in the next frame, as the floor does.
    for period in periods {
        let floor = row(Client::Floor, period);
        for client in [Client::Rust, Client::C] {
            let r = row(client, period);
            let met = floor.late() == 0 && r.late() == 0;
            println!(
                "- {} {}: turnaround equal to in-process (every commit in the next frame): {} \
                 ({:.2} % next frame, floor {:.2} %; {} of {} later or never; {} after a missed \
                 cycle; {} missed cycles, steal {:.0} ms)",
                client.name(),
                period_text(period),
                if met { "met" } else { "NOT met" },
                r.share(r.next_frame),
                floor.share(floor.next_frame),
                r.late(),
                r.judged(),
                r.after_miss,
                r.missed,
                r.steal_ms,
            );
        }
    }
    for period in periods {
        for client in clients {
            let r = row(client, period);
            let p99 = r.wake_p99_ns as f64 / 1000.0;
            println!(
                "- {} {}: wake p99 ≤ {WAKE_P99_GOAL_US:.0} µs with the bus thread real-time: {} \
                 (p99 {p99:.1} µs, max {:.1} µs)",
                client.name(),
                period_text(period),
                if p99 <= WAKE_P99_GOAL_US {
                    "met"
                } else {
                    "NOT met"
                },
                r.wake_max_ns as f64 / 1000.0,
            );
        }
    }
    let python = row(Client::Python, Duration::from_millis(1));
    let met = python.missed == 0 && python.late() == 0 && python.after_miss == 0;
    println!(
        "- Python keeps 1 kHz with 0 missed commits over {seconds} s: {} ({} missed cycles, \
         {} of {} commits later than the next frame or never, {} after a missed cycle, steal \
         {:.0} ms)",
        if met { "met" } else { "NOT met" },
        python.missed,
        python.late(),
        python.judged(),
        python.after_miss,
        python.steal_ms,
    );
}
