//! Cables and power: which links are up (ETG.1000.4 §6, DL status 0x0110).
//!
//! A link is up when its cable is connected and both of its ends have power. A cable into
//! a slave's port 0 is the slave's `plugged` flag, so unplugging slave *k* and cutting cable
//! *k* are one thing; the cable from the last slave back to the master's backup port exists
//! only in a ring. Every change sets both ends' port link bits at once, which counts a lost
//! link on the end that had one and raises its DL status change event, as a real ESC does.

use super::Segment;

impl Segment {
    /// Wires the last slave's port 1 to the master's backup port (`true`) or leaves it open,
    /// the end of a line (`false`). The last slave's port 1 link follows.
    pub fn set_ring(&mut self, ring: bool) {
        self.ring = ring;
        self.update_links();
    }

    /// Whether the segment is wired as a ring.
    pub fn is_ring(&self) -> bool {
        self.ring
    }

    /// Plugs or unplugs the cable into the port 0 of the slave at `position` (the same as
    /// cutting or reconnecting cable `position`). Unplugged, it sees no frames from the
    /// slave before it (in a line: it and every slave behind it see none); the slave before
    /// it shows port 1 without link. Link losses count in both ends' lost-link counters.
    pub fn set_plugged(&mut self, position: usize, plugged: bool) {
        if let Some(slave) = self.slaves.get_mut(position) {
            slave.plugged = plugged;
            self.update_links();
        }
    }

    /// Cuts cable `cable`: 0 = master primary → slave 0; k (1..len) = slave k-1 → slave k;
    /// len = last slave → master backup (ring only). Out of range: Err with a clear message,
    /// nothing changes. Cutting a cut cable changes nothing.
    pub fn break_cable(&mut self, cable: usize) -> Result<(), String> {
        let len = self.slaves.len();
        if let Some(slave) = self.slaves.get_mut(cable) {
            slave.plugged = false;
        } else if cable == len && self.ring {
            self.backup_cable = false;
        } else if cable == len {
            return Err(format!(
                "no cable {cable}: the segment is a line, its last cable is {}",
                len.saturating_sub(1)
            ));
        } else {
            return Err(format!(
                "no cable {cable}: the segment has {len} slaves, cables 0 to {}",
                if self.ring {
                    len
                } else {
                    len.saturating_sub(1)
                }
            ));
        }
        self.update_links();
        Ok(())
    }

    /// The slave at `position` loses power (neither processes nor forwards). Err for an
    /// unknown position. Its application sees its outputs go as on the way down to INIT,
    /// as a terminal without power does; it stays off until [`Segment::heal`].
    pub fn kill(&mut self, position: usize) -> Result<(), String> {
        let len = self.slaves.len();
        let slave = self
            .slaves
            .get_mut(position)
            .ok_or_else(|| format!("no slave at position {position} (the segment has {len})"))?;
        if !slave.powered {
            return Ok(());
        }
        slave.powered = false;
        // Nothing can read a dead ESC; resetting it now makes the application drop its
        // outputs and mailbox state at the moment the power goes.
        self.reset_slave(position);
        self.update_links();
        Ok(())
    }

    /// Every cable reconnected and every killed slave powered again (a killed slave comes
    /// back as after a power cycle: ESC in INIT, its clock restarted).
    pub fn heal(&mut self) {
        let now = self.time.now_ns();
        self.backup_cable = true;
        for slave in &mut self.slaves {
            slave.plugged = true;
            if !slave.powered {
                slave.powered = true;
                slave.esc.power_cycle(now);
            }
        }
        self.update_links();
    }

    /// Power-cycles the slave at `position`: its ESC goes back to power-on values (the SII
    /// image survives) and its neighbours see their links to it drop and come back. The
    /// device is not reset (the [`crate::device::Device`] trait has no reset; use
    /// [`super::Slave::replace_device`] for a fresh one); its queued mailbox messages are
    /// dropped with the ESC's mailbox. A killed slave stays without power (its ESC is
    /// reset all the same).
    pub fn power_cycle(&mut self, position: usize) {
        if position >= self.slaves.len() {
            return;
        }
        self.reset_slave(position);
        // Only links that are up can drop: the master's ports have no ESC to tell.
        if let Some(previous) = position.checked_sub(1).and_then(|p| self.slaves.get_mut(p))
            && previous.esc.link(1)
        {
            previous.esc.set_link(1, false);
            previous.esc.set_link(1, true);
        }
        if let Some(next) = self.slaves.get_mut(position + 1)
            && next.esc.link(0)
        {
            next.esc.set_link(0, false);
            next.esc.set_link(0, true);
        }
    }

    /// Whether cable `cable` carries frames: connected, and both of its ends powered (the
    /// master always is).
    pub(super) fn cable_up(&self, cable: usize) -> bool {
        let len = self.slaves.len();
        let connected = match self.slaves.get(cable) {
            Some(slave) => slave.plugged,
            None => cable == len && self.ring && self.backup_cable,
        };
        let powered = |position: Option<usize>| {
            position
                .and_then(|p| self.slaves.get(p))
                .is_none_or(|s| s.powered)
        };
        connected && powered(cable.checked_sub(1)) && powered(Some(cable))
    }

    /// Sets every ESC's port links from the cables and the power: slave *i*'s port 0 is up
    /// when cable *i* carries frames, its port 1 when cable *i + 1* does.
    pub(super) fn update_links(&mut self) {
        for position in 0..self.slaves.len() {
            let port0 = self.cable_up(position);
            let port1 = self.cable_up(position + 1);
            let esc = &mut self.slaves[position].esc;
            esc.set_link(0, port0);
            esc.set_link(1, port1);
        }
    }
}
