//! The service layer both APIs call: one method per operation, each one call into the
//! master or a slave's mailbox, typed in and out, errors as [`ApiError`]. An operation that
//! needs the write role is declared in `operation` and admitted and audited in `admission`:
//! its method takes the [`Ticket`] only [`Core::admit`] gives.
//!
//! Files: `admission` (who may write, and the audit line), `operation` (the operations that
//! need the write role), `view` (what the APIs serialise), `calls` (the mailbox requests it
//! made, counted), `gateway` (the mailbox gateway's state, start and stop), `bus` (frame and
//! cycle counters), `read_effects` (register reads that need the write role), `transfer`
//! (deadlines and progress of FoE and SDO transfers), `capture` (live captures), `rolling`
//! (the rolling capture's ring of files), `domains` (the process image by slave group),
//! `log_filter` (the runtime log filter), `process_data` (the layout, values and forced
//! outputs), `pd_stream` (the interval and changes of a process-data stream), `pdos` (each
//! slave's SyncManagers and PDOs), `redundancy` (the ring's state and its events).

pub mod admission;
pub mod bus;
pub mod bus_fault;
pub mod calls;
pub mod capture;
pub mod domains;
pub mod events;
pub mod gateway;
pub mod history;
pub mod journal;
pub mod log_filter;
pub mod master_view;
pub mod operation;
pub mod pd_stream;
pub mod pdos;
pub mod process_data;
pub mod read_effects;
pub mod redundancy;
pub mod rolling;
mod sii_checksum;
pub mod transfer;
pub mod view;

use std::sync::Arc;

use master_core::gateway::{MailboxGateway, MailboxGatewayStats};
use master_core::mailbox::{FoeOptions, FoeProgress, MailboxError, SlaveMailbox, VoeMessage};
use master_core::master::Master;
use master_core::wire::coe::info::OdListType;
use master_core::wire::register::AlState;
use master_core::wire::soe::{ElementFlags, Idn};
use tokio::sync::broadcast;

pub use crate::error::{ApiError, ErrorKind};
pub use crate::input::address::{SlaveName, parse_name, parse_slave};
use crate::input::ip;
use crate::input::value::{self, Typing, ValueType};
use crate::security::Caller;
pub use admission::Ticket;
pub use bus::BusView;
use calls::{MailboxCalls, Outcome, Protocol};
pub use gateway::GatewayView;
pub use master_view::MasterView;
pub use operation::{Operation, op};
pub use view::RedundancyView;
pub use view::{
    EmergencyView, EntryView, EventView, IdentityView, IpView, ObjectView, SlaveView, VoeView,
};

/// What an SDO download writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SdoPayload<'a> {
    /// Bytes as they are; `complete`: complete access from the subindex on.
    Bytes {
        /// The bytes.
        data: &'a [u8],
        /// Complete access.
        complete: bool,
    },
    /// A value as text, encoded by its type (the type the slave's SDO Information names, or
    /// one the caller names).
    Value {
        /// The value as text.
        text: &'a str,
        /// Its type.
        typing: Typing,
        /// Complete access asked for: refused (a typed value is one entry's; complete access
        /// writes the bytes of several).
        complete: bool,
    },
}

impl SdoPayload<'_> {
    /// What the audit log keeps of it: the bytes, or the value's text.
    pub fn audited(&self) -> &[u8] {
        match self {
            SdoPayload::Bytes { data, .. } => data,
            SdoPayload::Value { text, .. } => text.as_bytes(),
        }
    }
}

/// What an SDO upload read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Uploaded {
    /// The bytes.
    pub data: Vec<u8>,
    /// The value as text, when a type was asked for.
    pub value: Option<String>,
}

/// The largest register access in one request (the ESC's whole register space).
pub const MAX_REGISTER_LEN: usize = 0x1000;

