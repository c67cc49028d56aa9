//! The application interface (docs/application.md): control programs in other processes
//! attach over a Unix socket, follow the cycle through a shared process image, and one of
//! them owns the outputs, watched by a watchdog that puts the safe outputs on the wire.
//!
//! - `region`: the shared memory (one image region per layout generation, one commit
//!   region per claim);
//! - `cycle`: the bus thread's side (publish, wake, take commits, the watchdog);
//! - `session`: one attached program's socket;
//! - `layout`: the entries and the safe image of the master's current layout;
//! - here: the listener, the sessions' table, and the task that follows layout changes and
//!   watchdog trips.

mod cycle;
mod layout;
mod region;
mod session;

use std::collections::HashMap;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use ecat_app::protocol::Line;
use master_core::master::{Master, SlaveAddress};
use master_core::wire::register::AlState;
use tokio::net::UnixListener;
use tokio::sync::{broadcast, mpsc, watch};
use tokio::task::JoinHandle;

use crate::config::app::{AppSettings, OnWatchdog};

pub use cycle::Force;
pub use layout::SafeValue;
pub use layout::entries as layout_entries;

/// How often the layout is looked at besides the bus thread's notices (a scan in progress
/// postpones the look).
const LOOK: Duration = Duration::from_millis(50);

/// The credentials of an attached program (`SO_PEERCRED`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Peer {
    /// Process id (0 if the kernel gave none).
    pub pid: u32,
    /// User id.
    pub uid: u32,
    /// Group id.
    pub gid: u32,
}

/// What the application interface reports as events.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum AppEvent {
    /// A program took the outputs.
    Claimed {
        /// Who.
        peer: Peer,
    },
    /// The owner gave the outputs back, closed its socket or died: safe outputs.
    Released {
        /// Who.
        peer: Peer,
        /// `released`, `closed` or `detached`.
        how: &'static str,
    },
    /// The owner committed nothing for the watchdog's cycles: safe outputs.
    Watchdog {
        /// Who.
        peer: Peer,
        /// The watchdog in cycles.
        cycles: u32,
    },
    /// An output was forced from an API.
    Forced {
        /// The force.
        force: Force,
    },
    /// A force was released.
    ForceReleased {
        /// The entry.
        entry: ecat_app::entry::Entry,
        /// Who released it.
        by: String,
    },
    /// The image's layout changed: a new generation.
    LayoutChanged {
        /// The new generation.
        generation: u32,
        /// Its entries.
        entries: usize,
    },
}

impl AppEvent {
    /// The event's kind as the event stream names it.
    pub fn kind(&self) -> &'static str {
        match self {
            AppEvent::Claimed { .. } => "app_claimed",
            AppEvent::Released { .. } => "app_released",
            AppEvent::Watchdog { .. } => "app_watchdog",
            AppEvent::Forced { .. } => "process_data_forced",
            AppEvent::ForceReleased { .. } => "process_data_released",
            AppEvent::LayoutChanged { .. } => "app_layout_changed",
        }
    }

    /// The event in words.
    pub fn text(&self) -> String {
        match self {
            AppEvent::Claimed { peer } => format!(
                "application pid {} uid {} owns the outputs",
                peer.pid, peer.uid
            ),
            AppEvent::Released { peer, how } => format!(
                "application pid {} uid {} no longer owns the outputs ({how}): safe outputs",
                peer.pid, peer.uid
            ),
            AppEvent::Watchdog { peer, cycles } => format!(
                "application pid {} uid {} committed nothing for {cycles} cycles: watchdog, safe outputs",
                peer.pid, peer.uid
            ),
            AppEvent::Forced { force } => format!(
                "{} forced slave {} 0x{:04X}:{:02X} ({}) to {}{}",
                force.by,
                force.entry.position,
                force.entry.index,
                force.entry.subindex,
                force.entry.name,
                force.value,
                if force.over_owner {
                    " over the application's outputs"
                } else {
                    ""
                }
            ),
            AppEvent::ForceReleased { entry, by } => format!(
                "{by} released the force of slave {} 0x{:04X}:{:02X} ({})",
                entry.position, entry.index, entry.subindex, entry.name
            ),
            AppEvent::LayoutChanged {
                generation,
                entries,
            } => format!(
                "process image laid out again: generation {generation}, {entries} entries; applications attach again"
            ),
        }
    }
}

