//! The standard `process_*` metrics of the Prometheus client libraries, read from
//! `/proc/self` at each scrape (Linux only; elsewhere the families are absent).

use prometheus::proto::{MetricFamily, MetricType};

use super::family::Family;

/// Clock ticks per second of `/proc/<pid>/stat`'s times (USER_HZ, 100 on every Linux
/// architecture the kernel exports to user space).
const TICKS_PER_SECOND: f64 = 100.0;

fn gauge(name: &str, help: &str, value: f64) -> Option<MetricFamily> {
    Family::new(name, help, MetricType::GAUGE)
        .gauge(&[], value)
        .done()
}

/// The fields of `/proc/self/stat` after the command name (which may hold spaces).
fn stat_fields(stat: &str) -> Option<Vec<&str>> {
    let rest = &stat[stat.rfind(')')? + 1..];
    Some(rest.split_whitespace().collect())
}

/// A `/proc/self/status` line's value in kB, as bytes.
fn status_kb(status: &str, key: &str) -> Option<f64> {
    let line = status.lines().find(|l| l.starts_with(key))?;
    let kb: f64 = line[key.len()..].split_whitespace().next()?.parse().ok()?;
    Some(kb * 1024.0)
}

/// The boot time in seconds since the epoch (`btime` of `/proc/stat`).
fn boot_time() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    stat.lines()
        .find_map(|l| l.strip_prefix("btime "))?
        .trim()
        .parse()
        .ok()
}

/// The process families.
pub fn collect() -> Vec<Option<MetricFamily>> {
    let mut out = Vec::new();
    if let Ok(stat) = std::fs::read_to_string("/proc/self/stat")
        && let Some(fields) = stat_fields(&stat)
    {
        // proc(5): utime and stime are fields 14 and 15, starttime 22; `fields` starts at
        // field 3 (state).
        let ticks = |field: usize| -> Option<f64> { fields.get(field - 3)?.parse().ok() };
        if let (Some(user), Some(system)) = (ticks(14), ticks(15)) {
            out.push(
                Family::new(
                    "process_cpu_seconds_total",
                    "Total user and system CPU time spent in seconds.",
                    MetricType::COUNTER,
                )
                .counter(&[], (user + system) / TICKS_PER_SECOND)
                .done(),
            );
        }
        if let (Some(start), Some(boot)) = (ticks(22), boot_time()) {
            out.push(gauge(
                "process_start_time_seconds",
                "Start time of the process since unix epoch in seconds.",
                boot + start / TICKS_PER_SECOND,
            ));
        }
    }
    if let Ok(status) = std::fs::read_to_string("/proc/self/status") {
        if let Some(rss) = status_kb(&status, "VmRSS:") {
            out.push(gauge(
                "process_resident_memory_bytes",
                "Resident memory size in bytes.",
                rss,
            ));
        }
        if let Some(vsize) = status_kb(&status, "VmSize:") {
            out.push(gauge(
                "process_virtual_memory_bytes",
                "Virtual memory size in bytes.",
                vsize,
            ));
        }
        if let Some(threads) = status
            .lines()
            .find_map(|l| l.strip_prefix("Threads:"))
            .and_then(|n| n.trim().parse::<f64>().ok())
        {
            out.push(gauge("process_threads", "Number of OS threads.", threads));
        }
    }
    if let Ok(fds) = std::fs::read_dir("/proc/self/fd") {
        out.push(gauge(
            "process_open_fds",
            "Number of open file descriptors.",
            fds.count() as f64,
        ));
    }
    if let Ok(limits) = std::fs::read_to_string("/proc/self/limits")
        && let Some(max) = limits
            .lines()
            .find(|l| l.starts_with("Max open files"))
            .and_then(|l| l.split_whitespace().nth(3))
            .and_then(|n| n.parse::<f64>().ok())
    {
        out.push(gauge(
            "process_max_fds",
            "Maximum number of open file descriptors.",
            max,
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_command_name_with_spaces_and_parentheses_does_not_shift_the_fields() {
        let stat =
            "42 (tokio (w) 1) S 1 42 42 0 -1 4194304 10 0 0 0 250 50 0 0 20 0 9 0 1234 1000 200";
        let fields = stat_fields(stat).unwrap();
        assert_eq!(fields[0], "S");
        assert_eq!(fields[14 - 3], "250");
        assert_eq!(fields[15 - 3], "50");
        assert_eq!(fields[22 - 3], "1234");
    }

    #[test]
    fn this_process_has_the_families() {
        let names: Vec<String> = collect()
            .into_iter()
            .flatten()
            .map(|f| f.name().to_owned())
            .collect();
        for name in [
            "process_cpu_seconds_total",
            "process_start_time_seconds",
            "process_resident_memory_bytes",
            "process_open_fds",
            "process_max_fds",
        ] {
            assert!(names.iter().any(|n| n == name), "{name} missing: {names:?}");
        }
    }
}
