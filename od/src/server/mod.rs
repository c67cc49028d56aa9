//! The SDO server: answers CoE mailbox requests (SDO transfers and SDO Information) from
//! one mailbox partner against a [`Dictionary`] (spec-notes §coe.sdo, §coe.info, §master-od).
//!
//! One [`SdoServer`] per client: it holds the state of a segmented transfer between
//! requests. Requests and replies are CoE mailbox *data* (from the CoE header on); the
//! caller strips and adds the 6-byte mailbox header, because it owns the counter and
//! address rules. A request yields zero or more replies, which the caller posts to SM1
//! in order (more than one only for a fragmented SDO Information answer).
//!
//! Behaviour on wrong requests (every one ends in a reply the codec parses, or in an
//! [`Outcome`] that says why there is none):
//! - a segment with no matching transfer in progress, or an unknown command specifier
//!   (block transfer): abort 0x05040001;
//! - a toggle bit that did not alternate: abort 0x05030000, transfer dropped;
//! - a new initiate while a transfer is in progress: the old transfer is dropped silently
//!   and the new request served (the client has evidently given up on the old one);
//! - an abort from the client: transfer dropped, no reply;
//! - segmented download whose data do not add up to the announced size: 0x06070010.
//!
//! SDO Information: OD lists longer than SM1 holds are fragmented (Incomplete set on all
//! but the last, Fragments-left counting down, the list type only in the first). Object
//! and entry descriptions are always one message: names are cut and optional values left
//! out to fit, because common clients (SOEM, IgH) read them from one message and a
//! continuation fragment of a description does not parse as one; below the fixed part
//! the answer is an SDO Info error 0x06010005.

mod complete;
mod download;
mod info;
mod reply;
mod upload;

use ecat_wire::coe::sdo::SdoFrame;
use ecat_wire::coe::sdo_request::SdoRequest;
use ecat_wire::coe::{AbortCode, CoeFrame, CoeService};
use ecat_wire::error::WireError;
use ecat_wire::mailbox::HEADER_LEN;
use ecat_wire::register::AlState;

use super::dictionary::Dictionary;
use reply::Replies;

/// The smallest SM1 size the server can answer through: the 6-byte mailbox header and the
/// 10-byte SDO frame of an abort.
pub const MIN_MAILBOX_SIZE: usize = 16;

/// What the server needs to know about the mailbox and the device for one request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ServerContext {
    /// SM1 (slave → master) size in bytes, mailbox header included: limits every reply.
    pub mailbox_size: usize,
    /// SM0 (master → slave) size in bytes: a request longer than its data part could not
    /// have arrived through a real mailbox and is refused as [`Outcome::Malformed`]
    /// (0 disables the check).
    pub rx_mailbox_size: usize,
    /// The device's AL state, for state-dependent access rights.
    pub state: AlState,
}

impl ServerContext {
    /// Both mailboxes of `mailbox_size` bytes, device in `state`.
    pub fn new(mailbox_size: usize, state: AlState) -> Self {
        ServerContext {
            mailbox_size,
            rx_mailbox_size: mailbox_size,
            state,
        }
    }

    /// Most bytes of mailbox data a reply may have.
    pub fn reply_capacity(&self) -> usize {
        self.mailbox_size.saturating_sub(HEADER_LEN)
    }
}

/// What became of one request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Served; this many replies went to the sink (0 after a client's abort).
    Replied(usize),
    /// A CoE service the server does not serve (emergency, SDO response, PDO services):
    /// the caller may answer with a mailbox error "service not supported".
    Unsupported(CoeService),
    /// Too short for its headers (or longer than SM0 allows): no reply; the caller may
    /// answer with a mailbox error.
    Malformed,
    /// The SM1 size is below [`MIN_MAILBOX_SIZE`]: no reply fits.
    MailboxTooSmall,
}

/// A transfer spanning several requests.
#[derive(Debug, Default)]
enum Transfer {
    #[default]
    Idle,
    Upload(upload::Upload),
    Download(download::Download),
}

/// The CoE server for one mailbox partner.
#[derive(Debug, Default)]
pub struct SdoServer {
    transfer: Transfer,
    /// Reply bytes, reused between requests.
    out: Vec<u8>,
}

