//! Keeps the mailbox engine in step with the slaves' states.
//!
//! A slave's mailbox works from PREOP on (its SyncManagers are set on INIT → PREOP) and
//! stops in INIT, and a slave that went through INIT (a reset, a power cycle) starts its
//! mailbox counter again. So the engine takes a slave's mailbox over each time the slave
//! enters PREOP from INIT (the standard mailbox) or enters BOOT (the bootstrap mailbox,
//! at other addresses), which also gives it a fresh counter, and lets it go when the slave
//! returns to INIT or leaves the segment.

use crate::wire::register::AlState;

use crate::master::context::Context;
use crate::master::info::SlaveInfo;

/// Called after the slave of `info` moved from `from` to `to`.
pub(crate) fn follow(ctx: &Context, info: &SlaveInfo, from: AlState, to: AlState) {
    let layout = match to {
        AlState::Init => {
            ctx.mailboxes.remove_slave(info.station);
            return;
        }
        AlState::Boot => info.boot_mailbox,
        AlState::PreOp if matches!(from, AlState::Init | AlState::Boot) => info.mailbox,
        _ => return,
    };
    match layout {
        Some(layout) => {
            ctx.mailboxes.add_slave(layout);
        }
        None => {
            ctx.mailboxes.remove_slave(info.station);
        }
    }
}

/// The slave of `info` left the segment (or is about to be reset): its mailbox is gone.
pub(crate) fn release(ctx: &Context, station: u16) {
    ctx.mailboxes.remove_slave(station);
    let position = station.wrapping_sub(ctx.config.station_base);
    ctx.image.map_status(position, None);
}

/// A new scan resets every slave: no mailbox survives it.
pub(crate) fn release_all(ctx: &Context) {
    for station in ctx.mailboxes.stations() {
        ctx.mailboxes.remove_slave(station);
    }
}