/// The service layer over one master.
#[derive(Clone)]
pub struct Core {
    master: Arc<Master>,
    /// Ready: the first scan is done and the service is not shutting down (a watch, so the
    /// gRPC health service can follow it).
    ready: Arc<tokio::sync::watch::Sender<bool>>,
    /// The mailbox gateway, when one runs (its statistics feed the metrics).
    gateway: Arc<std::sync::Mutex<Option<MailboxGateway>>>,
    /// The merged event stream, started with its first subscriber.
    events: Arc<std::sync::OnceLock<events::EventHub>>,
    /// Where the mailbox requests are recorded (shared with the metrics, which own it).
    calls: Arc<MailboxCalls>,
    /// The link's name for [`master_view`] (`simulate` or the interface).
    link: Arc<std::sync::OnceLock<String>>,
    /// The bus's capture hub ([`capture`]).
    capture: Arc<std::sync::OnceLock<Arc<master_core::link::CaptureHub>>>,
    /// The rolling capture, when `[capture] rolling` is on ([`rolling`]).
    rolling: Arc<std::sync::OnceLock<rolling::RollingCapture>>,
    /// Set once at shutdown: every event stream ends when it is.
    stopping: Arc<tokio::sync::watch::Sender<bool>>,
    /// The effective configuration as TOML, and the ENI file it came from (`ecat config`).
    effective_config: Arc<std::sync::OnceLock<(String, String)>>,
    /// The EoE interfaces ecatd made (empty until their manager runs).
    eoe: crate::eoe::EoeInterfaces,
    /// The application interface, once it serves.
    app: Arc<std::sync::OnceLock<crate::app::AppHandle>>,
}

/// A core method's outcome.
pub type Result<T> = std::result::Result<T, ApiError>;

impl Core {
    /// A core over `master` that records its mailbox requests in `calls`, not ready until
    /// [`Core::set_ready`].
    pub fn new(master: Arc<Master>, calls: Arc<MailboxCalls>) -> Core {
        Core {
            master,
            ready: Arc::new(tokio::sync::watch::Sender::new(false)),
            gateway: Arc::default(),
            events: Arc::default(),
            calls,
            link: Arc::default(),
            capture: Arc::default(),
            rolling: Arc::default(),
            stopping: Arc::new(tokio::sync::watch::Sender::new(false)),
            effective_config: Arc::default(),
            eoe: crate::eoe::EoeInterfaces::default(),
            app: Arc::default(),
        }
    }

    /// Hands the core the running application interface, once.
    pub fn set_app(&self, app: crate::app::AppHandle) {
        let _ = self.app.set(app);
    }

    /// The application interface now; `None` when it does not serve.
    pub fn app_status(&self) -> Option<crate::app::AppStatus> {
        self.app.get().map(crate::app::AppHandle::status)
    }

    /// Records the effective configuration (TOML) and its ENI file, once, at start.
    pub fn set_effective_config(&self, toml: String, eni: String) {
        let _ = self.effective_config.set((toml, eni));
    }

    /// The effective configuration as TOML and the ENI file it came from (empty strings
    /// before [`Core::set_effective_config`]).
    pub fn effective_config(&self) -> (String, String) {
        self.effective_config.get().cloned().unwrap_or_default()
    }

    /// The EoE interfaces (their manager fills them in).
    pub fn eoe(&self) -> &crate::eoe::EoeInterfaces {
        &self.eoe
    }

    /// The EoE interfaces with their counters.
    pub fn eoe_interfaces(&self) -> Vec<crate::eoe::InterfaceView> {
        self.eoe.list(&self.master)
    }

    /// Hands the mailbox gateway (running or not) to the core.
    pub fn set_gateway(&self, gateway: MailboxGateway) {
        *self.gateway_slot() = Some(gateway);
    }

    /// Takes the mailbox gateway back (to stop it).
    pub fn take_gateway(&self) -> Option<MailboxGateway> {
        self.gateway_slot().take()
    }

    /// The gateway's statistics and whether it is running; `None` without a gateway.
    pub fn gateway_stats(&self) -> Option<(MailboxGatewayStats, bool)> {
        self.gateway_slot()
            .as_ref()
            .map(|gateway| (gateway.stats(), gateway.is_running()))
    }

    /// The datagrams the kernel dropped on the gateway's sockets (receive queue full)
    /// since they were bound, read from `/proc` outside the gateway's lock; `None` when no
    /// gateway serves or the count cannot be read.
    pub fn gateway_dropped_datagrams(&self) -> Option<u64> {
        let inodes = self.gateway_slot().as_ref()?.socket_inodes();
        if inodes.is_empty() {
            return None;
        }
        master_core::gateway::udp_drops(&inodes).ok()
    }

