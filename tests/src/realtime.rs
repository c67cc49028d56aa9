//! Starting a process as a control program is deployed: `SCHED_FIFO` below ecatd's bus
//! thread, set between fork and exec so that it runs real-time from its first instruction.

use std::os::unix::process::CommandExt;
use std::process::Command;

/// Makes `command` start under `SCHED_FIFO` at `priority` (the spawn fails if the kernel
/// refuses it).
pub fn fifo(command: &mut Command, priority: i32) -> &mut Command {
    // SAFETY: only a system call between fork and exec, on plain data.
    unsafe {
        command.pre_exec(move || {
            let param = libc::sched_param {
                sched_priority: priority,
            };
            if libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        })
    }
}