impl SdoServer {
    /// A server with no transfer in progress.
    pub fn new() -> Self {
        Self::default()
    }

    /// Whether a segmented transfer is in progress.
    pub fn in_transfer(&self) -> bool {
        !matches!(self.transfer, Transfer::Idle)
    }

    /// Drops a transfer in progress (e.g. when the device leaves PREOP/SAFEOP/OP or the
    /// mailbox is reset).
    pub fn reset(&mut self) {
        self.transfer = Transfer::Idle;
    }

    /// Serves one request (CoE mailbox data), passing each reply (CoE mailbox data) to
    /// `replies` in the order they must be posted.
    pub fn handle(
        &mut self,
        dict: &mut dyn Dictionary,
        request: &[u8],
        ctx: ServerContext,
        replies: &mut impl FnMut(&[u8]),
    ) -> Outcome {
        if ctx.mailbox_size < MIN_MAILBOX_SIZE {
            return Outcome::MailboxTooSmall;
        }
        if ctx.rx_mailbox_size != 0
            && request.len() > ctx.rx_mailbox_size.saturating_sub(HEADER_LEN)
        {
            return Outcome::Malformed;
        }
        let Ok(coe) = CoeFrame::new_checked(request) else {
            return Outcome::Malformed;
        };
        let mut out = Replies::new(&mut self.out, replies, ctx.reply_capacity());
        match coe.service() {
            CoeService::SdoRequest => {
                if !sdo(&mut self.transfer, dict, request, ctx, &mut out) {
                    return Outcome::Malformed;
                }
            }
            CoeService::SdoInfo => {
                if !info::serve(&*dict, request, &mut out) {
                    return Outcome::Malformed;
                }
            }
            other => return Outcome::Unsupported(other),
        }
        Outcome::Replied(out.count())
    }
}

/// Serves an SDO request; `false` if it is too short to be one.
fn sdo(
    transfer: &mut Transfer,
    dict: &mut dyn Dictionary,
    request: &[u8],
    ctx: ServerContext,
    out: &mut Replies<'_>,
) -> bool {
    let Ok(frame) = SdoFrame::new_checked(request) else {
        return false;
    };
    let req = match SdoRequest::parse(&frame) {
        Ok(req) => req,
        Err(e) => {
            *transfer = Transfer::Idle;
            // A client abort too short to carry its code is still an abort: no reply.
            if frame.specifier() != ABORT_SPECIFIER {
                out.abort(frame.index(), frame.subindex(), parse_abort_code(e));
            }
            return true;
        }
    };
    match req {
        SdoRequest::InitiateUpload {
            index,
            subindex,
            complete_access,
        } => {
            *transfer = Transfer::Idle;
            upload::initiate(transfer, dict, index, subindex, complete_access, ctx, out);
        }
        SdoRequest::UploadSegment { toggle } => upload::segment(transfer, toggle, out),
        SdoRequest::InitiateDownload {
            index,
            subindex,
            complete_access,
            payload,
        } => {
            *transfer = Transfer::Idle;
            let size_indicated = frame.command() & SIZE_INDICATED != 0;
            let request = download::Initiate {
                index,
                subindex,
                complete_access,
                payload,
                size_indicated,
            };
            download::initiate(transfer, dict, request, ctx.state, out);
        }
        SdoRequest::DownloadSegment { toggle, last, data } => {
            download::segment(transfer, dict, toggle, last, data, ctx.state, out)
        }
        SdoRequest::Abort { .. } => *transfer = Transfer::Idle,
    }
    true
}

/// Command specifier of an abort (bits 5-7 = 4).
const ABORT_SPECIFIER: u8 = 4;
/// Command bit 0 of an initiate download: size indicated.
const SIZE_INDICATED: u8 = 0x01;

/// The abort code for an SDO request the codec refused.
fn parse_abort_code(e: WireError) -> AbortCode {
    match e {
        // More data than the announced complete size.
        WireError::Invalid { .. } => AbortCode::LengthTooHigh,
        // An expedited value or complete size cut short.
        WireError::Truncated { .. } => AbortCode::LengthTooLow,
        // Block transfer and other specifiers we do not know.
        _ => AbortCode::UnknownCommand,
    }
}