    fn gateway_slot(&self) -> std::sync::MutexGuard<'_, Option<MailboxGateway>> {
        self.gateway
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Names the link (`simulate` or the interface) once, for [`Core::master_view`].
    pub fn set_link(&self, name: &str) {
        let _ = self.link.set(name.to_owned());
    }

    /// The link's name; empty until [`Core::set_link`].
    pub fn link(&self) -> String {
        self.link.get().cloned().unwrap_or_default()
    }

    /// The master.
    pub fn master(&self) -> &Arc<Master> {
        &self.master
    }

    /// Marks the service ready (after the first scan) or not (shutting down).
    pub fn set_ready(&self, ready: bool) {
        self.ready.send_replace(ready);
    }

    /// Starts the shutdown: the service is no longer ready and every event stream ends
    /// (a server's graceful shutdown would wait for them forever).
    pub fn stop_streams(&self) {
        self.set_ready(false);
        self.stopping.send_replace(true);
    }

    /// Completes once [`Core::stop_streams`] was called (at once if it already was).
    pub fn stopped(&self) -> impl std::future::Future<Output = ()> + Send + use<> {
        let mut rx = self.stopping.subscribe();
        async move {
            let _ = rx.wait_for(|stopping| *stopping).await;
        }
    }

    /// Whether the first scan is done and the service is not shutting down.
    pub fn ready(&self) -> bool {
        *self.ready.borrow()
    }

    /// Readiness from now on: the current value, then every change.
    pub fn readiness(&self) -> tokio::sync::watch::Receiver<bool> {
        self.ready.subscribe()
    }

    /// The master's address of `slave`.
    fn address(&self, slave: SlaveName) -> Result<master_core::master::SlaveAddress> {
        slave.resolve(|| self.master.slaves())
    }

    fn mailbox(&self, slave: SlaveName) -> Result<SlaveMailbox> {
        Ok(self.master.mailbox(self.address(slave)?)?)
    }

    /// Runs `op` on the mailbox of `slave` and records it in the metrics (per slave and
    /// protocol).
    async fn call<T, F>(
        &self,
        slave: SlaveName,
        protocol: Protocol,
        op: impl FnOnce(SlaveMailbox) -> F,
    ) -> Result<T>
    where
        F: std::future::Future<Output = master_core::mailbox::Result<T>>,
    {
        let mailbox = self.mailbox(slave)?;
        let station = mailbox.station();
        let started = std::time::Instant::now();
        let result = op(mailbox).await;
        let outcome = match &result {
            Ok(_) => Outcome::Ok,
            Err(MailboxError::Timeout { .. }) => Outcome::Timeout,
            Err(_) => Outcome::Error,
        };
        self.calls
            .record(station, protocol, outcome, started.elapsed());
        Ok(result?)
    }

    /// Every slave of the last scan.
    pub fn list_slaves(&self) -> Vec<SlaveView> {
        self.master.slaves().iter().map(SlaveView::from).collect()
    }

    /// One slave.
    pub fn get_slave(&self, slave: SlaveName) -> Result<SlaveView> {
        Ok(SlaveView::from(&self.master.slave(self.address(slave)?)?))
    }

    /// Moves a slave to `state` and returns it afterwards.
    pub async fn request_state(
        &self,
        mut ticket: Ticket,
        slave: SlaveName,
        state: AlState,
    ) -> Result<SlaveView> {
        ticket.check(
            Operation::RequestState,
            format_args!("{slave} {}", state.name()),
        )?;
        ticket.finish(
            async {
                let address = self.address(slave)?;
                self.master.request_state(address, state).await?;
                Ok(SlaveView::from(&self.master.slave(address)?))
            }
            .await,
        )
    }

    /// Scans the segment again; the slaves and one message per slave that refused a state.
    pub async fn rescan(&self, mut ticket: Ticket) -> Result<(Vec<SlaveView>, Vec<String>)> {
        ticket.check(Operation::Rescan, "all")?;
        let report = ticket.finish(self.master.scan().await.map_err(ApiError::from))?;
        let failures = report.failures.iter().map(|f| f.to_string()).collect();
        Ok((self.list_slaves(), failures))
    }