/// What the interface looks like now (for the APIs and the metrics).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AppStatus {
    /// The socket served.
    pub socket: PathBuf,
    /// The layout generation.
    pub generation: u32,
    /// Programs attached.
    pub attached: usize,
    /// The owner of the outputs.
    pub owner: Option<Peer>,
    /// Watchdog trips so far.
    pub watchdog_trips: u64,
    /// Commits taken into the image so far.
    pub commits: u64,
    /// Cycles published so far.
    pub cycles: u64,
}

struct SessionEntry {
    peer: Peer,
    events: mpsc::Sender<Line>,
}

/// What the sessions and the server's task share.
pub(crate) struct Inner {
    share: Arc<cycle::CycleShare>,
    sessions: Mutex<HashMap<u64, SessionEntry>>,
    events: broadcast::Sender<AppEvent>,
    next: AtomicU64,
}

impl Inner {
    fn sessions(&self) -> MutexGuard<'_, HashMap<u64, SessionEntry>> {
        self.sessions.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn peer_of(&self, session: u64) -> Option<Peer> {
        self.sessions().get(&session).map(|s| s.peer)
    }

    fn publish(&self, event: AppEvent) {
        // Nobody listening is fine.
        let _ = self.events.send(event);
    }

    fn forget(&self, session: u64) {
        self.sessions().remove(&session);
    }

    fn tell(&self, session: u64, line: Line) {
        if let Some(s) = self.sessions().get(&session) {
            // A full queue: the program does not read; its next wait sees the region's flags.
            let _ = s.events.try_send(line);
        }
    }

    fn tell_all(&self, line: &Line) {
        for s in self.sessions().values() {
            let _ = s.events.try_send(line.clone());
        }
    }

    /// The owner's session `session` ended its ownership `how`.
    fn owner_gone(&self, session: u64, how: &'static str) {
        if let Some(region) = self.share.region() {
            region.set_owner(0, 0);
        }
        if let Some(peer) = self.peer_of(session) {
            tracing::info!(
                pid = peer.pid,
                uid = peer.uid,
                how,
                "application no longer owns the outputs; safe outputs"
            );
            self.publish(AppEvent::Released { peer, how });
        }
    }
}

/// The bound socket, before the segment is up (so a taken path fails at start).
#[derive(Debug)]
pub struct AppListener {
    listener: UnixListener,
    path: PathBuf,
}

/// Binds the socket of `settings` at `path`: a stale socket file is replaced, a live one
/// (another ecatd) refused; then the mode and group are applied.
pub fn bind(settings: &AppSettings, path: &Path) -> Result<AppListener, String> {
    if let Some(dir) = path.parent()
        && !dir.as_os_str().is_empty()
    {
        std::fs::create_dir_all(dir)
            .map_err(|err| format!("[app] cannot make {}: {err}", dir.display()))?;
    }
    if std::os::unix::net::UnixStream::connect(path).is_ok() {
        return Err(format!(
            "[app] socket {}: another process serves it",
            path.display()
        ));
    }
    match std::fs::remove_file(path) {
        Ok(()) => {}
        Err(err) if err.kind() == std::io::ErrorKind::NotFound => {}
        Err(err) => return Err(format!("[app] cannot replace {}: {err}", path.display())),
    }
    let listener = UnixListener::bind(path)
        .map_err(|err| format!("[app] cannot listen on {}: {err}", path.display()))?;
    let mode = settings.mode_bits()?;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode))
        .map_err(|err| format!("[app] cannot set the mode of {}: {err}", path.display()))?;
    if let Some(group) = &settings.group {
        let gid = gid_of(group)?;
        std::os::unix::fs::chown(path, None, Some(gid)).map_err(|err| {
            format!(
                "[app] cannot give {} to group {group}: {err}",
                path.display()
            )
        })?;
    }
    Ok(AppListener {
        listener,
        path: path.to_path_buf(),
    })
}

