//! A control program for the application-interface tests, on the Rust client (`ecat-app`):
//! one scenario per run, one JSON line per result on stdout. The Python and C programs in
//! `tests/py/app_program.py` and `tests/c/app_program.c` run the same scenarios with their
//! libraries, so one test body checks all three.
//!
//! `app_program SOCKET SCENARIO [ARG]`:
//! - `drive`: claims, takes the drive (slave 0) through controlword 6, 7, 15 until the
//!   statusword says "operation enabled", sets target position 123456 and waits until the
//!   actual position reads it back;
//! - `mirror`: claims, writes eight patterns to the DO8 (slave 1, 0x7000:01..08) and counts
//!   the cycles until the DI8 (slave 2, 0x6000:01..08) reads each back;
//! - `hold`: claims (or reports the refusal), sets the DO8 to 0x01 and commits every cycle
//!   until killed;
//! - `monitor N`: read-only, reports the cycle numbers of N waits;
//! - `soak SECONDS`: claims and commits every cycle for that long, counting the cycles it
//!   missed and the commits the next frame did not carry, and reports the last commit the
//!   frames carried;
//! - `layout`: waits until the layout changes;
//! - `bench SECONDS`: the loop of the `app_cycle` benchmark (tests/benches/app_cycle.rs):
//!   claims, and every cycle reads the DI8, writes the DO8 and commits, for that long. The
//!   DO8's low nibble tags the commit (its number mod 16), its high nibble is the DI8's
//!   high nibble plus one (an output computed from the input just read). The DI8 reads the
//!   DO8 from the same frame on (the simulator's wire), so the DI8's low nibble in cycle
//!   `c` names the commit frame `c` carried. Reports the wake-up latency (the program's
//!   `CLOCK_MONOTONIC` after the wait minus the cycle's publication time) as p50, p99 and
//!   max; the commits the next frame carried (`next_frame`), those a later frame carried
//!   (`later`: the next cycle's DI8 did not show them), those no frame carried (`replaced`
//!   by the next commit before a frame took them), those whose next cycle the program
//!   missed (`after_miss`: carried by that frame or a later one, it cannot tell); and the
//!   cycles the program missed.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use ecat_app::{App, Error};

const WAIT: Duration = Duration::from_secs(2);

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (Some(socket), Some(scenario)) = (args.get(1), args.get(2)) else {
        eprintln!("usage: app_program SOCKET SCENARIO [ARG]");
        std::process::exit(2);
    };
    let arg = args.get(3).and_then(|a| a.parse::<u64>().ok());
    let socket = PathBuf::from(socket);
    let result = match scenario.as_str() {
        "drive" => drive(&socket),
        "mirror" => mirror(&socket),
        "hold" => hold(&socket),
        "monitor" => monitor(&socket, arg.unwrap_or(100)),
        "soak" => soak(&socket, arg.unwrap_or(60)),
        "layout" => layout(&socket),
        "bench" => bench(&socket, arg.unwrap_or(10)),
        other => {
            eprintln!("unknown scenario {other}");
            std::process::exit(2);
        }
    };
    if let Err(err) = result {
        println!(r#"{{"error": {:?}}}"#, err.to_string());
        std::process::exit(1);
    }
}

fn drive(socket: &std::path::Path) -> Result<(), Error> {
    let mut app = App::connect(Some(socket), false)?;
    let control = app.entry(0, 0x6040, 0)?;
    let status = app.entry(0, 0x6041, 0)?;
    let target = app.entry(0, 0x607A, 0)?;
    let actual = app.entry(0, 0x6064, 0)?;
    app.claim()?;
    let start = app.wait(WAIT)?;
    for (command, state) in [(6, 0x21), (7, 0x23), (15, 0x27)] {
        app.write(&control, command)?;
        app.commit()?;
        let deadline = app.cycle() + 100;
        while app.read(&status) & 0x6F != state {
            if app.wait(WAIT)? > deadline {
                return Err(Error::Protocol(format!(
                    "statusword {:#06x} after controlword {command}",
                    app.read(&status)
                )));
            }
            app.commit()?;
        }
    }
    app.write(&target, 123_456)?;
    app.commit()?;
    while app.read(&actual) != 123_456 {
        app.wait(WAIT)?;
        app.commit()?;
    }
    println!(
        r#"{{"statusword": {}, "actual": {}, "cycles": {}}}"#,
        app.read(&status),
        app.read(&actual),
        app.cycle() - start
    );
    Ok(())
}

