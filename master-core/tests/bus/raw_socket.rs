//! The bus end to end over a real (virtual) Ethernet: a raw socket on one end of a veth pair
//! in a network namespace of the test's own, the fake segment on a raw socket at the other.
//!
//! Needs root and iproute2's `ip`; fails with a message saying so otherwise.

use crate::bus_support;

use std::time::Duration;

use bus_support::bus::{finish, start_on};
use bus_support::netns::NetNs;
use bus_support::responder::Answer;
use bus_support::segment::FakeSegment;
use master_core::bus::{BusConfig, DatagramRequest, WaitMode};
use master_core::link::{RawSocket, RawSocketOptions};

const SLAVES: usize = 3;

fn run_over_veth(wait_mode: WaitMode) {
    let ns = NetNs::new();
    ns.add_veth_pair("master", "segment");
    let busy_poll = wait_mode == WaitMode::BusyPoll;
    let (near, far) = ns.run_inside(|| {
        (
            RawSocket::open(
                "master",
                RawSocketOptions {
                    busy_poll,
                    ..RawSocketOptions::default()
                },
            )
            .unwrap(),
            RawSocket::open("segment", RawSocketOptions::default()).unwrap(),
        )
    });
    let source_mac = near.mac_address();
    let bus = start_on(
        near,
        far,
        SLAVES,
        Answer,
        BusConfig {
            source_mac,
            wait_mode,
            // A veth pair answers in microseconds; a loaded test machine may take longer.
            response_timeout: Duration::from_millis(500),
            ..BusConfig::default()
        },
    );
    // Count the slaves, as a master's bring-up starts.
    let count = finish(bus.handle.brd(0x0000, 2)).unwrap();
    assert_eq!(count.wkc, SLAVES as u16);
    // Write and read back a register of each slave, and read a long block.
    for slave in 0..SLAVES {
        let station = FakeSegment::station(slave);
        let value = [0x5A, slave as u8];
        finish(
            bus.handle
                .submit(DatagramRequest::fpwr(station, 0x1C00, value).expect_wkc(1)),
        )
        .unwrap();
        let back = finish(bus.handle.fprd(station, 0x1C00, 2)).unwrap();
        assert_eq!(back.data.as_slice(), &value);
        let block = finish(bus.handle.aprd(slave as u16, 0x0200, 1000)).unwrap();
        let expected: Vec<u8> = (0..1000)
            .map(|i| FakeSegment::pattern(slave, 0x0200 + i))
            .collect();
        assert_eq!(block.data.as_slice(), expected);
    }
    // Many at once, sharing frames.
    let pendings: Vec<_> = (0..100usize)
        .map(|n| {
            let slave = n % SLAVES;
            let ado = 0x0300 + n as u16;
            (
                slave,
                ado,
                bus.handle.fprd(FakeSegment::station(slave), ado, 1),
            )
        })
        .collect();
    for (slave, ado, pending) in pendings {
        let reply = finish(pending).unwrap();
        assert_eq!(reply.data[0], FakeSegment::pattern(slave, usize::from(ado)));
    }
    let (stats, _, report) = bus.stop();
    assert_eq!(stats.datagrams_completed, 1 + 3 * 3 + 100);
    assert_eq!(stats.frames_lost, 0, "{stats:?}");
    assert_eq!(stats.frames_foreign + stats.frames_stale, 0);
    assert_eq!(report.frames, stats.frames_sent);
    assert!(stats.frames_sent < stats.datagrams_sent);
    assert!(stats.rtt_p50().is_some());
}

#[test]
fn bus_raw_socket_carries_datagrams_over_veth_in_poll_mode() {
    run_over_veth(WaitMode::Poll);
}

#[test]
fn bus_raw_socket_carries_datagrams_over_veth_in_busy_poll_mode() {
    run_over_veth(WaitMode::BusyPoll);
}
