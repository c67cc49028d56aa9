//! The cyclic slot: a task exchanges process data on the bus thread at its period while
//! acyclic traffic flows in the gaps; lost cyclic frames are reported, not retried.
//!
//! Only counts are checked here; how precisely cycles keep time is the benchmark's business.

use crate::bus_support;

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Sender, channel};
use std::time::{Duration, Instant};

use bus_support::bus::{PATIENCE, config, finish, start, start_on};
use bus_support::responder::Answer;
use bus_support::segment::{
    FakeSegment, INPUTS_AT, LOGICAL_START, OUTPUTS_AT, WINDOW_INPUTS, WINDOW_LEN, WINDOW_OUTPUTS,
};
use master_core::bus::{BusConfig, CyclicFrame, CyclicReply, CyclicTask};
use master_core::link::{FaultConfig, FaultInjector, MemoryLink};
use master_core::wire::command::{Command, DatagramAddress};

const SLAVES: usize = 3;

/// A process-data exchange: an LRW over every slave's window carrying a counter as
/// outputs, and a BRD of the AL status next to it.
struct Exchange {
    period: Duration,
    counter: u8,
    completed: Arc<AtomicU64>,
    /// The counter value of each completed cycle (bounded: a full channel drops).
    seen: std::sync::mpsc::SyncSender<u8>,
    lost: Sender<()>,
    dropped: Sender<()>,
}

impl CyclicTask for Exchange {
    fn period(&self) -> Duration {
        self.period
    }

    fn build(&mut self, frame: &mut CyclicFrame<'_>) {
        let len = SLAVES * WINDOW_LEN;
        let lrw = frame
            .push_zeroed(Command::Lrw, DatagramAddress::Logical(LOGICAL_START), len)
            .unwrap();
        let data = frame.data_mut(lrw).unwrap();
        for slave in 0..SLAVES {
            data[slave * WINDOW_LEN..][..WINDOW_OUTPUTS].fill(self.counter);
        }
        let brd = frame
            .push_zeroed(Command::Brd, DatagramAddress::broadcast(0x0130), 2)
            .unwrap();
        assert_eq!((lrw, brd, frame.len()), (0, 1, 2));
    }

    fn complete(&mut self, reply: &CyclicReply<'_>) {
        assert_eq!(reply.len(), 2);
        let lrw = reply.datagram(0).unwrap();
        assert_eq!(lrw.wkc, 3 * SLAVES as u16, "every slave read and wrote");
        for slave in 0..SLAVES {
            let inputs = &lrw.data[slave * WINDOW_LEN + WINDOW_OUTPUTS..][..WINDOW_INPUTS];
            let expected: Vec<u8> = (0..WINDOW_INPUTS)
                .map(|i| FakeSegment::pattern(slave, INPUTS_AT + i))
                .collect();
            assert_eq!(inputs, expected);
        }
        assert_eq!(reply.datagram(1).unwrap().wkc, SLAVES as u16);
        let _ = self.seen.try_send(self.counter);
        self.counter = self.counter.wrapping_add(1);
        self.completed.fetch_add(1, Ordering::SeqCst);
    }

    fn lost(&mut self) {
        let _ = self.lost.send(());
    }
}

impl Drop for Exchange {
    fn drop(&mut self) {
        let _ = self.dropped.send(());
    }
}

struct Probes {
    completed: Arc<AtomicU64>,
    seen: std::sync::mpsc::Receiver<u8>,
    lost: std::sync::mpsc::Receiver<()>,
    dropped: std::sync::mpsc::Receiver<()>,
}

fn exchange(period: Duration) -> (Exchange, Probes) {
    let completed = Arc::new(AtomicU64::new(0));
    let (seen_tx, seen) = std::sync::mpsc::sync_channel(10_000);
    let (lost_tx, lost) = channel();
    let (dropped_tx, dropped) = channel();
    (
        Exchange {
            period,
            counter: 1,
            completed: Arc::clone(&completed),
            seen: seen_tx,
            lost: lost_tx,
            dropped: dropped_tx,
        },
        Probes {
            completed,
            seen,
            lost,
            dropped,
        },
    )
}

