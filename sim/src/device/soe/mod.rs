//! The SoE server of a simulated servo drive (mailbox type 5, ETG.1000.6, spec-notes §soe).
//!
//! - [`idn`]: one IDN's elements, their encoding and the write checks;
//! - [`defaults`]: the parameter set a drive starts with (S-0-0032, IDN lists such as
//!   S-0-0016/17/24, a long text S-0-0030, numeric IDNs with limits);
//! - here: [`SoeService`], the request handling.
//!
//! Reads answer the requested elements in bit order. A response longer than SM1 can carry is
//! sent as several read responses at once — Incomplete = 1 with the fragments still to
//! follow, the last with the IDN (IgH's counting, `wire::soe::fragments`) — all posted to the
//! outbox, which the master empties one SM1 read at a time. Writes may come in fragments: the
//! service accumulates them and answers once, after the last fragment (the one carrying the
//! IDN). A fragment that does not continue the sequence in progress (other drive or
//! elements, fragments-left not one less than before) starts a new sequence; the abandoned
//! one is counted ([`SoeService::abandoned_writes`]).
//!
//! Errors follow spec-notes §soe: unknown IDN 0x1001, missing element 0x2001/0x4001/0x5001/0x6001/
//! 0x8001, drive not present 0x800A, no element 0x800C, value read-only 0x7004,
//! write-protected in this state 0x7005, too short/long 0x7002/0x7003, below/above the
//! limits 0x7006/0x7007, other elements read-only 0x2004.., 0x8004. A request with the error
//! bit set, or a read request flagged Incomplete, has no meaning: mailbox error 0x0005.
//! Opcodes a master never sends (responses, notifications) → mailbox error 0x0004.

pub mod defaults;
pub mod idn;

use std::any::Any;
use std::collections::BTreeMap;

use ecat_wire::Emit;
use ecat_wire::mailbox::{MailboxErrorCode, MailboxHeader, MailboxType};
use ecat_wire::soe::{
    self, ElementFlags, Idn, IdnOrFragments, SoeError, SoeOpcode, SoePacket, SoeRepr,
};

use crate::device::DeviceContext;
use crate::device::mailbox::{MailboxService, ReplySink};

pub use idn::IdnEntry;

/// Largest value a fragmented write may accumulate; beyond it the write answers 0x7003.
pub const MAX_WRITE_LEN: usize = 64 * 1024;

/// Most drives one SoE slave can address (3-bit drive number).
pub const MAX_DRIVES: u8 = 8;

/// A fragmented write in progress.
#[derive(Debug, Clone)]
struct PendingWrite {
    drive: u8,
    elements: ElementFlags,
    /// Fragments-left the next Incomplete fragment must carry; 0: the last one comes next.
    expect_left: u16,
    data: Vec<u8>,
    overflow: bool,
}

/// The SoE server: one IDN table per drive.
#[derive(Debug, Clone)]
pub struct SoeService {
    drives: Vec<BTreeMap<u16, IdnEntry>>,
    pending: Option<PendingWrite>,
    abandoned_writes: u64,
}

impl Default for SoeService {
    fn default() -> Self {
        Self::new(1)
    }
}

impl SoeService {
    /// A slave with `drives` drives (1..=8), each with the [`defaults`] parameter set.
    pub fn new(drives: u8) -> Self {
        let mut service = Self::empty(drives);
        for drive in 0..service.drives() {
            for (number, entry) in defaults::default_idns() {
                let _ = service.insert(drive, number, entry);
            }
        }
        service
    }

    /// A slave with `drives` drives (1..=8) and no IDNs.
    pub fn empty(drives: u8) -> Self {
        SoeService {
            drives: vec![BTreeMap::new(); usize::from(drives.clamp(1, MAX_DRIVES))],
            pending: None,
            abandoned_writes: 0,
        }
    }

    /// Number of drives.
    pub fn drives(&self) -> u8 {
        // At most MAX_DRIVES by construction.
        u8::try_from(self.drives.len()).unwrap_or(MAX_DRIVES)
    }

