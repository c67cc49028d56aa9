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