fn mirror(socket: &std::path::Path) -> Result<(), Error> {
    let mut app = App::connect(Some(socket), false)?;
    let outputs: Vec<_> = (1..=8)
        .map(|ch| app.entry(1, 0x7000, ch))
        .collect::<Result<_, _>>()?;
    let inputs: Vec<_> = (1..=8)
        .map(|ch| app.entry(2, 0x6000, ch))
        .collect::<Result<_, _>>()?;
    app.claim()?;
    app.wait(WAIT)?;
    let mut worst = 0;
    for pattern in [0x01u8, 0x80, 0x55, 0xAA, 0xFF, 0x00, 0x0F, 0xF0] {
        for (bit, output) in outputs.iter().enumerate() {
            app.write(output, i64::from((pattern >> bit) & 1))?;
        }
        app.commit()?;
        let committed = app.cycle();
        loop {
            let cycle = app.wait(WAIT)?;
            let seen = inputs.iter().enumerate().fold(0u8, |acc, (bit, input)| {
                acc | ((app.read(input) as u8 & 1) << bit)
            });
            if seen == pattern {
                worst = worst.max(cycle - committed);
                break;
            }
            if cycle - committed > 50 {
                return Err(Error::Protocol(format!(
                    "DI8 reads {seen:#04x}, DO8 was given {pattern:#04x}"
                )));
            }
            app.commit()?;
        }
    }
    println!(r#"{{"patterns": 8, "worst_cycles": {worst}}}"#);
    Ok(())
}

fn hold(socket: &std::path::Path) -> Result<(), Error> {
    let mut app = App::connect(Some(socket), false)?;
    let outputs: Vec<_> = (1..=8)
        .map(|ch| app.entry(1, 0x7000, ch))
        .collect::<Result<_, _>>()?;
    match app.claim() {
        Ok(()) => println!(r#"{{"claimed": true}}"#),
        Err(Error::Refused(reason)) => {
            println!(r#"{{"claimed": false, "reason": {reason:?}}}"#);
            return Ok(());
        }
        Err(err) => return Err(err),
    }
    // The DO8 at exactly 0x01, told apart from any safe value the tests configure.
    for (channel, output) in outputs.iter().enumerate() {
        app.write(output, i64::from(channel == 0))?;
    }
    loop {
        app.wait(WAIT)?;
        app.commit()?;
    }
}

fn monitor(socket: &std::path::Path, waits: u64) -> Result<(), Error> {
    let mut app = App::connect(Some(socket), true)?;
    let refused = matches!(app.claim(), Err(Error::Refused(_)));
    let mut cycles = Vec::new();
    for _ in 0..waits {
        cycles.push(app.wait(WAIT)?);
    }
    println!(
        r#"{{"claim_refused": {refused}, "first": {}, "last": {}, "waits": {}}}"#,
        cycles.first().unwrap_or(&0),
        cycles.last().unwrap_or(&0),
        cycles.len()
    );
    Ok(())
}

fn soak(socket: &std::path::Path, seconds: u64) -> Result<(), Error> {
    let mut app = App::connect(Some(socket), false)?;
    let output = app.entry(1, 0x7000, 1)?;
    app.claim()?;
    let end = Instant::now() + Duration::from_secs(seconds);
    let first = app.wait(WAIT)?;
    let (mut last, mut missed, mut not_carried, mut commits) = (first, 0u64, 0u64, 0u64);
    while Instant::now() < end {
        let cycle = app.wait(WAIT)?;
        missed += cycle - last - 1;
        last = cycle;
        // The commit of the last cycle went out in this one's frame, unless it was late.
        if commits > 0 && app.applied() != commits {
            not_carried += 1;
        }
        app.write(&output, (cycle & 1) as i64)?;
        app.commit()?;
        commits += 1;
    }
    // The last commit goes out with the next frame at the latest.
    app.wait(WAIT)?;
    app.wait(WAIT)?;
    println!(
        r#"{{"cycles": {}, "missed": {missed}, "not_carried": {not_carried}, "commits": {commits}, "carried": {}, "period_ns": {}}}"#,
        last - first,
        app.applied(),
        app.period().as_nanos()
    );
    Ok(())
}

fn layout(socket: &std::path::Path) -> Result<(), Error> {
    let mut app = App::connect(Some(socket), true)?;
    let generation = app.generation();
    println!(r#"{{"attached": {generation}}}"#);
    loop {
        match app.wait(Duration::from_secs(30)) {
            Ok(_) => continue,
            Err(Error::LayoutChanged(next)) => {
                println!(r#"{{"layout_changed": {next}, "was": {generation}}}"#);
                return Ok(());
            }
            Err(err) => return Err(err),
        }
    }
}

/// `CLOCK_MONOTONIC` in nanoseconds: the clock ecatd stamps each cycle's publication with.
fn monotonic_ns() -> u64 {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid clock id and a live timespec to fill.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut now) };
    now.tv_sec as u64 * 1_000_000_000 + now.tv_nsec as u64
}

/// The sample at quantile `q` of the sorted `samples` (0 when there are none).
fn quantile(samples: &[u64], q: f64) -> u64 {
    samples
        .get(((samples.len().max(1) - 1) as f64 * q) as usize)
        .copied()
        .unwrap_or(0)
}

fn bench(socket: &std::path::Path, seconds: u64) -> Result<(), Error> {
    let mut app = App::connect(Some(socket), false)?;
    let outputs: Vec<_> = (1..=8)
        .map(|ch| app.entry(1, 0x7000, ch))
        .collect::<Result<_, _>>()?;
    let inputs: Vec<_> = (1..=8)
        .map(|ch| app.entry(2, 0x6000, ch))
        .collect::<Result<_, _>>()?;
    app.claim()?;
    let period_ns = app.period().as_nanos().max(1) as u64;
    let mut wakes = Vec::with_capacity((seconds * 1_000_000_000 / period_ns) as usize + 4096);
    // Commits not yet seen on the wire: (commit number, cycle it was computed in).
    let mut pending: VecDeque<(u64, u64)> = VecDeque::with_capacity(16);
    let (mut next_frame, mut later, mut after_miss, mut replaced) = (0u64, 0u64, 0u64, 0u64);
    let (mut missed, mut commits, mut unstamped) = (0u64, 0u64, 0u64);
    let first = app.wait(WAIT)?;
    let mut last = first;
    let end = Instant::now() + Duration::from_secs(seconds);
    while Instant::now() < end {
        let cycle = app.wait(WAIT)?;
        let now = monotonic_ns();
        match app.published_ns() {
            0 => unstamped += 1,
            published => wakes.push(now.saturating_sub(published)),
        }
        missed += cycle - last - 1;
        let seen = inputs.iter().enumerate().fold(0u8, |acc, (bit, input)| {
            acc | ((app.read(input) as u8 & 1) << bit)
        });
        // The commit this cycle's frame carried: its tag is on the DI8's low nibble. The
        // commits before it were replaced unseen; it was carried by the next frame if this
        // is the next cycle, by a later one if the program saw a cycle in between.
        if let Some(at) = pending
            .iter()
            .position(|&(n, _)| n & 0xF == u64::from(seen & 0xF))
        {
            let made = pending[at].1;
            replaced += at as u64;
            match (last == made, cycle == made + 1) {
                (true, true) => next_frame += 1,
                (true, false) => after_miss += 1,
                (false, _) => later += 1,
            }
            pending.drain(..=at);
        }
        last = cycle;
        commits += 1;
        let value = ((seen >> 4).wrapping_add(1) << 4) | (commits & 0xF) as u8;
        for (bit, output) in outputs.iter().enumerate() {
            app.write(output, i64::from((value >> bit) & 1))?;
        }
        app.commit()?;
        pending.push_back((commits, cycle));
        if pending.len() > 8 {
            // Eight commits without one on the wire: the oldest will never be told apart.
            pending.pop_front();
            replaced += 1;
        }
    }
    wakes.sort_unstable();
    println!(
        r#"{{"client": "rust", "period_ns": {period_ns}, "seconds": {seconds}, "cycles": {}, "waits": {}, "missed": {missed}, "commits": {commits}, "next_frame": {next_frame}, "later": {later}, "replaced": {replaced}, "after_miss": {after_miss}, "unseen": {}, "unstamped": {unstamped}, "wake_p50_ns": {}, "wake_p99_ns": {}, "wake_max_ns": {}}}"#,
        last - first,
        wakes.len() as u64 + unstamped,
        pending.len(),
        quantile(&wakes, 0.50),
        quantile(&wakes, 0.99),
        wakes.last().copied().unwrap_or(0),
    );
    Ok(())
}
