//! A VoE (vendor specific over EtherCAT, mailbox type 0xF, spec-notes §voe) echo service.
//!
//! VoE has no standard semantics, so the simulated device defines its own: for requests
//! carrying the configured vendor id it answers with the same vendor id and vendor type and
//! the request's data with **every byte inverted (XOR 0xFF)**. Inverting, rather than a plain
//! echo, lets a test tell a processed reply from a message that was merely looped back.
//!
//! A request for another vendor id is a protocol this device does not speak: the slave does
//! support VoE (it is in SII word 0x1C), only not that vendor's service, so it answers with
//! the mailbox error 0x0004 `MBXERR_SERVICENOTSUPPORTED` (0x0002 would claim that VoE itself
//! is unsupported). Data shorter than the 6-byte VoE header → 0x0006.

use std::any::Any;

use ecat_wire::Emit;
use ecat_wire::mailbox::{MailboxErrorCode, MailboxHeader, MailboxType};
use ecat_wire::voe::{VoePacket, VoeRepr};

use crate::device::DeviceContext;
use crate::device::mailbox::{MailboxService, ReplySink};

/// Beckhoff's vendor id, the default this service answers to.
pub const DEFAULT_VENDOR_ID: u32 = 0x0000_1164;

/// Answers VoE requests for one vendor id with the data inverted.
#[derive(Debug, Clone)]
pub struct VoeEcho {
    vendor_id: u32,
    handled: u64,
}

impl Default for VoeEcho {
    fn default() -> Self {
        Self::new(DEFAULT_VENDOR_ID)
    }
}

impl VoeEcho {
    /// An echo service for `vendor_id`.
    pub fn new(vendor_id: u32) -> Self {
        VoeEcho {
            vendor_id,
            handled: 0,
        }
    }

    /// The vendor id this service answers to.
    pub fn vendor_id(&self) -> u32 {
        self.vendor_id
    }

    /// Requests answered with an echo so far.
    pub fn handled(&self) -> u64 {
        self.handled
    }

    /// The transform applied to the data (its own inverse).
    pub fn transform(data: &[u8]) -> Vec<u8> {
        data.iter().map(|b| b ^ 0xFF).collect()
    }
}

impl MailboxService for VoeEcho {
    fn mailbox_type(&self) -> MailboxType {
        MailboxType::Voe
    }

    fn handle(
        &mut self,
        _request: &MailboxHeader,
        data: &[u8],
        _ctx: &DeviceContext,
        replies: &mut ReplySink,
    ) {
        let request = match VoePacket::new_checked(data).and_then(|p| VoeRepr::parse(&p)) {
            Ok(request) => request,
            Err(e) => {
                let _ = replies.reject(&e);
                return;
            }
        };
        if request.vendor_id != self.vendor_id {
            let _ = replies.mailbox_error(MailboxErrorCode::ServiceNotSupported);
            return;
        }
        let inverted = Self::transform(request.data);
        let reply = VoeRepr {
            data: &inverted,
            ..request
        };
        let built = reply.to_vec();
        self.handled += 1;
        let _ = replies.send_emitted(built);
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
