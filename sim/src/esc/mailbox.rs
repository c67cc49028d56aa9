//! The mailbox SyncManagers seen from the slave firmware: SM0 (master → slave) delivers
//! complete messages to the device, SM1 (slave → master) is fed from the device's outbox
//! one message at a time, and the repeat procedure re-posts a lost message (spec-notes §mbx.handshake).

use std::collections::VecDeque;

use ecat_wire::mailbox::{HEADER_LEN, Mailbox};
use ecat_wire::register::al::AlState;
use ecat_wire::register::sync_manager::{SmActivate, SmDirection, SmPdiControl};

use crate::device::{Device, Outbox};

use super::Esc;
use super::sync_manager;

/// SM0: the master → slave mailbox.
pub(crate) const MAILBOX_OUT_SM: u8 = 0;
/// SM1: the slave → master mailbox.
pub(crate) const MAILBOX_IN_SM: u8 = 1;
/// How many replies a device may queue before it is told to wait.
const OUTBOX_CAPACITY: usize = 64;

/// Messages on their way from the device to the master.
#[derive(Debug)]
pub(crate) struct MailboxState {
    /// What the device queued.
    outbox: Outbox,
    /// Messages taken back out of SM1 by a repeat request; posted before the outbox.
    held: VecDeque<Vec<u8>>,
    /// The message currently in SM1, not yet completely read.
    in_sm1: Option<Vec<u8>>,
    /// The last message the master read completely: what a repeat request re-posts.
    backup: Option<Vec<u8>>,
}

impl MailboxState {
    /// Nothing queued.
    pub fn new() -> Self {
        MailboxState {
            outbox: Outbox::new(OUTBOX_CAPACITY),
            held: VecDeque::new(),
            in_sm1: None,
            backup: None,
        }
    }

    /// Drops everything (mailbox reset on the way down to INIT, power-on).
    pub fn clear(&mut self) {
        self.outbox.clear();
        self.held.clear();
        self.in_sm1 = None;
        self.backup = None;
    }

    /// Messages waiting to be posted.
    pub fn pending(&self) -> usize {
        self.outbox.len() + self.held.len()
    }
}

/// The message a master wrote into SM0: the header plus its declared length, clipped to
/// what the SyncManager holds. A header that is short or declares more than the SM holds
/// gives the whole buffer, so the device's mailbox layer can answer with a mailbox error.
fn message_of(buffer: &[u8]) -> &[u8] {
    match Mailbox::new_checked(buffer) {
        Ok(mailbox) => &buffer[..HEADER_LEN + usize::from(mailbox.length())],
        Err(_) => buffer,
    }
}

impl Esc {
    /// Whether the slave firmware runs its mailbox handler (PREOP, SAFEOP, OP, BOOT).
    fn mailbox_running(&self) -> bool {
        self.eeprom.loaded()
            && matches!(
                self.al_state(),
                AlState::PreOp | AlState::SafeOp | AlState::Op | AlState::Boot
            )
    }

    /// After a datagram: a committed SM0 goes to the device, and the next queued message
    /// goes into SM1 if it is empty.
    pub(crate) fn service_mailbox(&mut self, device: &mut dyn Device) {
        if !self.mailbox_running() {
            return;
        }
        self.note_sm1_read();
        // Posting first frees a place in the outbox for the reply to what SM0 may hold.
        self.post_next();
        // The firmware reads SM0 only when it has room for a reply, so a master that does
        // not read SM1 meets a full SM0 (WKC 0) instead of losing replies.
        let room = self.mailbox.outbox.len() < OUTBOX_CAPACITY;
        let taken = self
            .sms
            .get_mut(usize::from(MAILBOX_OUT_SM))
            .filter(|_| room)
            .and_then(|sm| sm.pdi_take(&mut self.mem));
        if let Some(buffer) = taken {
            let ctx = self.device_context();
            device.mailbox_received(message_of(&buffer), &ctx, &mut self.mailbox.outbox);
        }
        self.post_next();
    }

