//! EoE interfaces: one TAP interface per slave that speaks EoE (spec-notes §eoe), so
//! ordinary IP traffic reaches the device behind the slave.
//!
//! - the `[eoe]` section (names, per-slave Set IP, host address or bridge) is read in
//!   [`crate::config::eoe`];
//! - [`tap`]: the TAP interface itself;
//! - `link`: the two tasks that carry frames between a TAP and a slave's mailbox;
//! - here: the manager, which follows the master's slaves and events: an interface is made
//!   when an EoE slave is found (made anew at every scan that finds it, with its host
//!   settings applied again), its carrier is on only while the slave is present and in
//!   PREOP or higher, and it is removed when the slave is gone from the segment.

mod link;
pub mod tap;

use std::collections::{BTreeMap, HashSet};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use master_core::mailbox::{IpSettings, SlaveMailbox};
use master_core::master::{Master, MasterEvent, SlaveAddress, SlaveInfo};
use master_core::wire::mailbox::MailboxType;
use master_core::wire::register::AlState;
use serde::Serialize;
use tokio::sync::broadcast::error::{RecvError, TryRecvError};
use tokio::task::JoinHandle;

use crate::config::eoe::{EoeSettings, NameScheme, SlavePlan};
use tap::Tap;

/// How often the manager looks at the slaves besides reacting to the master's events.
const RECONCILE_INTERVAL: Duration = Duration::from_millis(250);

/// Frame counters of one interface; "out" is host → slave, "in" is slave → host.
#[derive(Debug, Default)]
pub struct Counters {
    frames_out: AtomicU64,
    bytes_out: AtomicU64,
    drops_out: AtomicU64,
    frames_in: AtomicU64,
    bytes_in: AtomicU64,
    drops_in: AtomicU64,
}

fn add(counter: &AtomicU64, n: usize) {
    counter.fetch_add(u64::try_from(n).unwrap_or(u64::MAX), Ordering::Relaxed);
}

/// One interface as the APIs, the CLI and the metrics show it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, utoipa::ToSchema)]
pub struct InterfaceView {
    /// Interface name (`eoe0s1`, `eoe0a7`).
    pub name: String,
    /// The interface's MAC address.
    pub mac: String,
    /// `up` (carrier on: the slave is present and in PREOP or higher) or `down`.
    pub state: String,
    /// The slave's ring position.
    pub position: u16,
    /// The slave's station address.
    pub station: u16,
    /// The slave's alias (0: none).
    pub alias: u16,
    /// Frames sent to the slave.
    pub frames_out: u64,
    /// Their bytes.
    pub bytes_out: u64,
    /// Frames from the host that could not be sent (mailbox errors, slave gone).
    pub drops_out: u64,
    /// Frames received from the slave.
    pub frames_in: u64,
    /// Their bytes.
    pub bytes_in: u64,
    /// Frames from the slave lost before the interface (the reader fell behind).
    pub drops_in: u64,
    /// Frames from the slave dropped in reassembly (lost or out-of-order fragment, timeout).
    pub reassembly_errors: u64,
}

/// One interface and the link to its slave, if one runs.
struct Interface {
    tap: Arc<Tap>,
    mac: [u8; 6],
    slave: SlaveInfo,
    counters: Arc<Counters>,
    /// Set by the link when the slave's mailbox went away under it: the manager restarts it.
    stale: Arc<AtomicBool>,
    link: Option<Link>,
}

/// The two tasks of a running link; aborted when dropped.
struct Link {
    tasks: [JoinHandle<()>; 2],
}

impl Drop for Link {
    fn drop(&mut self) {
        for task in &self.tasks {
            task.abort();
        }
    }
}

impl Interface {
    fn stop_link(&mut self) {
        if self.link.take().is_some()
            && let Err(err) = self.tap.set_carrier(false)
        {
            tracing::warn!(interface = self.tap.name(), %err, "cannot switch the carrier off");
        }
    }

    fn start_link(&mut self, mailbox: SlaveMailbox, ip: Option<IpSettings>, queue_len: usize) {
        self.stale.store(false, Ordering::Relaxed);
        let tasks = link::start(
            Arc::clone(&self.tap),
            mailbox,
            ip,
            queue_len,
            Arc::clone(&self.counters),
            Arc::clone(&self.stale),
        );
        self.link = Some(Link { tasks });
        if let Err(err) = self.tap.set_carrier(true) {
            tracing::warn!(interface = self.tap.name(), %err, "cannot switch the carrier on");
        }
    }
}

/// The EoE interfaces ecatd has made, for the APIs and the metrics. Cheap to clone.
#[derive(Clone, Default)]
pub struct EoeInterfaces {
    interfaces: Arc<Mutex<BTreeMap<u16, Interface>>>,
}

impl std::fmt::Debug for EoeInterfaces {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EoeInterfaces")
            .field("interfaces", &self.lock().len())
            .finish()
    }
}

