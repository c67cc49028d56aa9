//! The FoE server of a simulated slave (mailbox type 4, spec-notes §foe, with its slave rules).
//!
//! - [`store`]: the files ([`FileStore`], a shared handle);
//! - [`busy`]: the configurable BUSY phases of a write ([`BusyPhase`]);
//! - here: [`FoeService`], one transfer at a time.
//!
//! **Read (RRQ)**: file not found 0x8001, wrong password 0x800A, not readable 0x8002;
//! otherwise DATA packets of `min(SM1 − 12, remaining)` bytes, numbered from 1, each sent
//! after the ACK of the previous one. A packet shorter than SM1 − 12 ends the file — a 0-byte
//! packet when the size is a multiple; its ACK ends the transfer. An ACK with another number
//! → ERROR 0x8005.
//!
//! **Write (WRQ)**: checks as for a read (0x8002 when the file is not writable, 0x8001 when
//! it does not exist and the store does not create files), then ACK 0; DATA *n* must carry
//! the expected number (else ERROR 0x8005) and at most SM0 − 12 bytes (else 0x8004); a store
//! that would overflow answers 0x8003; each packet is ACKed with its number and a short one
//! ends the file, which is then stored.
//!
//! **BUSY** ([`BusyPhase`]): to emulate erasing and programming flash, the slave can answer
//! a WRQ, and the last DATA packet, with BUSY (done/entire progress and a text) a configured
//! number of times before the ACK. The master re-sends the packet it sent (spec-notes §foe, BUSY); each
//! repetition gets the next BUSY until the phase is over and the ACK comes. During the WRQ's
//! phase a DATA 1 also counts as the repetition (IgH answers BUSY by sending the data packet
//! it was about to send), and is processed once the phase is over.
//!
//! A new RRQ or WRQ abandons the transfer in progress and starts over (a master that timed
//! out retries this way); an ERROR from the master ends the transfer without a reply; any
//! other opcode the current state does not expect → ERROR 0x8004 and back to idle. Every
//! ERROR carries the code's text. BOOT-only rules (0x8008/0x8009) are not modelled.

pub mod busy;
pub mod store;

use std::any::Any;

use ecat_wire::foe::{self, FoeError, FoePacket, FoeRepr};
use ecat_wire::mailbox::{MailboxHeader, MailboxType};
use ecat_wire::{Emit, WireError};

use crate::device::DeviceContext;
use crate::device::mailbox::{MailboxService, ReplySink};

pub use busy::BusyPhase;
pub use store::{FileStore, FoeFile};

use busy::Busy;

#[derive(Debug, Clone)]
enum State {
    Idle,
    Reading {
        data: Vec<u8>,
        /// Bytes sent so far, including the packet awaiting its ACK.
        sent: usize,
        /// Number of the packet awaiting its ACK.
        packet: u32,
        /// Size of that packet; shorter than `max_data` means it was the last.
        last_len: usize,
        max_data: usize,
    },
    WriteRequestBusy {
        name: Vec<u8>,
        password: u32,
        space: usize,
        busy: Busy,
    },
    Writing {
        name: Vec<u8>,
        expected: u32,
        data: Vec<u8>,
        space: usize,
    },
    LastPacketBusy {
        name: Vec<u8>,
        packet: u32,
        data: Vec<u8>,
        busy: Busy,
    },
}

/// The FoE server.
#[derive(Debug, Clone)]
pub struct FoeService {
    store: FileStore,
    busy: BusyPhase,
    state: State,
    reads_completed: u64,
    writes_completed: u64,
    busy_sent: u64,
}

impl Default for FoeService {
    fn default() -> Self {
        Self::new(FileStore::default())
    }
}

/// Builds an FoE message with the codec.
fn build(repr: &FoeRepr<'_>) -> Result<Vec<u8>, WireError> {
    repr.to_vec()
}

fn send(replies: &mut ReplySink, repr: &FoeRepr<'_>) {
    let _ = replies.send_emitted(build(repr));
}

/// An FoE ERROR with the code's text.
fn send_error(replies: &mut ReplySink, code: FoeError) {
    send(
        replies,
        &FoeRepr::Error {
            code,
            text: code.description().as_bytes(),
        },
    );
}

/// Texts must not end in NUL (FoE strings are not NUL-terminated; the codec refuses it).
fn clean_text(text: &str) -> Vec<u8> {
    text.trim_end_matches('\0').as_bytes().to_vec()
}