    /// At the end of a frame: the device may post unsolicited messages while SM1 is empty.
    pub(crate) fn poll_device(&mut self, device: &mut dyn Device) {
        if !self.mailbox_running() {
            return;
        }
        self.note_sm1_read();
        let sm1_empty = self
            .sms
            .get(usize::from(MAILBOX_IN_SM))
            .is_some_and(|sm| sm.is_mailbox(SmDirection::Read) && !sm.is_full());
        if sm1_empty {
            let ctx = self.device_context();
            device.poll(&ctx, &mut self.mailbox.outbox);
        }
    }

    /// A message in SM1 that the master has read completely becomes the backup.
    fn note_sm1_read(&mut self) {
        let full = self
            .sms
            .get(usize::from(MAILBOX_IN_SM))
            .is_some_and(|sm| sm.is_full());
        if !full && let Some(read) = self.mailbox.in_sm1.take() {
            self.mailbox.backup = Some(read);
        }
    }

    /// Posts the next held or queued message into an empty SM1.
    fn post_next(&mut self) {
        let Some(sm1) = self.sms.get_mut(usize::from(MAILBOX_IN_SM)) else {
            return;
        };
        if !sm1.is_mailbox(SmDirection::Read) || sm1.is_full() {
            return;
        }
        let next = match self.mailbox.held.pop_front() {
            Some(m) => Some(m),
            None => self.mailbox.outbox.pop(),
        };
        if let Some(message) = next
            && sm1.pdi_post(&mut self.mem, &message)
        {
            self.mailbox.in_sm1 = Some(message);
        }
    }

    /// SM `n`'s registers were written: apply the configuration, and on SM1 handle a
    /// toggled repeat request.
    pub(crate) fn sm_registers_written(&mut self, n: u8) {
        let ram_end = self.mem.end();
        if let Some(sm) = self.sms.get_mut(usize::from(n))
            && sm.refresh(&mut self.mem, ram_end)
            && n == MAILBOX_IN_SM
        {
            // Reconfiguring SM1 empties it: the message in it is gone.
            self.mailbox.in_sm1 = None;
        }
        if n == MAILBOX_IN_SM {
            self.check_repeat_request();
        }
    }

