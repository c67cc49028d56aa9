//! The CPU the threads of a process have run so far, from the scheduler's own accounting
//! (`/proc/PID/task/TID/schedstat`, its first field: nanoseconds on a CPU; exact, not
//! sampled), as the request benchmarks divide it among their requests.

/// Each live thread of process `pid` (a number, or `self`): its name (`comm`) and the
/// nanoseconds it has run. Empty when the process is gone; a thread that ends while it is
/// read is left out.
pub fn threads(pid: &str) -> Vec<(String, u64)> {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return Vec::new();
    };
    tasks
        .flatten()
        .filter_map(|task| {
            let ns = std::fs::read_to_string(task.path().join("schedstat"))
                .ok()?
                .split_whitespace()
                .next()?
                .parse::<u64>()
                .ok()?;
            let name = std::fs::read_to_string(task.path().join("comm")).ok()?;
            Some((name.trim().to_owned(), ns))
        })
        .collect()
}

/// How often the threads of process `pid` left their CPU, summed by thread name: the
/// times they went to sleep (`voluntary_ctxt_switches` in `/proc/PID/task/TID/status`) and
/// the times the scheduler took them off it while they could still run
/// (`nonvoluntary_ctxt_switches`). Each sleep is a wake-up later: on a VM, an interrupt
/// across vCPUs, the cost the request benchmarks look for.
pub fn switches(pid: &str) -> std::collections::BTreeMap<String, (u64, u64)> {
    let mut by_name = std::collections::BTreeMap::new();
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return by_name;
    };
    for task in tasks.flatten() {
        let Ok(status) = std::fs::read_to_string(task.path().join("status")) else {
            continue;
        };
        let field = |key: &str| -> Option<u64> {
            status
                .lines()
                .find_map(|line| line.strip_prefix(key))?
                .trim()
                .parse()
                .ok()
        };
        let (Some(name), Some(slept), Some(preempted)) = (
            status.lines().find_map(|line| line.strip_prefix("Name:")),
            field("voluntary_ctxt_switches:"),
            field("nonvoluntary_ctxt_switches:"),
        ) else {
            continue;
        };
        let entry: &mut (u64, u64) = by_name.entry(name.trim().to_owned()).or_default();
        entry.0 += slept;
        entry.1 += preempted;
    }
    by_name
}