#[test]
fn bus_runs_the_cyclic_task_at_its_period_while_acyclic_traffic_flows() {
    let bus = start(SLAVES, Answer, config());
    let (task, probes) = exchange(Duration::from_millis(1));
    bus.handle.set_cyclic(Some(Box::new(task)));

    // Acyclic reads until at least 200 are done and 30 cycles have completed meanwhile.
    let started = Instant::now();
    let mut requests = 0usize;
    while requests < 200 || probes.completed.load(Ordering::SeqCst) < 30 {
        assert!(
            started.elapsed() < PATIENCE,
            "only {} cycles",
            probes.completed.load(Ordering::SeqCst)
        );
        let slave = requests % SLAVES;
        let ado = 0x0100 + (requests % 1024) as u16;
        let reply = finish(bus.handle.fprd(FakeSegment::station(slave), ado, 1)).unwrap();
        assert_eq!(reply.data[0], FakeSegment::pattern(slave, usize::from(ado)));
        requests += 1;
    }

    // Cycles complete in order, one counter value after the other.
    let first: Vec<u8> = probes.seen.try_iter().take(30).collect();
    assert_eq!(first, (1..=30).collect::<Vec<u8>>());

    // Removing the task drops it on the bus thread.
    bus.handle.set_cyclic(None);
    probes.dropped.recv_timeout(PATIENCE).expect("task dropped");
    let completed = probes.completed.load(Ordering::SeqCst);
    let (stats, _, report) = bus.stop();
    assert!(stats.cycles_run >= completed, "{stats:?}");
    assert_eq!(stats.cycle_start_delay.count(), stats.cycles_run);
    // A reply later than one period counts as lost (and as stale when it does arrive); on
    // a busy test machine that happens now and then.
    assert_eq!(stats.cycles_lost, probes.lost.try_iter().count() as u64);
    assert!(stats.cycles_lost + completed <= stats.cycles_run);
    assert_eq!(stats.datagrams_completed, requests as u64);
    // The slaves hold the outputs of the last cycle that completed, or of one more that
    // was on its way when the task was removed.
    let last = completed as u8;
    for slave in &report.segment.slaves {
        let outputs = slave.mem[OUTPUTS_AT];
        assert!(
            outputs == last || outputs == last.wrapping_add(1),
            "{outputs} vs {last}"
        );
    }
}

#[test]
fn bus_reports_lost_cyclic_frames_without_retrying_them() {
    let (near, far) = MemoryLink::pair(bus_support::bus::LINK_CAPACITY);
    let dead = FaultInjector::new(
        near,
        FaultConfig {
            drop_tx: 1.0,
            ..FaultConfig::default()
        },
        7,
    );
    let bus = start_on(dead, far, SLAVES, Answer, config());
    let (task, probes) = exchange(Duration::from_millis(2));
    bus.handle.set_cyclic(Some(Box::new(task)));
    for _ in 0..5 {
        probes.lost.recv_timeout(PATIENCE).expect("a lost cycle");
    }
    bus.handle.set_cyclic(None);
    probes.dropped.recv_timeout(PATIENCE).expect("task dropped");
    let (stats, _, report) = bus.stop();
    assert!(stats.cycles_lost >= 5, "{stats:?}");
    assert_eq!(stats.frames_lost, stats.cycles_lost);
    assert_eq!(stats.retries, 0);
    assert_eq!(report.frames, 0);
    assert_eq!(probes.completed.load(Ordering::SeqCst), 0);
}

#[test]
fn bus_drops_the_cyclic_task_when_it_shuts_down() {
    let bus = start(SLAVES, Answer, BusConfig { ..config() });
    let (task, probes) = exchange(Duration::from_millis(1));
    bus.handle.set_cyclic(Some(Box::new(task)));
    probes.seen.recv_timeout(PATIENCE).expect("one cycle");
    bus.stop();
    probes.dropped.recv_timeout(PATIENCE).expect("task dropped");
}
