//! The bus under ordinary traffic: results go to the right caller, datagrams from many
//! callers share frames, indices wrap around without ever being reused in flight, working
//! counters are checked, groups share a frame, and results can be awaited.

use crate::bus_support;

use std::collections::HashSet;
use std::sync::{Arc, Barrier, Mutex};

use bus_support::bus::{PATIENCE, config, finish, start};
use bus_support::responder::{Answer, Gated, Recording, Script, answer, indices_of};
use bus_support::segment::{
    FakeSegment, INPUTS_AT, LOGICAL_START, WINDOW_INPUTS, WINDOW_LEN, WINDOW_OUTPUTS,
};
use master_core::bus::{BusConfig, BusError, DatagramRequest, Pending};
use master_core::link::Link;
use master_core::wire::command::{Command, DatagramAddress};

const SLAVES: usize = 3;

fn pattern(slave: usize, offset: u16, len: usize) -> Vec<u8> {
    (0..len)
        .map(|i| FakeSegment::pattern(slave, usize::from(offset) + i))
        .collect()
}

fn station(slave: usize) -> u16 {
    FakeSegment::station(slave)
}

/// What one of the 200 callers does, and checks.
fn caller(bus: &master_core::bus::BusHandle, caller: usize) {
    let slave = caller % SLAVES;
    let ado = 0x0100 + (caller as u16) * 4;
    let len = 1 + caller % 8;
    match caller % 4 {
        0 => {
            let reply = finish(bus.fprd(station(slave), ado, len)).unwrap();
            assert_eq!(reply.data.as_slice(), pattern(slave, ado, len), "{caller}");
            assert_eq!(reply.wkc, 1);
        }
        1 => {
            let reply = finish(bus.aprd(slave as u16, ado, len)).unwrap();
            assert_eq!(reply.data.as_slice(), pattern(slave, ado, len), "{caller}");
            // Every slave incremented ADP on the way.
            assert_eq!(
                reply.address,
                DatagramAddress::Position {
                    adp: 0u16.wrapping_sub(slave as u16).wrapping_add(SLAVES as u16),
                    ado
                }
            );
        }
        2 => {
            // A write, then the read of what was written: one caller's order holds.
            let value = (caller as u32 * 0x0101_0101).to_le_bytes();
            let at = 0x1800 + (caller as u16) * 4;
            let write = DatagramRequest::fpwr(station(slave), at, value).expect_wkc(1);
            finish(bus.submit(write)).unwrap();
            let read = DatagramRequest::fprd(station(slave), at, 4).expect_wkc(1);
            assert_eq!(finish(bus.submit(read)).unwrap().data.as_slice(), value);
        }
        _ => {
            let reply = finish(bus.brd(ado, 2)).unwrap();
            let or: Vec<u8> = (0..2)
                .map(|i| (0..SLAVES).fold(0, |acc, s| acc | pattern(s, ado, 2)[i]))
                .collect();
            assert_eq!(reply.data.as_slice(), or, "{caller}");
            assert_eq!(reply.wkc, SLAVES as u16);
        }
    }
}

#[test]
fn bus_results_reach_the_right_caller_when_200_callers_on_8_threads_submit_at_once() {
    let bus = start(SLAVES, Answer, config());
    let start_together = Arc::new(Barrier::new(8));
    std::thread::scope(|scope| {
        for thread in 0..8 {
            let handle = bus.handle.clone();
            let start_together = Arc::clone(&start_together);
            scope.spawn(move || {
                start_together.wait();
                // 25 callers per thread, each on its own scoped thread so that all 200 have
                // a request outstanding at the same time.
                std::thread::scope(|inner| {
                    for n in 0..25 {
                        let handle = handle.clone();
                        inner.spawn(move || caller(&handle, thread * 25 + n));
                    }
                });
            });
        }
    });
    let (stats, _, _) = bus.stop();
    // 200 first datagrams, and 50 reads after writes.
    assert_eq!(stats.datagrams_completed, 250);
    assert_eq!(stats.datagrams_sent, 250);
    assert_eq!(stats.datagrams_failed, 0);
    assert_eq!(stats.frames_lost, 0);
    assert_eq!((stats.frames_stale, stats.frames_foreign), (0, 0));
    assert_eq!(stats.frames_received, stats.frames_sent);
    assert!(
        stats.frames_sent < stats.datagrams_sent,
        "no frame carried two datagrams: {stats:?}"
    );
    assert_eq!(stats.round_trip.count(), stats.frames_received);
}