    /// The event history and stream, started on first use (ecatd starts it at once, so
    /// that the history begins with the first scan). Call from within the tokio runtime.
    /// Starts the event history with `settings` (its size, its journal read back); before
    /// anything else asks for events. Refused when the journal cannot be read or written.
    pub fn start_events(
        &self,
        settings: &crate::config::events::EventSettings,
    ) -> std::result::Result<(), String> {
        let hub = events::EventHub::start_configured(&self.master, settings)?;
        self.events
            .set(hub)
            .map_err(|_| "the event history was started already".to_owned())
    }

    /// The event history and stream (started with the defaults if
    /// [`start_events`](Self::start_events) was not called).
    pub fn event_log(&self) -> &std::sync::Arc<history::EventLog> {
        self.events
            .get_or_init(|| events::EventHub::start(&self.master))
            .log()
    }

    /// Events from now on: the master's topology and state events and every slave's CoE
    /// emergencies ([`events`]). Call from within the tokio runtime.
    pub fn events(&self) -> broadcast::Receiver<EventView> {
        self.event_log().subscribe()
    }

    /// Where a stream starts: with `after` (the last event a client saw), the kept events
    /// numbered after it (the newest `limit` of them) and every event from then on, with no
    /// gap and no repeat ([`history`]); without, the events from now on.
    pub fn events_from(
        &self,
        after: Option<u64>,
        limit: Option<usize>,
    ) -> (Vec<EventView>, broadcast::Receiver<EventView>) {
        let Some(after) = after else {
            return (Vec::new(), self.events());
        };
        let (mut past, live) = self.event_log().replay(after);
        if let Some(limit) = limit {
            past.drain(..past.len().saturating_sub(limit));
        }
        (past, live)
    }

    /// The kept events `query` wants, oldest first.
    pub fn event_history(&self, query: history::EventQuery) -> Result<Vec<EventView>> {
        use master_core::master::SlaveAddress;
        let position = match query.slave {
            None => None,
            // A lost slave's events are still asked for by its position.
            Some(SlaveName::Address(SlaveAddress::Position(position))) => Some(position),
            Some(name) => Some(self.get_slave(name)?.position),
        };
        Ok(self.event_log().query(&history::EventFilter {
            since: query.since,
            kind: query.kind,
            position,
            limit: query.limit,
        }))
    }

    /// Publishes `event` on the event stream (events of ecatd's own parts beside the
    /// master's). Call from within the tokio runtime.
    pub fn publish_event(&self, event: EventView) {
        self.event_log().publish(event);
    }

    /// Reads `len` bytes of ESC registers from `address` for `caller` (the API's
    /// authenticated caller). A read with a side effect on the slave
    /// ([`read_effects`]) needs the write role: refused (and audited) for a read token.
    pub async fn read_register(
        &self,
        caller: Option<&Caller>,
        slave: SlaveName,
        address: u16,
        len: usize,
    ) -> Result<Vec<u8>> {
        if len == 0 || len > MAX_REGISTER_LEN {
            return Err(ApiError::invalid_field(
                "length",
                format!("register length must be 1..={MAX_REGISTER_LEN}"),
            ));
        }
        let resolved = self.address(slave)?;
        let info = self.master.slave(resolved)?;
        let Some(effect) = read_effects::side_effect(&info, address, len) else {
            return Ok(self.master.read_register(resolved, address, len).await?);
        };
        let target = format!("{slave} 0x{address:04X}+{len} over {effect}");
        let mut ticket = self.admit_on(caller, Operation::ReadRegisterWithEffect, &target)?;
        ticket.check(Operation::ReadRegisterWithEffect, target)?;
        ticket.finish(
            self.master
                .read_register(resolved, address, len)
                .await
                .map_err(ApiError::from),
        )
    }