impl FoeService {
    /// A server over `store`, without BUSY phases.
    pub fn new(store: FileStore) -> Self {
        FoeService {
            store,
            busy: BusyPhase::default(),
            state: State::Idle,
            reads_completed: 0,
            writes_completed: 0,
            busy_sent: 0,
        }
    }

    /// With BUSY phases.
    pub fn with_busy(mut self, busy: BusyPhase) -> Self {
        self.busy = busy;
        self
    }

    /// The files (a shared handle).
    pub fn store(&self) -> &FileStore {
        &self.store
    }

    /// Uploads finished (final ACK received).
    pub fn reads_completed(&self) -> u64 {
        self.reads_completed
    }

    /// Downloads finished (file stored).
    pub fn writes_completed(&self) -> u64 {
        self.writes_completed
    }

    /// BUSY answers sent.
    pub fn busy_sent(&self) -> u64 {
        self.busy_sent
    }

    /// Whether no transfer is in progress.
    pub fn is_idle(&self) -> bool {
        matches!(self.state, State::Idle)
    }

    fn send_busy(&mut self, replies: &mut ReplySink, busy: &mut Busy) {
        let text = clean_text(&self.busy.text);
        send(
            replies,
            &FoeRepr::Busy {
                done: busy.sent,
                entire: busy.total,
                text: &text,
            },
        );
        busy.sent += 1;
        self.busy_sent += 1;
    }

    fn start_read(&mut self, name: &[u8], password: u32, replies: &mut ReplySink) {
        self.state = State::Idle;
        let max_data = replies.max_data_len().saturating_sub(foe::HEADER_LEN);
        if max_data == 0 {
            return send_error(replies, FoeError::Illegal);
        }
        match self.store.open_read(name, password) {
            Err(code) => send_error(replies, code),
            Ok(data) => {
                let len = data.len().min(max_data);
                send(
                    replies,
                    &FoeRepr::Data {
                        packet: 1,
                        data: &data[..len],
                    },
                );
                self.state = State::Reading {
                    data,
                    sent: len,
                    packet: 1,
                    last_len: len,
                    max_data,
                };
            }
        }
    }

    fn start_write(&mut self, name: &[u8], password: u32, replies: &mut ReplySink) {
        self.state = State::Idle;
        let space = match self.store.open_write(name, password) {
            Ok(space) => space,
            Err(code) => return send_error(replies, code),
        };
        if self.busy.after_write_request > 0 && self.busy.applies(name) {
            let mut busy = Busy::new(self.busy.after_write_request);
            self.send_busy(replies, &mut busy);
            self.state = State::WriteRequestBusy {
                name: name.to_vec(),
                password,
                space,
                busy,
            };
        } else {
            self.accept_write(name.to_vec(), space, replies);
        }
    }

    fn accept_write(&mut self, name: Vec<u8>, space: usize, replies: &mut ReplySink) {
        send(replies, &FoeRepr::Ack { packet: 0 });
        self.state = State::Writing {
            name,
            expected: 1,
            data: Vec::new(),
            space,
        };
    }

    fn on_ack(&mut self, number: u32, replies: &mut ReplySink) {
        let State::Reading {
            data,
            sent,
            packet,
            last_len,
            max_data,
        } = &mut self.state
        else {
            self.state = State::Idle;
            return send_error(replies, FoeError::Illegal);
        };
        if number != *packet {
            self.state = State::Idle;
            return send_error(replies, FoeError::PacketNumberWrong);
        }
        if *last_len < *max_data {
            self.reads_completed += 1;
            self.state = State::Idle;
            return;
        }
        let rest = data.get(*sent..).unwrap_or_default();
        let len = rest.len().min(*max_data);
        *packet = packet.wrapping_add(1);
        *sent += len;
        *last_len = len;
        let repr = FoeRepr::Data {
            packet: *packet,
            data: &rest[..len],
        };
        send(replies, &repr);
    }