impl EoeInterfaces {
    fn lock(&self) -> MutexGuard<'_, BTreeMap<u16, Interface>> {
        self.interfaces
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
    }

    /// Every interface, by slave position, with its counters; `master` gives the
    /// reassembly errors (counted by the slave's mailbox).
    pub fn list(&self, master: &Master) -> Vec<InterfaceView> {
        let views: Vec<InterfaceView> = self
            .lock()
            .values()
            .map(|i| {
                let c = &*i.counters;
                let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
                InterfaceView {
                    name: i.tap.name().to_owned(),
                    mac: format_mac(i.mac),
                    state: if i.link.is_some() { "up" } else { "down" }.into(),
                    position: i.slave.position,
                    station: i.slave.station,
                    alias: i.slave.alias,
                    frames_out: get(&c.frames_out),
                    bytes_out: get(&c.bytes_out),
                    drops_out: get(&c.drops_out),
                    frames_in: get(&c.frames_in),
                    bytes_in: get(&c.bytes_in),
                    drops_in: get(&c.drops_in),
                    reassembly_errors: 0,
                }
            })
            .collect();
        // The engine's counters are read with the lock released.
        views
            .into_iter()
            .map(|mut view| {
                if let Ok(mailbox) = master.mailbox(SlaveAddress::Station(view.station)) {
                    view.reassembly_errors = mailbox.stats().eoe_reassembly_errors;
                }
                view
            })
            .collect()
    }
}

/// The manager's task; stopping it (drop) removes every interface.
pub struct EoeManager {
    task: JoinHandle<()>,
    interfaces: EoeInterfaces,
}

impl Drop for EoeManager {
    fn drop(&mut self) {
        self.task.abort();
        self.interfaces.lock().clear();
    }
}

/// `02:NIC:NIC:NIC:RP:RP`: locally administered, the lower half of the master NIC's MAC and
/// the ring position, so two masters on one host do not collide.
pub fn default_mac(nic: [u8; 6], position: u16) -> [u8; 6] {
    let [hi, lo] = position.to_be_bytes();
    [0x02, nic[3], nic[4], nic[5], hi, lo]
}

/// `aa:bb:cc:dd:ee:ff`.
pub fn format_mac(mac: [u8; 6]) -> String {
    mac.map(|b| format!("{b:02x}")).join(":")
}

/// The interface name of the slave at `position` with `alias` (0: none) under `settings`.
pub fn interface_name(settings: &EoeSettings, position: u16, alias: u16) -> String {
    let m = settings.master_index;
    match settings.name_scheme {
        NameScheme::Alias if alias != 0 => format!("eoe{m}a{alias}"),
        _ => format!("eoe{m}s{position}"),
    }
}

fn plan_for<'a>(plans: &'a [SlavePlan], slave: &SlaveInfo) -> Option<&'a SlavePlan> {
    plans.iter().find(|plan| match plan.address {
        SlaveAddress::Position(p) => p == slave.position,
        SlaveAddress::Station(s) => s == slave.station,
        SlaveAddress::Alias(a) => a != 0 && a == slave.alias,
    })
}

/// Starts the manager on `master`; `nic` is the master NIC's MAC (for the default MACs).
pub fn start(
    master: Arc<Master>,
    settings: &EoeSettings,
    nic: [u8; 6],
    interfaces: EoeInterfaces,
) -> Result<EoeManager, String> {
    let plans = settings.plans()?;
    let manager = Manager {
        master,
        settings: settings.clone(),
        plans,
        nic,
        interfaces: interfaces.clone(),
        recreate: HashSet::new(),
        restart: HashSet::new(),
        failed: HashSet::new(),
    };
    Ok(EoeManager {
        task: tokio::spawn(manager.run()),
        interfaces,
    })
}

struct Manager {
    master: Arc<Master>,
    settings: EoeSettings,
    plans: Vec<SlavePlan>,
    nic: [u8; 6],
    interfaces: EoeInterfaces,
    /// Slaves a scan found again: their interface is made anew.
    recreate: HashSet<u16>,
    /// Slaves whose link is started anew (they went through INIT: a new mailbox owner).
    restart: HashSet<u16>,
    /// Interface names that could not be made (logged once until they can).
    failed: HashSet<String>,
}