    /// Writes ESC registers at `address`.
    pub async fn write_register(
        &self,
        mut ticket: Ticket,
        slave: SlaveName,
        address: u16,
        data: &[u8],
    ) -> Result<()> {
        ticket.check(
            Operation::WriteRegister,
            format_args!("{slave} 0x{address:04X}"),
        )?;
        ticket.value(data);
        ticket.finish(
            async {
                register_data(data)?;
                Ok(self
                    .master
                    .write_register(self.address(slave)?, address, data)
                    .await?)
            }
            .await,
        )
    }

    /// Writes ESC registers at `address` and returns their contents from before the write,
    /// in one FPRW datagram.
    pub async fn read_write_register(
        &self,
        mut ticket: Ticket,
        slave: SlaveName,
        address: u16,
        data: &[u8],
    ) -> Result<Vec<u8>> {
        ticket.check(
            Operation::ReadWriteRegister,
            format_args!("{slave} 0x{address:04X}"),
        )?;
        ticket.value(data);
        ticket.finish(
            async {
                register_data(data)?;
                Ok(self
                    .master
                    .read_write_register(self.address(slave)?, address, data)
                    .await?)
            }
            .await,
        )
    }

    /// Reads the whole SII image.
    pub async fn read_sii(&self, slave: SlaveName) -> Result<Vec<u8>> {
        Ok(self.master.read_sii(self.address(slave)?).await?)
    }

    /// Writes SII words from `word` on; `data` is little-endian bytes, an even number. A
    /// write into words 0-7 keeps the checksum valid (ETG.2010, spec-notes §sii.fixed):
    /// recomputed and written to word 7 when the write leaves word 7 out, refused (nothing
    /// written) when it writes a word 7 that does not match; `force` writes as given.
    pub async fn write_sii(
        &self,
        mut ticket: Ticket,
        slave: SlaveName,
        word: u16,
        data: &[u8],
        force: bool,
    ) -> Result<()> {
        ticket.check(Operation::WriteSii, format_args!("{slave} word {word}"))?;
        ticket.value(data);
        ticket.finish(self.write_sii_words(slave, word, data, force).await)
    }

    async fn write_sii_words(
        &self,
        slave: SlaveName,
        word: u16,
        data: &[u8],
        force: bool,
    ) -> Result<()> {
        if data.is_empty() || !data.len().is_multiple_of(2) {
            return Err(ApiError::invalid_field(
                "data",
                "SII data must be a non-empty even number of bytes",
            ));
        }
        let address = self.address(slave)?;
        let words: Vec<u16> = data
            .chunks_exact(2)
            .map(|w| u16::from_le_bytes([w[0], w[1]]))
            .collect();
        let checksum = if force {
            None
        } else {
            sii_checksum::keep_valid(&self.master, address, word, &words).await?
        };
        self.master.write_sii(address, word, &words).await?;
        if let Some(word7) = checksum {
            self.master
                .write_sii(address, sii_checksum::CHECKSUM_WORD, &[word7])
                .await?;
        }
        Ok(())
    }

    /// Sets the station alias; returns the alias register read back.
    pub async fn set_alias(&self, mut ticket: Ticket, slave: SlaveName, alias: u16) -> Result<u16> {
        ticket.check(Operation::SetAlias, slave)?;
        ticket.value(&alias.to_le_bytes());
        ticket.finish(async { Ok(self.master.set_alias(self.address(slave)?, alias).await?) }.await)
    }

    /// SDO upload (complete access from `subindex` when `complete`).
    pub async fn coe_upload(
        &self,
        slave: SlaveName,
        index: u16,
        subindex: u8,
        complete: bool,
    ) -> Result<Vec<u8>> {
        self.call(slave, Protocol::Coe, |mailbox| async move {
            // A segmented upload's window restarts with each segment.
            let mailbox = transfer::with_progress_deadlines(&mailbox, transfer::READ_CAP_SIZE);
            if complete {
                mailbox.sdo_upload_complete(index, subindex).await
            } else {
                mailbox.sdo_upload(index, subindex).await
            }
        })
        .await
    }

    /// SDO download (complete access from `subindex` when `complete`).
    async fn sdo_download(
        &self,
        slave: SlaveName,
        index: u16,
        subindex: u8,
        data: &[u8],
        complete: bool,
    ) -> Result<()> {
        self.call(slave, Protocol::Coe, |mailbox| async move {
            // A segmented download's window restarts with each segment.
            let mailbox = transfer::with_progress_deadlines(&mailbox, data.len());
            if complete {
                mailbox.sdo_download_complete(index, subindex, data).await
            } else {
                mailbox.sdo_download(index, subindex, data).await
            }
        })
        .await
    }