#[test]
fn bus_packs_datagrams_from_many_callers_into_few_frames() {
    // One frame in flight, held by the responder until every datagram is queued: whatever
    // the first frame carried, the other datagrams must then leave packed together.
    let (gated, open) = Gated::new();
    let bus = start(
        SLAVES,
        gated,
        BusConfig {
            frames_in_flight: 1,
            ..config()
        },
    );
    let pendings: Vec<(usize, u16, Pending)> = std::thread::scope(|scope| {
        let threads: Vec<_> = (0..4)
            .map(|thread| {
                let handle = bus.handle.clone();
                scope.spawn(move || {
                    (0..25)
                        .map(|n| {
                            let slave = (thread + n) % SLAVES;
                            let ado = 0x0200 + (thread * 25 + n) as u16 * 4;
                            (slave, ado, handle.fprd(station(slave), ado, 4))
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        threads
            .into_iter()
            .flat_map(|t| t.join().unwrap())
            .collect()
    });
    open.send(()).unwrap();
    for (slave, ado, pending) in pendings {
        assert_eq!(
            finish(pending).unwrap().data.as_slice(),
            pattern(slave, ado, 4)
        );
    }
    let (stats, _, report) = bus.stop();
    assert_eq!(stats.datagrams_sent, 100);
    // 100 datagrams of 16 bytes need two full frames (93 fit in 1498 bytes), plus the
    // first frame if it left before the rest was queued.
    assert!(stats.frames_sent <= 3, "{} frames", stats.frames_sent);
    assert_eq!(report.frames, stats.frames_sent);
}

#[test]
fn bus_index_wraps_around_after_256_datagrams() {
    let (recording, seen) = Recording::new(Answer);
    let bus = start(SLAVES, recording, config());
    for n in 0..600usize {
        let slave = n % SLAVES;
        let ado = 0x0400 + (n as u16 % 512) * 2;
        let reply = finish(bus.handle.fprd(station(slave), ado, 2)).unwrap();
        assert_eq!(reply.data.as_slice(), pattern(slave, ado, 2), "request {n}");
    }
    let (stats, _, _) = bus.stop();
    assert_eq!(stats.datagrams_completed, 600);
    let seen = seen.lock().unwrap();
    let indices: Vec<u8> = seen.iter().flatten().copied().collect();
    assert_eq!(indices.len(), 600);
    // Round-robin: one after the other, through 255 and back to 0, twice over.
    for (n, index) in indices.iter().enumerate() {
        assert_eq!(usize::from(*index), n % 256, "datagram {n}");
    }
}

/// Holds every frame until the link has been quiet for a moment, checks that the held
/// frames (all in flight at once) use each index at most once, then answers them in reverse
/// order.
struct Batches {
    held: Vec<Vec<u8>>,
    sizes: Arc<Mutex<Vec<usize>>>,
}

impl Script for Batches {
    fn on_frame(&mut self, frame: &mut [u8], _: &mut FakeSegment, _: &mut dyn Link) {
        self.held.push(frame.to_vec());
    }

    fn on_quiet(&mut self, segment: &mut FakeSegment, link: &mut dyn Link) {
        if self.held.is_empty() {
            return;
        }
        let indices: Vec<u8> = self.held.iter().flat_map(|f| indices_of(f)).collect();
        let unique: HashSet<u8> = indices.iter().copied().collect();
        assert_eq!(unique.len(), indices.len(), "an index used twice in flight");
        self.sizes.lock().unwrap().push(indices.len());
        for mut frame in self.held.drain(..).rev() {
            answer(&mut frame, segment, link);
        }
    }
}

#[test]
fn bus_never_reuses_an_index_still_in_flight_and_matches_replies_out_of_order() {
    let sizes = Arc::new(Mutex::new(Vec::new()));
    let script = Batches {
        held: Vec::new(),
        sizes: Arc::clone(&sizes),
    };
    let bus = start(SLAVES, script, config());
    // 600 reads at once: four frames would hold far more than the 240 indices acyclic
    // traffic may use, so the bus has to wait for replies before using more.
    let pendings: Vec<_> = (0..600usize)
        .map(|n| {
            let slave = n % SLAVES;
            let ado = 0x0400 + n as u16 * 2;
            (slave, ado, bus.handle.fprd(station(slave), ado, 2))
        })
        .collect();
    for (slave, ado, pending) in pendings {
        assert_eq!(
            finish(pending).unwrap().data.as_slice(),
            pattern(slave, ado, 2)
        );
    }
    let (stats, _, _) = bus.stop();
    assert_eq!(stats.datagrams_completed, 600);
    assert_eq!((stats.frames_lost, stats.frames_stale), (0, 0));
    let sizes = sizes.lock().unwrap();
    assert_eq!(sizes.iter().sum::<usize>(), 600);
    assert!(sizes.iter().all(|&n| n <= 240), "batches {sizes:?}");
    // Once the queue is deep, the 240 indices acyclic traffic may hold are what limits a
    // batch, not the four frames (which could carry 428 such datagrams).
    assert_eq!(sizes.iter().max(), Some(&240), "batches {sizes:?}");
}

#[test]
fn bus_reports_working_counter_mismatches_with_the_reply_attached() {
    let bus = start(SLAVES, Answer, config());
    // No slave has station address 0x2000.
    let absent = DatagramRequest::fprd(0x2000, 0x0130, 2).expect_wkc(1);
    match finish(bus.handle.submit(absent)) {
        Err(BusError::WorkingCounter {
            expected: 1,
            got: 0,
            response,
        }) => assert_eq!(response.data.as_slice(), &[0, 0]),
        other => panic!("{other:?}"),
    }
    let all = finish(
        bus.handle
            .submit(DatagramRequest::brd(0x0000, 2).expect_wkc(3)),
    );
    assert_eq!(all.unwrap().wkc, 3);
    match finish(
        bus.handle
            .submit(DatagramRequest::brd(0x0000, 2).expect_wkc(4)),
    ) {
        Err(BusError::WorkingCounter {
            expected: 4,
            got: 3,
            response,
        }) => assert_eq!(response.data.len(), 2),
        other => panic!("{other:?}"),
    }
    let (stats, _, _) = bus.stop();
    assert_eq!(stats.wkc_mismatches, 2);
    assert_eq!(stats.datagrams_completed, 3);
}

#[test]
fn bus_refuses_requests_it_cannot_send_without_queueing_them() {
    let bus = start(SLAVES, Answer, config());
    let logical_fprd = DatagramRequest::read(Command::Fprd, DatagramAddress::Logical(0), 2);
    assert!(matches!(
        finish(bus.handle.submit(logical_fprd)),
        Err(BusError::InvalidRequest(_))
    ));
    assert!(matches!(
        finish(bus.handle.lrd(0, 1487)),
        Err(BusError::TooLarge { need: 1487, .. })
    ));
    // Two datagrams of 1000 bytes cannot share a frame.
    let group = bus
        .handle
        .submit_group([DatagramRequest::lrd(0, 1000), DatagramRequest::lrd(0, 1000)]);
    for pending in group {
        assert!(matches!(finish(pending), Err(BusError::TooLarge { .. })));
    }
    // The largest datagram does go through.
    let reply = finish(bus.handle.lrd(0, 1486)).unwrap();
    assert_eq!((reply.data.len(), reply.wkc), (1486, 0));
    let (stats, _, _) = bus.stop();
    assert_eq!(stats.datagrams_sent, 1);
}

#[test]
fn bus_group_travels_in_one_frame_in_order() {
    let (recording, seen) = Recording::new(Answer);
    let bus = start(SLAVES, recording, config());
    // Outputs for all three windows, inputs read back from each slave's memory.
    let mut image = vec![0u8; SLAVES * WINDOW_LEN];
    for slave in 0..SLAVES {
        image[slave * WINDOW_LEN..][..WINDOW_OUTPUTS].copy_from_slice(&[slave as u8 + 1; 4]);
    }
    let group = bus.handle.submit_group([
        DatagramRequest::fpwr(station(1), 0x1900, [0xAB, 0xCD]).expect_wkc(1),
        DatagramRequest::fprd(station(1), 0x1900, 2).expect_wkc(1),
        DatagramRequest::lrw(LOGICAL_START, image.clone()).expect_wkc(3 * SLAVES as u16),
        DatagramRequest::brd(0x0000, 2).expect_wkc(SLAVES as u16),
    ]);
    let results: Vec<_> = group.into_iter().map(finish).collect();
    let results: Vec<_> = results.into_iter().map(Result::unwrap).collect();
    assert_eq!(
        results[1].data.as_slice(),
        &[0xAB, 0xCD],
        "write before read"
    );
    let mut expected = image;
    for slave in 0..SLAVES {
        let inputs = pattern(slave, INPUTS_AT as u16, WINDOW_INPUTS);
        expected[slave * WINDOW_LEN + WINDOW_OUTPUTS..][..WINDOW_INPUTS].copy_from_slice(&inputs);
    }
    assert_eq!(results[2].data.as_slice(), expected);
    let (stats, _, report) = bus.stop();
    assert_eq!(stats.frames_sent, 1);
    assert_eq!(seen.lock().unwrap().len(), 1);
    assert_eq!(seen.lock().unwrap()[0].len(), 4);
    // The outputs reached the slaves.
    for slave in 0..SLAVES {
        let outputs = &report.segment.slaves[slave].mem[bus_support::segment::OUTPUTS_AT..][..4];
        assert_eq!(outputs, &[slave as u8 + 1; 4]);
    }
}

#[test]
fn bus_results_can_be_awaited_without_blocking_a_single_threaded_runtime() {
    let (gated, open) = Gated::new();
    let bus = start(SLAVES, gated, config());
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .unwrap();
    let handle = bus.handle.clone();
    runtime.block_on(async move {
        let work = async {
            // 50 tasks wait at once; the reply to the first frame is held until the task
            // below opens the gate, which it can only do if awaiting did not block the one
            // thread this runtime has.
            let tasks: Vec<_> = (0..50usize)
                .map(|n| {
                    let handle = handle.clone();
                    tokio::spawn(async move {
                        let slave = n % SLAVES;
                        let ado = 0x0600 + n as u16 * 2;
                        let reply = handle.fprd(station(slave), ado, 2).await.unwrap();
                        assert_eq!(reply.data.as_slice(), pattern(slave, ado, 2));
                    })
                })
                .collect();
            let opener = tokio::spawn(async move {
                tokio::task::yield_now().await;
                open.send(()).unwrap();
            });
            for task in tasks {
                task.await.unwrap();
            }
            opener.await.unwrap();
        };
        tokio::time::timeout(PATIENCE, work)
            .await
            .expect("awaiting blocked the runtime");
    });
    let (stats, _, _) = bus.stop();
    assert_eq!(stats.datagrams_completed, 50);
}