/// A group's id from its name or number.
fn gid_of(group: &str) -> Result<u32, String> {
    if let Ok(gid) = group.parse() {
        return Ok(gid);
    }
    let name = std::ffi::CString::new(group).map_err(|_| format!("[app] group {group:?}"))?;
    // SAFETY: a NUL-terminated name; the result is read at once (getgrnam's static buffer)
    // and only its gid copied.
    let entry = unsafe { libc::getgrnam(name.as_ptr()) };
    if entry.is_null() {
        return Err(format!("[app] group {group:?}: no such group"));
    }
    // SAFETY: non-null, points at getgrnam's result.
    Ok(unsafe { (*entry).gr_gid })
}

/// The running application interface; [`AppServer::stop`] ends it.
pub struct AppServer {
    handle: AppHandle,
    stop: watch::Sender<bool>,
    tasks: Vec<JoinHandle<()>>,
}

/// Why a force was refused.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ForceRefusal {
    /// An application owns the outputs (and the force did not say to override it).
    Owned(Peer),
    /// The entry is an input.
    NotOutput,
    /// The value does not fit the entry's type and bits.
    OutOfRange,
}

/// A cheap handle on the running interface, for the APIs and the metrics: what it looks
/// like now.
#[derive(Clone)]
pub struct AppHandle {
    inner: Arc<Inner>,
    path: PathBuf,
}

impl AppHandle {
    /// The entries of the current layout generation.
    pub fn entries(&self) -> Vec<ecat_app::entry::Entry> {
        self.inner
            .share
            .region()
            .map(|r| r.entries().to_vec())
            .unwrap_or_default()
    }

    /// Forces output `entry` to `value` from the next frame on, for `by`; refused while an
    /// application owns the outputs unless `over_owner`.
    pub fn force(
        &self,
        entry: ecat_app::entry::Entry,
        value: i64,
        by: &str,
        over_owner: bool,
    ) -> Result<Force, ForceRefusal> {
        if entry.direction != ecat_app::entry::Direction::Out {
            return Err(ForceRefusal::NotOutput);
        }
        if !entry.accepts(value) || entry.bit_length > 64 {
            return Err(ForceRefusal::OutOfRange);
        }
        let share = &self.inner.share;
        let owner = share.owner_session().and_then(|s| self.inner.peer_of(s));
        if let (Some(peer), false) = (owner, over_owner) {
            return Err(ForceRefusal::Owned(peer));
        }
        let force = Force {
            entry,
            // The low bits carry the value, as the clients write it.
            value: value as u64,
            by: by.into(),
            over_owner: owner.is_some(),
            since: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs()),
        };
        share.force(force.clone());
        tracing::info!(
            by,
            position = force.entry.position,
            index = force.entry.index,
            subindex = force.entry.subindex,
            value,
            over_owner = force.over_owner,
            "output forced"
        );
        self.inner.publish(AppEvent::Forced {
            force: force.clone(),
        });
        Ok(force)
    }

    /// Releases the force of `entry`; whether there was one.
    pub fn release_force(&self, entry: &ecat_app::entry::Entry, by: &str) -> bool {
        let released = self.inner.share.release_force(entry);
        if released {
            tracing::info!(
                by,
                position = entry.position,
                index = entry.index,
                subindex = entry.subindex,
                "force released"
            );
            self.inner.publish(AppEvent::ForceReleased {
                entry: entry.clone(),
                by: by.into(),
            });
        }
        released
    }

    /// The forced outputs.
    pub fn forces(&self) -> Vec<Force> {
        self.inner.share.forces()
    }

    /// The interface now.
    pub fn status(&self) -> AppStatus {
        let share = &self.inner.share;
        let region = share.region();
        let owner = share.owner_session().and_then(|s| self.inner.peer_of(s));
        AppStatus {
            socket: self.path.clone(),
            generation: region.as_ref().map_or(0, |r| r.generation()),
            attached: self.inner.sessions().len(),
            owner,
            watchdog_trips: share.trips(),
            commits: share.commits(),
            cycles: share.cycles(),
        }
    }
}