    /// The value type `typing` stands for at `index:subindex`: `auto` asks the slave (SDO
    /// Information entry description).
    async fn value_type(
        &self,
        slave: SlaveName,
        index: u16,
        subindex: u8,
        typing: Typing,
    ) -> Result<ValueType> {
        match typing {
            Typing::As(ty) => Ok(ty),
            Typing::Auto => {
                let entry = self
                    .call(slave, Protocol::Coe, |m| async move {
                        m.sdo_info_entry(index, subindex, 0).await
                    })
                    .await?;
                Ok(value::for_data_type(entry.data_type))
            }
        }
    }

    /// SDO upload as the caller asked: the bytes, and with `typing` also the value as text.
    pub async fn coe_read(
        &self,
        slave: SlaveName,
        index: u16,
        subindex: u8,
        complete: bool,
        typing: Option<Typing>,
    ) -> Result<Uploaded> {
        match typing {
            None => Ok(Uploaded {
                data: self.coe_upload(slave, index, subindex, complete).await?,
                value: None,
            }),
            Some(ty) => {
                let (data, value) = self
                    .coe_upload_value(slave, index, subindex, complete, ty)
                    .await?;
                Ok(Uploaded {
                    data,
                    value: Some(value),
                })
            }
        }
    }

    /// SDO download of `payload`: bytes as they are, or a value as text with its type.
    pub async fn coe_write(
        &self,
        mut ticket: Ticket,
        slave: SlaveName,
        index: u16,
        subindex: u8,
        payload: SdoPayload<'_>,
    ) -> Result<()> {
        ticket.check(Operation::CoeDownload, slave)?;
        ticket.value(payload.audited());
        ticket.finish(match payload {
            SdoPayload::Bytes { data, complete } => {
                self.sdo_download(slave, index, subindex, data, complete)
                    .await
            }
            SdoPayload::Value { complete: true, .. } => Err(ApiError::invalid_field(
                "complete_access",
                "complete access writes bytes: give data, not a typed value",
            )),
            SdoPayload::Value { text, typing, .. } => {
                self.coe_download_value(slave, index, subindex, text, typing)
                    .await
            }
        })
    }

    /// SDO upload with the value as text, typed by `typing`.
    async fn coe_upload_value(
        &self,
        slave: SlaveName,
        index: u16,
        subindex: u8,
        complete: bool,
        typing: Typing,
    ) -> Result<(Vec<u8>, String)> {
        let ty = match self.value_type(slave, index, subindex, typing).await {
            Ok(ty) => ty,
            // The slave would not describe the entry (an SDO Information error, with or
            // without its code): a plain upload gets the slave's own SDO abort to the user,
            // or the value, shown as hex.
            Err(err) if matches!(err.tag, "sdo_abort" | "sdo_info_error") => {
                let data = self.coe_upload(slave, index, subindex, complete).await?;
                let text = value::decode(ValueType::Hex, &data)?;
                return Ok((data, text));
            }
            Err(err) => return Err(err),
        };
        let data = self.coe_upload(slave, index, subindex, complete).await?;
        let text = value::decode(ty, &data)?;
        Ok((data, text))
    }

    /// SDO download of a value given as text, typed by `typing`.
    async fn coe_download_value(
        &self,
        slave: SlaveName,
        index: u16,
        subindex: u8,
        text: &str,
        typing: Typing,
    ) -> Result<()> {
        let ty = self.value_type(slave, index, subindex, typing).await?;
        let data = value::encode(ty, text).map_err(|err| err.in_field("value"))?;
        self.sdo_download(slave, index, subindex, &data, false)
            .await
    }

    /// The object list of type `list` (1 all, 2 RxPDO, 3 TxPDO, 4 backup, 5 settings).
    pub async fn coe_object_list(&self, slave: SlaveName, list: u16) -> Result<Vec<u16>> {
        if !(1..=5).contains(&list) {
            return Err(ApiError::invalid_field(
                "list",
                "object list type must be 1..=5",
            ));
        }
        self.call(slave, Protocol::Coe, |m| async move {
            m.sdo_info_od_list(OdListType::from(list)).await
        })
        .await
    }