    fn on_data(&mut self, number: u32, chunk: &[u8], ctx: &DeviceContext, replies: &mut ReplySink) {
        match std::mem::replace(&mut self.state, State::Idle) {
            State::WriteRequestBusy {
                name,
                password,
                space,
                mut busy,
            } if number == 1 => {
                if busy.over() {
                    self.state = State::Writing {
                        name,
                        expected: 1,
                        data: Vec::new(),
                        space,
                    };
                    self.on_data(number, chunk, ctx, replies);
                } else {
                    self.send_busy(replies, &mut busy);
                    self.state = State::WriteRequestBusy {
                        name,
                        password,
                        space,
                        busy,
                    };
                }
            }
            State::Writing {
                name,
                expected,
                mut data,
                space,
            } => {
                let max_data = usize::from(ctx.rx_mailbox_size)
                    .saturating_sub(ecat_wire::mailbox::HEADER_LEN + foe::HEADER_LEN);
                if number != expected {
                    return send_error(replies, FoeError::PacketNumberWrong);
                }
                if chunk.len() > max_data {
                    return send_error(replies, FoeError::Illegal);
                }
                if data.len() + chunk.len() > space {
                    return send_error(replies, FoeError::DiskFull);
                }
                data.extend_from_slice(chunk);
                if chunk.len() == max_data {
                    send(replies, &FoeRepr::Ack { packet: number });
                    self.state = State::Writing {
                        name,
                        expected: expected.wrapping_add(1),
                        data,
                        space,
                    };
                } else if self.busy.after_last_packet > 0 && self.busy.applies(&name) {
                    let mut busy = Busy::new(self.busy.after_last_packet);
                    self.send_busy(replies, &mut busy);
                    self.state = State::LastPacketBusy {
                        name,
                        packet: number,
                        data,
                        busy,
                    };
                } else {
                    self.finish_write(&name, data, number, replies);
                }
            }
            State::LastPacketBusy {
                name,
                packet,
                data,
                mut busy,
            } => {
                if number != packet {
                    return send_error(replies, FoeError::PacketNumberWrong);
                }
                if busy.over() {
                    self.finish_write(&name, data, packet, replies);
                } else {
                    self.send_busy(replies, &mut busy);
                    self.state = State::LastPacketBusy {
                        name,
                        packet,
                        data,
                        busy,
                    };
                }
            }
            State::WriteRequestBusy { .. } => send_error(replies, FoeError::PacketNumberWrong),
            State::Idle | State::Reading { .. } => send_error(replies, FoeError::Illegal),
        }
    }

    fn finish_write(&mut self, name: &[u8], data: Vec<u8>, packet: u32, replies: &mut ReplySink) {
        self.store.commit(name, data);
        self.writes_completed += 1;
        self.state = State::Idle;
        send(replies, &FoeRepr::Ack { packet });
    }

    fn on_write_request(&mut self, name: &[u8], password: u32, replies: &mut ReplySink) {
        // A repeated WRQ during its BUSY phase is the master's retry, not a new transfer.
        let retry = matches!(
            &self.state,
            State::WriteRequestBusy { name: n, password: p, .. } if n.as_slice() == name && *p == password
        );
        if !retry {
            return self.start_write(name, password, replies);
        }
        let State::WriteRequestBusy {
            name,
            password,
            space,
            mut busy,
        } = std::mem::replace(&mut self.state, State::Idle)
        else {
            return;
        };
        if busy.over() {
            self.accept_write(name, space, replies);
        } else {
            self.send_busy(replies, &mut busy);
            self.state = State::WriteRequestBusy {
                name,
                password,
                space,
                busy,
            };
        }
    }
}

impl MailboxService for FoeService {
    fn mailbox_type(&self) -> MailboxType {
        MailboxType::Foe
    }

    fn handle(
        &mut self,
        _request: &MailboxHeader,
        data: &[u8],
        ctx: &DeviceContext,
        replies: &mut ReplySink,
    ) {
        let packet = match FoePacket::new_checked(data) {
            Ok(packet) => packet,
            Err(e) => {
                let _ = replies.reject(&e);
                return;
            }
        };
        let Ok(request) = FoeRepr::parse(&packet) else {
            // The header is there but the opcode is none of the six.
            self.state = State::Idle;
            return send_error(replies, FoeError::Illegal);
        };
        match request {
            FoeRepr::ReadRequest {
                password,
                file_name,
            } => self.start_read(file_name, password, replies),
            FoeRepr::WriteRequest {
                password,
                file_name,
            } => self.on_write_request(file_name, password, replies),
            FoeRepr::Data { packet, data } => self.on_data(packet, data, ctx, replies),
            FoeRepr::Ack { packet } => self.on_ack(packet, replies),
            FoeRepr::Error { .. } => self.state = State::Idle,
            FoeRepr::Busy { .. } => {
                self.state = State::Idle;
                send_error(replies, FoeError::Illegal);
            }
        }
    }

    fn reset(&mut self) {
        self.state = State::Idle;
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