    /// The repeat procedure (spec-notes §mbx.repeat): when the master toggles SM1's repeat request
    /// (0x080E bit 1), a newer unread message is taken back out of SM1 for later, the last
    /// message the master read is posted again, and the repeat acknowledge (0x080F bit 1)
    /// is set equal to the request.
    fn check_repeat_request(&mut self) {
        let sm = sync_manager::registers(&self.mem, MAILBOX_IN_SM);
        let request = SmActivate::decode(sm.activate_raw()).repeat_request;
        let mut pdi = SmPdiControl::decode(sm.pdi_control_raw());
        if request == pdi.repeat_ack {
            return;
        }
        if self.mailbox_running() {
            self.note_sm1_read();
            if let Some(sm1) = self.sms.get_mut(usize::from(MAILBOX_IN_SM))
                && sm1.is_mailbox(SmDirection::Read)
            {
                if sm1.is_full() {
                    sm1.reset(&mut self.mem);
                    // A newer message goes back to the queue; the backup itself (posted by
                    // a repeat just before, whose read was lost again) is posted anew
                    // below and must not be queued a second time.
                    if let Some(newer) = self.mailbox.in_sm1.take()
                        && self.mailbox.backup.as_ref() != Some(&newer)
                    {
                        self.mailbox.held.push_front(newer);
                    }
                }
                if let Some(backup) = self.mailbox.backup.clone()
                    && sm1.pdi_post(&mut self.mem, &backup)
                {
                    self.mailbox.in_sm1 = Some(backup);
                }
            }
        }
        pdi.repeat_ack = request;
        sync_manager::update_registers(&mut self.mem, MAILBOX_IN_SM, |sm| {
            sm.set_pdi_control_raw(pdi.encode())
        });
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use super::*;
    use ecat_wire::command::Command;

    /// A CoE-looking message of `len` data bytes with `marker` as first data byte, padded
    /// to the 128-byte SM0.
    fn request_bytes(len: u16, marker: u8) -> Vec<u8> {
        let mut m = vec![0u8; 128];
        m[..2].copy_from_slice(&len.to_le_bytes());
        m[5] = 0x13;
        m[6] = marker;
        m
    }

    fn sm1_full(esc: &Esc) -> bool {
        esc.read_u8(0x080D) & 0x08 != 0
    }

    #[test]
    fn sm0_commit_delivers_and_the_reply_lands_in_sm1() {
        let (mut esc, mut dev) = slave();
        bring_to_preop(&mut esc, &mut dev);
        let r = exec(
            &mut esc,
            &mut dev,
            Command::Fpwr,
            0,
            0x1000,
            &request_bytes(4, 0xA1),
        );
        assert_eq!(r.wkc, 1);
        assert_eq!(dev.received, vec![request_bytes(4, 0xA1)[..10].to_vec()]);
        assert!(sm1_full(&esc));
        assert_eq!(esc.read_u8(0x0805) & 0x08, 0, "SM0 empty again");
        let r = exec(&mut esc, &mut dev, Command::Fprd, 0, 0x1080, &[0; 128]);
        assert_eq!(r.wkc, 1);
        assert_eq!(r.data[..10], request_bytes(4, 0xA1)[..10]);
        assert!(r.data[10..].iter().all(|&b| b == 0));
        assert!(!sm1_full(&esc));
        let r = exec(&mut esc, &mut dev, Command::Fprd, 0, 0x1080, &[0; 128]);
        assert_eq!(r.wkc, 0, "empty mailbox");
    }

    #[test]
    fn bad_length_delivers_the_whole_sm() {
        let (mut esc, mut dev) = slave();
        bring_to_preop(&mut esc, &mut dev);
        exec(
            &mut esc,
            &mut dev,
            Command::Fpwr,
            0,
            0x1000,
            &request_bytes(200, 1),
        );
        assert_eq!(dev.received[0].len(), 128);
    }

    #[test]
    fn partial_write_does_not_commit() {
        let (mut esc, mut dev) = slave();
        bring_to_preop(&mut esc, &mut dev);
        let m = request_bytes(4, 2);
        assert_eq!(
            exec(&mut esc, &mut dev, Command::Fpwr, 0, 0x1000, &m[..64]).wkc,
            1
        );
        assert!(dev.received.is_empty());
        assert_eq!(
            exec(&mut esc, &mut dev, Command::Fpwr, 0, 0x1040, &m[64..]).wkc,
            0,
            "not at SM start"
        );
    }

    #[test]
    fn full_outbox_keeps_sm0_full() {
        let (mut esc, mut dev) = slave();
        bring_to_preop(&mut esc, &mut dev);
        let mut accepted = 0;
        for i in 0..100u8 {
            accepted += exec(
                &mut esc,
                &mut dev,
                Command::Fpwr,
                0,
                0x1000,
                &request_bytes(4, i),
            )
            .wkc;
        }
        // One in SM1, 64 queued, one waiting in SM0.
        assert_eq!(accepted, 66);
        assert_eq!(esc.pending_mailbox_messages(), 64);
        assert_eq!(esc.read_u8(0x0805) & 0x08, 0x08, "SM0 full");
        exec(&mut esc, &mut dev, Command::Fprd, 0, 0x1080, &[0; 128]);
        assert_eq!(esc.read_u8(0x0805) & 0x08, 0, "room again: SM0 taken");
        assert_eq!(dev.received.len(), 66);
    }

    #[test]
    fn repeat_request_reposts_the_lost_message() {
        let (mut esc, mut dev) = slave();
        bring_to_preop(&mut esc, &mut dev);
        exec(
            &mut esc,
            &mut dev,
            Command::Fpwr,
            0,
            0x1000,
            &request_bytes(4, 0xA),
        );
        exec(
            &mut esc,
            &mut dev,
            Command::Fpwr,
            0,
            0x1000,
            &request_bytes(4, 0xB),
        );
        // The master reads A, but the frame is lost on its way back; B moves into SM1.
        exec(&mut esc, &mut dev, Command::Fprd, 0, 0x1080, &[0; 128]);
        assert!(sm1_full(&esc));
        // Repeat request: toggle 0x080E bit 1 (SOEM writes 0x080D-0x080E).
        let s = exec(&mut esc, &mut dev, Command::Fprd, 0, 0x080D, &[0; 2]).data;
        let r = exec(
            &mut esc,
            &mut dev,
            Command::Fpwr,
            0,
            0x080D,
            &[s[0], s[1] ^ 0x02],
        );
        assert_eq!(r.wkc, 1);
        assert_eq!(esc.read_u8(0x080F) & 0x02, 0x02, "acknowledged");
        let r = exec(&mut esc, &mut dev, Command::Fprd, 0, 0x1080, &[0; 128]);
        assert_eq!((r.wkc, r.data[6]), (1, 0xA), "A again");
        let r = exec(&mut esc, &mut dev, Command::Fprd, 0, 0x1080, &[0; 128]);
        assert_eq!((r.wkc, r.data[6]), (1, 0xB), "then B");
        // Toggle back: A was not lost this time, but the backup (B) is posted again.
        exec(&mut esc, &mut dev, Command::Fpwr, 0, 0x080E, &[0x01]);
        assert_eq!(esc.read_u8(0x080F) & 0x02, 0);
        let r = exec(&mut esc, &mut dev, Command::Fprd, 0, 0x1080, &[0; 128]);
        assert_eq!((r.wkc, r.data[6]), (1, 0xB));
    }

    #[test]
    fn two_repeat_requests_in_a_row_post_the_lost_message_once() {
        let (mut esc, mut dev) = slave();
        bring_to_preop(&mut esc, &mut dev);
        for marker in [0xA, 0xB] {
            exec(
                &mut esc,
                &mut dev,
                Command::Fpwr,
                0,
                0x1000,
                &request_bytes(4, marker),
            );
        }
        // A is read and lost; B moves into SM1.
        exec(&mut esc, &mut dev, Command::Fprd, 0, 0x1080, &[0; 128]);
        // Two repeat requests without a read between them (the first one's answer lost);
        // bit 0 of 0x080E keeps SM1 enabled, bit 1 toggles.
        exec(&mut esc, &mut dev, Command::Fpwr, 0, 0x080E, &[0x03]);
        exec(&mut esc, &mut dev, Command::Fpwr, 0, 0x080E, &[0x01]);
        assert_eq!(esc.read_u8(0x080F) & 0x02, 0, "both acknowledged");
        let r = exec(&mut esc, &mut dev, Command::Fprd, 0, 0x1080, &[0; 128]);
        assert_eq!((r.wkc, r.data[6]), (1, 0xA), "A again");
        let r = exec(&mut esc, &mut dev, Command::Fprd, 0, 0x1080, &[0; 128]);
        assert_eq!((r.wkc, r.data[6]), (1, 0xB), "then B, not A a second time");
        let r = exec(&mut esc, &mut dev, Command::Fprd, 0, 0x1080, &[0; 128]);
        assert_eq!(r.wkc, 0, "nothing more");
    }

    #[test]
    fn going_to_init_drops_the_mailbox() {
        let (mut esc, mut dev) = slave();
        bring_to_preop(&mut esc, &mut dev);
        exec(
            &mut esc,
            &mut dev,
            Command::Fpwr,
            0,
            0x1000,
            &request_bytes(4, 1),
        );
        exec(
            &mut esc,
            &mut dev,
            Command::Fpwr,
            0,
            0x1000,
            &request_bytes(4, 2),
        );
        assert_eq!(esc.pending_mailbox_messages(), 1);
        assert_eq!(request(&mut esc, &mut dev, 0x0001), (0x0001, 0));
        assert_eq!(esc.pending_mailbox_messages(), 0);
        assert!(!sm1_full(&esc));
        assert_eq!(request(&mut esc, &mut dev, 0x0002), (0x0002, 0));
        let r = exec(&mut esc, &mut dev, Command::Fprd, 0, 0x1080, &[0; 128]);
        assert_eq!(r.wkc, 0, "nothing left over");
    }

    #[test]
    fn message_is_clipped_to_the_declared_length() {
        let mut sm = vec![0u8; 16];
        sm[0] = 4;
        assert_eq!(message_of(&sm).len(), 10);
        sm[0] = 11;
        assert_eq!(message_of(&sm).len(), 16, "too long: the whole SM");
        assert_eq!(message_of(&sm[..3]).len(), 3, "shorter than a header");
    }
}