    /// The description of object `index`.
    pub async fn coe_object(&self, slave: SlaveName, index: u16) -> Result<ObjectView> {
        let info = self
            .call(slave, Protocol::Coe, |m| async move {
                m.sdo_info_object(index).await
            })
            .await?;
        Ok(ObjectView {
            index: info.index,
            data_type: u16::from(info.data_type),
            data_type_name: info.data_type.to_string(),
            max_subindex: info.max_subindex,
            object_code: u8::from(info.object_code),
            name: info.name,
        })
    }

    /// The description of entry `index:subindex`.
    pub async fn coe_entry(&self, slave: SlaveName, index: u16, subindex: u8) -> Result<EntryView> {
        let info = self
            .call(slave, Protocol::Coe, |m| async move {
                m.sdo_info_entry(index, subindex, 0).await
            })
            .await?;
        Ok(EntryView {
            index: info.index,
            subindex: info.subindex,
            data_type: u16::from(info.data_type),
            data_type_name: info.data_type.to_string(),
            bit_length: info.bit_length,
            access: info.access.0,
            description: info.description,
        })
    }

    /// Reads the `elements` (0: the value) of IDN `idn` of drive `drive`.
    pub async fn soe_read(
        &self,
        slave: SlaveName,
        drive: u8,
        idn: u16,
        elements: u8,
    ) -> Result<Vec<u8>> {
        self.call(slave, Protocol::Soe, |m| async move {
            m.soe_read(drive, Idn::from_raw(idn), element_flags(elements))
                .await
        })
        .await
    }

    /// [`Core::soe_read`], and with `ty` the value as text ([`crate::input::soe_value`]).
    pub async fn soe_read_as(
        &self,
        slave: SlaveName,
        drive: u8,
        idn: u16,
        elements: u8,
        ty: Option<value::ValueType>,
    ) -> Result<(Vec<u8>, Option<String>)> {
        let data = self.soe_read(slave, drive, idn, elements).await?;
        let value = ty
            .map(|ty| crate::input::soe_value::decode(ty, &data))
            .transpose()?;
        Ok((data, value))
    }

    /// Writes the `elements` (0: the value) of IDN `idn` of drive `drive`.
    pub async fn soe_write(
        &self,
        mut ticket: Ticket,
        slave: SlaveName,
        drive: u8,
        idn: u16,
        elements: u8,
        data: &[u8],
    ) -> Result<()> {
        ticket.check(Operation::SoeWrite, slave)?;
        ticket.value(data);
        ticket.finish(
            self.call(slave, Protocol::Soe, |m| async move {
                m.soe_write(drive, Idn::from_raw(idn), element_flags(elements), data)
                    .await
            })
            .await,
        )
    }

    /// Reads file `name`; `progress` hears the bytes transferred so far, and so does the
    /// event stream (`foe_progress`). Deadlines follow the transfer ([`transfer`]);
    /// dropping the call ends the transfer towards the slave with an FoE ERROR.
    pub async fn foe_read(
        &self,
        slave: SlaveName,
        name: &str,
        password: u32,
        progress: Option<transfer::ProgressFn>,
    ) -> Result<Vec<u8>> {
        let read = self
            .call(slave, Protocol::Foe, |m| async move {
                let report = self.foe_reporter(&m, name, None, progress);
                let options = FoeOptions {
                    password,
                    progress: Some(Arc::clone(&report)),
                };
                let m = transfer::with_progress_deadlines(&m, transfer::READ_CAP_SIZE);
                let data = m.foe_read(name, options).await?;
                // The size is known now: the last report says the read is complete.
                report(FoeProgress::Transferred {
                    bytes: data.len(),
                    total: Some(data.len()),
                });
                Ok(data)
            })
            .await;
        if let Err(err) = &read {
            transfer::log_failure("read", slave, name, err);
        }
        read
    }