impl Manager {
    async fn run(mut self) {
        let mut events = self.master.events();
        let mut tick = tokio::time::interval(RECONCILE_INTERVAL);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            let first = tokio::select! {
                event = events.recv() => Some(event),
                _ = tick.tick() => None,
            };
            // Every event already there is taken before acting, so that a scan's events
            // lead to one new interface and one link, not a link started and restarted.
            let mut next = first;
            while let Some(event) = next.take() {
                match event {
                    Ok(event) => self.note(&event),
                    Err(RecvError::Lagged(_)) => {
                        // Events were lost: every link starts anew to be safe.
                        let all: Vec<u16> = self.interfaces.lock().keys().copied().collect();
                        self.restart.extend(all);
                    }
                    Err(RecvError::Closed) => return,
                }
                next = match events.try_recv() {
                    Ok(event) => Some(Ok(event)),
                    Err(TryRecvError::Lagged(n)) => Some(Err(RecvError::Lagged(n))),
                    Err(_) => None,
                };
            }
            self.reconcile();
        }
    }

    fn note(&mut self, event: &MasterEvent) {
        let working = |s: &AlState| matches!(s, AlState::PreOp | AlState::SafeOp | AlState::Op);
        match event {
            MasterEvent::SlaveFound { position, .. }
            | MasterEvent::SlaveReplaced { position, .. } => {
                self.recreate.insert(*position);
            }
            MasterEvent::SlaveLost { position, .. } => {
                self.restart.insert(*position);
            }
            MasterEvent::StateChanged {
                position, from, to, ..
            } if !(working(from) && working(to)) => {
                self.restart.insert(*position);
            }
            _ => {}
        }
    }

    fn reconcile(&mut self) {
        let queue_len = self
            .master
            .mailbox_engine()
            .config()
            .eoe_tx_queue_len
            .max(1);
        let slaves = self.master.slaves();
        let mut seen = HashSet::new();
        for slave in &slaves {
            let speaks_eoe = slave
                .mailbox
                .is_some_and(|m| m.protocols.supports(MailboxType::Eoe));
            if !speaks_eoe || !self.settings.enabled {
                continue;
            }
            let position = slave.position;
            seen.insert(position);
            let plan = plan_for(&self.plans, slave).cloned();
            let name = interface_name(&self.settings, slave.position, slave.alias);
            let mac = plan
                .as_ref()
                .and_then(|p| p.mac)
                .unwrap_or_else(|| default_mac(self.nic, position));
            let mut interfaces = self.interfaces.lock();
            let renew = interfaces.get(&position).is_none_or(|i| {
                i.tap.name() != name || i.mac != mac || self.recreate.contains(&position)
            });
            if renew {
                // The old TAP closes once its link's tasks are gone; until then the name
                // is taken and the next round tries again.
                interfaces.remove(&position);
                match Tap::create(&name, mac) {
                    Ok(tap) => {
                        self.failed.remove(&name);
                        self.recreate.remove(&position);
                        // A new interface gets a new link anyway.
                        self.restart.remove(&position);
                        apply_host(&tap, plan.as_ref());
                        tracing::info!(
                            interface = name,
                            mac = format_mac(mac),
                            position,
                            "EoE interface made"
                        );
                        interfaces.insert(
                            position,
                            Interface {
                                tap: Arc::new(tap),
                                mac,
                                slave: slave.clone(),
                                counters: Arc::default(),
                                stale: Arc::default(),
                                link: None,
                            },
                        );
                    }
                    Err(err) => {
                        if self.failed.insert(name.clone()) {
                            tracing::warn!(interface = name, %err, "cannot make the EoE interface; retrying");
                        }
                        continue;
                    }
                }
            }
            let Some(interface) = interfaces.get_mut(&position) else {
                continue;
            };
            interface.slave = slave.clone();
            if self.restart.remove(&position) || interface.stale.load(Ordering::Relaxed) {
                interface.stop_link();
            }
            let working = matches!(
                slave.al_state,
                AlState::PreOp | AlState::SafeOp | AlState::Op
            );
            if !(slave.present && working) {
                interface.stop_link();
                continue;
            }
            if interface.link.is_none()
                && let Ok(mailbox) = self.master.mailbox(SlaveAddress::Position(position))
            {
                let ip = plan.and_then(|p| p.ip);
                interface.start_link(mailbox, ip, queue_len);
            }
        }
        self.interfaces.lock().retain(|position, i| {
            let keep = seen.contains(position);
            if !keep {
                tracing::info!(
                    interface = i.tap.name(),
                    "EoE interface removed: the slave is gone"
                );
            }
            keep
        });
    }
}

/// The host side of `plan` on a new interface: its address or its bridge.
fn apply_host(tap: &Tap, plan: Option<&SlavePlan>) {
    let Some(plan) = plan else { return };
    if let Some((address, prefix)) = plan.host_address
        && let Err(err) = tap.set_address(address, prefix)
    {
        tracing::warn!(interface = tap.name(), %err, "cannot put {address}/{prefix} on the interface");
    }
    if let Some(bridge) = &plan.bridge
        && let Err(err) = tap.join_bridge(bridge)
    {
        tracing::warn!(interface = tap.name(), bridge, %err, "cannot join the bridge");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_macs_follow_the_schemes() {
        let mut settings = EoeSettings::default();
        assert_eq!(interface_name(&settings, 3, 0), "eoe0s3");
        assert_eq!(interface_name(&settings, 3, 7), "eoe0a7");
        settings.name_scheme = NameScheme::Position;
        settings.master_index = 1;
        assert_eq!(interface_name(&settings, 3, 7), "eoe1s3");
        let nic = [0x00, 0x11, 0x22, 0x33, 0x44, 0x55];
        assert_eq!(
            default_mac(nic, 0x0102),
            [0x02, 0x33, 0x44, 0x55, 0x01, 0x02]
        );
        assert_eq!(format_mac([2, 0x33, 0, 0, 1, 0xab]), "02:33:00:00:01:ab");
    }
}