impl AppServer {
    /// Serves `listener` over `master`'s cycle (installs the cycle hook), with the safe
    /// values `safe` (resolved from `[[app.safe_output]]`).
    pub fn start(
        listener: AppListener,
        master: Arc<Master>,
        settings: &AppSettings,
        safe: Vec<SafeValue>,
    ) -> Result<AppServer, String> {
        let share = Arc::new(cycle::CycleShare::new(settings.watchdog));
        let (events, _) = broadcast::channel(64);
        let inner = Arc::new(Inner {
            share: Arc::clone(&share),
            sessions: Mutex::new(HashMap::new()),
            events,
            next: AtomicU64::new(1),
        });
        let mut follower = Follower {
            master: Arc::clone(&master),
            inner: Arc::clone(&inner),
            safe,
            watchdog: settings.watchdog,
            on_watchdog: settings.on_watchdog,
            generation: 0,
        };
        follower.lay_out()?;
        let hook: Arc<dyn master_core::master::CycleHook> = share;
        master.set_cycle_hook(Some(hook));
        let (stop, stopped) = watch::channel(false);
        let accept = tokio::spawn(accept(
            listener.listener,
            Arc::clone(&inner),
            settings.max_clients,
            stopped.clone(),
        ));
        let follow = tokio::spawn(follower.run(stopped));
        tracing::info!(socket = %listener.path.display(), watchdog = settings.watchdog, "application interface serving");
        Ok(AppServer {
            handle: AppHandle {
                inner,
                path: listener.path,
            },
            stop,
            tasks: vec![accept, follow],
        })
    }

    /// Events of the interface from now on.
    pub fn events(&self) -> broadcast::Receiver<AppEvent> {
        self.handle.inner.events.subscribe()
    }

    /// A handle for the APIs and the metrics.
    pub fn handle(&self) -> AppHandle {
        self.handle.clone()
    }

    /// Stops serving: every program is told, an owner's outputs go to the safe values from
    /// the next frame, and the socket file is removed.
    pub async fn stop(self) {
        let inner = &self.handle.inner;
        let _ = self.stop.send(true);
        if let Some(session) = inner.share.release_all() {
            inner.owner_gone(session, "closed");
        }
        if let Some(region) = inner.share.region() {
            region.mark_dead();
        }
        inner.tell_all(&Line::Shutdown);
        for task in self.tasks {
            let _ = task.await;
        }
        // The sessions end on the shutdown line (bounded by their send timeout).
        let _ = std::fs::remove_file(&self.handle.path);
    }
}

/// Accepts programs until stopped.
async fn accept(
    listener: UnixListener,
    inner: Arc<Inner>,
    max_clients: usize,
    mut stopped: watch::Receiver<bool>,
) {
    loop {
        let accepted = tokio::select! {
            accepted = listener.accept() => accepted,
            _ = stopped.wait_for(|s| *s) => return,
        };
        let stream = match accepted {
            Ok((stream, _)) => stream,
            Err(err) => {
                tracing::warn!(%err, "application socket: accept failed");
                continue;
            }
        };
        let peer = match stream.peer_cred() {
            Ok(cred) => Peer {
                pid: cred.pid().and_then(|p| u32::try_from(p).ok()).unwrap_or(0),
                uid: cred.uid(),
                gid: cred.gid(),
            },
            Err(err) => {
                tracing::warn!(%err, "application socket: no peer credentials; refused");
                continue;
            }
        };
        let id = inner.next.fetch_add(1, Ordering::Relaxed);
        let (tx, rx) = mpsc::channel(8);
        {
            let mut sessions = inner.sessions();
            if sessions.len() >= max_clients {
                drop(sessions);
                tracing::warn!(
                    pid = peer.pid,
                    uid = peer.uid,
                    max_clients,
                    "application refused: too many attached"
                );
                tokio::spawn(refuse(stream, max_clients));
                continue;
            }
            sessions.insert(id, SessionEntry { peer, events: tx });
        }
        let mut stop = stopped.clone();
        let inner = Arc::clone(&inner);
        tokio::spawn(async move {
            tokio::select! {
                () = session::serve(stream, id, peer, Arc::clone(&inner), rx) => {}
                // ecatd stopping: the session got the shutdown line through its queue; a
                // program that does not read it is cut here.
                _ = async {
                    let _ = stop.wait_for(|s| *s).await;
                    tokio::time::sleep(Duration::from_secs(1)).await;
                } => {
                    inner.share.release(id);
                    inner.forget(id);
                }
            }
        });
    }
}