    /// Writes file `name`; `progress` hears the bytes the slave acknowledged so far, and so
    /// does the event stream (`foe_progress`). Deadlines follow the transfer
    /// ([`transfer`]); dropping the call ends the transfer towards the slave with an FoE
    /// ERROR.
    pub async fn foe_write(
        &self,
        mut ticket: Ticket,
        slave: SlaveName,
        name: &str,
        password: u32,
        data: &[u8],
        progress: Option<transfer::ProgressFn>,
    ) -> Result<()> {
        ticket.check(Operation::FoeWrite, format_args!("{slave} {name}"))?;
        ticket.value(data);
        let written = self
            .call(slave, Protocol::Foe, |m| async move {
                let report = self.foe_reporter(&m, name, Some(data.len()), progress);
                let options = FoeOptions {
                    password,
                    progress: Some(report),
                };
                let m = transfer::with_progress_deadlines(&m, data.len());
                m.foe_write(name, data, options).await
            })
            .await;
        if let Err(err) = &written {
            transfer::log_failure("write", slave, name, err);
        }
        ticket.finish(written)
    }

    /// The progress reporter of an FoE transfer on `mailbox` (events only once somebody
    /// subscribed to the stream).
    fn foe_reporter(
        &self,
        mailbox: &SlaveMailbox,
        name: &str,
        write_size: Option<usize>,
        also: Option<transfer::ProgressFn>,
    ) -> transfer::ProgressFn {
        let station = mailbox.station();
        let position = self
            .master
            .slaves()
            .iter()
            .find(|s| s.station == station)
            .map_or(0, |s| s.position);
        let events = self.events.get().map(|hub| Arc::clone(hub.log()));
        transfer::reporter(events, (position, station), name, write_size, also)
    }

    /// Sends one VoE message and returns the answer.
    pub async fn voe(
        &self,
        mut ticket: Ticket,
        slave: SlaveName,
        vendor_id: u32,
        vendor_type: u16,
        data: &[u8],
    ) -> Result<VoeMessage> {
        ticket.check(Operation::Voe, slave)?;
        ticket.value(data);
        ticket.finish(
            self.call(slave, Protocol::Voe, |m| async move {
                m.voe(vendor_id, vendor_type, data).await
            })
            .await,
        )
    }

    /// Sets IP parameters of the slave's EoE port.
    pub async fn eoe_set_ip(
        &self,
        mut ticket: Ticket,
        slave: SlaveName,
        settings: &IpView,
    ) -> Result<()> {
        ticket.check(Operation::EoeSetIp, slave)?;
        ticket.finish(
            async {
                let settings = ip::to_settings(settings)?;
                self.call(slave, Protocol::Eoe, |m| async move {
                    m.eoe_set_ip(&settings).await
                })
                .await
            }
            .await,
        )
    }

    /// Sets the address filter of the slave's EoE port (which frames reach its device).
    pub async fn eoe_set_address_filter(
        &self,
        mut ticket: Ticket,
        slave: SlaveName,
        view: &crate::input::mac_filter::MacFilterView,
    ) -> Result<()> {
        ticket.check(Operation::EoeSetAddressFilter, slave)?;
        ticket.finish(
            async {
                let filter = crate::input::mac_filter::to_filter(view)?;
                self.call(slave, Protocol::Eoe, |m| async move {
                    m.eoe_set_address_filter(&filter).await
                })
                .await
            }
            .await,
        )
    }

    /// Reads IP parameters of the slave's EoE port.
    pub async fn eoe_get_ip(&self, slave: SlaveName) -> Result<IpView> {
        let settings = self
            .call(
                slave,
                Protocol::Eoe,
                |m| async move { m.eoe_get_ip().await },
            )
            .await?;
        Ok(ip::from_settings(&settings))
    }
}

/// Refuses register data of no bytes or more than the ESC's register space.
fn register_data(data: &[u8]) -> Result<()> {
    if data.is_empty() || data.len() > MAX_REGISTER_LEN {
        return Err(ApiError::invalid(format!(
            "register data must be 1..={MAX_REGISTER_LEN} bytes"
        )));
    }
    Ok(())
}

fn element_flags(elements: u8) -> ElementFlags {
    if elements == 0 {
        ElementFlags::VALUE
    } else {
        ElementFlags::from_bits(elements)
    }
}