    /// Adds or replaces IDN `number` of `drive`; returns the entry replaced. S-0-0017, if
    /// present, is updated to list every IDN of the drive.
    pub fn insert(
        &mut self,
        drive: u8,
        number: u16,
        entry: IdnEntry,
    ) -> Result<Option<IdnEntry>, SoeError> {
        let table = self
            .drives
            .get_mut(usize::from(drive))
            .ok_or(SoeError::InvalidDriveNumber)?;
        let old = table.insert(number, entry);
        refresh_idn_list(table);
        Ok(old)
    }

    /// IDN `number` of `drive`.
    pub fn entry(&self, drive: u8, number: u16) -> Option<&IdnEntry> {
        self.drives.get(usize::from(drive))?.get(&number)
    }

    /// IDN `number` of `drive`, mutably (e.g. to move a feedback value).
    pub fn entry_mut(&mut self, drive: u8, number: u16) -> Option<&mut IdnEntry> {
        self.drives.get_mut(usize::from(drive))?.get_mut(&number)
    }

    /// Fragmented writes given up because a fragment did not continue them.
    pub fn abandoned_writes(&self) -> u64 {
        self.abandoned_writes
    }

    fn table(&mut self, drive: u8) -> Result<&mut BTreeMap<u16, IdnEntry>, SoeError> {
        self.drives
            .get_mut(usize::from(drive))
            .ok_or(SoeError::InvalidDriveNumber)
    }

    fn read(&mut self, request: &SoeRepr<'_>, replies: &mut ReplySink) {
        let IdnOrFragments::Idn(idn) = request.idn_or_fragments else {
            let _ = replies.mailbox_error(MailboxErrorCode::InvalidHeader);
            return;
        };
        let data = self.table(request.drive).and_then(|table| {
            table
                .get(&idn.raw())
                .ok_or(SoeError::NoIdn)?
                .read(request.elements)
        });
        match data {
            Err(code) => respond_error(replies, SoeOpcode::ReadResponse, request, idn, code),
            Ok(data) => send_read_response(replies, request, idn, &data),
        }
    }

    fn write(&mut self, request: &SoeRepr<'_>, ctx: &DeviceContext, replies: &mut ReplySink) {
        match request.idn_or_fragments {
            IdnOrFragments::FragmentsLeft(left) => self.accumulate(request, left),
            IdnOrFragments::Idn(idn) => {
                let data = match self.pending.take() {
                    Some(p) if continues(&p, request) && p.expect_left == 0 => {
                        if p.overflow || p.data.len() + request.data.len() > MAX_WRITE_LEN {
                            let code = SoeError::DataTooLong;
                            respond_error(replies, SoeOpcode::WriteResponse, request, idn, code);
                            return;
                        }
                        let mut data = p.data;
                        data.extend_from_slice(request.data);
                        data
                    }
                    Some(_) => {
                        self.abandoned_writes += 1;
                        request.data.to_vec()
                    }
                    None => request.data.to_vec(),
                };
                let result = self.table(request.drive).and_then(|table| {
                    table.get_mut(&idn.raw()).ok_or(SoeError::NoIdn)?.write(
                        request.elements,
                        &data,
                        ctx.al_state,
                    )
                });
                match result {
                    Err(code) => {
                        respond_error(replies, SoeOpcode::WriteResponse, request, idn, code)
                    }
                    Ok(()) => respond(replies, SoeOpcode::WriteResponse, request, idn, &[]),
                }
            }
        }
    }

    /// One Incomplete write fragment: no reply until the last one.
    fn accumulate(&mut self, request: &SoeRepr<'_>, left: u16) {
        match &mut self.pending {
            Some(p) if continues(p, request) && left != 0 && left == p.expect_left => {
                if p.data.len() + request.data.len() > MAX_WRITE_LEN {
                    p.overflow = true;
                } else {
                    p.data.extend_from_slice(request.data);
                }
                p.expect_left = left - 1;
            }
            other => {
                if other.is_some() {
                    self.abandoned_writes += 1;
                }
                *other = Some(PendingWrite {
                    drive: request.drive,
                    elements: request.elements,
                    expect_left: left.saturating_sub(1),
                    data: request.data.to_vec(),
                    overflow: request.data.len() > MAX_WRITE_LEN,
                });
            }
        }
    }
}