async fn refuse(mut stream: tokio::net::UnixStream, max: usize) {
    use tokio::io::AsyncWriteExt;
    let line = format!(
        "{}\n",
        Line::Refused(format!("too many attached programs (max_clients = {max})"))
    );
    let _ = tokio::time::timeout(Duration::from_secs(1), stream.write_all(line.as_bytes())).await;
}

/// Follows the master's layout and the watchdog.
struct Follower {
    master: Arc<Master>,
    inner: Arc<Inner>,
    safe: Vec<SafeValue>,
    watchdog: u32,
    on_watchdog: OnWatchdog,
    generation: u32,
}

impl Follower {
    async fn run(mut self, mut stopped: watch::Receiver<bool>) {
        let mut look = tokio::time::interval(LOOK);
        look.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                () = self.inner.share.noticed() => {}
                _ = look.tick() => {}
                _ = stopped.wait_for(|s| *s) => return,
            }
            if let Some(session) = self.inner.share.take_trip() {
                self.tripped(session).await;
            }
            if self.inner.share.layout_pending().is_some()
                && !self.master.topology_busy()
                && let Err(err) = self.lay_out()
            {
                tracing::error!(%err, "application interface: cannot lay out the new image");
            }
        }
    }

    async fn tripped(&self, session: u64) {
        let peer = self.inner.peer_of(session).unwrap_or(Peer {
            pid: 0,
            uid: 0,
            gid: 0,
        });
        tracing::warn!(
            pid = peer.pid,
            uid = peer.uid,
            cycles = self.watchdog,
            "application watchdog: no commit; safe outputs"
        );
        self.inner.tell(session, Line::Watchdog);
        self.inner.publish(AppEvent::Watchdog {
            peer,
            cycles: self.watchdog,
        });
        if self.on_watchdog == OnWatchdog::Safeop {
            for slave in self.master.slaves() {
                if slave.process_data.outputs == 0 || slave.al_state != AlState::Op {
                    continue;
                }
                let address = SlaveAddress::Position(slave.position);
                if let Err(err) = self.master.request_state(address, AlState::SafeOp).await {
                    tracing::warn!(position = slave.position, %err, "application watchdog: SAFEOP not reached");
                }
            }
        }
    }

    /// Makes the region of the master's current layout, unless the current one still fits.
    fn lay_out(&mut self) -> Result<(), String> {
        let layout_count = self.master.layout_count();
        let (entries, image_len) = layout::entries(&self.master);
        if let Some(region) = self.inner.share.region()
            && region.entries() == entries.as_slice()
            && region.image_len() == image_len
        {
            self.inner.share.accept_layout(layout_count);
            return Ok(());
        }
        self.generation += 1;
        let safe = layout::safe_image(&self.master, &entries, image_len, &self.safe);
        let region = region::ImageRegion::create(
            self.generation,
            entries,
            image_len,
            self.master.cycle_timing().period,
            self.watchdog,
        )
        .map_err(|err| format!("shared memory: {err}"))?;
        let count = region.entries().len();
        let first = self.generation == 1;
        let lost = self
            .inner
            .share
            .install(Arc::new(region), layout_count, safe);
        if let Some(session) = lost {
            self.inner.owner_gone(session, "detached");
        }
        if !first {
            tracing::info!(
                generation = self.generation,
                entries = count,
                "process image laid out again; applications attach again"
            );
            self.inner.tell_all(&Line::LayoutChanged(self.generation));
            self.inner.publish(AppEvent::LayoutChanged {
                generation: self.generation,
                entries: count,
            });
        }
        Ok(())
    }
}