/// Whether `request` belongs to the fragmented write `pending`.
fn continues(pending: &PendingWrite, request: &SoeRepr<'_>) -> bool {
    pending.drive == request.drive && pending.elements == request.elements
}

/// Keeps S-0-0017 listing every IDN of its drive.
fn refresh_idn_list(table: &mut BTreeMap<u16, IdnEntry>) {
    let numbers: Vec<u8> = table.keys().flat_map(|n| n.to_le_bytes()).collect();
    if let Some(list) = table.get_mut(&defaults::IDN_LIST_OF_ALL) {
        let len = u16::try_from(numbers.len()).unwrap_or(u16::MAX);
        list.list_capacity = list.list_capacity.max(len);
        list.value = numbers;
    }
}

/// Emits a response with the codec.
fn build(repr: &SoeRepr<'_>) -> Result<Vec<u8>, ecat_wire::WireError> {
    repr.to_vec()
}

fn respond(
    replies: &mut ReplySink,
    opcode: SoeOpcode,
    request: &SoeRepr<'_>,
    idn: Idn,
    data: &[u8],
) {
    let repr = SoeRepr {
        opcode,
        drive: request.drive,
        elements: request.elements,
        idn_or_fragments: IdnOrFragments::Idn(idn),
        error: None,
        data,
    };
    let _ = replies.send_emitted(build(&repr));
}

fn respond_error(
    replies: &mut ReplySink,
    opcode: SoeOpcode,
    request: &SoeRepr<'_>,
    idn: Idn,
    code: SoeError,
) {
    let repr = SoeRepr {
        opcode,
        drive: request.drive,
        elements: request.elements,
        idn_or_fragments: IdnOrFragments::Idn(idn),
        error: Some(code),
        data: &[],
    };
    let _ = replies.send_emitted(build(&repr));
}

/// A read response, in fragments when it does not fit one SM1 message.
fn send_read_response(replies: &mut ReplySink, request: &SoeRepr<'_>, idn: Idn, data: &[u8]) {
    let capacity = replies.max_data_len().saturating_sub(soe::HEADER_LEN);
    if data.len() <= capacity {
        respond(replies, SoeOpcode::ReadResponse, request, idn, data);
        return;
    }
    let fragments: Vec<_> = match soe::fragments(data.len(), capacity) {
        Ok(fragments) => fragments.collect(),
        Err(_) => {
            let _ = replies.mailbox_error(MailboxErrorCode::NoMoreMemory);
            return;
        }
    };
    if fragments.len() > replies.room() {
        // All or nothing: a master cannot use half a value.
        let _ = replies.mailbox_error(MailboxErrorCode::NoMoreMemory);
        return;
    }
    for fragment in fragments {
        let repr = SoeRepr {
            opcode: SoeOpcode::ReadResponse,
            drive: request.drive,
            elements: request.elements,
            idn_or_fragments: match fragment.fragments_left {
                Some(left) => IdnOrFragments::FragmentsLeft(left),
                None => IdnOrFragments::Idn(idn),
            },
            error: None,
            data: data.get(fragment.range).unwrap_or_default(),
        };
        let _ = replies.send_emitted(build(&repr));
    }
}

impl MailboxService for SoeService {
    fn mailbox_type(&self) -> MailboxType {
        MailboxType::Soe
    }

    fn handle(
        &mut self,
        _request: &MailboxHeader,
        data: &[u8],
        ctx: &DeviceContext,
        replies: &mut ReplySink,
    ) {
        let packet = match SoePacket::new_checked(data) {
            Ok(packet) => packet,
            Err(e) => {
                let _ = replies.reject(&e);
                return;
            }
        };
        if packet.error() {
            let _ = replies.mailbox_error(MailboxErrorCode::InvalidHeader);
            return;
        }
        let request = match SoeRepr::parse(&packet) {
            Ok(request) => request,
            Err(e) => {
                let _ = replies.reject(&e);
                return;
            }
        };
        match request.opcode {
            SoeOpcode::ReadRequest => self.read(&request, replies),
            SoeOpcode::WriteRequest => self.write(&request, ctx, replies),
            _ => {
                let _ = replies.mailbox_error(MailboxErrorCode::ServiceNotSupported);
            }
        }
    }

    fn reset(&mut self) {
        self.pending = None;
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
